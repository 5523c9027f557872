#pragma once
// Residual velocity after perforation: the Recht-Ipson (1963) and Lambert-Jonas (1976) relation
//
//     v_r = a (v_i^p - v_bl^p)^(1/p)   for v_i > v_bl,   v_r = 0 otherwise,
//
// (REFERENCE.md §4; seed 003 Eq. 20; seed 002 Eq. 1 writes the same relation normalised by v_bl:
// v_r/v_bl = a ((v_i/v_bl)^p - 1)^(1/p)). Recht-Ipson fixes p = 2 and derives a = m_p / (m_p + m_pl) from
// momentum conservation with a plug of mass m_pl; Lambert-Jonas treats a, p and v_bl as free fit constants.
// All velocities are in m/s.
//
// Fitting to measured (v_i, v_r) pairs, and what a stopped shot (v_r = 0) means:
// - When every stopped shot is slower than every perforating shot, the data admit a sharp threshold, and the
//   fit demands one: max(stopped v_i) <= v_bl < min(perforating v_i) are hard bounds. Inside that bracket
//   the model is smooth for every row (stopped rows are predicted exactly 0, perforating rows lie above
//   v_bl), so there is no kink for the optimiser to trip on. If the perforating rows alone would prefer a
//   lower v_bl, v_bl ends on the lower bound and is reported as such (no standard error).
// - When the outcomes overlap (a stopped shot faster than a perforating one, as near a real V50), no v_bl
//   honours all of them. The fit then minimises the squared v_r error of the piecewise model over all
//   rows, a stopped row being a measurement of 0 m/s. The model is continuous in v_bl but has a kink at
//   every measured v_i; between two neighbouring measured velocities the set of rows above v_bl is fixed
//   and the problem is smooth, so each such interval is fitted separately and the best is kept (exact
//   treatment, no smoothing). The number of outcomes the fitted v_bl gets wrong is reported.
// Standard errors come from the Gauss-Newton covariance (ceres::Covariance) scaled by
// sigma^2 = SSR / (n_used - k): n_used counts the rows whose residual depends on the parameters
// (perforating rows, and stopped rows predicted to perforate), k the free parameters. A parameter on a
// bound gets none, and the others are then conditional on it; a rank-deficient Jacobian gives none at all.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "blt/core/csv.hpp"

namespace blt::analytic {

struct ResidualVelocityParameters {
  double a = 1.0;               // velocity ratio constant, 0 < a <= 1 (Recht-Ipson: m_p / (m_p + m_pl))
  double p = 2.0;               // exponent, p > 0 (Recht-Ipson: 2)
  double ballisticLimit = 0.0;  // v_bl, m/s, >= 0
};

// v_r for an impact at `impactVelocity` (m/s). Throws std::invalid_argument for parameters outside the
// ranges above or a negative impact velocity.
double residualVelocity(const ResidualVelocityParameters& parameters, double impactVelocity);

// Recht-Ipson's a = m_p / (m_p + m_pl) for a projectile of mass m_p pushing out a plug of mass m_pl (kg).
// Throws std::invalid_argument unless m_p > 0 and m_pl >= 0.
double rechtIpsonA(double projectileMass, double plugMass);

enum class ResidualVelocityModel {
  rechtIpson,    // p = 2 fixed; a and v_bl fitted (a may be fixed, e.g. from the masses)
  lambertJonas,  // a, p and v_bl fitted
};
// "recht-ipson" or "lambert-jonas", as on the command line.
std::string_view modelName(ResidualVelocityModel model);
std::optional<ResidualVelocityModel> parseModelName(std::string_view name);

// One test shot. A residual velocity of exactly 0 means the projectile was stopped.
struct VelocityShot {
  double impactVelocity = 0.0;    // m/s, > 0
  double residualVelocity = 0.0;  // m/s, 0 <= v_r <= v_i
  int line = 0;                   // line in the source file, for messages (0: not from a file)
};

struct VelocityData {
  std::string source;  // file name, used in error messages
  std::vector<VelocityShot> shots;
};

// Reads columns impact_velocity_m_s and residual_velocity_m_s. Throws InputError naming file, line and
// field for a missing column, an empty file, a non-number, a velocity that is negative (or zero impact
// velocity) or a residual velocity above the impact velocity.
VelocityData velocityDataFromTable(const csv::Table& table);
VelocityData readVelocityData(const std::string& path);

struct ResidualVelocityFitOptions {
  ResidualVelocityModel model = ResidualVelocityModel::lambertJonas;
  // Hold a at this value instead of fitting it (0 < a <= 1), e.g. rechtIpsonA(m_p, m_pl).
  std::optional<double> fixedA;
};

enum class ParameterStatus {
  fitted,   // free, inside its bounds: has a standard error when the covariance is available
  fixed,    // held by the model or the options
  atBound,  // the optimum sits on a bound (or a kink at a measured velocity): no standard error
};
std::string_view statusName(ParameterStatus status);  // "fitted", "fixed", "at_bound"

struct FittedParameter {
  double value = 0.0;
  std::optional<double> standardError;  // empty when fixed, on a bound, or the covariance is unavailable
  ParameterStatus status = ParameterStatus::fitted;
  std::string note;  // why there is no standard error, when there is none
};

struct ResidualVelocityFit {
  ResidualVelocityModel model = ResidualVelocityModel::lambertJonas;
  FittedParameter a, p, ballisticLimit;  // ballisticLimit in m/s
  double sumOfSquares = 0.0;             // SSR over all rows, (m/s)^2
  double rms = 0.0;                      // sqrt(SSR / nUsed), m/s: RMS v_r error over the rows that enter the fit
  std::optional<double> sigma;           // sqrt(SSR / dof), m/s; empty when dof = 0
  int nPoints = 0, nStopped = 0, nPerforated = 0;
  int nUsed = 0;                                                // rows whose residual depends on the parameters
  int nFree = 0;                                                // free parameters k
  int dof = 0;                                                  // nUsed - nFree
  bool outcomesOverlap = false;                                 // a stopped shot is faster than a perforating one
  int misclassified = 0;                                        // rows on the wrong side of the fitted v_bl
  double ballisticLimitLower = 0.0, ballisticLimitUpper = 0.0;  // the bracket searched for v_bl, m/s
  std::string covarianceNote;  // set when no standard errors could be computed, and why

  ResidualVelocityParameters parameters() const { return {a.value, p.value, ballisticLimit.value}; }
};

// Least-squares fit of the model to the data, as described at the top of this header. Bounds:
// 0 < a <= 1, 1 <= p <= 5, v_bl > 0. Deterministic (fixed multi-start grid). Throws InputError (naming the
// file and field residual_velocity_m_s) when fewer rows perforate than there are free parameters.
ResidualVelocityFit fitResidualVelocity(const VelocityData& data, const ResidualVelocityFitOptions& options = {});

}  // namespace blt::analytic
