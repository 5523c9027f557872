#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {
void registerFlorenceCommand(CLI::App& analytic) { (void)analytic; }
}  // namespace blt::cli
