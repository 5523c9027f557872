// The numerical side of fitting the Christiansen BLE: the normal distribution, the global search + local polish,
// the least-squares covariance and the probit likelihood's derivatives. See fit_detail.hpp for the coordinates.
#include <ceres/ceres.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <nlopt.hpp>
#include <numeric>

#include "fit_detail.hpp"

namespace blt::ble::fit_detail {

namespace {
constexpr double kInvSqrt2 = 0.70710678118654752440;
// NLopt's random generator is seeded with this before every search, so a fit never depends on what ran before.
constexpr unsigned long kSearchSeed = 20240531;
// Polishing starts besides the given start and the search's best: the next best visited points that differ from
// every chosen one by more than kDistinctStart of the box in some coordinate.
constexpr int kExtraPolishStarts = 3;
constexpr double kDistinctStart = 0.05;
}  // namespace

// ---- Normal distribution -------------------------------------------------------------------------------------

double logNormalCdf(double x) {
  // Upper half: Φ = 1 - Q with Q small, so log1p keeps the digits of Q.
  if (x > 0) return std::log1p(-0.5 * std::erfc(x * kInvSqrt2));
  // std::erfc keeps full relative accuracy in its tail until it underflows near x = -37.5; stay well clear.
  if (x > -30) return std::log(0.5 * std::erfc(-x * kInvSqrt2));
  // Far lower tail: Φ(x) = φ(x)/|x| · (1 - 1/x² + 3/x⁴ - 15/x⁶ + 105/x⁸ - 945/x¹⁰ ...); at |x| >= 30 the omitted
  // terms are below 1e-15 relative.
  const double r = 1.0 / (x * x);
  const double series = 1.0 + r * (-1.0 + r * (3.0 + r * (-15.0 + r * (105.0 - 945.0 * r))));
  return -0.5 * x * x - std::log(-x) - kLogSqrtTwoPi + std::log(series);
}

double normalQuantile(double p) {
  if (!(p > 0.0 && p < 1.0)) return std::numeric_limits<double>::quiet_NaN();
  // Work on the lower tail (q <= 1/2, x <= 0), where Φ(x) = erfc(-x/√2)/2 has full relative accuracy.
  const double q = std::min(p, 1.0 - p);
  // Starting value: the classic three-term rational approximation in t = √(-2 ln q) (Abramowitz & Stegun
  // 26.2.23, |error| < 4.5e-4), then Halley steps, each of which roughly triples the number of correct digits.
  const double t = std::sqrt(-2.0 * std::log(q));
  double x = -(t - (2.515517 + t * (0.802853 + t * 0.010328)) / (1.0 + t * (1.432788 + t * (0.189269 + t * 0.001308))));
  for (int step = 0; step < 3; ++step) {
    const double error = 0.5 * std::erfc(-x * kInvSqrt2) - q;
    const double u = error * std::exp(0.5 * x * x + kLogSqrtTwoPi);  // error / φ(x)
    x -= u / (1.0 + 0.5 * x * u);
  }
  return p < 0.5 ? x : -x;
}

// ---- Global search and local polish --------------------------------------------------------------------------

namespace {

// The global search runs on the free, non-profiled coordinates, normalised to [0, 1].
struct SearchContext {
  const BoundedProblem* problem;
  std::vector<int> searchIndices;
  std::vector<double> base;  // the other coordinates' values
  std::vector<std::pair<double, std::vector<double>>> visits;  // objective, full x

  std::vector<double> toFull(const double* z) const {
    std::vector<double> x = base;
    for (size_t k = 0; k < searchIndices.size(); ++k) {
      const int i = searchIndices[k];
      x[i] = problem->lower[i] + z[k] * (problem->upper[i] - problem->lower[i]);
    }
    return x;
  }
  double normalised(const std::vector<double>& x, size_t k) const {
    const int i = searchIndices[k];
    return (x[i] - problem->lower[i]) / (problem->upper[i] - problem->lower[i]);
  }
  double evaluate(std::vector<double>& x) const {
    const double value = problem->profiledObjective ? problem->profiledObjective(x.data()) : problem->objective(x.data());
    return std::isfinite(value) ? value : std::numeric_limits<double>::max();
  }
};

double searchObjective(unsigned n, const double* z, double* gradient, void* data) {
  (void)n;
  (void)gradient;  // the search is derivative free
  auto* context = static_cast<SearchContext*>(data);
  std::vector<double> x = context->toFull(z);
  const double value = context->evaluate(x);
  context->visits.emplace_back(value, std::move(x));
  return value;
}

// Ceres from `x` within the box, the held coordinates fixed. Returns the objective at the end point.
double polish(const BoundedProblem& bp, std::vector<double>& x) {
  ceres::Problem problem;
  bp.addResiduals(problem, x.data());
  std::vector<int> held;
  for (int i = 0; i < bp.size; ++i) {
    if (!bp.isFree[i]) {
      held.push_back(i);
    } else {
      problem.SetParameterLowerBound(x.data(), i, bp.lower[i]);
      problem.SetParameterUpperBound(x.data(), i, bp.upper[i]);
    }
  }
  if (!held.empty()) problem.SetManifold(x.data(), new ceres::SubsetManifold(bp.size, held));
  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 200;
  options.function_tolerance = 1e-12;
  options.gradient_tolerance = 1e-14;
  options.parameter_tolerance = 1e-12;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  return bp.objective(x.data());
}

}  // namespace

std::vector<double> minimise(const BoundedProblem& problem, std::vector<double> start, int globalEvaluations) {
  SearchContext context{&problem, {}, {}, {}};
  for (int i = 0; i < problem.size; ++i) {
    start[i] = std::clamp(start[i], problem.lower[i], problem.upper[i]);
    const bool profiled = !problem.profiled.empty() && problem.profiled[i];
    if (problem.isFree[i] && !profiled) context.searchIndices.push_back(i);
  }
  std::vector<std::vector<double>> starts{start};

  const size_t m = context.searchIndices.size();
  if (globalEvaluations > 0 && m > 0) {
    context.base = start;
    context.visits.reserve(static_cast<size_t>(globalEvaluations) + 1);
    std::vector<double> z(m);
    // Three searches share the budget and pool what they visit: controlled random search (CRS2 with local
    // mutation), multi-level single linkage on a Sobol sequence with BOBYQA local searches, and DIRECT-L's
    // systematic box division. The objective is rough (every point whose velocity crosses V1 or V2 puts a kink
    // in it): on the seed's stage-1 problem, against a brute-force grid, each of them alone missed the optimum
    // for some minimum transition width, the three pooled did not. All are derivative free and start from
    // `start`; NLopt's generator is reseeded before each.
    const nlopt::algorithm algorithms[] = {nlopt::GN_CRS2_LM, nlopt::GN_MLSL_LDS, nlopt::GN_DIRECT_L};
    const int share = globalEvaluations / 3;
    for (int a = 0; a < 3; ++a) {
      const int evaluations = a == 0 ? globalEvaluations - 2 * share : share;
      if (evaluations <= 0) continue;
      nlopt::opt search(algorithms[a], static_cast<unsigned>(m));
      if (algorithms[a] == nlopt::GN_MLSL_LDS) {
        nlopt::opt local(m >= 2 ? nlopt::LN_BOBYQA : nlopt::LN_COBYLA, static_cast<unsigned>(m));  // BOBYQA needs n >= 2
        local.set_xtol_rel(1e-6);
        local.set_maxeval(200);
        search.set_local_optimizer(local);
      }
      search.set_lower_bounds(std::vector<double>(m, 0.0));
      search.set_upper_bounds(std::vector<double>(m, 1.0));
      search.set_min_objective(searchObjective, &context);
      search.set_maxeval(evaluations);
      nlopt::srand(kSearchSeed);
      for (size_t k = 0; k < m; ++k) z[k] = context.normalised(start, k);
      double value = 0;
      try {
        search.optimize(z, value);
      } catch (const std::exception&) {
        // Round-off or a stalled search: what it visited is still good for starts.
      }
    }
    // The best visited points, distinct from one another and from the start.
    std::stable_sort(context.visits.begin(), context.visits.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    std::vector<std::vector<double>> chosen{start};
    const auto distinct = [&](const std::vector<double>& x) {
      return std::all_of(chosen.begin(), chosen.end(), [&](const std::vector<double>& other) {
        for (size_t k = 0; k < m; ++k) {
          if (std::abs(context.normalised(other, k) - context.normalised(x, k)) > kDistinctStart) return true;
        }
        return false;
      });
    };
    for (const auto& visit : context.visits) {
      if (static_cast<int>(chosen.size()) > kExtraPolishStarts + 1) break;
      if (!distinct(visit.second)) continue;
      chosen.push_back(visit.second);
      starts.push_back(visit.second);
    }
  }

  std::vector<double> best = start;
  double bestValue = problem.objective(start.data());
  if (!std::isfinite(bestValue)) bestValue = std::numeric_limits<double>::max();
  for (auto x : starts) {
    const double value = polish(problem, x);
    if (std::isfinite(value) && value < bestValue) {
      bestValue = value;
      best = x;
    }
  }
  return best;
}

// ---- Covariances ---------------------------------------------------------------------------------------------

bool leastSquaresCovariance(const std::vector<FitPoint>& points, const std::array<double, kCoefficientCount>& scaled,
                            const std::array<bool, kCoefficientCount>& isFree, const Hinge& hinge,
                            double residualVariance, std::array<double, 64>& covarianceSI) {
  // A fresh problem in scaled coefficients (no V_L < V_H map), so the covariance comes out in the coefficients
  // themselves; the held ones are constant through a SubsetManifold and get zero rows and columns.
  std::array<double, kCoefficientCount> u = scaled;
  ceres::Problem problem;
  for (const FitPoint& point : points) {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<DiameterResidual, DiameterResidual::kResiduals, kCoefficientCount>(
            new DiameterResidual{point, nullptr, hinge}),
        nullptr, u.data());
  }
  std::vector<int> held;
  for (int i = 0; i < kCoefficientCount; ++i) {
    if (!isFree[i]) held.push_back(i);
  }
  if (!held.empty()) problem.SetManifold(u.data(), new ceres::SubsetManifold(kCoefficientCount, held));

  // Ceres reports a rank-deficient Jacobian through glog on stderr; look first, with the same test it applies
  // (reciprocal condition number of JᵀJ, i.e. (σ_min/σ_max)² of J, below 1e-14), and stay quiet.
  {
    using Jet = ceres::Jet<double, kCoefficientCount>;
    std::array<Jet, kCoefficientCount> x;
    for (int i = 0; i < kCoefficientCount; ++i) x[i] = Jet(u[i], i);
    std::vector<int> freeIndices;
    for (int i = 0; i < kCoefficientCount; ++i) {
      if (isFree[i]) freeIndices.push_back(i);
    }
    constexpr int m = DiameterResidual::kResiduals;
    Eigen::MatrixXd jacobian(m * points.size(), freeIndices.size());
    for (size_t k = 0; k < points.size(); ++k) {
      Jet r[m];
      DiameterResidual{points[k], nullptr, hinge}(x.data(), r);
      for (int row = 0; row < m; ++row) {
        for (size_t j = 0; j < freeIndices.size(); ++j) {
          jacobian(static_cast<long>(m * k) + row, static_cast<long>(j)) = r[row].v[freeIndices[j]];
        }
      }
    }
    if (!jacobian.allFinite()) return false;
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(jacobian);
    const auto& singular = svd.singularValues();
    if (singular.size() == 0 || singular(0) <= 0) return false;
    const double ratio = singular(singular.size() - 1) / singular(0);
    if (ratio * ratio < 1e-13) return false;
  }
  ceres::Covariance::Options options;
  // Dense SVD: the problem is tiny, and it reports a rank-deficient Jacobian (e.g. no point between V1 and V2, so
  // nothing pins V_L and V_H) instead of returning garbage.
  options.algorithm_type = ceres::DENSE_SVD;
  options.num_threads = 1;
  ceres::Covariance covariance(options);
  const std::vector<std::pair<const double*, const double*>> blocks{{u.data(), u.data()}};
  if (!covariance.Compute(blocks, &problem)) return false;
  std::array<double, 64> c{};
  if (!covariance.GetCovarianceBlock(u.data(), u.data(), c.data())) return false;
  // Ceres returns (JᵀJ)⁻¹, i.e. unit residual variance: scale by s², and from km/s and mm-residuals to SI. The
  // residuals are in mm but (d - d_c) enters only through them, so the coefficient units are untouched by that.
  for (int i = 0; i < kCoefficientCount; ++i) {
    for (int j = 0; j < kCoefficientCount; ++j) {
      covarianceSI[i * 8 + j] = c[i * 8 + j] * residualVariance * scaleOf(i) * scaleOf(j);
    }
  }
  return std::all_of(covarianceSI.begin(), covarianceSI.end(), [](double v) { return std::isfinite(v); });
}

namespace {

// Exact gradient (Jets) of the negative log-likelihood with the regimes given.
void probitGradient(const std::vector<FitPoint>& points, const std::vector<Regime>& regimes, const ClassifyVector& x,
                    ClassifyVector& gradient) {
  using Jet = ceres::Jet<double, kClassifyCount>;
  std::array<Jet, kClassifyCount> xs;
  for (int i = 0; i < kClassifyCount; ++i) xs[i] = Jet(x[i], i);
  Jet total(0.0);
  for (size_t k = 0; k < points.size(); ++k) {
    total += probitFromCriticalDiameter(criticalDiameterInRegime(xs.data(), points[k], regimes[k]),
                                        xs[kCoefficientCount], points[k]);
  }
  for (int i = 0; i < kClassifyCount; ++i) gradient[i] = total.v[i];
}

}  // namespace

std::array<double, kClassifyCount * kClassifyCount> probitHessian(const std::vector<FitPoint>& points,
                                                                  const ClassifyVector& x) {
  // The likelihood is only piecewise smooth: its slope in V_L, V_H, S_L, S_H jumps wherever a point's velocity
  // crosses V1 or V2, and a minimum found by the local solver typically sits exactly on such a crossing (like
  // the minimum of |x|), where no Hessian exists. We take the Hessian of the smooth piece the optimum belongs
  // to: every point keeps the regime it has at x while the coefficients move. It agrees with the likelihood at
  // x and is its Hessian wherever that exists.
  // Differentiation: central differences of the exact (Jet) gradient, steps of 1e-5 relative (truncation error
  // near 1e-10, round-off near 1e-11, relative). Nested Jets would be exact, but Ceres provides pow(double, Jet)
  // only for single-level Jets.
  constexpr int n = kClassifyCount;
  std::vector<Regime> regimes;
  for (const FitPoint& point : points) regimes.push_back(regimeOf(x.data(), point));
  std::array<double, n * n> h{};
  for (int j = 0; j < n; ++j) {
    const double step = 1e-5 * std::max(std::abs(x[j]), 1.0);
    ClassifyVector plus = x, minus = x, gPlus{}, gMinus{};
    plus[j] += step;
    minus[j] -= step;
    probitGradient(points, regimes, plus, gPlus);
    probitGradient(points, regimes, minus, gMinus);
    for (int i = 0; i < n; ++i) h[i * n + j] = (gPlus[i] - gMinus[i]) / (2.0 * step);
  }
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) h[i * n + j] = h[j * n + i] = 0.5 * (h[i * n + j] + h[j * n + i]);
  }
  return h;
}

}  // namespace blt::ble::fit_detail
