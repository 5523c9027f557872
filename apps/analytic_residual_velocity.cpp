// blt analytic residual-velocity: fit the Recht-Ipson / Lambert-Jonas relation to (v_i, v_r) test data, or
// evaluate it for given constants.
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "blt/analytic/residual_velocity.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace blt::cli {

namespace {

namespace rv = blt::analytic;

nlohmann::json optionalJson(const std::optional<double>& value) {
  return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
}

// Options shared by fit and eval for holding a: either --a, or the projectile and plug masses.
struct AOptions {
  std::string aText;
  double projectileMass = 0.0, plugMass = 0.0;
  CLI::Option* aOption = nullptr;
  CLI::Option* projectileOption = nullptr;
  CLI::Option* plugOption = nullptr;

  void add(CLI::App& cmd, const std::string& aHelp) {
    aOption = cmd.add_option("--a", aText, aHelp)->type_name("NUMBER");
    projectileOption = addQuantity(cmd, "--projectile-mass", projectileMass, units::mass,
                                   "projectile mass m_p; with --plug-mass sets a = m_p/(m_p + m_pl) (Recht-Ipson)");
    plugOption = addQuantity(cmd, "--plug-mass", plugMass, units::mass, "plug mass m_pl, with --projectile-mass");
    aOption->excludes(projectileOption)->excludes(plugOption);
  }

  // The value of a when given, validated; empty when neither --a nor the masses were given.
  std::optional<double> value() const {
    if (aOption->count() > 0) {
      const auto where = InputLocation::flag("--a");
      const double a = units::parse(aText, units::dimensionless, where);
      if (!(a > 0.0 && a <= 1.0))
        throw InputError(where, "a = " + aText + " is outside the physical range", "0 < a <= 1");
      return a;
    }
    const bool haveProjectile = projectileOption->count() > 0, havePlug = plugOption->count() > 0;
    if (haveProjectile != havePlug)
      throw InputError(InputLocation::flag(haveProjectile ? "--plug-mass" : "--projectile-mass"),
                       "the flag is missing: a = m_p/(m_p + m_pl) needs both masses",
                       "--projectile-mass and --plug-mass together, or --a");
    if (!haveProjectile) return std::nullopt;
    if (!(projectileMass > 0.0))
      throw InputError(InputLocation::flag("--projectile-mass"),
                       "projectile mass " + number(projectileMass, 5) + " kg is not positive", "a mass above 0 kg");
    if (!(plugMass >= 0.0))
      throw InputError(InputLocation::flag("--plug-mass"), "plug mass " + number(plugMass, 5) + " kg is negative",
                       "a mass of 0 kg or more");
    return rv::rechtIpsonA(projectileMass, plugMass);
  }
};

std::string describeParameter(const rv::FittedParameter& p, const std::string& unit) {
  std::string text = number(p.value, 6) + unit;
  if (p.standardError) text += "  +/- " + number(*p.standardError, 3) + unit;
  if (p.status == rv::ParameterStatus::fixed)
    text += "  (fixed" + (p.note.empty() ? "" : ": " + p.note) + ")";
  else if (p.status == rv::ParameterStatus::atBound)
    text += "  (on a bound: " + p.note + "; no standard error)";
  else if (!p.standardError && !p.note.empty())
    text += "  (no standard error: " + p.note + ")";
  return text;
}

void registerFit(CLI::App& parent) {
  auto* cmd = parent.add_subcommand(
      "fit",
      "Fit v_r = a (v_i^p - v_bl^p)^(1/p) to test data.\n"
      "DATA.csv has columns impact_velocity_m_s,residual_velocity_m_s (m/s); a residual velocity of 0 is a\n"
      "stopped shot. Stopped shots slower than every perforating shot bound v_bl from below, the slowest\n"
      "perforating shot bounds it from above; if the outcomes overlap, every row counts as a v_r measurement.\n"
      "Bounds: 0 < a <= 1, 1 <= p <= 5, v_bl > 0. Standard errors are scaled by SSR/(n - k).\n"
      "Example: blt analytic residual-velocity fit data/examples/residual_velocity_t4_synthetic.csv --json");
  struct State {
    std::string path;
    std::string model = "lambert-jonas";
    AOptions a;
    bool json = false;
  };
  auto s = std::make_shared<State>();
  cmd->add_option("data", s->path, "CSV file with impact_velocity_m_s,residual_velocity_m_s")->required();
  cmd->add_option("--model", s->model,
                  "recht-ipson (p = 2, a and v_bl fitted) or lambert-jonas (a, p, v_bl fitted; default)")
      ->type_name("MODEL");
  s->a.add(*cmd, "hold a at this value instead of fitting it (0 < a <= 1)");
  addJsonFlag(*cmd, s->json);
  cmd->callback([s] {
    const auto model = rv::parseModelName(s->model);
    if (!model)
      throw InputError(InputLocation::flag("--model"), "unknown model '" + s->model + "'",
                       "recht-ipson, lambert-jonas");
    rv::ResidualVelocityFitOptions options;
    options.model = *model;
    options.fixedA = s->a.value();
    const rv::VelocityData data = rv::readVelocityData(s->path);
    const rv::ResidualVelocityFit fit = rv::fitResidualVelocity(data, options);
    if (s->json) {
      printJson({{"model", std::string(rv::modelName(fit.model))},
                 {"source", data.source},
                 {"a", fit.a.value},
                 {"p", fit.p.value},
                 {"v_bl_m_s", fit.ballisticLimit.value},
                 {"a_stderr", optionalJson(fit.a.standardError)},
                 {"p_stderr", optionalJson(fit.p.standardError)},
                 {"v_bl_m_s_stderr", optionalJson(fit.ballisticLimit.standardError)},
                 {"a_status", std::string(rv::statusName(fit.a.status))},
                 {"p_status", std::string(rv::statusName(fit.p.status))},
                 {"v_bl_status", std::string(rv::statusName(fit.ballisticLimit.status))},
                 {"a_note", fit.a.note},
                 {"p_note", fit.p.note},
                 {"v_bl_note", fit.ballisticLimit.note},
                 {"rms_m_s", fit.rms},
                 {"sigma_m_s", optionalJson(fit.sigma)},
                 {"sum_of_squares_m2_s2", fit.sumOfSquares},
                 {"n_points", fit.nPoints},
                 {"n_stopped", fit.nStopped},
                 {"n_perforated", fit.nPerforated},
                 {"n_used", fit.nUsed},
                 {"n_free_parameters", fit.nFree},
                 {"dof", fit.dof},
                 {"outcomes_overlap", fit.outcomesOverlap},
                 {"misclassified", fit.misclassified},
                 {"v_bl_search_lower_m_s", fit.ballisticLimitLower},
                 {"v_bl_search_upper_m_s", fit.ballisticLimitUpper},
                 {"covariance_note", fit.covarianceNote}});
      return;
    }
    const bool ri = fit.model == rv::ResidualVelocityModel::rechtIpson;
    std::cout << (ri ? "Recht-Ipson" : "Lambert-Jonas") << " fit to " << data.source
              << ": v_r = a (v_i^p - v_bl^p)^(1/p) for v_i > v_bl\n"
              << "  a    = " << describeParameter(fit.a, "") << "\n"
              << "  p    = " << describeParameter(fit.p, "") << "\n"
              << "  v_bl = " << describeParameter(fit.ballisticLimit, " m/s") << "\n"
              << "  rms error " << number(fit.rms, 4) << " m/s over " << fit.nUsed << " rows in the fit";
    if (fit.sigma) std::cout << " (sigma " << number(*fit.sigma, 4) << " m/s, " << fit.dof << " degrees of freedom)";
    std::cout << "\n  " << fit.nPoints << " points: " << fit.nPerforated << " perforated, " << fit.nStopped
              << " stopped; " << fit.misclassified << " outcome(s) on the wrong side of v_bl\n";
    if (fit.outcomesOverlap)
      std::cout << "  outcomes overlap (a stopped shot is faster than a perforating one): every row, stopped ones\n"
                   "  as 0 m/s, counts as a v_r measurement\n";
    else
      std::cout << "  v_bl bracketed by the outcomes: " << number(fit.ballisticLimitLower, 6) << " m/s <= v_bl < "
                << number(fit.ballisticLimitUpper, 6) << " m/s\n";
    if (!fit.covarianceNote.empty()) std::cout << "  no standard errors: " << fit.covarianceNote << "\n";
  });
}

void registerEval(CLI::App& parent) {
  auto* cmd = parent.add_subcommand(
      "eval",
      "Evaluate v_r = a (v_i^p - v_bl^p)^(1/p) (0 for v_i <= v_bl) at one or more impact velocities.\n"
      "Example: blt analytic residual-velocity eval --a 0.9 --p 2.6 --v-bl 133.8m/s --velocity 150m/s,200m/s\n"
      "(constants of seed 003 Table 6, plate T4). Give a directly, or projectile and plug masses (Recht-Ipson).");
  struct State {
    AOptions a;
    std::string pText = "2";
    double ballisticLimit = 0.0;
    std::vector<std::string> velocities;
    bool json = false;
  };
  auto s = std::make_shared<State>();
  s->a.add(*cmd, "velocity ratio constant a (0 < a <= 1); required unless the masses are given");
  cmd->add_option("--p", s->pText, "exponent p (> 0; default 2, Recht-Ipson)")->type_name("NUMBER");
  addQuantity(*cmd, "--v-bl", s->ballisticLimit, units::velocity, "ballistic limit velocity v_bl")->required();
  cmd->add_option("--velocity", s->velocities,
                  "impact velocity v_i with unit (e.g. 200m/s); repeat the flag or give a comma list")
      ->required()
      ->delimiter(',')
      ->type_name("QUANTITY");
  addJsonFlag(*cmd, s->json);
  cmd->callback([s] {
    const std::optional<double> a = s->a.value();
    if (!a)
      throw InputError(InputLocation::flag("--a"), "the flag is missing",
                       "--a NUMBER, or --projectile-mass and --plug-mass");
    const double p = units::parse(s->pText, units::dimensionless, InputLocation::flag("--p"));
    if (!(p > 0.0)) throw InputError(InputLocation::flag("--p"), "p = " + s->pText + " is not positive", "p > 0");
    if (!(s->ballisticLimit >= 0.0))
      throw InputError(InputLocation::flag("--v-bl"), "v_bl = " + number(s->ballisticLimit, 5) + " m/s is negative",
                       "v_bl >= 0 m/s");
    const rv::ResidualVelocityParameters parameters{*a, p, s->ballisticLimit};
    std::vector<double> impact, residual;
    for (const auto& text : s->velocities) {
      const auto where = InputLocation::flag("--velocity");
      const double v = units::parse(text, units::velocity, where);
      if (!(v >= 0.0)) throw InputError(where, "impact velocity '" + text + "' is negative", "a velocity >= 0 m/s");
      impact.push_back(v);
      residual.push_back(rv::residualVelocity(parameters, v));
    }
    if (s->json) {
      printJson({{"a", *a},
                 {"p", p},
                 {"v_bl_m_s", s->ballisticLimit},
                 {"impact_velocity_m_s", impact},
                 {"v_r_m_s", residual}});
      return;
    }
    std::cout << "v_r = a (v_i^p - v_bl^p)^(1/p) with a = " << number(*a, 6) << ", p = " << number(p, 6)
              << ", v_bl = " << number(s->ballisticLimit, 6) << " m/s\n";
    for (size_t i = 0; i < impact.size(); ++i)
      std::cout << "  v_i = " << number(impact[i], 6) << " m/s  ->  v_r = " << number(residual[i], 6) << " m/s"
                << (residual[i] == 0.0 ? "  (stopped)" : "") << "\n";
  });
}

}  // namespace

void registerResidualVelocityCommand(CLI::App& analytic) {
  auto* cmd = analytic.add_subcommand(
      "residual-velocity",
      "Recht-Ipson / Lambert-Jonas residual velocity v_r = a (v_i^p - v_bl^p)^(1/p): fit to data or evaluate");
  cmd->require_subcommand(1);
  registerFit(*cmd);
  registerEval(*cmd);
}

}  // namespace blt::cli
