#pragma once
// Private to the fitting code (fit.cpp, fit_solvers.cpp): the objectives, their coordinates and the solvers.
//
// Coordinates. Three views of the eight coefficients appear here:
//  - SI: (VL, VH, CL, CH, SL, SH, X, XH) as in ChristiansenCoefficients, velocities in m/s.
//  - scaled: the same with VL and VH in km/s, so that every coefficient is of order 0.1-100. Covariances and the
//    Hessian are computed in these and converted to SI at the end.
//  - search (q): scaled, but with VH replaced by t in [0, 1], VH = a + t (VH_max - a), a = max(VH_min, VL + gap).
//    Every q in its box maps onto a coefficient set with VL + gap <= VH inside the user's bounds, which is how
//    V_L < V_H is enforced: Ceres and NLopt only know box bounds. The map has a kink where VL + gap = VH_min;
//    harmless for the local solvers, which already live with the kinks of d_c itself.
// Classify adds a ninth coordinate, ln σ.

#include <ceres/jet.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "blt/ble/christiansen.hpp"

namespace ceres {
class Problem;
}

namespace blt::ble::fit_detail {

constexpr int kCoefficientCount = ChristiansenCoefficients::kCount;
constexpr int kClassifyCount = kCoefficientCount + 1;  // coefficients + ln σ
constexpr double kVelocityScale = 1000.0;               // scaled VL, VH are in km/s
constexpr double kLengthScale = 1000.0;                 // residuals in mm

// One impact point with everything resolved: SI, density known.
struct FitPoint {
  double diameter = 0;  // m
  double velocity = 0;  // m/s
  double angle = 0;     // rad
  double density = 0;   // kg/m³
  bool perforated = false;
};

// Scaled <-> SI for the velocities (indices 0 and 1).
inline double scaleOf(int index) { return index < 2 ? kVelocityScale : 1.0; }

// The search-coordinate map described at the top. All bounds are in scaled units.
struct CoordinateMap {
  std::array<double, kCoefficientCount> lower{}, upper{};  // scaled bounds on the coefficients
  double gap = 0;                                          // smallest VH - VL, km/s

  // Bounds of q. VL's upper bound is trimmed so that VL + gap <= VH_max.
  std::array<double, kCoefficientCount> searchLower() const {
    auto lo = lower;
    lo[1] = 0.0;
    return lo;
  }
  std::array<double, kCoefficientCount> searchUpper() const {
    auto hi = upper;
    hi[0] = std::min(upper[0], upper[1] - gap);
    hi[1] = 1.0;
    return hi;
  }

  // q -> scaled coefficients.
  template <typename T>
  void toScaled(const T* q, T* u) const {
    T floor = q[0] + gap;
    if (floor < lower[1]) floor = T(lower[1]);
    for (int i = 0; i < kCoefficientCount; ++i) u[i] = q[i];
    u[1] = floor + q[1] * (upper[1] - floor);
  }
  // scaled coefficients -> q (VH is clipped into its feasible range first).
  std::array<double, kCoefficientCount> toSearch(const std::array<double, kCoefficientCount>& u) const {
    auto q = u;
    q[0] = std::clamp(u[0], lower[0], searchUpper()[0]);
    const double floor = std::max(lower[1], q[0] + gap);
    q[1] = upper[1] > floor ? std::clamp((u[1] - floor) / (upper[1] - floor), 0.0, 1.0) : 0.0;
    return q;
  }
};

// d_c (m) from scaled coefficients.
template <typename T>
T criticalDiameterScaled(const T* u, const FitPoint& point) {
  T p[kCoefficientCount];
  for (int i = 0; i < kCoefficientCount; ++i) p[i] = u[i] * scaleOf(i);
  return christiansenCriticalDiameter(p, point.velocity, point.angle, point.density);
}

// Which of the three regimes of Eq. 12 a point falls in, by christiansenCriticalDiameter's rule.
enum class Regime { Ballistic, Blend, Shatter };
inline Regime regimeOf(const double* u, const FitPoint& point) {
  const double cosTheta = std::cos(point.angle);
  const double v1 = u[0] * kVelocityScale / std::pow(cosTheta, u[4]);
  const double v2 = u[1] * kVelocityScale / std::pow(cosTheta, u[5]);
  if (point.velocity <= v1) return Regime::Ballistic;
  if (point.velocity >= v2) return Regime::Shatter;
  return Regime::Blend;
}

// d_c (m) from scaled coefficients with the regime given rather than decided: the same formulas as
// christiansenCriticalDiameter, but smooth in every coefficient. Used to differentiate twice at an optimum that
// sits on a regime boundary (see probitHessian).
template <typename T>
T criticalDiameterInRegime(const T* u, const FitPoint& point, Regime regime) {
  using std::pow;
  const double cosTheta = std::cos(point.angle);
  const double sqrtRho = std::sqrt(point.density);
  if (regime == Regime::Ballistic) return u[2] / (sqrtRho * std::cbrt(point.velocity * point.velocity) * pow(cosTheta, u[6]));
  if (regime == Regime::Shatter) return u[3] / (sqrtRho * std::cbrt(point.velocity * point.velocity) * pow(cosTheta, u[7]));
  const T v1 = kVelocityScale * u[0] / pow(cosTheta, u[4]);
  const T v2 = kVelocityScale * u[1] / pow(cosTheta, u[5]);
  const T atV1 = u[2] / (sqrtRho * pow(v1, 2.0 / 3.0) * pow(cosTheta, u[6]));
  const T atV2 = u[3] / (sqrtRho * pow(v2, 2.0 / 3.0) * pow(cosTheta, u[7]));
  const T w = (point.velocity - v1) / (v2 - v1);
  return atV2 * w + atV1 * (1.0 - w);
}

// ---- The standard normal distribution ----------------------------------------------------------------------

constexpr double kLogSqrtTwoPi = 0.91893853320467274178;  // ln √(2π)

// ln Φ(x), accurate to a few ulps over the whole real line (no underflow to -inf for large negative x).
double logNormalCdf(double x);

// ln Φ for Jets: d/dx ln Φ(x) = φ(x)/Φ(x), formed as exp(ln φ - ln Φ) so that it stays finite in the far tail.
template <typename T, int N>
ceres::Jet<T, N> logNormalCdf(const ceres::Jet<T, N>& x) {
  using std::exp;
  const T value = logNormalCdf(x.a);
  const T slope = exp(-0.5 * x.a * x.a - kLogSqrtTwoPi - value);
  return ceres::Jet<T, N>(value, slope * x.v);
}

// Φ⁻¹(p) for 0 < p < 1, to about 1e-15 relative.
double normalQuantile(double p);

// ---- Objectives ----------------------------------------------------------------------------------------------

// The wrong-side hinge of FitOptions: a point adds (weight · v)² to the least-squares objective, v being how far it
// is on the wrong side of the curve less `margin` (see hingeViolation). weight = 0 is plain least squares.
struct Hinge {
  double weight = 0;  // dimensionless
  double margin = 0;  // mm, like the residuals
};

// How far (mm) a point with residual r = d - d_c (mm) falls short of lying `margin` on its own side of the curve
// (perforated above it, stopped below it); 0 when it does. With margin 0 it is the distance on the wrong side.
template <typename T>
T hingeViolation(const T& residual, bool perforated, double margin) {
  const T shortfall = perforated ? margin - residual : margin + residual;
  return shortfall > T(0.0) ? shortfall : T(0.0);
}

// Least squares on d with the wrong-side hinge, two residuals per point: r = (d - d_c) in mm, and weight ·
// hingeViolation(r). Both are continuous in the coefficients, so Σ r² is continuously differentiable. Coefficients
// either in search coordinates (through `map`) or scaled (map == nullptr).
struct DiameterResidual {
  static constexpr int kResiduals = 2;
  FitPoint point;
  const CoordinateMap* map = nullptr;
  Hinge hinge;

  template <typename T>
  bool operator()(const T* x, T* residual) const {
    T u[kCoefficientCount];
    if (map) {
      map->toScaled(x, u);
    } else {
      for (int i = 0; i < kCoefficientCount; ++i) u[i] = x[i];
    }
    residual[0] = kLengthScale * (point.diameter - criticalDiameterScaled(u, point));
    residual[1] = hinge.weight * hingeViolation(residual[0], point.perforated, hinge.margin);
    return true;
  }
};

// One point's share of the probit negative log-likelihood, -ln Φ(±ln(d/d_c)/σ) (+ for perforated, - for
// stopped); x = 8 coefficients then ln σ.
template <typename T>
T probitFromCriticalDiameter(const T& criticalDiameter, const T& logSigma, const FitPoint& point) {
  using std::exp;
  using std::log;
  const T z = (std::log(point.diameter) - log(criticalDiameter)) / exp(logSigma);
  return -logNormalCdf(point.perforated ? z : -z);
}
template <typename T>
T probitNegativeLogLikelihood(const T* u, const T& logSigma, const FitPoint& point) {
  return probitFromCriticalDiameter(criticalDiameterScaled(u, point), logSigma, point);
}

// As a least-squares residual sqrt(-ln L), so that Ceres' Σ r² is the negative log-likelihood (-ln Φ > 0). Where
// Φ rounds to 1 the point costs nothing and has no gradient; sqrt would give 0/0 there.
struct ProbitResidual {
  FitPoint point;
  const CoordinateMap* map = nullptr;

  template <typename T>
  bool operator()(const T* x, T* residual) const {
    using std::sqrt;
    T u[kCoefficientCount];
    if (map) {
      map->toScaled(x, u);
    } else {
      for (int i = 0; i < kCoefficientCount; ++i) u[i] = x[i];
    }
    const T cost = probitNegativeLogLikelihood(u, x[kCoefficientCount], point);
    residual[0] = cost > 1e-300 ? sqrt(cost) : T(0.0);
    return true;
  }
};

// ---- Solvers -------------------------------------------------------------------------------------------------

// A bounded least-squares problem in some coordinates x (size n): objective(x) = Σ r², the same residuals that
// addResiduals puts into a Ceres problem on the single parameter block x.
struct BoundedProblem {
  int size = 0;
  std::vector<double> lower, upper;
  std::vector<bool> isFree;  // held coordinates keep their start value
  std::function<double(const double*)> objective;
  std::function<void(ceres::Problem&, double*)> addResiduals;
  // Optional variable projection for the global search: coordinates marked `profiled` are left out of the
  // search space, and profiledObjective(x) sets them to their best values for the rest of x (in place) and
  // returns the objective there. Least squares on d profiles C_L and C_H, on which d_c depends linearly.
  std::vector<bool> profiled;
  std::function<double(double*)> profiledObjective;
};

// Deterministic global search (NLopt from `start`, `globalEvaluations` evaluations, fixed seed) followed by
// Ceres polishing from the start, the search's best point and the next best distinct points it visited. Returns
// the best point found.
std::vector<double> minimise(const BoundedProblem& problem, std::vector<double> start, int globalEvaluations);

// ---- Covariances conditional on held coordinates --------------------------------------------------------------
//
// An optimum may leave some coordinates without a covariance of their own: a coefficient on a bound of its box
// (the curvature there says nothing about the bound, which the caller holds), or one the data do not determine
// (its Jacobian column is zero, or a combination of the other columns: e.g. V_H and C_H at θ = 0 with no point
// above V_H, where both only set the slope of the blend). The functions below take the search coordinates q the
// caller leaves free, hold the ones that do not add to the numerical rank too, and return the covariance of the
// rest with the held ones treated as known: their rows and columns are zero, and the free ones' block is that of
// the problem with the held ones fixed.
// Working coordinates w. Where V_H's t is free, w = u, the scaled coefficients themselves, so that holding a
// coefficient the data do not determine means exactly that: zero variance for it. Where t is held (on a bound, or
// by the stage), w = q: then V_H is a function of V_L, and the map says which: with t on 0 and V_L + gap above
// V_H's lower bound, V_H moves with V_L (the transition width is active); with t on 1, V_H sits on its upper bound.
// The covariance in w is carried to the coefficients by the Jacobian M = ∂u/∂w (Σ_u = M Σ_w Mᵀ).
//
// Rank. The columns (of J for least squares, of the Hessian's square root for the likelihood) are equilibrated to
// unit length first, so that only directions count, not units. A column-pivoted factorisation then orders them,
// the most independent first; the numerical rank is the number of directions whose relative size exceeds the
// tolerance, and the columns after it in the pivot order are held. The kept block is checked again and, should it
// still be ill-conditioned, shortened by its last pivot. All of it is plain dense linear algebra: deterministic.

// Relative size, on equilibrated columns, of the smallest singular value of J kept: 1e-7 is Ceres' own test
// (reciprocal condition number of JᵀJ below 1e-14) and leaves the covariance, formed from the SVD of J rather
// than from JᵀJ, accurate to about 1e-9.
constexpr double kJacobianRankTolerance = 1e-7;
// Relative size, on an equilibrated Hessian, of the smallest eigenvalue kept. The Hessian is a central difference
// of exact gradients, good to about 1e-10 relative, so directions with a curvature below 1e-8 of the largest are
// within its noise.
constexpr double kHessianRankTolerance = 1e-8;

struct ConditionalCovariance {
  bool available = false;
  std::array<double, 64> covarianceSI{};  // of the 8 coefficients, SI, row-major
  // Coordinates that were free on entry but were held because the data do not determine them (see above).
  std::vector<int> unidentifiable;
  std::string failure;  // why not available, when not
};

// ∂u/∂q of CoordinateMap::toScaled at q (8x8, row-major: row = scaled coefficient, column = search coordinate).
std::array<double, kCoefficientCount * kCoefficientCount> searchToScaledJacobian(const CoordinateMap& map,
                                                                                  const double* q);

// Least squares on d (DiameterResidual with the given hinge, residuals in mm) at the search coordinates q:
// residualVariance (mm²) · (JᵀJ)⁻¹ over the coordinates `isFree` leaves free less the unidentifiable ones, J the
// Jacobian of the residuals with respect to them (in the working coordinates), carried to the coefficients and to
// SI. Index 1 of isFree and of `unidentifiable` stands for V_H's t, i.e. for V_H.
ConditionalCovariance leastSquaresCovariance(const std::vector<FitPoint>& points, const CoordinateMap& map,
                                             const std::vector<double>& q, const std::vector<bool>& isFree,
                                             const Hinge& hinge, double residualVariance);

// Hessian of the probit negative log-likelihood in (scaled coefficients, ln σ), with every point's regime
// frozen at x; see fit_solvers.cpp for why.
using ClassifyVector = std::array<double, kClassifyCount>;
std::array<double, kClassifyCount * kClassifyCount> probitHessian(const std::vector<FitPoint>& points,
                                                                  const ClassifyVector& x);

// The inverse of the observed information (probitHessian, carried to the working coordinates and ln σ) over
// the coordinates of x that `isFree` (size 9) leaves free less the unidentifiable ones (zero or negative
// curvature included): the coefficients' block of it, in SI. With ln σ free, σ is profiled over; held, the
// covariance is conditional on σ as well.
ConditionalCovariance probitCovariance(const std::vector<FitPoint>& points, const CoordinateMap& map,
                                       const std::vector<double>& x, const std::vector<bool>& isFree);

}  // namespace blt::ble::fit_detail
