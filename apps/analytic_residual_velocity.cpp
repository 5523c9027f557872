#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {
void registerResidualVelocityCommand(CLI::App& analytic) { (void)analytic; }
}  // namespace blt::cli
