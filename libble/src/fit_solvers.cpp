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

namespace {

using RowMajor8 = Eigen::Matrix<double, kCoefficientCount, kCoefficientCount, Eigen::RowMajor>;

// Columns whose length is below this fraction of the longest one are zero: the coordinate does not move any
// residual (e.g. X_H with no point in the shatter regime, where the derivative is exactly 0). The scaled
// coordinates are all of order 0.1-100, so no real effect comes near it.
constexpr double kZeroColumn = 1e-12;

// Which columns of `a` (equilibrated: unit length) to keep, in pivot order: the first `rank` of a column-pivoted
// QR, rank from the singular values, then shortened until the kept block passes the test. Empty when none.
std::vector<int> independentColumns(const Eigen::MatrixXd& a) {
  if (a.cols() == 0) return {};
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a);
  const auto& singular = svd.singularValues();
  long rank = 0;
  while (rank < singular.size() && singular(rank) > kJacobianRankTolerance * singular(0)) ++rank;
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  const auto& order = qr.colsPermutation().indices();
  for (; rank > 0; --rank) {
    std::vector<int> kept(order.data(), order.data() + rank);
    Eigen::MatrixXd block(a.rows(), rank);
    for (long j = 0; j < rank; ++j) block.col(j) = a.col(kept[static_cast<size_t>(j)]);
    const Eigen::JacobiSVD<Eigen::MatrixXd> check(block);
    const auto& s = check.singularValues();
    if (s(rank - 1) > kJacobianRankTolerance * s(0)) return kept;
  }
  return {};
}

// The same for a symmetric matrix `h` with unit diagonal (an equilibrated Hessian): pivoted Cholesky, each step
// taking the coordinate with the largest remaining curvature (Schur complement diagonal), stopping when that is
// no longer above the tolerance, then shortened until the kept block's eigenvalues pass the test.
std::vector<int> independentCurvatures(const Eigen::MatrixXd& h) {
  const long n = h.rows();
  Eigen::MatrixXd schur = h;
  std::vector<int> kept;
  std::vector<bool> taken(static_cast<size_t>(n), false);
  for (long step = 0; step < n; ++step) {
    long pivot = -1;
    for (long j = 0; j < n; ++j) {
      if (!taken[static_cast<size_t>(j)] && (pivot < 0 || schur(j, j) > schur(pivot, pivot))) pivot = j;
    }
    if (!(schur(pivot, pivot) > kHessianRankTolerance)) break;
    taken[static_cast<size_t>(pivot)] = true;
    kept.push_back(static_cast<int>(pivot));
    const Eigen::VectorXd column = schur.col(pivot) / std::sqrt(schur(pivot, pivot));
    schur -= column * column.transpose();
  }
  for (; !kept.empty(); kept.pop_back()) {
    const long r = static_cast<long>(kept.size());
    Eigen::MatrixXd block(r, r);
    for (long i = 0; i < r; ++i) {
      for (long j = 0; j < r; ++j) block(i, j) = h(kept[static_cast<size_t>(i)], kept[static_cast<size_t>(j)]);
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(block, Eigen::EigenvaluesOnly);
    const auto& values = eigen.eigenvalues();
    if (eigen.info() == Eigen::Success && values(0) > kHessianRankTolerance * values(r - 1)) break;
  }
  return kept;
}

}  // namespace

namespace {
// The covariance of the kept working coordinates, equilibrated: the true block is D⁻¹ inverse D⁻¹, D = scales.
struct KeptBlock {
  std::vector<int> coordinates;  // working coordinates, in pivot order
  std::vector<double> scales;
  Eigen::MatrixXd inverse;
};

// The ConditionalCovariance of a kept block: the free coordinates not kept are listed as unidentifiable, the
// block is put into the working coordinates' covariance (zero elsewhere), carried to the scaled coefficients by
// toScaled = ∂u/∂w (Σ_u = M Σ_w Mᵀ; for Classify ln σ comes last and is dropped) and converted to SI.
template <typename Matrix>
ConditionalCovariance conditionalCovariance(const std::vector<int>& freeIndices, const KeptBlock& block,
                                            const Matrix& toScaled) {
  ConditionalCovariance result;
  for (int i : freeIndices) {
    if (std::find(block.coordinates.begin(), block.coordinates.end(), i) == block.coordinates.end()) {
      result.unidentifiable.push_back(i);
    }
  }
  if (block.coordinates.empty()) {
    result.failure = "no coefficient is left free once those on bounds and those the data do not determine are held";
    return result;
  }
  Matrix working = Matrix::Zero();
  const size_t r = block.coordinates.size();
  for (size_t i = 0; i < r; ++i) {
    for (size_t j = 0; j < r; ++j) {
      working(block.coordinates[i], block.coordinates[j]) =
          block.inverse(static_cast<long>(i), static_cast<long>(j)) / (block.scales[i] * block.scales[j]);
    }
  }
  const Matrix scaled = toScaled * working * toScaled.transpose();
  for (int i = 0; i < kCoefficientCount; ++i) {
    for (int j = 0; j < kCoefficientCount; ++j) {
      result.covarianceSI[static_cast<size_t>(i * 8 + j)] = scaled(i, j) * scaleOf(i) * scaleOf(j);
    }
  }
  if (!std::all_of(result.covarianceSI.begin(), result.covarianceSI.end(), [](double v) { return std::isfinite(v); })) {
    result.covarianceSI = {};
    result.failure = "the covariance is not finite";
    return result;
  }
  result.available = true;
  return result;
}

// ∂u/∂w, w the working coordinates: the identity where V_H's t is free (w = u), the map's Jacobian where it is
// held.
RowMajor8 workingJacobian(const CoordinateMap& map, const double* q, bool transitionFree) {
  if (transitionFree) return RowMajor8::Identity();
  const auto m = searchToScaledJacobian(map, q);
  return Eigen::Map<const RowMajor8>(m.data());
}
}  // namespace

std::array<double, kCoefficientCount * kCoefficientCount> searchToScaledJacobian(const CoordinateMap& map,
                                                                                  const double* q) {
  using Jet = ceres::Jet<double, kCoefficientCount>;
  std::array<Jet, kCoefficientCount> qs, u;
  for (int i = 0; i < kCoefficientCount; ++i) qs[i] = Jet(q[i], i);
  map.toScaled(qs.data(), u.data());
  std::array<double, kCoefficientCount * kCoefficientCount> m{};
  for (int i = 0; i < kCoefficientCount; ++i) {
    for (int j = 0; j < kCoefficientCount; ++j) m[i * kCoefficientCount + j] = u[i].v[j];
  }
  return m;
}

ConditionalCovariance leastSquaresCovariance(const std::vector<FitPoint>& points, const CoordinateMap& map,
                                             const std::vector<double>& q, const std::vector<bool>& isFree,
                                             const Hinge& hinge, double residualVariance) {
  ConditionalCovariance result;
  std::vector<int> freeIndices;
  for (int i = 0; i < kCoefficientCount; ++i) {
    if (isFree[static_cast<size_t>(i)]) freeIndices.push_back(i);
  }
  // The Jacobian of the residuals (mm) in the working coordinates (see fit_detail.hpp): exact in the scaled
  // coefficients (Jets), then times the map's Jacobian where V_H is tied to the others.
  const RowMajor8 toScaledCoefficients = workingJacobian(map, q.data(), isFree[1]);
  std::array<double, kCoefficientCount> u{};
  map.toScaled(q.data(), u.data());
  using Jet = ceres::Jet<double, kCoefficientCount>;
  std::array<Jet, kCoefficientCount> x;
  for (int i = 0; i < kCoefficientCount; ++i) x[i] = Jet(u[static_cast<size_t>(i)], i);
  constexpr int m = DiameterResidual::kResiduals;
  const long freeCount = static_cast<long>(freeIndices.size());
  Eigen::MatrixXd scaledJacobian(m * static_cast<long>(points.size()), kCoefficientCount);
  for (size_t k = 0; k < points.size(); ++k) {
    Jet r[m];
    DiameterResidual{points[k], nullptr, hinge}(x.data(), r);
    for (int row = 0; row < m; ++row) {
      for (int j = 0; j < kCoefficientCount; ++j) scaledJacobian(static_cast<long>(m * k) + row, j) = r[row].v[j];
    }
  }
  const Eigen::MatrixXd workingFull = scaledJacobian * toScaledCoefficients;
  Eigen::MatrixXd jacobian(workingFull.rows(), freeCount);
  for (long j = 0; j < freeCount; ++j) jacobian.col(j) = workingFull.col(freeIndices[static_cast<size_t>(j)]);
  if (!jacobian.allFinite()) {
    result.failure = "the Jacobian is not finite at the optimum";
    return result;
  }

  // Zero columns are held at once; the others are equilibrated and ranked.
  const Eigen::VectorXd norms = jacobian.colwise().norm();
  const double longest = freeCount > 0 ? norms.maxCoeff() : 0.0;
  std::vector<int> candidates;  // positions in freeIndices
  for (int j = 0; j < static_cast<int>(freeCount); ++j) {
    if (norms(j) > kZeroColumn * longest && norms(j) > 0) candidates.push_back(j);
  }
  Eigen::MatrixXd equilibrated(jacobian.rows(), static_cast<long>(candidates.size()));
  for (size_t c = 0; c < candidates.size(); ++c) {
    equilibrated.col(static_cast<long>(c)) = jacobian.col(candidates[c]) / norms(candidates[c]);
  }
  const std::vector<int> kept = independentColumns(equilibrated);  // positions in candidates

  // (JᵀJ)⁻¹ of the kept columns from the SVD of their equilibrated block, J = U S Vᵀ D: D⁻¹ V S⁻² Vᵀ D⁻¹.
  KeptBlock block;
  Eigen::MatrixXd columns(jacobian.rows(), static_cast<long>(kept.size()));
  for (size_t k = 0; k < kept.size(); ++k) {
    const int position = candidates[static_cast<size_t>(kept[k])];
    columns.col(static_cast<long>(k)) = equilibrated.col(kept[k]);
    block.coordinates.push_back(freeIndices[static_cast<size_t>(position)]);
    block.scales.push_back(norms(position));
  }
  if (!kept.empty()) {
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(columns, Eigen::ComputeThinV);
    const Eigen::MatrixXd scaledV = svd.matrixV() * svd.singularValues().cwiseInverse().asDiagonal();
    block.inverse = residualVariance * scaledV * scaledV.transpose();
  }
  // To the coefficients, then from km/s to SI. The residuals are in mm, but (d - d_c) enters only through them and
  // residualVariance is in mm² too, so the coefficient units are untouched by that.
  return conditionalCovariance(freeIndices, block, toScaledCoefficients);
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

ConditionalCovariance probitCovariance(const std::vector<FitPoint>& points, const CoordinateMap& map,
                                       const std::vector<double>& x, const std::vector<bool>& isFree) {
  constexpr int n = kClassifyCount;
  using RowMajor9 = Eigen::Matrix<double, n, n, Eigen::RowMajor>;
  ConditionalCovariance result;
  ClassifyVector at{};
  map.toScaled(x.data(), at.data());
  at[kCoefficientCount] = x[kCoefficientCount];
  const auto hArray = probitHessian(points, at);
  const RowMajor9 hessianU = Eigen::Map<const RowMajor9>(hArray.data());
  // To the working coordinates (see fit_detail.hpp), ln σ passed through. Where V_H is tied, the map's second
  // derivatives would add gradient terms, but those vanish at an optimum in every free coordinate (and the held
  // ones are dropped).
  RowMajor9 jacobianMap = RowMajor9::Zero();
  jacobianMap.topLeftCorner<kCoefficientCount, kCoefficientCount>() = workingJacobian(map, x.data(), isFree[1]);
  jacobianMap(kCoefficientCount, kCoefficientCount) = 1.0;
  const RowMajor9 hessianX = jacobianMap.transpose() * hessianU * jacobianMap;
  if (!hessianX.allFinite()) {
    result.failure = "the Hessian of the negative log-likelihood is not finite at the optimum";
    return result;
  }

  std::vector<int> freeIndices;
  for (int i = 0; i < n; ++i) {
    if (isFree[static_cast<size_t>(i)]) freeIndices.push_back(i);
  }
  double largest = 0;
  for (int i : freeIndices) largest = std::max(largest, hessianX(i, i));
  // No curvature (or a negative one) on the diagonal: held at once; see kZeroColumn (here squared, a curvature).
  std::vector<int> candidates;  // coordinates
  for (int i : freeIndices) {
    if (hessianX(i, i) > kZeroColumn * kZeroColumn * largest && hessianX(i, i) > 0) candidates.push_back(i);
  }
  const long c = static_cast<long>(candidates.size());
  Eigen::VectorXd scale(c);
  for (long i = 0; i < c; ++i) {
    const int k = candidates[static_cast<size_t>(i)];
    scale(i) = std::sqrt(hessianX(k, k));
  }
  Eigen::MatrixXd equilibrated(c, c);
  for (long i = 0; i < c; ++i) {
    for (long j = 0; j < c; ++j) {
      equilibrated(i, j) =
          hessianX(candidates[static_cast<size_t>(i)], candidates[static_cast<size_t>(j)]) / (scale(i) * scale(j));
    }
  }
  const std::vector<int> kept = independentCurvatures(equilibrated);  // positions in candidates

  KeptBlock block;
  const long r = static_cast<long>(kept.size());
  Eigen::MatrixXd keptBlock(r, r);
  for (long i = 0; i < r; ++i) {
    const int position = kept[static_cast<size_t>(i)];
    block.coordinates.push_back(candidates[static_cast<size_t>(position)]);
    block.scales.push_back(scale(position));
    for (long j = 0; j < r; ++j) keptBlock(i, j) = equilibrated(position, kept[static_cast<size_t>(j)]);
  }
  if (r > 0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(keptBlock);
    block.inverse =
        eigen.eigenvectors() * eigen.eigenvalues().cwiseInverse().asDiagonal() * eigen.eigenvectors().transpose();
  }
  return conditionalCovariance(freeIndices, block, jacobianMap);
}

}  // namespace blt::ble::fit_detail
