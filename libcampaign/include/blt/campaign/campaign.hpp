#pragma once
// A bisection campaign: one base impact scenario, many points (velocity x angle, or diameter x angle), each a
// bisection for its ballistic limit. Read from a TOML file (data/campaigns/README.md gives the format); every
// key is checked and an error names the file, line and key and says what is allowed.

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "blt/sim/impact.hpp"
#include "blt/sim/run_cache.hpp"
#include "blt/sim/scenario.hpp"

namespace blt::campaign {

// One point: the values it fixes. With variable = diameter a point fixes the velocity (and the diameter is
// bisected); with variable = velocity it fixes the diameter.
struct CampaignPoint {
  double velocity = 0;  // m/s (diameter campaigns)
  double diameter = 0;  // m (velocity campaigns)
  double angle = 0;     // rad, from the target normal
  // A bracket of this point's own (SI), in place of the campaign's; NaN when it has none.
  double lower = std::numeric_limits<double>::quiet_NaN(), upper = std::numeric_limits<double>::quiet_NaN();
  int line = 0;         // where it was defined in the campaign file (0: a grid point)
};

// Seeding brackets from a stored BLE fit: the first bracket of a diameter point is the fit's d_c there times
// (1 -+ halfWidth); a bracket that does not hold is widened (each step twice the last) up to the campaign's own.
struct BleSeed {
  std::string db;          // the BLE store (path as resolved against the campaign file)
  std::string fit;         // the fit's name in it
  double density = 0;      // kg/m³ of the projectile for the prediction; 0: the projectile material's density
  double halfWidth = 0.1;  // relative half-width of the first bracket
};

struct Campaign {
  std::string name, description;
  std::string path;                   // the campaign file
  std::string scenarioPath;           // the base scenario, as resolved against the campaign file
  std::string scenarioText;           // its contents, read once: every run of a session builds on these bytes
  std::vector<std::string> settings;  // key=value on top of the scenario for every run (resolution, run time)
  sim::BisectVariable variable = sim::BisectVariable::diameter;
  double lower = 0, upper = 0;        // SI, the campaign's bracket; perforation expected at upper, not at lower
  double tolerance = 0;               // SI, half-width of a resolved point's final bracket
  int maxRuns = 30;                   // per point, bracket runs included
  std::optional<BleSeed> ble;
  std::vector<CampaignPoint> points;  // explicit points in file order, then the grid (angle-major)

  // What defines the campaign's runs, as JSON with SI values: everything above but the paths, the description
  // and the BLE store's location (the scenario by the hash of its text). Two sessions whose definitions agree
  // make the same runs given the same outcomes.
  nlohmann::json definition() const;
  std::string definitionHash() const;
};

// The key=value settings that fix a point on the base scenario (projectile.velocity and .angle, or .diameter),
// exact: values in SI written as the shortest text that reads back to the same double.
std::vector<std::string> pointSettings(const Campaign& c, const CampaignPoint& p);
// The setting that puts the bisected variable at `value` (SI).
std::string variableSetting(const Campaign& c, double value);
// "4.5 km/s, 45 deg" (or "1.2 mm, 45 deg" for velocity campaigns), for progress and status.
std::string describePoint(const Campaign& c, const CampaignPoint& p);
// Text of a double that parses back to the same value (std::to_chars' shortest round trip).
std::string exactNumber(double v);

// Reads a campaign file. Paths in it (scenario, ble.db) are relative to the file's directory. Every point's
// scenario is checked at both ends of its bracket, so that a bad setting is an error now, not in a run hours in.
// Throws InputError.
Campaign loadCampaign(const std::string& path);
// The same from text; `sourceName` names it in errors and is what relative paths resolve against.
Campaign parseCampaign(const std::string& text, const std::string& sourceName);

// The scenario of one run: the base scenario's text with `settings` (all of them: the campaign's come first).
// Throws InputError.
sim::ImpactScenario runScenario(const Campaign& c, const std::vector<std::string>& settings);

// The identity of a run's inputs (scenario text and settings), as every run store keys it.
using sim::scenarioHash;

}  // namespace blt::campaign
