#pragma once
// What every subcommand shares: flags that take values with units (parsed by the units module, SI inside),
// the --json switch, and printing of JSON documents.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "blt/core/units.hpp"
#include "blt/sim/run.hpp"

namespace blt::cli {

// A wall time as m:ss, or h:mm:ss from an hour on; "?" when not finite (an estimate not yet possible).
inline std::string wallClock(double seconds) {
  if (!std::isfinite(seconds)) return "?";
  const long s = std::lround(seconds);
  char buf[32];
  if (s >= 3600) std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", s / 3600, s / 60 % 60, s % 60);
  else std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  return buf;
}

// Wall seconds left to the end time at the pace so far (simulated time per wall second, over the whole run, a
// resumed run's earlier part included); infinite before any time has passed. A run that stops once its verdict
// settles may end sooner, and one whose time step shrinks later (crushed material), later. Here, not in the
// solver library, so that the model fingerprint (and every cached run) stays as it is.
inline double remainingWallSeconds(const sim::RunProgress& progress) {
  if (!(progress.time > 0) || !(progress.wallSeconds >= 0)) return INFINITY;
  return progress.wallSeconds * std::max(progress.endTime - progress.time, 0.0) / progress.time;
}

// One progress line of a run, for stderr. The kinetic energy is shown only where it is a whole-body figure
// (a 3D example); an axisymmetric scenario's energies are per radian and would mislead without their unit.
inline std::string progressLine(const sim::RunProgress& p, bool withKinetic) {
  char kinetic[48] = "";
  if (withKinetic) std::snprintf(kinetic, sizeof kinetic, "  kinetic %.4g J", p.energy.kinetic);
  char buf[256];
  std::snprintf(buf, sizeof buf, "  step %ld  t = %.2f / %.2f us  dt = %.3g ns%s  %zu particles  wall %.1f s  ETA %s\n",
                p.step, p.time * 1e6, p.endTime * 1e6, p.timeStep * 1e9, kinetic, p.activeParticles, p.wallSeconds,
                wallClock(remainingWallSeconds(p)).c_str());
  return buf;
}

// A value for a message or a table, to `digits` significant digits (shortest form, as an ostream prints it).
inline std::string number(double value, int digits) {
  std::ostringstream out;
  out.precision(digits);
  out << value;
  return out.str();
}

// An option whose value carries a unit ("6.5 km/s"). The SI value is stored in `target`; a missing unit or
// a wrong dimension is an InputError naming the flag. The help text shows an example of the expected unit.
inline CLI::Option* addQuantity(CLI::App& app, const std::string& name, double& target, units::Dimension dim,
                                const std::string& description) {
  const std::string flag = name.substr(0, name.find(','));
  auto* opt = app.add_option_function<std::string>(
      name, [&target, dim, flag](const std::string& text) { target = units::parse(text, dim, InputLocation::flag(flag)); },
      description + " (e.g. " + units::example(dim) + ")");
  opt->type_name(units::describe(dim) == "pressure or stress" ? "STRESS" : "QUANTITY");
  return opt;
}

// A wall-clock interval ("10min", "1h", "30s"; SI seconds in `target`), for how often a long job saves its state.
inline CLI::Option* addWallTime(CLI::App& app, const std::string& name, double& target, const std::string& description) {
  const std::string flag = name.substr(0, name.find(','));
  return app
      .add_option_function<std::string>(
          name, [&target, flag](const std::string& text) { target = units::parse(text, units::time, InputLocation::flag(flag)); },
          description + " (e.g. 10min)")
      ->type_name("DURATION");
}

// Adds --json; subcommands print one JSON document to stdout when it is set.
inline CLI::Option* addJsonFlag(CLI::App& app, bool& json) {
  return app.add_flag("--json", json, "Print one JSON document (SI values, keys carry their unit) instead of text");
}

inline void printJson(const nlohmann::json& doc) { std::cout << doc.dump(2) << "\n"; }

}  // namespace blt::cli
