#pragma once
// A solid material is a composition of three small models, each one class behind a small interface
// (as in Karamelo and MPM3D-cpp): an equation of state for the pressure, a strength model for the deviatoric
// stress (radial return), and a failure model. Johnson-Cook + Mie-Grueneisen + maximum principal stress
// is a combination of three parts, not a class of its own. Models register by the `model` name used in the
// material cards (data/materials/README.md), so a new model is one class and one registration line.

#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "blt/core/materials.hpp"
#include "blt/sim/particles.hpp"

namespace blt::sim {

// The state of one material point as the constitutive update sees it.
struct PointState {
  Mat3 stress = Mat3::Zero();  // Pa, Cauchy
  double density = 0;          // kg/m^3, current
  double specificEnergy = 0;   // J/kg
  double temperature = 0;      // K
  double plasticStrain = 0;
  double damage = 0;
  bool failed = false;
  Mat3 deformationGradient = Mat3::Identity();
};

// What one update produced besides the new state.
struct PointUpdate {
  double plasticWorkDensity = 0;  // J/m^3 dissipated by plasticity in this step
  double soundSpeed = 0;          // m/s, longitudinal (time step control)
};

// p(mu, E) with mu = rho/rho0 - 1 and E internal energy per unit reference volume. Affine in E, which lets the
// energy equation be solved for the end-of-step pressure in closed form.
class EquationOfState {
 public:
  virtual ~EquationOfState() = default;
  virtual double coldPressure(double mu) const = 0;      // p(mu, 0), Pa
  virtual double energyCoefficient(double mu) const = 0;  // dp/dE
  double pressure(double mu, double E) const { return coldPressure(mu) + energyCoefficient(mu) * E; }
  // Isentropic bulk modulus rho dp/drho at (mu, E), Pa.
  virtual double bulkModulus(double mu, double E) const;
};

// Mie-Grueneisen with a linear Us-up Hugoniot, seed 000 Eq. 10:
//   p = pH (1 - gamma mu / 2) + (gamma0 + a mu) E,  gamma = gamma0 / (1 + mu),
//   pH = rho0 c0^2 mu (1 + mu) / (1 - (s - 1) mu)^2 in compression, rho0 c0^2 mu in tension.
// On the Hugoniot (E = pH mu / (2 (1 + mu))) this gives p = pH = rho0 Us up exactly.
class MieGrueneisen final : public EquationOfState {
 public:
  MieGrueneisen(double rho0, double c0, double s, double gamma0, double a = 0)
      : rho0_(rho0), c0_(c0), s_(s), gamma0_(gamma0), a_(a) {}
  double coldPressure(double mu) const override;
  double energyCoefficient(double mu) const override { return gamma0_ + a_ * mu; }
  double bulkModulus(double mu, double E) const override;
  double hugoniotPressure(double mu) const;

 private:
  double rho0_, c0_, s_, gamma0_, a_;
};

// Linear pressure from the bulk modulus, p = K mu: for materials whose card has no [eos]. Its bulk modulus
// rho dp/drho is K (1 + mu), not K: the sound speed sqrt(K / rho0) is then the same at every density. Taken as K,
// failed Q235 debris expanded 24-fold had a sound speed of 22.6 km/s and set a time step of 3.3 ns where the
// intact plates allow 12 ns (seed 003's T4 at 150 m/s, 0.125 mm spacing, from 90 us on).
class LinearEos final : public EquationOfState {
 public:
  explicit LinearEos(double bulkModulus) : k_(bulkModulus) {}
  double coldPressure(double mu) const override { return k_ * mu; }
  double energyCoefficient(double) const override { return 0.0; }
  double bulkModulus(double mu, double) const override { return k_ * (1.0 + mu); }

 private:
  double k_;
};

// Flow stress for radial return. rate: equivalent plastic strain rate dep/dt (1/s, seed 000 Eq. 9); temperature
// in K. The return map solves for the plastic increment with the rate that increment implies.
class StrengthModel {
 public:
  // The flow stress and its two partial derivatives, which the return map's Newton iteration combines into
  // d(flow stress)/d(plastic increment) = dPlasticStrain + dRate / dt.
  struct FlowStress {
    double value = 0;          // Pa
    double dPlasticStrain = 0; // Pa
    double dRate = 0;          // Pa s
  };
  // What a model needs of the temperature, taken once per return map: the map holds the temperature fixed while
  // it iterates on the plastic increment, so a temperature factor of its own (Johnson-Cook's 1 - T*^m) need not be
  // recomputed at each iteration.
  struct ThermalState {
    double temperature = 0;  // K
    double factor = 1;       // the model's temperature factor where it has a separate one, else 1
  };
  virtual ~StrengthModel() = default;
  virtual bool plastic() const { return true; }
  virtual double yieldStress(double plasticStrain, double rate, double temperature) const = 0;
  virtual ThermalState thermalState(double temperature) const { return {temperature, 1.0}; }
  // The slopes are those of yieldStress where it is smooth; at a kink (Johnson-Cook's rate term at the reference
  // rate) either side's. Where d/d(plastic strain) is infinite (ep^n, n < 1, at ep = 0) it is capped at
  // ep = 1e-6: the return map brackets its root, so a capped slope only slows one iteration. `thermal` comes from
  // thermalState; the value equals yieldStress at its temperature to the last bit.
  virtual FlowStress flowStress(double plasticStrain, double rate, const ThermalState& thermal) const = 0;
};

// Johnson-Cook's rate term 1 + C ln(rate/rate0) for rates above rate0, else 1 (seed 000 Eq. 9); shared by the
// Johnson-Cook and the bilinear models. C = 0 gives exactly 1.
inline double johnsonCookRateFactor(double rate, double coefficient, double referenceRate) {
  const double r = rate / referenceRate;
  return coefficient != 0.0 && r > 1.0 ? 1.0 + coefficient * std::log(r) : 1.0;
}

class ElasticStrength final : public StrengthModel {
 public:
  bool plastic() const override { return false; }
  double yieldStress(double, double, double) const override { return 0; }
  FlowStress flowStress(double, double, const ThermalState&) const override { return {}; }
};

// sigma_y = (sigma_y0 + H ep) (1 + C ln max(rate/rate0, 1)) with the plastic modulus H = E Et / (E - Et) from the
// tangent modulus Et. The rate term is Johnson-Cook's (seed 000 Eq. 9); C = 0 (the default) leaves the curve rate
// independent, as the quasi-static tensile tests of the fabric cards (seed 000 Table 4) give it.
class BilinearStrength final : public StrengthModel {
 public:
  BilinearStrength(double yield, double youngs, double tangent, double rateCoefficient = 0.0,
                   double referenceRate = 1.0);
  double yieldStress(double ep, double rate, double) const override { return (yield_ + h_ * ep) * rateFactor(rate); }
  FlowStress flowStress(double ep, double rate, const ThermalState&) const override;

 private:
  double rateFactor(double rate) const { return johnsonCookRateFactor(rate, c_, rate0_); }
  double yield_, h_, c_, rate0_;
};

// Johnson-Cook, seed 000 Eq. 9: (A + B ep^n)(1 + C ln max(rate/rate0, 1))(1 - T*^m), T* clamped to [0, 1].
// `modified` selects seed 003 Eq. 18's rate term (1 + rate/rate0)^C.
class JohnsonCookStrength final : public StrengthModel {
 public:
  struct Parameters {
    double A = 0, B = 0, n = 1, C = 0, m = 1;
    double referenceRate = 1.0;      // 1/s
    double roomTemperature = 293.0;  // K
    double meltTemperature = 1e30;   // K
    bool modified = false;
  };
  explicit JohnsonCookStrength(const Parameters& p) : p_(p) {}
  double yieldStress(double ep, double rate, double temperature) const override;
  ThermalState thermalState(double temperature) const override { return {temperature, thermalFactor(temperature)}; }
  FlowStress flowStress(double ep, double rate, const ThermalState& thermal) const override;
  double homologousTemperature(double temperature) const;

 private:
  double rateFactor(double rate) const;
  double thermalFactor(double temperature) const;
  Parameters p_;
};

// Zerilli-Armstrong for fcc metals (Zerilli and Armstrong, J. Appl. Phys. 61 (1987) 1816, Eq. 12 without the
// Hall-Petch split): C0 + C2 sqrt(ep) exp(-C3 T + C4 T ln(rate/rate0)), T absolute. Rates below rate0 count as
// rate0, so the elastic trial (rate 0) sees the quasi-static stress instead of ln 0.
class ZerilliArmstrongFccStrength final : public StrengthModel {
 public:
  struct Parameters {
    double C0 = 0, C2 = 0;  // Pa
    double C3 = 0, C4 = 0;  // 1/K
    double referenceRate = 1.0;  // 1/s
  };
  explicit ZerilliArmstrongFccStrength(const Parameters& p) : p_(p) {}
  double yieldStress(double ep, double rate, double temperature) const override;
  FlowStress flowStress(double ep, double rate, const ThermalState& thermal) const override;

 private:
  double thermalRateFactor(double rate, double temperature) const;
  Parameters p_;
};

// Failure: `accumulate` updates the damage, `check` says whether the point has failed now.
struct FailureInput {
  const Mat3& stress;
  const Mat3& deformationGradient;
  double plasticStrainIncrement;
  double rate;
  double homologousTemperature;
};

class FailureModel {
 public:
  virtual ~FailureModel() = default;
  // Returns true when the point fails in this step; may update `damage`.
  virtual bool check(const FailureInput& in, double& damage) const = 0;
};

// Fails when the largest principal stress exceeds the limit (seed 000 sec. 4, spall and cratering).
class MaxPrincipalStressFailure final : public FailureModel {
 public:
  explicit MaxPrincipalStressFailure(double limit) : limit_(limit) {}
  bool check(const FailureInput& in, double& damage) const override;

 private:
  double limit_;
};

// Fails when the largest principal engineering strain (stretch - 1, from F F^T) exceeds the limit (fabrics).
class MaxPrincipalStrainFailure final : public FailureModel {
 public:
  explicit MaxPrincipalStrainFailure(double limit) : limit_(limit) {}
  bool check(const FailureInput& in, double& damage) const override;

 private:
  double limit_;
};

// Johnson-Cook damage: D += d ep / eps_f, eps_f = [D1 + D2 exp(D3 s*)][1 + D4 ln max(rate*, 1)][1 + D5 T*],
// s* = -p / sigma_eq the stress triaxiality; fails when D reaches the critical damage (1 by default).
class JohnsonCookDamage final : public FailureModel {
 public:
  struct Parameters {
    double D1 = 0, D2 = 0, D3 = 0, D4 = 0, D5 = 0;
    double referenceRate = 1.0;
    double criticalDamage = 1.0;
  };
  explicit JohnsonCookDamage(const Parameters& p) : p_(p) {}
  bool check(const FailureInput& in, double& damage) const override;
  double fractureStrain(double triaxiality, double rate, double homologousTemperature) const;

 private:
  Parameters p_;
};

class NoFailure final : public FailureModel {
 public:
  bool check(const FailureInput&, double&) const override { return false; }
};

// Settings of the artificial bulk viscosity (von Neumann-Richtmyer quadratic + Landshoff linear), applied in
// compression only: q = rho l (cq l |trD|^2 + cl c |trD|), l the cell size. Defaults are the customary ones.
struct BulkViscosity {
  double quadratic = 1.5;
  double linear = 0.06;
};

// One material: density, elastic constants, and the three parts.
class SolidMaterial {
 public:
  std::string id;
  double density = 0;         // kg/m^3, reference
  double shearModulus = 0;    // Pa
  double bulkModulus = 0;     // Pa (elastic, used when no EOS is given)
  double specificHeat = 0;    // J/kg/K; 0 means no temperature change
  double taylorQuinney = 0.9; // fraction of plastic work turned into heat
  double roomTemperature = 293.0;
  std::shared_ptr<const EquationOfState> eos;
  std::shared_ptr<const StrengthModel> strength;
  std::shared_ptr<const FailureModel> failure;
  std::shared_ptr<const JohnsonCookStrength> johnsonCook;  // set when the strength is Johnson-Cook (for T*)

  // Longitudinal wave speed of the undeformed material, m/s.
  double referenceWaveSpeed() const;
  // Advances one point by one step: D = sym(L), W = skew(L), dt; `q` is the bulk viscosity pressure of this
  // step, whose work goes into the internal energy. Objective through the Jaumann rate.
  PointUpdate update(PointState& s, const Mat3& D, const Mat3& W, double dt, double q) const;
};

// Builds a solver material from a library card. Throws InputError (file, section.key) for a model that the
// solver does not support or a missing parameter. Registries: the names are the cards' `model` keys.
SolidMaterial makeSolidMaterial(const Material& card);
using EosFactory = std::function<std::shared_ptr<const EquationOfState>(const Material&)>;
using StrengthFactory = std::function<std::shared_ptr<const StrengthModel>(const Material&)>;
using FailureFactory = std::function<std::shared_ptr<const FailureModel>(const Material&)>;
void registerEos(const std::string& model, EosFactory make);
void registerStrength(const std::string& model, StrengthFactory make);
void registerFailure(const std::string& model, FailureFactory make);
std::vector<std::string> supportedModels();  // "strength:johnson-cook", ... for messages and --help

// Principal values of a symmetric 3x3 matrix, largest first (closed form, no allocation).
Eigen::Vector3d principalValues(const Mat3& a);

}  // namespace blt::sim
