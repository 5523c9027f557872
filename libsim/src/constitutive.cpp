#include "blt/sim/constitutive.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>

namespace blt::sim {

namespace {
const Mat3 kIdentity = Mat3::Identity();

double doubleContraction(const Mat3& a, const Mat3& b) { return a.cwiseProduct(b).sum(); }

// Whether the largest eigenvalue of a symmetric matrix is surely at most `bound`: it is at most
// mean + sqrt(2/3) |deviator|, compared here squared. Most points of a run are far from their failure limit
// and skip the eigenvalues on this test.
bool largestEigenvalueSurelyAtMost(const Mat3& a, double bound) {
  const double mean = a.trace() / 3.0;
  const double margin = bound - mean;
  return margin >= 0 && 2.0 / 3.0 * (a - mean * kIdentity).squaredNorm() <= margin * margin;
}
}  // namespace

Eigen::Vector3d principalValues(const Mat3& a) {
  const double p1 = a(0, 1) * a(0, 1) + a(0, 2) * a(0, 2) + a(1, 2) * a(1, 2);
  const double q = a.trace() / 3.0;
  if (p1 <= 1e-30 * (a.squaredNorm() + 1e-300)) {
    Eigen::Vector3d d(a(0, 0), a(1, 1), a(2, 2));
    std::sort(d.data(), d.data() + 3, std::greater<>());
    return d;
  }
  const double p2 = (a(0, 0) - q) * (a(0, 0) - q) + (a(1, 1) - q) * (a(1, 1) - q) + (a(2, 2) - q) * (a(2, 2) - q) +
                    2.0 * p1;
  const double p = std::sqrt(p2 / 6.0);
  const Mat3 b = (a - q * kIdentity) / p;
  const double r = std::clamp(b.determinant() / 2.0, -1.0, 1.0);
  const double phi = std::acos(r) / 3.0;
  const double e1 = q + 2.0 * p * std::cos(phi);
  const double e3 = q + 2.0 * p * std::cos(phi + 2.0 * M_PI / 3.0);
  return {e1, 3.0 * q - e1 - e3, e3};
}

// ---- equations of state ----

double EquationOfState::bulkModulus(double mu, double E) const {
  // rho dp/drho = (1 + mu) dp/dmu at fixed E (the energy term changes little over a step).
  const double h = 1e-6;
  return std::max((1.0 + mu) * (pressure(mu + h, E) - pressure(mu - h, E)) / (2.0 * h), 0.0);
}

double MieGrueneisen::hugoniotPressure(double mu) const {
  const double k = rho0_ * c0_ * c0_;
  if (mu <= 0) return k * mu;
  const double den = 1.0 - (s_ - 1.0) * mu;
  // Past the Hugoniot's asymptote the fit has no meaning; keep the pressure finite and steep.
  const double d = std::max(den, 0.05);
  return k * mu * (1.0 + mu) / (d * d);
}

double MieGrueneisen::bulkModulus(double mu, double E) const {
  // The base class's central difference, with this class's own (inlined) pressure: the same numbers without four
  // virtual calls for every point every step.
  const double h = 1e-6;
  const auto p = [&](double m) { return MieGrueneisen::coldPressure(m) + MieGrueneisen::energyCoefficient(m) * E; };
  return std::max((1.0 + mu) * (p(mu + h) - p(mu - h)) / (2.0 * h), 0.0);
}

double MieGrueneisen::coldPressure(double mu) const {
  const double pH = hugoniotPressure(mu);
  if (mu <= 0) return pH;
  const double gamma = gamma0_ / (1.0 + mu);
  return pH * (1.0 - 0.5 * gamma * mu);
}

// ---- strength ----

BilinearStrength::BilinearStrength(double yield, double youngs, double tangent, double rateCoefficient,
                                   double referenceRate)
    : yield_(yield),
      h_(tangent < youngs ? youngs * tangent / (youngs - tangent) : 0.0),
      c_(rateCoefficient),
      rate0_(referenceRate) {}

double JohnsonCookStrength::homologousTemperature(double temperature) const {
  // At or below room temperature T* is 0 without the division (most points are never heated).
  if (p_.meltTemperature >= 1e29 || temperature <= p_.roomTemperature) return 0.0;
  return std::clamp((temperature - p_.roomTemperature) / (p_.meltTemperature - p_.roomTemperature), 0.0, 1.0);
}

double JohnsonCookStrength::rateFactor(double rate) const {
  if (rate <= 0.0) return 1.0;  // the elastic trial's rate: both forms give exactly 1 (ln and pow not evaluated)
  if (p_.modified) return std::pow(1.0 + rate / p_.referenceRate, p_.C);
  return johnsonCookRateFactor(rate, p_.C, p_.referenceRate);
}

double JohnsonCookStrength::thermalFactor(double temperature) const {
  const double t = homologousTemperature(temperature);
  return t <= 0.0 ? 1.0 : 1.0 - std::pow(t, p_.m);
}

double JohnsonCookStrength::yieldStress(double ep, double rate, double temperature) const {
  const double strain = ep > 0 ? p_.A + p_.B * std::pow(ep, p_.n) : p_.A;
  return strain * rateFactor(rate) * thermalFactor(temperature);
}

StrengthModel::FlowStress JohnsonCookStrength::flowStress(double ep, double rate, const ThermalState& thermal) const {
  // The same products as yieldStress, so that the value is the same to the last bit; one pow serves the value
  // and the slope B n ep^(n-1) = B n ep^n / ep.
  const double power = ep > 0 ? std::pow(ep, p_.n) : 0.0;
  const double strain = ep > 0 ? p_.A + p_.B * power : p_.A;
  const double strainSlope = ep >= 1e-6 ? p_.B * p_.n * power / ep : p_.B * p_.n * std::pow(1e-6, p_.n - 1.0);
  double factor = 1.0, factorSlope = 0.0;  // the rate term and its derivative, s
  if (rate > 0.0) {
    if (p_.modified) {
      const double base = 1.0 + rate / p_.referenceRate;
      factor = std::pow(base, p_.C);
      factorSlope = p_.C * factor / (base * p_.referenceRate);
    } else {
      factor = johnsonCookRateFactor(rate, p_.C, p_.referenceRate);
      if (factor != 1.0) factorSlope = p_.C / rate;
    }
  }
  const double t = thermal.factor;
  return {strain * factor * t, strainSlope * factor * t, strain * factorSlope * t};
}

double ZerilliArmstrongFccStrength::thermalRateFactor(double rate, double temperature) const {
  const double logRate = std::log(std::max(rate / p_.referenceRate, 1.0));
  return std::exp(-p_.C3 * temperature + p_.C4 * temperature * logRate);
}

double ZerilliArmstrongFccStrength::yieldStress(double ep, double rate, double temperature) const {
  return p_.C0 + p_.C2 * std::sqrt(std::max(ep, 0.0)) * thermalRateFactor(rate, temperature);
}

StrengthModel::FlowStress ZerilliArmstrongFccStrength::flowStress(double ep, double rate,
                                                                   const ThermalState& thermal) const {
  const double temperature = thermal.temperature;
  const double factor = thermalRateFactor(rate, temperature);
  const double root = std::sqrt(std::max(ep, 0.0));
  const double rateSlope = rate > p_.referenceRate ? p_.C2 * root * factor * p_.C4 * temperature / rate : 0.0;
  return {p_.C0 + p_.C2 * root * factor, 0.5 * p_.C2 / std::sqrt(std::max(ep, 1e-6)) * factor, rateSlope};
}

StrengthModel::FlowStress BilinearStrength::flowStress(double ep, double rate, const ThermalState&) const {
  const double factor = rateFactor(rate);
  const double rateSlope = factor != 1.0 ? (yield_ + h_ * ep) * c_ / rate : 0.0;
  return {(yield_ + h_ * ep) * factor, h_ * factor, rateSlope};
}

// ---- failure ----

bool MaxPrincipalStressFailure::check(const FailureInput& in, double&) const {
  if (largestEigenvalueSurelyAtMost(in.stress, limit_)) return false;
  return principalValues(in.stress)(0) > limit_;
}

bool MaxPrincipalStrainFailure::check(const FailureInput& in, double&) const {
  const Mat3 b = in.deformationGradient * in.deformationGradient.transpose();
  // The largest eigenvalue of b is the squared largest stretch.
  if (largestEigenvalueSurelyAtMost(b, (1.0 + limit_) * (1.0 + limit_))) return false;
  const double stretch = std::sqrt(std::max(principalValues(b)(0), 0.0));
  return stretch - 1.0 > limit_;
}

double JohnsonCookDamage::fractureStrain(double triaxiality, double rate, double homologousTemperature) const {
  const double r = rate / p_.referenceRate;
  return (p_.D1 + p_.D2 * std::exp(p_.D3 * triaxiality)) * (1.0 + p_.D4 * std::log(std::max(r, 1.0))) *
         (1.0 + p_.D5 * homologousTemperature);
}

bool JohnsonCookDamage::check(const FailureInput& in, double& damage) const {
  if (in.plasticStrainIncrement > 0) {
    const double p = -in.stress.trace() / 3.0;
    const Mat3 s = in.stress + p * kIdentity;
    const double seq = std::sqrt(1.5 * doubleContraction(s, s));
    const double triax = seq > 0 ? -p / seq : 0.0;
    const double ef = fractureStrain(triax, in.rate, in.homologousTemperature);
    if (ef > 0) damage += in.plasticStrainIncrement / ef;
  }
  return damage >= p_.criticalDamage;
}

// ---- the composed material ----

double SolidMaterial::referenceWaveSpeed() const {
  const double k = eos ? eos->bulkModulus(0.0, 0.0) : bulkModulus;
  return std::sqrt((k + 4.0 / 3.0 * shearModulus) / density);
}

PointUpdate SolidMaterial::update(PointState& s, const Mat3& D, const Mat3& W, double dt, double q) const {
  PointUpdate out;
  const double rho = s.density;
  const double mu = rho / density - 1.0;
  const double trD = D.trace();
  const Mat3 Ddev = D - (trD / 3.0) * kIdentity;
  const double pOld = -s.stress.trace() / 3.0;
  const Mat3 sOld = s.stress + pOld * kIdentity;

  Mat3 sNew = Mat3::Zero();
  double dep = 0.0, flow = 0.0;
  if (!s.failed) {
    sNew = sOld + dt * (2.0 * shearModulus * Ddev + W * sOld - sOld * W);
    if (strength->plastic()) {
      // Rate-dependent radial return (seed 000 Eq. 9: the rate is the plastic strain rate dep/dt). Solve
      // f(dep) = seqTrial - 3 G dep - y(ep + dep, dep / dt) = 0; f decreases with dep, f(0) > 0 when the trial
      // state yields, and f(hi) <= 0 at hi = (seqTrial - y(ep, 0)) / 3G. The Newton steps are taken in ln(dep):
      // every strength law here (power-law hardening, a logarithmic or power-law rate term) is convex in ln(dep),
      // so f is concave there and the steps from hi close on the root from above without overshooting. In dep
      // itself a steep rate term ((1 + rate/rate0)^C with rate0 = 1.1e-3 1/s, seed 003) took 10 to 26 steps of
      // three pow calls each; in ln(dep) a few. The bracket still guards against a step out of it.
      // The root is taken only where the squared equivalent stress says the trial may yield: most points stay
      // elastic.
      const double seqTrialSquared = 1.5 * doubleContraction(sNew, sNew);
      const double y0 = strength->yieldStress(s.plasticStrain, 0.0, s.temperature);
      const double seqTrial = seqTrialSquared > y0 * y0 || y0 < 0 ? std::sqrt(seqTrialSquared) : 0.0;
      if (seqTrial > y0) {
        const double threeG = 3.0 * shearModulus;
        double lo = 0.0, hi = threeG > 0 ? (seqTrial - y0) / threeG : 0.0;
        dep = hi;
        bool flowAtDep = false;  // whether `flow` is the flow stress at the current dep
        const StrengthModel::ThermalState thermal = strength->thermalState(s.temperature);
        for (int it = 0; it < 30 && threeG > 0; ++it) {
          const StrengthModel::FlowStress y = strength->flowStress(s.plasticStrain + dep, dep / dt, thermal);
          flow = y.value;
          flowAtDep = true;
          const double f = seqTrial - threeG * dep - y.value;
          if (std::fabs(f) <= 1e-10 * seqTrial || hi - lo <= 1e-14 * hi) break;
          if (f > 0) lo = dep; else hi = dep;
          const double slope = threeG + y.dPlasticStrain + y.dRate / dt;  // -df/d(dep)
          double next = dep * std::exp(f / (dep * slope));
          if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
          dep = next;
          flowAtDep = false;
        }
        if (!flowAtDep) flow = strength->yieldStress(s.plasticStrain + dep, dep / dt, s.temperature);
        sNew *= seqTrial > 0 ? flow / seqTrial : 0.0;
        if (threeG <= 0) sNew.setZero();
      }
    }
  }

  // Energy equation with the mid-step stress; the end-of-step pressure enters linearly and is solved for.
  const double devWork = 0.5 * doubleContraction(sOld + sNew, Ddev) * dt;  // J/m^3 (current volume)
  const double eStar = s.specificEnergy + (devWork - (0.5 * pOld + q) * trD * dt) / rho;
  const double g = eos->energyCoefficient(mu);
  double pNew = (eos->coldPressure(mu) + g * density * eStar) / (1.0 + g * density * dt * trD / (2.0 * rho));
  // Failed material carries compression only; expanded past its rest density it is debris whose pieces do not
  // push each other apart, so it carries nothing (as it gets no bulk viscosity). That keeps the Mie-Grueneisen
  // thermal term Gamma0 rho0 e from acting across a spreading debris cloud.
  if (s.failed) pNew = rho < density ? 0.0 : std::max(pNew, 0.0);
  s.specificEnergy = eStar - 0.5 * pNew * trD * dt / rho;

  if (dep > 0) {
    out.plasticWorkDensity = flow * dep;
    s.plasticStrain += dep;
    if (specificHeat > 0) s.temperature += taylorQuinney * flow * dep / (rho * specificHeat);
  }
  s.stress = sNew - pNew * kIdentity;

  if (!s.failed) {
    const double tStar = johnsonCook ? johnsonCook->homologousTemperature(s.temperature) : 0.0;
    const FailureInput in{s.stress, s.deformationGradient, dep, dep / dt, tStar};
    if (failure->check(in, s.damage)) {
      s.failed = true;
      s.stress = -std::max(pNew, 0.0) * kIdentity;  // failed material carries compression only
    }
  }
  const double k = eos->bulkModulus(mu, density * s.specificEnergy);
  const double gEff = s.failed ? 0.0 : shearModulus;
  out.soundSpeed = std::sqrt((k + 4.0 / 3.0 * gEff) / rho);
  return out;
}

// ---- registries and the factory ----

namespace {
struct Registry {
  std::map<std::string, EosFactory> eos;
  std::map<std::string, StrengthFactory> strength;
  std::map<std::string, FailureFactory> failure;
};

InputLocation cardLocation(const Material& m, const std::string& section, const std::string& key) {
  const auto it = m.sections.find(section);
  std::optional<int> line;
  if (it != m.sections.end()) {
    const auto l = it->second.lines.find(key);
    if (l != it->second.lines.end()) line = l->second;
  }
  return InputLocation::file(m.path.empty() ? m.id : m.path, line, section + "." + key);
}

double youngsModulus(const Material& m) {
  if (m.has("elastic", "youngs_modulus")) return m.param("elastic", "youngs_modulus");
  if (m.has("elastic", "shear_modulus") && m.has("elastic", "poisson_ratio"))
    return 2.0 * m.param("elastic", "shear_modulus") * (1.0 + m.param("elastic", "poisson_ratio"));
  return m.param("elastic", "youngs_modulus");  // throws, naming the key
}

Registry& registry() {
  static Registry r = [] {
    Registry reg;
    reg.eos["mie-grueneisen"] = [](const Material& m) -> std::shared_ptr<const EquationOfState> {
      const double a = m.has("eos", "a") ? m.param("eos", "a") : 0.0;
      return std::make_shared<MieGrueneisen>(m.density, m.param("eos", "c0"), m.param("eos", "s"),
                                             m.param("eos", "gamma0"), a);
    };
    reg.strength["elastic"] = [](const Material&) -> std::shared_ptr<const StrengthModel> {
      return std::make_shared<ElasticStrength>();
    };
    reg.strength["bilinear"] = [](const Material& m) -> std::shared_ptr<const StrengthModel> {
      const double rate0 = m.has("strength", "reference_strain_rate") ? m.param("strength", "reference_strain_rate") : 1.0;
      if (!(rate0 > 0))
        throw InputError(cardLocation(m, "strength", "reference_strain_rate"), "must be positive", "a rate such as 1 1/s");
      return std::make_shared<BilinearStrength>(m.param("strength", "yield_stress"), youngsModulus(m),
                                                m.param("strength", "tangent_modulus"),
                                                m.has("strength", "C") ? m.param("strength", "C") : 0.0, rate0);
    };
    const auto jc = [](bool modified) {
      return [modified](const Material& m) -> std::shared_ptr<const StrengthModel> {
        JohnsonCookStrength::Parameters p;
        p.A = m.param("strength", "A");
        p.B = m.param("strength", "B");
        p.n = m.param("strength", "n");
        p.C = m.has("strength", "C") ? m.param("strength", "C") : 0.0;
        p.m = m.has("strength", "m") ? m.param("strength", "m") : 1.0;
        if (m.has("strength", "reference_strain_rate")) p.referenceRate = m.param("strength", "reference_strain_rate");
        if (m.has("strength", "room_temperature")) p.roomTemperature = m.param("strength", "room_temperature");
        if (m.has("strength", "melt_temperature")) p.meltTemperature = m.param("strength", "melt_temperature");
        p.modified = modified;
        return std::make_shared<JohnsonCookStrength>(p);
      };
    };
    reg.strength["zerilli-armstrong-fcc"] = [](const Material& m) -> std::shared_ptr<const StrengthModel> {
      ZerilliArmstrongFccStrength::Parameters p;
      p.C0 = m.param("strength", "C0");
      p.C2 = m.param("strength", "C2");
      p.C3 = m.param("strength", "C3");
      p.C4 = m.param("strength", "C4");
      if (m.has("strength", "reference_strain_rate")) p.referenceRate = m.param("strength", "reference_strain_rate");
      return std::make_shared<ZerilliArmstrongFccStrength>(p);
    };
    reg.strength["johnson-cook"] = jc(false);
    reg.strength["modified-johnson-cook"] = jc(true);
    reg.failure["max-principal-stress"] = [](const Material& m) -> std::shared_ptr<const FailureModel> {
      return std::make_shared<MaxPrincipalStressFailure>(m.param("failure", "max_principal_stress"));
    };
    reg.failure["max-principal-strain"] = [](const Material& m) -> std::shared_ptr<const FailureModel> {
      return std::make_shared<MaxPrincipalStrainFailure>(m.param("failure", "max_principal_strain"));
    };
    reg.failure["johnson-cook-damage"] = [](const Material& m) -> std::shared_ptr<const FailureModel> {
      JohnsonCookDamage::Parameters p;
      p.D1 = m.param("failure", "D1");
      p.D2 = m.has("failure", "D2") ? m.param("failure", "D2") : 0.0;
      p.D3 = m.has("failure", "D3") ? m.param("failure", "D3") : 0.0;
      p.D4 = m.has("failure", "D4") ? m.param("failure", "D4") : 0.0;
      p.D5 = m.has("failure", "D5") ? m.param("failure", "D5") : 0.0;
      if (m.has("failure", "critical_damage")) p.criticalDamage = m.param("failure", "critical_damage");
      if (m.has("strength", "reference_strain_rate")) p.referenceRate = m.param("strength", "reference_strain_rate");
      return std::make_shared<JohnsonCookDamage>(p);
    };
    return reg;
  }();
  return r;
}
std::mutex registryMutex;

template <class Map>
std::string names(const Map& map) {
  std::string s;
  for (const auto& [k, v] : map) s += (s.empty() ? "" : ", ") + k;
  return s;
}
}  // namespace

void registerEos(const std::string& model, EosFactory make) {
  std::lock_guard lock(registryMutex);
  registry().eos[model] = std::move(make);
}
void registerStrength(const std::string& model, StrengthFactory make) {
  std::lock_guard lock(registryMutex);
  registry().strength[model] = std::move(make);
}
void registerFailure(const std::string& model, FailureFactory make) {
  std::lock_guard lock(registryMutex);
  registry().failure[model] = std::move(make);
}

std::vector<std::string> supportedModels() {
  std::lock_guard lock(registryMutex);
  std::vector<std::string> out;
  for (const auto& [k, v] : registry().eos) out.push_back("eos:" + k);
  for (const auto& [k, v] : registry().strength) out.push_back("strength:" + k);
  for (const auto& [k, v] : registry().failure) out.push_back("failure:" + k);
  return out;
}

SolidMaterial makeSolidMaterial(const Material& card) {
  std::lock_guard lock(registryMutex);
  const Registry& reg = registry();
  SolidMaterial m;
  m.id = card.id;
  m.density = card.density;
  if (!(m.density > 0))
    throw InputError(InputLocation::file(card.path.empty() ? card.id : card.path, std::nullopt, "density"),
                     "the solver needs a positive density", "a density such as \"2770 kg/m3\"");

  // An unsupported strength model is reported before the elastic constants: a card written for it (e.g. a
  // fluid) may lack them, and the missing constant is not what the user has to fix first.
  const std::string strengthModel = card.has("strength") ? card.section("strength").model : "elastic";
  const auto st = reg.strength.find(strengthModel);
  if (st == reg.strength.end())
    throw InputError(cardLocation(card, "strength", "model"), "strength model '" + strengthModel + "' is not in the solver",
                     names(reg.strength));

  // Elastic constants: any two of E, nu, G, K; the bulk modulus may come from the EOS (rho0 c0^2).
  const auto has = [&](const char* k) { return card.has("elastic", k); };
  const auto get = [&](const char* k) { return card.param("elastic", k); };
  double G = 0, K = 0;
  if (has("shear_modulus")) G = get("shear_modulus");
  if (has("bulk_modulus")) K = get("bulk_modulus");
  if (has("youngs_modulus") && has("poisson_ratio")) {
    const double E = get("youngs_modulus"), nu = get("poisson_ratio");
    if (G == 0) G = E / (2.0 * (1.0 + nu));
    if (K == 0) K = E / (3.0 * (1.0 - 2.0 * nu));
  } else if (has("youngs_modulus") && G > 0 && K == 0) {
    K = get("youngs_modulus") * G / (3.0 * (3.0 * G - get("youngs_modulus")));
  }
  if (card.has("eos")) {
    const std::string& model = card.section("eos").model;
    const auto it = reg.eos.find(model);
    if (it == reg.eos.end())
      throw InputError(cardLocation(card, "eos", "model"), "equation of state '" + model + "' is not in the solver",
                       names(reg.eos));
    m.eos = it->second(card);
    if (K == 0) K = m.eos->bulkModulus(0.0, 0.0);
  }
  if (K <= 0)
    throw InputError(cardLocation(card, "elastic", "bulk_modulus"),
                     "no bulk modulus: the card gives no [eos] and too few elastic constants",
                     "youngs_modulus with poisson_ratio, or bulk_modulus, or an [eos] section");
  if (!m.eos) m.eos = std::make_shared<LinearEos>(K);
  m.bulkModulus = K;
  m.shearModulus = G;

  m.strength = st->second(card);
  m.johnsonCook = std::dynamic_pointer_cast<const JohnsonCookStrength>(m.strength);
  if (m.shearModulus <= 0 && !card.has("elastic", "shear_modulus"))
    throw InputError(cardLocation(card, "elastic", "shear_modulus"), "no shear modulus",
                     "shear_modulus, or youngs_modulus with poisson_ratio");
  if (card.has("strength", "room_temperature"))
    m.roomTemperature = card.param("strength", "room_temperature");

  if (card.has("failure")) {
    const std::string& model = card.section("failure").model;
    const auto it = reg.failure.find(model);
    if (it == reg.failure.end())
      throw InputError(cardLocation(card, "failure", "model"), "failure model '" + model + "' is not in the solver",
                       names(reg.failure));
    m.failure = it->second(card);
  } else {
    m.failure = std::make_shared<NoFailure>();
  }
  if (card.has("thermal", "specific_heat")) m.specificHeat = card.param("thermal", "specific_heat");
  if (card.has("thermal", "taylor_quinney")) m.taylorQuinney = card.param("thermal", "taylor_quinney");
  return m;
}

}  // namespace blt::sim
