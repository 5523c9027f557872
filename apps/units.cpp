// blt units: converts a value between units, so a user can check how a flag will be read.
#include "blt/core/units.hpp"

#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

void registerUnitsCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("units", "Show how a value with a unit is read (SI) or convert it: blt units '6.5 km/s' --to m/s");
  auto value = std::make_shared<std::string>();
  auto to = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  cmd->add_option("value", *value, "A value with its unit, e.g. '6.5 km/s'")->required();
  cmd->add_option("--to", *to, "Unit to convert to (default: SI)");
  addJsonFlag(*cmd, *json);
  cmd->callback([value, to, json] {
    const auto where = InputLocation::flag("value");
    const units::Quantity q = units::parseQuantity(*value, where);
    double converted = q.si;
    if (!to->empty()) {
      const units::Quantity target = units::parseUnit(*to, InputLocation::flag("--to"));
      if (!(target.dimension == q.dimension))
        throw InputError(InputLocation::flag("--to"),
                         "'" + *to + "' is a " + units::describe(target.dimension) + ", the value a " +
                             units::describe(q.dimension),
                         "a unit of " + units::describe(q.dimension));
      converted = q.si / target.si;
    }
    if (*json) {
      printJson({{"si_value", q.si}, {"dimension", units::describe(q.dimension)}, {"value", converted}, {"unit", *to}});
    } else {
      std::cout << converted << (to->empty() ? "" : " " + *to) << "  (" << units::describe(q.dimension) << ", SI "
                << q.si << ")\n";
    }
  });
}

}  // namespace blt::cli
