// Fitting the generalized Christiansen BLE (seed 000 §6; REFERENCE §1): checking the input, the three methods,
// the metrics, cross-validation and the delta-method band. The numerics (global search, polish, covariances,
// the normal distribution) are in fit_solvers.cpp; the coordinates are explained in fit_detail.hpp.
#include "blt/ble/fit.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>

#include "blt/core/error.hpp"
#include "blt/core/units.hpp"
#include "fit_detail.hpp"

namespace blt::ble {

namespace fd = fit_detail;

namespace {

// Points closer than this to θ = 0 are at normal incidence (TwoStage's stage 1). Files give 0 exactly; the
// tolerance only absorbs the round-off of a unit conversion.
constexpr double kNormalIncidence = 1e-9;  // rad
// Classify's probit scatter σ of ln d is kept in [kMinScatter, kMaxScatter]. The floor matters when the curve
// separates the outcomes perfectly: the likelihood then keeps growing as σ -> 0 and has no interior maximum.
constexpr double kMinScatter = 1e-3;
constexpr double kMaxScatter = 2.0;
// Fold assignment: a Fisher-Yates shuffle driven by std::mt19937 (whose output sequence the standard fixes)
// with this seed, so the folds are the same on every platform.
constexpr std::uint32_t kFoldSeed = 20240601;

using Scaled = std::array<double, fd::kCoefficientCount>;
using Mask = std::array<bool, fd::kCoefficientCount>;

std::string number(double value) {
  std::ostringstream out;
  out.precision(6);
  out << value;
  return out.str();
}

// "data.csv:12" -> file data.csv, line 12.
InputLocation pointLocation(const ImpactPoint& point, const std::string& field) {
  const auto colon = point.origin.rfind(':');
  if (colon != std::string::npos && colon + 1 < point.origin.size() &&
      std::all_of(point.origin.begin() + static_cast<long>(colon) + 1, point.origin.end(),
                  [](unsigned char c) { return std::isdigit(c) != 0; })) {
    return InputLocation::file(point.origin.substr(0, colon), std::stoi(point.origin.substr(colon + 1)), field);
  }
  if (!point.origin.empty()) return InputLocation::file(point.origin, std::nullopt, field);
  return InputLocation{{}, std::nullopt, field};
}

std::string pointName(const ImpactPoint& point, size_t index) {
  std::string name = "point " + std::to_string(index + 1);
  if (!point.source.empty()) name += " (" + point.source + ")";
  return name;
}

// The files a data set came from, for errors about the set as a whole.
InputLocation dataLocation(const std::vector<ImpactPoint>& points, const std::string& field) {
  std::vector<std::string> files;
  for (const ImpactPoint& point : points) {
    const std::string file = pointLocation(point, "").source;
    if (!file.empty() && std::find(files.begin(), files.end(), file) == files.end()) files.push_back(file);
  }
  std::string source;
  for (size_t i = 0; i < files.size() && i < 3; ++i) source += (i ? ", " : "") + files[i];
  if (files.size() > 3) source += " and " + std::to_string(files.size() - 3) + " more";
  return InputLocation{source, std::nullopt, field};
}

InputLocation optionLocation(const std::string& field) { return InputLocation{{}, std::nullopt, field}; }

void checkOptions(const FitOptions& options, size_t pointCount) {
  if (!(std::isfinite(options.minimumTransitionWidth) && options.minimumTransitionWidth > 0)) {
    throw InputError(optionLocation("minimumTransitionWidth"),
                     "minimum V_H - V_L of " + number(options.minimumTransitionWidth) + " m/s",
                     "a finite width > 0 m/s (V_L < V_H is required)");
  }
  if (!(std::isfinite(options.wrongSideWeight) && options.wrongSideWeight >= 0)) {
    throw InputError(optionLocation("wrongSideWeight"), "wrong-side weight " + number(options.wrongSideWeight),
                     "a finite weight >= 0 (0 = plain least squares)");
  }
  if (!(std::isfinite(options.wrongSideMargin) && options.wrongSideMargin >= 0)) {
    throw InputError(optionLocation("wrongSideMargin"),
                     "wrong-side margin " + number(units::toUnit(options.wrongSideMargin, "mm")) + " mm",
                     "a finite margin >= 0 mm");
  }
  if (!std::isfinite(options.defaultProjectileDensity) || options.defaultProjectileDensity < 0) {
    throw InputError(optionLocation("defaultProjectileDensity"),
                     "default projectile density " + number(options.defaultProjectileDensity) + " kg/m3",
                     "0 (every point gives its own) or a finite density > 0 kg/m3");
  }
  const auto lower = options.bounds.lower.toArray();
  const auto upper = options.bounds.upper.toArray();
  for (int i = 0; i < fd::kCoefficientCount; ++i) {
    const std::string name = ChristiansenCoefficients::kNames[static_cast<size_t>(i)];
    if (!(std::isfinite(lower[i]) && std::isfinite(upper[i]) && lower[i] < upper[i])) {
      throw InputError(optionLocation("bounds." + name),
                       "bounds [" + number(lower[i]) + ", " + number(upper[i]) + "] are not an interval",
                       "finite lower < upper");
    }
  }
  for (int i : {0, 1, 2, 3}) {
    if (lower[i] <= 0) {
      throw InputError(optionLocation("bounds." + std::string(ChristiansenCoefficients::kNames[static_cast<size_t>(i)])),
                       "lower bound " + number(lower[i]) + " admits non-positive values", "a lower bound > 0");
    }
  }
  if (upper[1] - lower[0] <= options.minimumTransitionWidth) {
    throw InputError(optionLocation("bounds.VH"),
                     "upper bound of VH " + number(upper[1]) + " m/s leaves no room above VL's lower bound " +
                         number(lower[0]) + " m/s",
                     "upper VH > lower VL + " + number(options.minimumTransitionWidth) + " m/s");
  }
  for (int k = 0; k < 4; ++k) {
    const int i = 4 + k;
    const double start = options.angleExponentStart[static_cast<size_t>(k)];
    if (!(start >= lower[i] && start <= upper[i])) {
      throw InputError(optionLocation("angleExponentStart." +
                                      std::string(ChristiansenCoefficients::kNames[static_cast<size_t>(i)])),
                       "start value " + number(start) + " is outside the bounds",
                       "[" + number(lower[i]) + ", " + number(upper[i]) + "]");
    }
  }
  if (options.crossValidationFolds < 0 ||
      (options.crossValidationFolds > 1 && static_cast<size_t>(options.crossValidationFolds) > pointCount)) {
    throw InputError(optionLocation("crossValidationFolds"),
                     std::to_string(options.crossValidationFolds) + " folds for " + std::to_string(pointCount) +
                         " points",
                     "0 or 1 (none), or 2 to the number of points");
  }
  if (options.globalEvaluations < 0) {
    throw InputError(optionLocation("globalEvaluations"), std::to_string(options.globalEvaluations) + " evaluations",
                     "0 (local fit from the start values only) or more");
  }
}

std::vector<fd::FitPoint> resolvePoints(const std::vector<ImpactPoint>& points, double defaultDensity) {
  if (points.empty()) {
    throw InputError(optionLocation("points"), "there are no impact points to fit", "at least one point per coefficient");
  }
  std::vector<fd::FitPoint> resolved;
  resolved.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const ImpactPoint& p = points[i];
    auto fail = [&](const std::string& field, const std::string& what, const std::string& allowed) {
      throw InputError(pointLocation(p, field), pointName(p, i) + ": " + what, allowed);
    };
    if (!(std::isfinite(p.diameter) && p.diameter > 0)) {
      fail("diameter_mm", "diameter " + number(units::toUnit(p.diameter, "mm")) + " mm", "a finite diameter > 0");
    }
    if (!(std::isfinite(p.velocity) && p.velocity > 0)) {
      fail("velocity_km_s", "velocity " + number(units::toUnit(p.velocity, "km/s")) + " km/s",
           "a finite velocity > 0");
    }
    if (!(std::isfinite(p.angle) && p.angle >= 0 && p.angle < 0.5 * std::numbers::pi)) {
      fail("angle_deg", "angle " + number(units::toUnit(p.angle, "deg")) + " deg", "0 <= angle < 90 deg");
    }
    if (!(std::isfinite(p.projectileDensity) && p.projectileDensity >= 0)) {
      fail("projectile_density_kg_m3", "projectile density " + number(p.projectileDensity) + " kg/m3",
           "a finite density > 0 kg/m3, or none (the default density applies)");
    }
    resolved.push_back({p.diameter, p.velocity, p.angle, pointDensity(p, defaultDensity), p.perforated});
  }
  return resolved;
}

fd::CoordinateMap makeMap(const FitOptions& options) {
  fd::CoordinateMap map;
  const auto lower = options.bounds.lower.toArray();
  const auto upper = options.bounds.upper.toArray();
  for (int i = 0; i < fd::kCoefficientCount; ++i) {
    map.lower[i] = lower[i] / fd::scaleOf(i);
    map.upper[i] = upper[i] / fd::scaleOf(i);
  }
  map.gap = options.minimumTransitionWidth / fd::kVelocityScale;
  return map;
}

Scaled toScaled(const fd::CoordinateMap& map, const double* q) {
  Scaled u{};
  map.toScaled(q, u.data());
  return u;
}

ChristiansenCoefficients toCoefficients(const Scaled& u) {
  std::array<double, fd::kCoefficientCount> p{};
  for (int i = 0; i < fd::kCoefficientCount; ++i) p[i] = u[i] * fd::scaleOf(i);
  return ChristiansenCoefficients::fromArray(p.data());
}

// Start values: Christiansen's EMU regime boundaries (seed 000 Eq. 11), the given angle exponents, and C_L = C_H
// = the median of d ρ^½ V^⅔ (cos θ)^X over the points, i.e. the constant that puts the median point on a
// single-branch curve. All clipped into the bounds; the global search takes it from there.
Scaled startValues(const std::vector<fd::FitPoint>& points, const FitOptions& options, const fd::CoordinateMap& map) {
  std::vector<double> constants;
  for (const fd::FitPoint& p : points) {
    constants.push_back(p.diameter * std::sqrt(p.density) * std::cbrt(p.velocity * p.velocity) *
                        std::pow(std::cos(p.angle), options.angleExponentStart[2]));
  }
  std::nth_element(constants.begin(), constants.begin() + static_cast<long>(constants.size() / 2), constants.end());
  const double c = constants[constants.size() / 2];
  Scaled u{5.1, 6.95, c, c, options.angleExponentStart[0], options.angleExponentStart[1],
           options.angleExponentStart[2], options.angleExponentStart[3]};
  for (int i = 0; i < fd::kCoefficientCount; ++i) u[i] = std::clamp(u[i], map.lower[i], map.upper[i]);
  return u;
}

// |d - x a - y b|² = dd - 2 (x ad + y bd) + x² aa + 2 x y ab + y² bb, minimised over a box in (x, y).
struct QuadraticForm {
  double aa = 0, ab = 0, bb = 0, ad = 0, bd = 0, dd = 0;

  double value(double x, double y) const {
    return dd - 2.0 * (x * ad + y * bd) + x * x * aa + 2.0 * x * y * ab + y * y * bb;
  }
  // Sets (x, y) to the minimiser in [xLo, xHi] x [yLo, yHi] and returns the minimum. A convex quadratic on a box
  // has its minimum inside (the unconstrained solution) or on an edge (where the other variable is a clamped 1-D
  // minimiser). A variable that changes nothing (a zero column: no point on that branch) keeps its value.
  double minimiseInBox(double& x, double& y, double xLo, double xHi, double yLo, double yHi) const {
    double bestX = x, bestY = y, best = std::numeric_limits<double>::infinity();
    const auto consider = [&](double cx, double cy) {
      const double v = value(cx, cy);
      if (v < best) {
        best = v;
        bestX = cx;
        bestY = cy;
      }
    };
    const double det = aa * bb - ab * ab;
    if (det > 1e-12 * aa * bb) {
      const double ux = (ad * bb - bd * ab) / det, uy = (aa * bd - ab * ad) / det;
      if (ux >= xLo && ux <= xHi && uy >= yLo && uy <= yHi) consider(ux, uy);
    }
    for (double cy : {y, yLo, yHi}) {
      consider(aa > 0 ? std::clamp((ad - cy * ab) / aa, xLo, xHi) : x, cy);
    }
    for (double cx : {x, xLo, xHi}) {
      consider(cx, bb > 0 ? std::clamp((bd - cx * ab) / bb, yLo, yHi) : y);
    }
    x = bestX;
    y = bestY;
    return std::max(best, 0.0);
  }
};

// The hinge in the residuals' units (mm).
fd::Hinge hingeOf(const FitOptions& options) {
  return {options.wrongSideWeight, options.wrongSideMargin * fd::kLengthScale};
}

// Σ_i f_i(d_i - x a_i - y b_i) with f_i(r) = r² + (w v_i(r))², v_i = fd::hingeViolation: the hinge-augmented
// least-squares objective as a function of (x, y) = (C_L, C_H) for the other coefficients fixed. Each f_i is convex
// and continuously differentiable in r (one quadratic, and another past the hinge point r = ±margin), so the sum is
// a convex piecewise quadratic in (x, y); without the hinge it is QuadraticForm.
struct HingedForm {
  std::vector<double> a, b, d;
  std::vector<bool> perforated;
  fd::Hinge hinge;

  double residual(size_t i, double x, double y) const { return d[i] - x * a[i] - y * b[i]; }
  // σ = +1 for perforated, -1 for stopped: the hinge of point i is active where g = margin - σ r > 0.
  double sign(size_t i) const { return perforated[i] ? 1.0 : -1.0; }

  double value(double x, double y) const {
    double sum = 0;
    for (size_t i = 0; i < d.size(); ++i) {
      const double r = residual(i, x, y);
      const double v = hinge.weight * fd::hingeViolation(r, perforated[i], hinge.margin);
      sum += r * r + v * v;
    }
    return sum;
  }
  // The quadratic that is the objective around (x, y), hinges as they are there (without them when !withHinge): an
  // active hinge adds w² (m - σ r)² to r², i.e. (1 + w²) (r - σ m w² / (1 + w²))² up to a constant, a weighted
  // least-squares term with a shifted target. It has the objective's gradient at (x, y).
  QuadraticForm localForm(double x, double y, bool withHinge) const {
    QuadraticForm form;
    const double w2 = withHinge ? hinge.weight * hinge.weight : 0.0;
    for (size_t i = 0; i < d.size(); ++i) {
      double weight = 1.0, target = d[i];
      if (w2 > 0 && fd::hingeViolation(residual(i, x, y), perforated[i], hinge.margin) > 0) {
        weight = 1.0 + w2;
        target = d[i] - sign(i) * hinge.margin * w2 / weight;
      }
      form.aa += weight * a[i] * a[i];
      form.ab += weight * a[i] * b[i];
      form.bb += weight * b[i] * b[i];
      form.ad += weight * a[i] * target;
      form.bd += weight * b[i] * target;
      form.dd += weight * target * target;
    }
    return form;
  }
  // The exact minimiser s in [0, 1] of the objective on the segment (x, y) + s (dx, dy). Along it r_i = r + s ρ and
  // g_i = g + s h (h = -σ ρ) are linear, so the objective is c0 + c1 s + c2 s² between the values of s where some
  // g_i changes sign; one sweep over those, sorted, toggles each point's hinge once: O(N log N).
  double bestStep(double x, double y, double dx, double dy) const {
    const double w2 = hinge.weight * hinge.weight;
    double c0 = 0, c1 = 0, c2 = 0;
    std::vector<std::pair<double, size_t>> toggles;
    std::vector<double> gs(d.size()), hs(d.size());
    for (size_t i = 0; i < d.size(); ++i) {
      const double r = residual(i, x, y), rate = -(dx * a[i] + dy * b[i]);
      c0 += r * r;
      c1 += 2.0 * r * rate;
      c2 += rate * rate;
      const double g = hinge.margin - sign(i) * r, h = -sign(i) * rate;
      gs[i] = g;
      hs[i] = h;
      if (g > 0 || (g == 0 && h > 0)) {  // active just after s = 0
        c0 += w2 * g * g;
        c1 += 2.0 * w2 * g * h;
        c2 += w2 * h * h;
      }
      if (h != 0 && -g / h > 0 && -g / h < 1) toggles.emplace_back(-g / h, i);
    }
    std::sort(toggles.begin(), toggles.end());
    const auto quadratic = [&](double s) { return c0 + s * (c1 + s * c2); };
    double bestS = 0, best = quadratic(0.0), lo = 0.0;
    for (size_t k = 0; k <= toggles.size(); ++k) {
      const double hi = k < toggles.size() ? toggles[k].first : 1.0;
      if (hi > lo) {
        const double s = c2 > 0 ? std::clamp(-c1 / (2.0 * c2), lo, hi) : (c1 < 0 ? hi : lo);
        if (quadratic(s) < best) {
          best = quadratic(s);
          bestS = s;
        }
      }
      if (k == toggles.size()) break;
      // Past the break the hinge of point i switches: on when h > 0 (g grows through zero), off when h < 0.
      const size_t i = toggles[k].second;
      const double g = gs[i], h = hs[i], on = h > 0 ? 1.0 : -1.0;
      c0 += on * w2 * g * g;
      c1 += on * 2.0 * w2 * g * h;
      c2 += on * w2 * h * h;
      lo = hi;
    }
    return bestS;
  }
  // Sets (x, y) to the minimiser in the box and returns the minimum. Without the hinge: QuadraticForm's closed
  // form. With it, Newton's method for this convex piecewise quadratic, from the plain least-squares solution: the
  // box minimiser of the local quadratic gives the direction (one of descent unless (x, y) is already optimal,
  // since the local quadratic has the objective's gradient there), an exact line search the step. Once the local
  // quadratic is the objective along the whole step, the step lands on the minimiser and the next direction is
  // zero; that takes a handful of steps. kMaxSteps only guards against round-off ping-pong.
  double minimiseInBox(double& x, double& y, double xLo, double xHi, double yLo, double yHi) const {
    localForm(x, y, false).minimiseInBox(x, y, xLo, xHi, yLo, yHi);
    if (hinge.weight == 0) return std::max(value(x, y), 0.0);
    constexpr int kMaxSteps = 50;
    constexpr double kRelativeStep = 1e-13;
    for (int step = 0; step < kMaxSteps; ++step) {
      double nx = x, ny = y;
      localForm(x, y, true).minimiseInBox(nx, ny, xLo, xHi, yLo, yHi);
      if (std::abs(nx - x) <= kRelativeStep * (xHi - xLo) && std::abs(ny - y) <= kRelativeStep * (yHi - yLo)) break;
      const double s = bestStep(x, y, nx - x, ny - y);
      if (s <= 0) break;
      x += s * (nx - x);
      y += s * (ny - y);
    }
    return std::max(value(x, y), 0.0);
  }
};

fd::BoundedProblem leastSquaresProblem(const std::vector<fd::FitPoint>& points, const fd::CoordinateMap& map,
                                       const Mask& isFree, const fd::Hinge& hinge) {
  fd::BoundedProblem problem;
  problem.size = fd::kCoefficientCount;
  const auto lo = map.searchLower();
  const auto hi = map.searchUpper();
  problem.lower.assign(lo.begin(), lo.end());
  problem.upper.assign(hi.begin(), hi.end());
  problem.isFree.assign(isFree.begin(), isFree.end());
  problem.objective = [&points, &map, hinge](const double* q) {
    double sum = 0;
    for (const fd::FitPoint& point : points) {
      double r[fd::DiameterResidual::kResiduals] = {};
      fd::DiameterResidual{point, &map, hinge}(q, r);
      for (double ri : r) sum += ri * ri;
    }
    return sum;
  };
  problem.addResiduals = [&points, &map, hinge](ceres::Problem& ceresProblem, double* q) {
    for (const fd::FitPoint& point : points) {
      using Cost = ceres::AutoDiffCostFunction<fd::DiameterResidual, fd::DiameterResidual::kResiduals,
                                               fd::kCoefficientCount>;
      ceresProblem.AddResidualBlock(new Cost(new fd::DiameterResidual{point, &map, hinge}), nullptr, q);
    }
  };
  if (isFree[2] && isFree[3]) {
    // d_c = C_L A + C_H B with A, B independent of C_L, C_H (each branch and the blend are linear in them), so
    // for the rest fixed the best constants minimise a function of two variables: a 2x2 least-squares problem
    // without the hinge, a convex piecewise quadratic with it (HingedForm), both solved exactly. The search then
    // only roams the regime boundaries and the angle exponents, where the objective is rough.
    problem.profiled = {false, false, true, true, false, false, false, false};
    problem.profiledObjective = [&points, &map, hinge](double* q) {
      Scaled u{};
      map.toScaled(q, u.data());
      HingedForm form;
      form.hinge = hinge;
      for (const fd::FitPoint& point : points) {
        u[2] = 1.0;
        u[3] = 0.0;
        form.a.push_back(fd::kLengthScale * fd::criticalDiameterScaled(u.data(), point));
        u[2] = 0.0;
        u[3] = 1.0;
        form.b.push_back(fd::kLengthScale * fd::criticalDiameterScaled(u.data(), point));
        form.d.push_back(fd::kLengthScale * point.diameter);
        form.perforated.push_back(point.perforated);
      }
      return form.minimiseInBox(q[2], q[3], map.lower[2], map.upper[2], map.lower[3], map.upper[3]);
    };
  }
  return problem;
}

fd::BoundedProblem classifyProblem(const std::vector<fd::FitPoint>& points, const fd::CoordinateMap& map) {
  fd::BoundedProblem problem;
  problem.size = fd::kClassifyCount;
  const auto lo = map.searchLower();
  const auto hi = map.searchUpper();
  problem.lower.assign(lo.begin(), lo.end());
  problem.upper.assign(hi.begin(), hi.end());
  problem.lower.push_back(std::log(kMinScatter));
  problem.upper.push_back(std::log(kMaxScatter));
  problem.isFree.assign(fd::kClassifyCount, true);
  problem.objective = [&points, &map](const double* x) {
    Scaled u{};
    map.toScaled(x, u.data());
    double sum = 0;
    for (const fd::FitPoint& point : points) sum += fd::probitNegativeLogLikelihood(u.data(), x[8], point);
    return sum;
  };
  problem.addResiduals = [&points, &map](ceres::Problem& ceresProblem, double* x) {
    for (const fd::FitPoint& point : points) {
      ceresProblem.AddResidualBlock(new ceres::AutoDiffCostFunction<fd::ProbitResidual, 1, fd::kClassifyCount>(
                                        new fd::ProbitResidual{point, &map}),
                                    nullptr, x);
    }
  };
  return problem;
}

// A free coordinate of a solver's x (search coordinates, then ln σ for Classify) that ended on a bound of its box.
struct BoundHit {
  int index = 0;
  bool atLower = false;
};

std::vector<BoundHit> coordinatesOnBounds(const fd::BoundedProblem& problem, const std::vector<double>& x) {
  std::vector<BoundHit> hits;
  for (int i = 0; i < problem.size; ++i) {
    if (!problem.isFree[static_cast<size_t>(i)]) continue;
    const double tolerance = 1e-6 * (problem.upper[i] - problem.lower[i]);
    const bool atLower = x[i] - problem.lower[i] <= tolerance;
    const bool atUpper = problem.upper[i] - x[i] <= tolerance;
    if (atLower || atUpper) hits.push_back({i, atLower});
  }
  return hits;
}

std::string coordinateName(int index) {
  return index == fd::kCoefficientCount ? "sigma" : ChristiansenCoefficients::kNames[static_cast<size_t>(index)];
}

// A bound value in the units the notes use: km/s for the velocities, the plain number for the rest.
std::string boundValue(int index, double scaled) {
  return index < 2 ? number(scaled) + " km/s" : number(scaled);
}

// V_H's t on 0 makes V_H = max(V_H's lower bound, V_L + gap): tied to V_L where the second is the larger (the
// same rule as CoordinateMap::toScaled, so that the map's Jacobian agrees with the words).
bool transitionWidthActive(const BoundHit& hit, const fd::CoordinateMap& map, const std::vector<double>& x) {
  return hit.index == 1 && hit.atLower && !(x[0] + map.gap < map.lower[1]);
}

// "VH (on its upper bound, 12 km/s)", in words, from the search coordinate's bound.
std::string describeBound(const BoundHit& hit, const fd::CoordinateMap& map, const std::vector<double>& x) {
  const int i = hit.index;
  std::string where;
  if (i == 1) {
    if (!hit.atLower) {
      where = "on its upper bound, " + boundValue(1, map.upper[1]);
    } else if (transitionWidthActive(hit, map, x)) {
      where = "on VL + " + number(map.gap * fd::kVelocityScale) +
              " m/s, the minimum transition width: it moves with VL";
    } else {
      where = "on its lower bound, " + boundValue(1, map.lower[1]);
    }
  } else if (i == 0 && !hit.atLower && map.upper[1] - map.gap < map.upper[0]) {
    where = "on VH's upper bound less the minimum transition width, " + boundValue(0, map.upper[1] - map.gap);
  } else if (i == fd::kCoefficientCount) {
    where = std::string("on its ") + (hit.atLower ? "lower" : "upper") + " bound, " +
            number(hit.atLower ? kMinScatter : kMaxScatter);
  } else {
    where = std::string("on its ") + (hit.atLower ? "lower" : "upper") + " bound, " +
            boundValue(i, hit.atLower ? map.lower[i] : map.upper[i]);
  }
  return coordinateName(i) + " (" + where + ")";
}

std::string joined(const std::vector<std::string>& parts) {
  std::string text;
  for (size_t i = 0; i < parts.size(); ++i) text += (i ? ", " : "") + parts[i];
  return text;
}

// One least-squares stage: the free coefficients fitted from q, the others held.
struct StageFit {
  std::vector<double> q;           // search coordinates at the optimum
  double sumOfSquares = 0;         // objective there (mm²)
  std::vector<BoundHit> onBounds;  // free coordinates that ended on a bound
};
StageFit leastSquaresStage(const std::vector<fd::FitPoint>& points, const fd::CoordinateMap& map,
                           const std::vector<double>& q, const Mask& isFree, const fd::Hinge& hinge,
                           int globalEvaluations) {
  const fd::BoundedProblem problem = leastSquaresProblem(points, map, isFree, hinge);
  StageFit fit;
  fit.q = fd::minimise(problem, q, globalEvaluations);
  fit.sumOfSquares = problem.objective(fit.q.data());
  fit.onBounds = coordinatesOnBounds(problem, fit.q);
  return fit;
}

struct MethodResult {
  Scaled coefficients{};  // scaled
  std::array<double, 64> covariance{};
  bool covarianceAvailable = false;
  std::string covarianceNote;
  double scatter = 0;
  // For the note: coordinates held at their fitted values (zero variance) and V_H tied to V_L, each described with
  // its block and why; and the coordinates on bounds, for when no covariance comes out.
  std::vector<std::string> held, tied, onBounds;
};

// Sorts a block's free coordinates into those the covariance keeps free and those it holds (on a bound) or ties
// (V_H on V_L + gap: t is held, and V_H then moves with V_L), with their descriptions recorded in `result`. The
// held ones are set onto their bounds in `x` (the solver leaves them within its tolerance of it): the covariance is
// conditional on the bound, and the map's Jacobian must see it exactly (with t a hair below 1, V_H would still
// move with V_L).
std::vector<bool> holdBounds(const std::vector<bool>& isFree, const std::vector<BoundHit>& hits,
                             const std::vector<double>& lower, const std::vector<double>& upper,
                             const fd::CoordinateMap& map, std::vector<double>& x, const std::string& block,
                             MethodResult& result) {
  std::vector<bool> free = isFree;
  const std::string prefix = block.empty() ? "" : block + ", ";
  for (const BoundHit& hit : hits) {
    free[static_cast<size_t>(hit.index)] = false;
    const auto i = static_cast<size_t>(hit.index);
    x[i] = hit.atLower ? lower[i] : upper[i];
    std::string text = describeBound(hit, map, x);
    result.onBounds.push_back(text);
    text.insert(text.find('(') + 1, prefix);
    (transitionWidthActive(hit, map, x) ? result.tied : result.held).push_back(text);
  }
  return free;
}

void recordUnidentifiable(const std::vector<int>& indices, const std::string& block, MethodResult& result) {
  const std::string prefix = block.empty() ? "" : block + ", ";
  for (int i : indices) {
    result.held.push_back(coordinateName(i) + " (" + prefix +
                          "not determined by the data at the optimum: its column of the Jacobian is zero or a "
                          "combination of the others')");
  }
}

// Least-squares covariance of one stage (or the joint fit) into `result`; false with a note when unavailable.
// The coefficients on bounds and those the data do not determine are held (see fd::leastSquaresCovariance).
bool addLeastSquaresCovariance(const std::vector<fd::FitPoint>& points, const fd::CoordinateMap& map,
                               const std::vector<double>& q, const Mask& isFree, const std::vector<BoundHit>& hits,
                               const fd::Hinge& hinge, double sumOfSquares, const std::string& label,
                               const std::string& block, MethodResult& result) {
  // The residual variance counts every coefficient the stage fitted, the held ones too: they were fitted (onto a
  // bound, or to a value the data leave open), so they cost degrees of freedom as much as the others.
  const int freeCount = static_cast<int>(std::count(isFree.begin(), isFree.end(), true));
  const int dof = static_cast<int>(points.size()) - freeCount;
  if (dof <= 0) {
    result.covarianceNote += label + ": as many points as coefficients, so no residual variance to scale by. ";
    return false;
  }
  const auto lower = map.searchLower(), upper = map.searchUpper();
  std::vector<double> at = q;
  const std::vector<bool> free = holdBounds(std::vector<bool>(isFree.begin(), isFree.end()), hits,
                                            {lower.begin(), lower.end()}, {upper.begin(), upper.end()}, map, at,
                                            block, result);
  const fd::ConditionalCovariance covariance =
      fd::leastSquaresCovariance(points, map, at, free, hinge, sumOfSquares / dof);
  recordUnidentifiable(covariance.unidentifiable, block, result);
  if (!covariance.available) {
    result.covarianceNote += label + ": " + covariance.failure + ". ";
    return false;
  }
  for (int k = 0; k < 64; ++k) result.covariance[k] += covariance.covarianceSI[k];
  const std::string hingeNote =
      "With the wrong-side hinge, the Jacobian and the residual variance include the active hinge terms: the "
      "curvature of the penalised objective, not of a likelihood. ";
  if (hinge.weight > 0 && result.covarianceNote.find(hingeNote) == std::string::npos) {
    result.covarianceNote += hingeNote;
  }
  return true;
}

// The last words of the note: what the covariance holds and ties, or, without one, what sits on a bound.
void noteHeld(MethodResult& result) {
  if (!result.covarianceAvailable) {
    if (!result.onBounds.empty()) {
      result.covarianceNote += "On a bound at the optimum: " + joined(result.onBounds) + ". ";
    }
    return;
  }
  if (!result.held.empty()) {
    result.covarianceNote += "Held at their fitted values, with zero variance: " + joined(result.held) +
                             ". The covariance of the other coefficients, and every band from it, is conditional "
                             "on these values. ";
  }
  if (!result.tied.empty()) {
    result.covarianceNote += "Tied: " + joined(result.tied) +
                             "; the covariance is conditional on V_H - V_L staying at that width, so VH's variance "
                             "is VL's. ";
  }
}

MethodResult fitTwoStage(const std::vector<ImpactPoint>& raw, const std::vector<fd::FitPoint>& points,
                         const FitOptions& options, const fd::CoordinateMap& map) {
  // Stage 1 takes the points at θ = 0, where d_c does not depend on the angle exponents (seed 000 Eq. 13);
  // stage 2 takes all oblique points. Selecting by angle is the seed's own split (Table 1 + Table 6 at 0 deg,
  // Table 7 at 45 and 60 deg); the caller picks which 0 deg points go in by what it passes.
  std::vector<fd::FitPoint> normal, oblique;
  for (const fd::FitPoint& p : points) (p.angle < kNormalIncidence ? normal : oblique).push_back(p);
  const std::string allowed = "at least 4 points at 0 deg and 4 oblique points, or the joint or classify method";
  const std::string count = std::to_string(points.size());
  if (normal.empty()) {
    throw InputError(dataLocation(raw, "angle_deg"),
                     "the two-stage fit needs points at 0 deg for stage 1 (VL, VH, CL, CH), but none of the " + count +
                         " points is at normal incidence",
                     allowed);
  }
  if (oblique.empty()) {
    throw InputError(dataLocation(raw, "angle_deg"),
                     "the two-stage fit needs oblique points for stage 2 (SL, SH, X, XH), but all " + count +
                         " points are at 0 deg",
                     allowed);
  }
  if (normal.size() < 4 || oblique.size() < 4) {
    throw InputError(dataLocation(raw, "angle_deg"),
                     "fewer points than parameters: " + std::to_string(normal.size()) + " points at 0 deg and " +
                         std::to_string(oblique.size()) + " oblique ones for 4 coefficients in each stage",
                     allowed);
  }
  const Scaled start = startValues(normal, options, map);
  const auto q0 = map.toSearch(start);
  const Mask stage1{true, true, true, true, false, false, false, false};
  const Mask stage2{false, false, false, false, true, true, true, true};
  const fd::Hinge w = hingeOf(options);
  const StageFit fit1 = leastSquaresStage(normal, map, {q0.begin(), q0.end()}, stage1, w, options.globalEvaluations);
  const StageFit fit2 = leastSquaresStage(oblique, map, fit1.q, stage2, w, options.globalEvaluations);

  // Both covariances at the final q, whose stage-1 coordinates are stage 1's (stage 2 held them).
  MethodResult result;
  result.coefficients = toScaled(map, fit2.q.data());
  const bool ok1 = addLeastSquaresCovariance(normal, map, fit2.q, stage1, fit1.onBounds, w, fit1.sumOfSquares,
                                             "Stage 1", "stage 1", result);
  const bool ok2 = addLeastSquaresCovariance(oblique, map, fit2.q, stage2, fit2.onBounds, w, fit2.sumOfSquares,
                                             "Stage 2", "stage 2", result);
  result.covarianceAvailable = ok1 && ok2;
  if (!result.covarianceAvailable) {
    result.covariance = {};
  } else {
    result.covarianceNote +=
        "Two-stage: the (VL, VH, CL, CH) block is stage 1's and the (SL, SH, X, XH) block stage 2's, each scaled "
        "by its own residual variance; the covariances between the blocks are set to zero because stage 2 takes "
        "stage 1's values as exact, so the bands understate the uncertainty at oblique angles. ";
  }
  noteHeld(result);
  return result;
}

MethodResult fitJointLeastSquares(const std::vector<ImpactPoint>& raw, const std::vector<fd::FitPoint>& points,
                                  const FitOptions& options, const fd::CoordinateMap& map) {
  if (points.size() < static_cast<size_t>(fd::kCoefficientCount)) {
    throw InputError(dataLocation(raw, "points"),
                     "fewer points than parameters: " + std::to_string(points.size()) +
                         " points for the 8 coefficients of the joint fit",
                     "at least 8 points");
  }
  const auto q0 = map.toSearch(startValues(points, options, map));
  const Mask all{true, true, true, true, true, true, true, true};
  const StageFit fit =
      leastSquaresStage(points, map, {q0.begin(), q0.end()}, all, hingeOf(options), options.globalEvaluations);
  MethodResult result;
  result.coefficients = toScaled(map, fit.q.data());
  result.covarianceAvailable = addLeastSquaresCovariance(points, map, fit.q, all, fit.onBounds, hingeOf(options),
                                                         fit.sumOfSquares, "Joint fit", "", result);
  if (!result.covarianceAvailable) result.covariance = {};
  noteHeld(result);
  return result;
}

FitQuality quality(const std::vector<fd::FitPoint>& points, const ChristiansenCoefficients& c) {
  FitQuality q;
  double sum = 0;
  for (const fd::FitPoint& p : points) {
    const double dc = criticalDiameter(c, p.velocity, p.angle, p.density);
    sum += (p.diameter - dc) * (p.diameter - dc);
    if ((p.perforated && p.diameter < dc) || (!p.perforated && p.diameter > dc)) ++q.misclassified;
  }
  q.pointCount = static_cast<int>(points.size());
  q.meanSquareError = points.empty() ? 0.0 : sum / static_cast<double>(points.size());
  return q;
}

MethodResult fitClassify(const std::vector<ImpactPoint>& raw, const std::vector<fd::FitPoint>& points,
                         const FitOptions& options, const fd::CoordinateMap& map) {
  const auto perforated = std::count_if(points.begin(), points.end(), [](const auto& p) { return p.perforated; });
  if (perforated == 0 || perforated == static_cast<long>(points.size())) {
    throw InputError(dataLocation(raw, "perforated"),
                     std::string("every one of the ") + std::to_string(points.size()) + " points is " +
                         (perforated ? "perforated" : "stopped") + ": a single outcome class places no curve",
                     "both perforated and stopped points for the classify method");
  }
  if (points.size() < static_cast<size_t>(fd::kClassifyCount)) {
    throw InputError(dataLocation(raw, "points"),
                     "fewer points than parameters: " + std::to_string(points.size()) +
                         " points for the 8 coefficients and the scatter of the classify fit",
                     "at least 9 points");
  }
  // Start: the plain joint least-squares fit (wrongSideWeight does not apply: the likelihood weighs the outcomes
  // itself), with σ the spread of ln(d/d_c) about it.
  const auto q0 = map.toSearch(startValues(points, options, map));
  const Mask all{true, true, true, true, true, true, true, true};
  std::vector<double> x =
      leastSquaresStage(points, map, {q0.begin(), q0.end()}, all, fd::Hinge{}, options.globalEvaluations).q;
  const Scaled uLeastSquares = toScaled(map, x.data());
  double spread = 0;
  for (const fd::FitPoint& p : points) {
    const double r = std::log(p.diameter / fd::criticalDiameterScaled(uLeastSquares.data(), p));
    spread += r * r;
  }
  spread = std::sqrt(spread / static_cast<double>(points.size()));
  x.push_back(std::log(std::clamp(spread, kMinScatter, kMaxScatter)));

  const fd::BoundedProblem problem = classifyProblem(points, map);
  x = fd::minimise(problem, x, options.globalEvaluations);

  MethodResult result;
  result.coefficients = toScaled(map, x.data());
  result.scatter = std::exp(x[fd::kCoefficientCount]);
  const auto onBounds = coordinatesOnBounds(problem, x);

  // A curve that puts every point on its own side gains from every decrease of σ: the likelihood has no maximum at
  // any σ > 0, only a supremum at σ -> 0, and the solver stops where the floor or the round-off of Φ to 1 halts it.
  // The curvature there measures that stopping point, not the data (it may be 1e-180 or 1e+180), so no covariance.
  if (quality(points, toCoefficients(result.coefficients)).misclassified == 0) {
    result.covarianceNote = "No covariance: the curve separates the outcomes without overlap, so the likelihood has "
                            "no maximum at any sigma > 0 (it grows as sigma -> 0) and its curvature at the point "
                            "where the search stopped says nothing about the data. ";
    return result;
  }

  // Covariance: the inverse of the observed information, the Hessian of the negative log-likelihood at the
  // optimum, in (coefficients, ln σ); the coefficients' block of the inverse is their covariance with σ
  // profiled over. ceres::Covariance would return (JᵀJ)⁻¹ of the residuals sqrt(-ln L_k) instead: that is only
  // the Gauss-Newton part of half this Hessian (the Σ r_k ∇²r_k terms do not vanish, since the residuals do not
  // vanish at the optimum), and Ceres' scaling assumes unit-variance residuals, which these are not.
  // Coordinates on bounds, σ among them, are held, and so are those the likelihood does not curve in.
  std::vector<double> at = x;
  const std::vector<bool> free =
      holdBounds(problem.isFree, onBounds, problem.lower, problem.upper, map, at, "", result);
  const fd::ConditionalCovariance covariance = fd::probitCovariance(points, map, at, free);
  recordUnidentifiable(covariance.unidentifiable, "", result);
  if (!covariance.available) {
    result.covarianceNote = "No covariance from the observed information (Hessian of the negative log-likelihood): " +
                            covariance.failure + ". ";
    noteHeld(result);
    return result;
  }
  result.covariance = covariance.covarianceSI;
  result.covarianceAvailable = true;
  const bool sigmaFree = free[fd::kCoefficientCount] &&
                         std::find(covariance.unidentifiable.begin(), covariance.unidentifiable.end(),
                                   fd::kCoefficientCount) == covariance.unidentifiable.end();
  result.covarianceNote = sigmaFree ? "Inverse observed information (Hessian of the negative log-likelihood), sigma "
                                      "profiled. "
                                    : "Inverse observed information (Hessian of the negative log-likelihood) with "
                                      "sigma held. ";
  if (!free[fd::kCoefficientCount]) {
    result.covarianceNote += "The likelihood would move sigma past its bound; the curvature grows as sigma shrinks, "
                             "so at the lower bound the covariance understates the uncertainty. ";
  }
  noteHeld(result);
  return result;
}

double crossValidate(const std::vector<ImpactPoint>& points, const std::vector<fd::FitPoint>& resolved,
                     const FitOptions& options) {
  const int folds = options.crossValidationFolds;
  const size_t n = points.size();
  std::vector<size_t> order(n);
  for (size_t i = 0; i < n; ++i) order[i] = i;
  std::mt19937 rng(kFoldSeed);
  for (size_t i = n - 1; i > 0; --i) std::swap(order[i], order[rng() % (i + 1)]);
  std::vector<int> fold(n);
  for (size_t k = 0; k < n; ++k) fold[order[k]] = static_cast<int>(k % static_cast<size_t>(folds));

  FitOptions inner = options;
  inner.crossValidationFolds = 0;
  size_t correct = 0;
  for (int f = 0; f < folds; ++f) {
    std::vector<ImpactPoint> training;
    for (size_t i = 0; i < n; ++i) {
      if (fold[i] != f) training.push_back(points[i]);
    }
    FitResult fit;
    try {
      fit = fitChristiansen(training, inner);
    } catch (const InputError& e) {
      throw InputError(optionLocation("crossValidationFolds"),
                       "the training set of fold " + std::to_string(f + 1) + " of " + std::to_string(folds) +
                           " cannot be fitted: " + e.what(),
                       "fewer folds, or more points");
    }
    for (size_t i = 0; i < n; ++i) {
      if (fold[i] != f) continue;
      const fd::FitPoint& p = resolved[i];
      const double dc = criticalDiameter(fit.coefficients, p.velocity, p.angle, p.density);
      if (!((p.perforated && p.diameter < dc) || (!p.perforated && p.diameter > dc))) ++correct;
    }
  }
  return static_cast<double>(correct) / static_cast<double>(n);
}

}  // namespace

std::string toString(FitMethod method) {
  switch (method) {
    case FitMethod::TwoStage: return "two-stage";
    case FitMethod::Joint: return "joint";
    case FitMethod::Classify: return "classify";
  }
  return "two-stage";
}

FitMethod fitMethodFromString(const std::string& text) {
  std::string lower = text;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  for (FitMethod m : {FitMethod::TwoStage, FitMethod::Joint, FitMethod::Classify}) {
    if (lower == toString(m)) return m;
  }
  throw InputError(optionLocation("method"), "unknown fit method '" + text + "'", "two-stage, joint, classify");
}

double pointDensity(const ImpactPoint& point, double defaultProjectileDensity) {
  if (point.projectileDensity > 0) return point.projectileDensity;
  if (defaultProjectileDensity > 0) return defaultProjectileDensity;
  std::string name = point.source.empty() ? "the point" : "the point (" + point.source + ")";
  throw InputError(pointLocation(point, "projectile_density_kg_m3"),
                   name + " gives no projectile density and no default density is set",
                   "a projectile_density_kg_m3 column, or a default projectile density > 0 kg/m3 (--density)");
}

FitQuality evaluateFit(const std::vector<ImpactPoint>& points, const ChristiansenCoefficients& coefficients,
                       double defaultProjectileDensity) {
  return quality(resolvePoints(points, defaultProjectileDensity), coefficients);
}

FitResult fitChristiansen(const std::vector<ImpactPoint>& points, const FitOptions& options) {
  checkOptions(options, points.size());
  const std::vector<fd::FitPoint> resolved = resolvePoints(points, options.defaultProjectileDensity);
  const fd::CoordinateMap map = makeMap(options);

  MethodResult method;
  switch (options.method) {
    case FitMethod::TwoStage: method = fitTwoStage(points, resolved, options, map); break;
    case FitMethod::Joint: method = fitJointLeastSquares(points, resolved, options, map); break;
    case FitMethod::Classify: method = fitClassify(points, resolved, options, map); break;
  }

  FitResult result;
  result.method = options.method;
  result.coefficients = toCoefficients(method.coefficients);
  result.covariance = method.covariance;
  result.covarianceAvailable = method.covarianceAvailable;
  result.covarianceNote = method.covarianceNote;
  while (!result.covarianceNote.empty() && result.covarianceNote.back() == ' ') result.covarianceNote.pop_back();
  result.scatter = method.scatter;
  const FitQuality q = quality(resolved, result.coefficients);
  result.meanSquareError = q.meanSquareError;
  result.misclassified = q.misclassified;
  result.pointCount = q.pointCount;
  if (options.crossValidationFolds > 1) result.crossValidatedAccuracy = crossValidate(points, resolved, options);
  return result;
}

DiameterBand criticalDiameterBand(const FitResult& fit, double velocity, double angle, double projectileDensity,
                                  double level) {
  if (!(std::isfinite(velocity) && velocity > 0)) {
    throw InputError(optionLocation("velocity"), "velocity " + number(velocity) + " m/s", "a finite velocity > 0");
  }
  if (!(std::isfinite(angle) && angle >= 0 && angle < 0.5 * std::numbers::pi)) {
    throw InputError(optionLocation("angle"), "angle " + number(units::toUnit(angle, "deg")) + " deg",
                     "0 <= angle < 90 deg");
  }
  if (!(std::isfinite(projectileDensity) && projectileDensity > 0)) {
    throw InputError(optionLocation("projectileDensity"), "projectile density " + number(projectileDensity) + " kg/m3",
                     "a finite density > 0 kg/m3");
  }
  if (!(level > 0 && level < 1)) {
    throw InputError(optionLocation("level"), "confidence level " + number(level), "0 < level < 1, e.g. 0.90");
  }
  // Gradient of d_c with respect to the eight coefficients (SI) by forward-mode autodiff.
  using Jet = ceres::Jet<double, fd::kCoefficientCount>;
  const auto c = fit.coefficients.toArray();
  std::array<Jet, fd::kCoefficientCount> p;
  for (int i = 0; i < fd::kCoefficientCount; ++i) p[i] = Jet(c[i], i);
  const Jet dc = christiansenCriticalDiameter(p.data(), velocity, angle, projectileDensity);
  DiameterBand band{dc.a, dc.a, dc.a};
  if (!fit.covarianceAvailable) return band;
  double variance = 0;
  for (int i = 0; i < fd::kCoefficientCount; ++i) {
    for (int j = 0; j < fd::kCoefficientCount; ++j) variance += dc.v[i] * fit.covariance[i * 8 + j] * dc.v[j];
  }
  // ln d_c has gradient ∇d_c / d_c, so its standard deviation is √(gᵀΣg) / d_c.
  const double sigmaLn = std::sqrt(std::max(variance, 0.0)) / dc.a;
  const double z = fd::normalQuantile(0.5 * (1.0 + level));
  band.low = dc.a * std::exp(-z * sigmaLn);
  band.high = dc.a * std::exp(z * sigmaLn);
  return band;
}

}  // namespace blt::ble
