// libsim is built out in issue 4 (MPM impact solver).
namespace blt::sim {}
