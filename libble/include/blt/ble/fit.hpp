#pragma once
// Fitting the generalized Christiansen BLE to binary impact data.
//
// Methods (FitMethod):
//  - TwoStage: seed 000 §6. Least squares on d (each point's diameter is taken as a sample of d_c at its V, θ).
//    Stage 1 fits V_L, V_H, C_L, C_H to the θ = 0 points with S_L, S_H, X, X_H at their start values; stage 2 fits
//    S_L, S_H, X, X_H to the oblique points with stage 1 held. Every point of the list at θ = 0 goes to stage 1
//    and every other one to stage 2, so the caller chooses the stage-1 set by what it passes (the seed's own
//    stage 1 is Table 1 plus only the 7-9 km/s rows of Table 6).
//  - Joint: least squares on d, all eight coefficients at once, all points.
//  - Classify: every point is the binary outcome it is. P(perforated) = Φ(ln(d/d_c) / σ) (probit) with the
//    scatter σ fitted too; the negative log-likelihood is minimised. A perforated point far above the curve or a
//    stopped one far below it costs almost nothing; a point on the wrong side costs.
// The local problems are solved by Ceres (automatic derivatives); starting points come from a deterministic
// global search with NLopt (for least squares with C_L, C_H eliminated in closed form, since d_c is linear in
// them). V_L < V_H is enforced (FitOptions::minimumTransitionWidth). Same data and options, same result.

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "blt/ble/christiansen.hpp"
#include "blt/ble/impact_data.hpp"

namespace blt::ble {

enum class FitMethod { TwoStage, Joint, Classify };
std::string toString(FitMethod method);                // "two-stage", "joint", "classify"
FitMethod fitMethodFromString(const std::string& text);  // throws InputError listing the methods

// Box bounds on the coefficients (SI). Defaults cover every published Christiansen-type fit we know of with room
// to spare; V_L < V_H is enforced on top of these.
struct ChristiansenBounds {
  ChristiansenCoefficients lower{1000.0, 2000.0, 0.1, 0.1, -1.0, -1.0, -1.0, -1.0};
  ChristiansenCoefficients upper{8000.0, 12000.0, 200.0, 200.0, 2.0, 2.0, 3.0, 3.0};
};

struct FitOptions {
  FitMethod method = FitMethod::TwoStage;
  // Projectile density (kg/m³) for points whose data do not give one. 0 = every point must give its own.
  double defaultProjectileDensity = 0.0;
  ChristiansenBounds bounds;
  // Starting values for the angle exponents S_L, S_H, X, X_H (held in stage 1 of TwoStage): Eq. 11's.
  std::array<double, 4> angleExponentStart{0.132, 0.45, 0.5, 0.45};
  // K-fold cross-validated classification accuracy when > 1 (deterministic folds: point i goes to fold i mod K
  // after a fixed-seed shuffle).
  int crossValidationFolds = 0;
  // Evaluations allowed to the NLopt global start search per local problem.
  int globalEvaluations = 4000;
  // The smallest V_H - V_L (m/s) a fit may reach: V_L < V_H is enforced as V_H >= V_L + this (the solvers work
  // with V_H = max(V_H's lower bound, V_L + width) + t (V_H's upper bound - that), t in [0, 1]). Least squares on
  // d tends to end on this bound (left free it drifts to V_H < V_L, REFERENCE §1), so it is a modelling choice:
  // the width of the ballistic-to-shatter blend the fit may not go below. The note says when it is active.
  double minimumTransitionWidth = 100.0;
};

struct FitResult {
  FitMethod method = FitMethod::TwoStage;
  ChristiansenCoefficients coefficients;
  // Covariance of (VL, VH, CL, CH, SL, SH, X, XH), SI, row-major 8x8. Least squares: from ceres::Covariance scaled
  // by the residual variance; Classify: the inverse of the observed information (Hessian of the negative
  // log-likelihood). Rows and columns of coefficients a stage held fixed are zero for that stage's block only.
  std::array<double, 64> covariance{};
  bool covarianceAvailable = false;
  std::string covarianceNote;       // why it is unavailable or partial, when it is
  double scatter = 0.0;             // Classify: fitted σ of ln(d/d_c); 0 for least squares
  double meanSquareError = 0.0;     // mean of (d - d_c)² over all points, m²
  int misclassified = 0;            // points on the wrong side of the curve
  int pointCount = 0;
  std::optional<double> crossValidatedAccuracy;  // fraction in [0, 1]
};

// Fits; throws InputError for unusable data: no points, NaN, a point without density when no default is given,
// no θ = 0 points for TwoStage's stage 1, no oblique points for its stage 2, a single outcome class for Classify.
FitResult fitChristiansen(const std::vector<ImpactPoint>& points, const FitOptions& options);

// The metrics fitChristiansen reports (meanSquareError, misclassified, pointCount), for any coefficient set, e.g. to
// score published coefficients on the same data. Throws InputError for unusable points as fitChristiansen does.
struct FitQuality {
  double meanSquareError = 0;  // m²
  int misclassified = 0;
  int pointCount = 0;
};
FitQuality evaluateFit(const std::vector<ImpactPoint>& points, const ChristiansenCoefficients& coefficients,
                       double defaultProjectileDensity);

// The density a point is evaluated with (its own, else the default). Throws InputError when neither is set.
double pointDensity(const ImpactPoint& point, double defaultProjectileDensity);

// d_c with a two-sided band at `level` (e.g. 0.90): the delta method on the covariance, applied to ln d_c so the
// band stays positive. When no covariance is available, low = high = d_c.
struct DiameterBand {
  double criticalDiameter = 0, low = 0, high = 0;  // m
};
DiameterBand criticalDiameterBand(const FitResult& fit, double velocity, double angle, double projectileDensity,
                                  double level = 0.90);

}  // namespace blt::ble
