// Recht-Ipson / Lambert-Jonas residual velocity: evaluation, data reading and the bounded least-squares fit.
// The treatment of stopped shots and of the kink at v_bl is explained in the header.
#include "blt/analytic/residual_velocity.hpp"

#include <ceres/ceres.h>
#include <ceres/covariance.h>
#include <ceres/dynamic_autodiff_cost_function.h>
#include <glog/logging.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace blt::analytic {

namespace {

constexpr double kMinA = 1e-6;  // a > 0: a tiny positive floor keeps the bound closed for the optimiser
constexpr double kMaxA = 1.0;
constexpr double kMinP = 1.0;
constexpr double kMaxP = 5.0;
// v_bl must stay strictly below the slowest perforating shot; this relative gap keeps that shot's residual
// (whose slope in v_bl grows without limit as v_bl reaches it) finite.
constexpr double kBelowShot = 1e-9;
// Relative distance from a bound within which a parameter counts as sitting on it.
constexpr double kOnBound = 1e-7;

// Ceres reports a start that ends in a run of rejected steps (as a start at an exact or degenerate optimum
// does) through glog on stderr, whatever Solver::Options::logging_type says. Such a start is simply
// outvoted by the others, so the message is noise for a CLI user: hold glog to fatal messages during a fit.
class QuietSolverLog {
 public:
  QuietSolverLog() : saved_(FLAGS_minloglevel) { FLAGS_minloglevel = google::GLOG_FATAL; }
  ~QuietSolverLog() { FLAGS_minloglevel = saved_; }
  QuietSolverLog(const QuietSolverLog&) = delete;
  QuietSolverLog& operator=(const QuietSolverLog&) = delete;

 private:
  int saved_;
};

std::string formatNumber(double value) {
  std::ostringstream out;
  out.precision(6);
  out << value;
  return out.str();
}

// The v_r residuals (model - measured) of all rows in one block. a, p and v_bl are separate parameter blocks so
// that each can be bounded or held constant on its own. The model is written as a v_i (1 - (v_bl/v_i)^p)^(1/p),
// which avoids the large powers of v_i^p.
struct ShotResiduals {
  const std::vector<VelocityShot>* shots;

  template <typename T>
  bool operator()(T const* const* parameters, T* residuals) const {
    using std::pow;
    const T& a = parameters[0][0];
    const T& p = parameters[1][0];
    const T& ballisticLimit = parameters[2][0];
    for (size_t i = 0; i < shots->size(); ++i) {
      const VelocityShot& s = (*shots)[i];
      const T gap = T(1.0) - pow(ballisticLimit / s.impactVelocity, p);
      if (gap <= T(0.0)) {
        residuals[i] = T(-s.residualVelocity);  // predicted stopped
      } else {
        residuals[i] = a * s.impactVelocity * pow(gap, T(1.0) / p) - s.residualVelocity;
      }
    }
    return true;
  }
};

double modelValue(double a, double p, double ballisticLimit, double impactVelocity) {
  if (impactVelocity <= ballisticLimit) return 0.0;
  const double gap = 1.0 - std::pow(ballisticLimit / impactVelocity, p);
  return gap <= 0.0 ? 0.0 : a * impactVelocity * std::pow(gap, 1.0 / p);
}

double sumOfSquares(const std::vector<VelocityShot>& shots, double a, double p, double ballisticLimit) {
  double ssr = 0.0;
  for (const auto& s : shots) {
    const double r = modelValue(a, p, ballisticLimit, s.impactVelocity) - s.residualVelocity;
    ssr += r * r;
  }
  return ssr;
}

// The range v_bl is allowed to take in one bounded fit.
struct Bracket {
  double lower;  // inclusive
  double upper;  // inclusive, already a hair below the measured velocity that closes the interval
};

struct Candidate {
  double a = 0.0, p = 0.0, ballisticLimit = 0.0, ssr = std::numeric_limits<double>::infinity();
  Bracket bracket{0.0, 0.0};
};

class Fitter {
 public:
  Fitter(const std::vector<VelocityShot>& shots, bool freeA, bool freeP, double fixedA, double fixedP)
      : shots_(shots), freeA_(freeA), freeP_(freeP), fixedA_(fixedA), fixedP_(fixedP) {
    for (const auto& s : shots_) costScale_ += s.residualVelocity * s.residualVelocity;
    costScale_ = std::max(costScale_, 1.0);
  }

  // Builds the bounded problem for one bracket around the given start values (held in the members a_, p_, vbl_).
  void build(ceres::Problem& problem, const Bracket& bracket) {
    auto* cost = new ceres::DynamicAutoDiffCostFunction<ShotResiduals, 4>(new ShotResiduals{&shots_});
    for (int block = 0; block < 3; ++block) cost->AddParameterBlock(1);
    cost->SetNumResiduals(static_cast<int>(shots_.size()));
    problem.AddResidualBlock(cost, nullptr, &a_, &p_, &vbl_);
    problem.SetParameterLowerBound(&a_, 0, kMinA);
    problem.SetParameterUpperBound(&a_, 0, kMaxA);
    problem.SetParameterLowerBound(&p_, 0, kMinP);
    problem.SetParameterUpperBound(&p_, 0, kMaxP);
    problem.SetParameterLowerBound(&vbl_, 0, bracket.lower);
    problem.SetParameterUpperBound(&vbl_, 0, bracket.upper);
    if (!freeA_) problem.SetParameterBlockConstant(&a_);
    if (!freeP_) problem.SetParameterBlockConstant(&p_);
  }

  Candidate solve(const Bracket& bracket, double startP, double startBallisticLimit) {
    p_ = freeP_ ? startP : fixedP_;
    vbl_ = startBallisticLimit;
    a_ = freeA_ ? bestA(p_, vbl_) : fixedA_;
    ceres::Problem::Options problemOptions;
    ceres::Problem problem(problemOptions);
    build(problem, bracket);
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::DENSE_QR;
    options.max_num_iterations = 500;
    options.function_tolerance = 1e-14;
    // Absolute in Ceres: scaled by the data (cost units (m/s)^2) so that it sits just above round-off.
    options.gradient_tolerance = 1e-12 * costScale_;
    options.parameter_tolerance = 1e-13;
    options.logging_type = ceres::SILENT;
    options.minimizer_progress_to_stdout = false;
    options.num_threads = 1;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    Candidate c;
    c.a = a_;
    c.p = p_;
    c.ballisticLimit = vbl_;
    c.bracket = bracket;
    // Recomputed in plain doubles so candidates from different brackets compare on the same footing.
    c.ssr = std::isfinite(summary.final_cost) ? sumOfSquares(shots_, a_, p_, vbl_)
                                              : std::numeric_limits<double>::infinity();
    return c;
  }

  // Deterministic multi-start inside one bracket: a grid of v_bl and p starts, a from linear least squares.
  // The starts are ranked by their SSR and the optimiser runs from the best `solvedStarts` of them.
  Candidate fitBracket(const Bracket& bracket, size_t solvedStarts) {
    static constexpr std::array<double, 5> kFractions{0.02, 0.25, 0.5, 0.75, 0.98};
    static constexpr std::array<double, 4> kStartP{1.3, 2.0, 3.0, 4.5};
    struct Start {
      double ssr, p, ballisticLimit;
    };
    std::vector<Start> starts;
    for (double f : kFractions) {
      const double v = bracket.lower + f * (bracket.upper - bracket.lower);
      for (double p : kStartP) {
        const double pStart = freeP_ ? p : fixedP_;
        const double a = freeA_ ? bestA(pStart, v) : fixedA_;
        starts.push_back({sumOfSquares(shots_, a, pStart, v), pStart, v});
        if (!freeP_) break;
      }
    }
    std::stable_sort(starts.begin(), starts.end(), [](const Start& x, const Start& y) { return x.ssr < y.ssr; });
    Candidate best;
    for (size_t i = 0; i < std::min(solvedStarts, starts.size()); ++i) {
      Candidate c = solve(bracket, starts[i].p, starts[i].ballisticLimit);
      if (c.ssr < best.ssr) best = c;
    }
    return best;
  }

  // The a that minimises the SSR for fixed p and v_bl (the model is linear in a), kept within its bounds.
  double bestA(double p, double ballisticLimit) const {
    double num = 0.0, den = 0.0;
    for (const auto& s : shots_) {
      const double g = modelValue(1.0, p, ballisticLimit, s.impactVelocity);
      num += g * s.residualVelocity;
      den += g * g;
    }
    if (den <= 0.0) return 0.5;
    return std::clamp(num / den, 1e-3, kMaxA);
  }

  double a_ = 1.0, p_ = 2.0, vbl_ = 1.0;

 private:
  const std::vector<VelocityShot>& shots_;
  bool freeA_, freeP_;
  double fixedA_, fixedP_;
  double costScale_ = 0.0;
};

bool nearValue(double value, double target, double scale) { return std::abs(value - target) <= kOnBound * scale; }

}  // namespace

double residualVelocity(const ResidualVelocityParameters& parameters, double impactVelocity) {
  if (!(parameters.a > 0.0 && parameters.a <= 1.0))
    throw std::invalid_argument("residualVelocity: a must lie in (0, 1], got " + formatNumber(parameters.a));
  if (!(parameters.p > 0.0))
    throw std::invalid_argument("residualVelocity: p must be > 0, got " + formatNumber(parameters.p));
  if (!(parameters.ballisticLimit >= 0.0))
    throw std::invalid_argument("residualVelocity: v_bl must be >= 0, got " + formatNumber(parameters.ballisticLimit));
  if (!(impactVelocity >= 0.0))
    throw std::invalid_argument("residualVelocity: impact velocity must be >= 0, got " + formatNumber(impactVelocity));
  return modelValue(parameters.a, parameters.p, parameters.ballisticLimit, impactVelocity);
}

double rechtIpsonA(double projectileMass, double plugMass) {
  if (!(projectileMass > 0.0) || !(plugMass >= 0.0))
    throw std::invalid_argument("rechtIpsonA: need projectile mass > 0 and plug mass >= 0");
  return projectileMass / (projectileMass + plugMass);
}

std::string_view modelName(ResidualVelocityModel model) {
  return model == ResidualVelocityModel::rechtIpson ? "recht-ipson" : "lambert-jonas";
}

std::optional<ResidualVelocityModel> parseModelName(std::string_view name) {
  if (name == "recht-ipson") return ResidualVelocityModel::rechtIpson;
  if (name == "lambert-jonas") return ResidualVelocityModel::lambertJonas;
  return std::nullopt;
}

std::string_view statusName(ParameterStatus status) {
  switch (status) {
    case ParameterStatus::fitted:
      return "fitted";
    case ParameterStatus::fixed:
      return "fixed";
    case ParameterStatus::atBound:
      return "at_bound";
  }
  return "fitted";
}

VelocityData velocityDataFromTable(const csv::Table& table) {
  const size_t vi = table.column("impact_velocity_m_s");
  const size_t vr = table.column("residual_velocity_m_s");
  VelocityData data;
  data.source = table.source();
  for (size_t row = 0; row < table.rowCount(); ++row) {
    VelocityShot shot;
    shot.impactVelocity = table.quantity(row, vi, "m/s");
    shot.residualVelocity = table.quantity(row, vr, "m/s");
    shot.line = table.line(row);
    if (!(shot.impactVelocity > 0.0))
      throw InputError(table.where(row, vi), "impact velocity " + table.text(row, vi) + " m/s is not positive",
                       "an impact velocity above 0 m/s");
    if (shot.residualVelocity < 0.0)
      throw InputError(table.where(row, vr), "residual velocity " + table.text(row, vr) + " m/s is negative",
                       "0 m/s for a stopped projectile, otherwise a positive velocity");
    if (shot.residualVelocity > shot.impactVelocity)
      throw InputError(table.where(row, vr),
                       "residual velocity " + table.text(row, vr) + " m/s exceeds the impact velocity " +
                           table.text(row, vi) + " m/s",
                       "0 <= residual velocity <= impact velocity");
    data.shots.push_back(shot);
  }
  return data;
}

VelocityData readVelocityData(const std::string& path) { return velocityDataFromTable(csv::Table::read(path)); }

ResidualVelocityFit fitResidualVelocity(const VelocityData& data, const ResidualVelocityFitOptions& options) {
  const bool freeP = options.model == ResidualVelocityModel::lambertJonas;
  const bool freeA = !options.fixedA.has_value();
  const double fixedP = 2.0;  // Recht-Ipson
  const double fixedA = options.fixedA.value_or(1.0);
  if (!freeA && !(fixedA > 0.0 && fixedA <= 1.0))
    throw std::invalid_argument("fitResidualVelocity: fixed a must lie in (0, 1], got " + formatNumber(fixedA));

  ResidualVelocityFit fit;
  fit.model = options.model;
  fit.nFree = 1 + (freeA ? 1 : 0) + (freeP ? 1 : 0);
  fit.nPoints = static_cast<int>(data.shots.size());
  double fastestStopped = 0.0;
  double slowestPerforating = std::numeric_limits<double>::infinity();
  std::vector<double> velocities;
  for (const auto& s : data.shots) {
    if (!(s.impactVelocity > 0.0) || !(s.residualVelocity >= 0.0) || s.residualVelocity > s.impactVelocity)
      throw std::invalid_argument("fitResidualVelocity: shot outside 0 <= v_r <= v_i, v_i > 0 (validate input first)");
    velocities.push_back(s.impactVelocity);
    if (s.residualVelocity == 0.0) {
      ++fit.nStopped;
      fastestStopped = std::max(fastestStopped, s.impactVelocity);
    } else {
      ++fit.nPerforated;
      slowestPerforating = std::min(slowestPerforating, s.impactVelocity);
    }
  }
  if (fit.nPerforated < fit.nFree)
    throw InputError(InputLocation::file(data.source, std::nullopt, "residual_velocity_m_s"),
                     std::to_string(fit.nPerforated) + " row(s) perforate (residual velocity > 0) but the " +
                         std::string(modelName(options.model)) + " fit has " + std::to_string(fit.nFree) +
                         " free parameters",
                     "at least " + std::to_string(fit.nFree) + " perforating rows (more to get standard errors)");

  std::sort(velocities.begin(), velocities.end());
  velocities.erase(std::unique(velocities.begin(), velocities.end()), velocities.end());
  const double floor = 1e-6 * velocities.front();  // v_bl > 0

  std::vector<Bracket> brackets;
  fit.outcomesOverlap = fit.nStopped > 0 && fastestStopped >= slowestPerforating;
  if (!fit.outcomesOverlap) {
    brackets.push_back({std::max(floor, fastestStopped), slowestPerforating * (1.0 - kBelowShot)});
  } else {
    // Every interval between neighbouring measured velocities, below the fastest one.
    double lower = floor;
    for (double v : velocities) {
      const double upper = v * (1.0 - kBelowShot);
      if (upper > lower) brackets.push_back({lower, upper});
      lower = v;
    }
  }
  fit.ballisticLimitLower = brackets.front().lower;
  fit.ballisticLimitUpper = brackets.back().upper;

  const QuietSolverLog quiet;
  Fitter fitter(data.shots, freeA, freeP, fixedA, fixedP);
  Candidate best;
  if (!fit.outcomesOverlap) {
    best = fitter.fitBracket(brackets.front(), std::numeric_limits<size_t>::max());
  } else {
    // Perforating rows at or below a bracket's lower end are predicted stopped throughout it and add their
    // v_r^2 whatever a and p are: a lower bound on the bracket's SSR. Visiting brackets by that bound lets
    // the ones that cannot beat the best so far be skipped without changing the result.
    std::vector<std::pair<double, size_t>> order;
    for (size_t i = 0; i < brackets.size(); ++i) {
      double floorSsr = 0.0;
      for (const auto& s : data.shots)
        if (s.residualVelocity > 0.0 && s.impactVelocity <= brackets[i].lower)
          floorSsr += s.residualVelocity * s.residualVelocity;
      order.emplace_back(floorSsr, i);
    }
    std::stable_sort(order.begin(), order.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    for (const auto& [floorSsr, i] : order) {
      if (floorSsr >= best.ssr) break;
      Candidate c = fitter.fitBracket(brackets[i], 4);
      if (c.ssr < best.ssr || (c.ssr == best.ssr && brackets[i].lower < best.bracket.lower)) best = c;
    }
  }
  if (!std::isfinite(best.ssr))
    throw std::runtime_error("residual-velocity fit: the optimiser found no finite solution");
  // With overlapping outcomes the top of a bracket stands a hair below a measured velocity u only to keep the
  // slope finite; the SSR is continuous there and v_bl = u itself is the next bracket's lower end. Snap to
  // it so that the shot at u is classified as the model says (stopped) rather than by the hair.
  if (fit.outcomesOverlap && best.ballisticLimit >= best.bracket.upper * (1.0 - kOnBound)) {
    const double closing = best.bracket.upper / (1.0 - kBelowShot);
    const auto it = std::lower_bound(velocities.begin(), velocities.end(), closing * (1.0 - 1e-12));
    if (it != velocities.end()) {
      best.ballisticLimit = *it;
      best.ssr = sumOfSquares(data.shots, best.a, best.p, best.ballisticLimit);
      best.bracket = {*it, *it};
    }
  }

  fit.a = {best.a, std::nullopt, freeA ? ParameterStatus::fitted : ParameterStatus::fixed, {}};
  fit.p = {best.p, std::nullopt, freeP ? ParameterStatus::fitted : ParameterStatus::fixed, {}};
  fit.ballisticLimit = {best.ballisticLimit, std::nullopt, ParameterStatus::fitted, {}};
  if (!freeA) fit.a.note = "held at the given value";
  if (!freeP) fit.p.note = "fixed by the Recht-Ipson model";

  if (freeA && (nearValue(best.a, kMaxA, 1.0) || nearValue(best.a, kMinA, 1.0))) {
    fit.a.status = ParameterStatus::atBound;
    fit.a.note = best.a > 0.5 ? "on the bound a <= 1" : "on the bound a > 0";
  }
  if (freeP && (nearValue(best.p, kMinP, 1.0) || nearValue(best.p, kMaxP, 1.0))) {
    fit.p.status = ParameterStatus::atBound;
    fit.p.note = best.p < 3.0 ? "on the bound p >= 1" : "on the bound p <= 5";
  }
  {
    const double scale = best.bracket.upper;
    const bool onLower = nearValue(best.ballisticLimit, best.bracket.lower, scale);
    const bool onUpper = nearValue(best.ballisticLimit, best.bracket.upper, scale);
    if (onLower || onUpper) {
      fit.ballisticLimit.status = ParameterStatus::atBound;
      if (fit.outcomesOverlap) {
        fit.ballisticLimit.note = best.ballisticLimit <= floor * (1.0 + kOnBound)
                                      ? "on the bound v_bl > 0"
                                      : "at a measured impact velocity, where the model has a kink";
      } else if (onLower) {
        fit.ballisticLimit.note =
            best.ballisticLimit <= floor * (1.0 + kOnBound)
                ? "on the bound v_bl > 0"
                : "held up by the fastest stopped shot (" + formatNumber(fastestStopped) + " m/s)";
      } else {
        fit.ballisticLimit.note =
            "just below the slowest perforating shot (" + formatNumber(slowestPerforating) + " m/s)";
      }
    }
  }

  fit.sumOfSquares = best.ssr;
  for (const auto& s : data.shots) {
    const bool predictedPerforation = s.impactVelocity > best.ballisticLimit;
    const bool stopped = s.residualVelocity == 0.0;
    if (stopped == predictedPerforation) ++fit.misclassified;
    if (!stopped || predictedPerforation) ++fit.nUsed;
  }
  fit.dof = fit.nUsed - fit.nFree;
  fit.rms = fit.nUsed > 0 ? std::sqrt(fit.sumOfSquares / fit.nUsed) : 0.0;
  if (fit.dof > 0) fit.sigma = std::sqrt(fit.sumOfSquares / fit.dof);

  // Covariance of the parameters that are free and inside their bounds; the others are held.
  std::vector<double*> blocks;
  std::vector<FittedParameter*> targets;
  fitter.a_ = best.a;
  fitter.p_ = best.p;
  fitter.vbl_ = best.ballisticLimit;
  ceres::Problem problem;
  fitter.build(problem, best.bracket);
  const std::array<std::pair<double*, FittedParameter*>, 3> all{
      {{&fitter.a_, &fit.a}, {&fitter.p_, &fit.p}, {&fitter.vbl_, &fit.ballisticLimit}}};
  for (const auto& [block, target] : all) {
    if (target->status == ParameterStatus::fitted) {
      blocks.push_back(block);
      targets.push_back(target);
    } else {
      problem.SetParameterBlockConstant(block);
    }
  }
  auto giveUp = [&](const std::string& why) {
    fit.covarianceNote = why;
    for (auto* t : targets) t->note = why;
  };
  if (blocks.empty()) return fit;
  if (!fit.sigma) {
    giveUp("no residual degrees of freedom (" + std::to_string(fit.nUsed) + " rows in the fit, " +
           std::to_string(fit.nFree) + " free parameters)");
    return fit;
  }
  // Rank check on the column-scaled Jacobian first, so that a degenerate data set gives a clear note
  // instead of a pseudo-inverse.
  ceres::Problem::EvaluateOptions evalOptions;
  evalOptions.parameter_blocks = blocks;
  ceres::CRSMatrix crs;
  problem.Evaluate(evalOptions, nullptr, nullptr, nullptr, &crs);
  Eigen::MatrixXd jacobian = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int r = 0; r < crs.num_rows; ++r)
    for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) jacobian(r, crs.cols[k]) = crs.values[k];
  for (int c = 0; c < jacobian.cols(); ++c) {
    const double norm = jacobian.col(c).norm();
    if (norm > 0.0) jacobian.col(c) /= norm;
  }
  const Eigen::VectorXd singular = Eigen::JacobiSVD<Eigen::MatrixXd>(jacobian).singularValues();
  if (singular.size() == 0 || !(singular(singular.size() - 1) > 1e-7 * singular(0))) {
    giveUp("the Jacobian is rank deficient (the data do not determine the parameters separately)");
    return fit;
  }
  ceres::Covariance::Options covOptions;
  covOptions.algorithm_type = ceres::DENSE_SVD;
  covOptions.min_reciprocal_condition_number = 1e-30;  // the scaled check above decides
  covOptions.num_threads = 1;
  ceres::Covariance covariance(covOptions);
  std::vector<std::pair<const double*, const double*>> pairs;
  for (auto* b : blocks) pairs.emplace_back(b, b);
  if (!covariance.Compute(pairs, &problem)) {
    giveUp("the covariance could not be computed");
    return fit;
  }
  const double variance = *fit.sigma * *fit.sigma;
  for (size_t i = 0; i < blocks.size(); ++i) {
    double cii = 0.0;
    covariance.GetCovarianceBlock(blocks[i], blocks[i], &cii);
    if (cii >= 0.0 && std::isfinite(cii))
      targets[i]->standardError = std::sqrt(cii * variance);
    else
      targets[i]->note = "the covariance is not positive";
  }
  return fit;
}

}  // namespace blt::analytic
