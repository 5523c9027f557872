// libanalytic: analytical ballistic baselines.
namespace blt::analytic {}
