// Constitutive models of the MPM solver (libsim/include/blt/sim/constitutive.hpp): principal values, the
// Mie-Grueneisen EOS, Johnson-Cook strength, the radial return (elastic, perfectly plastic, linear hardening),
// adiabatic heating, the failure models, and the factory on the material library. Every check compares with an
// independent number: a closed form written out here, named in the comment above it.
#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "approx.hpp"
#include "blt/core/error.hpp"
#include "blt/core/materials.hpp"
#include "blt/sim/cases.hpp"
#include "blt/sim/constitutive.hpp"
#include "blt/sim/run.hpp"

using namespace blt;
using namespace blt::sim;

namespace {

const Mat3 kZero = Mat3::Zero();

SolidMaterial fromCard(const std::string& text, const std::string& id) {
  return makeSolidMaterial(parseMaterial(text, id + ".toml (test card)", id));
}

// A card with E = 70 GPa, nu = 0.3 and the given strength and failure sections; no [eos], so p = K mu.
std::string card(const std::string& strength, const std::string& failure = "") {
  return "name = \"test solid\"\nsource = \"unit test\"\ndensity = \"2700 kg/m3\"\n"
         "[elastic]\nyoungs_modulus = \"70 GPa\"\npoisson_ratio = 0.3\n"
         "[strength]\n" + strength + "\n" + failure;
}
constexpr double kE = 70e9, kNu = 0.3, kRho0 = 2700.0;
const double kK = kE / (3.0 * (1.0 - 2.0 * kNu));  // bulk modulus from E, nu
const double kG = kE / (2.0 * (1.0 + kNu));        // shear modulus from E, nu

PointState freshState(const SolidMaterial& m, double temperature = 293.0) {
  PointState s;
  s.density = m.density;
  s.temperature = temperature;
  return s;
}

double vonMises(const Mat3& stress) {
  const Mat3 dev = stress - stress.trace() / 3.0 * Mat3::Identity();
  return std::sqrt(1.5 * dev.cwiseProduct(dev).sum());
}

Mat3 pureShear(double g) {
  Mat3 d = Mat3::Zero();
  d(0, 1) = d(1, 0) = g;
  return d;
}

Mat3 rotation() {
  return Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, -2.0, 0.5).normalized()).toRotationMatrix();
}

// Strains the card's material in pure shear at `rate` from temperature T0 to a plastic strain of 0.05 and checks
// that every step with a plastic rate above minPlasticRate ends on flowCurve(ep, plastic rate, T), the curve
// written out by the caller (not through the strength model), at the step's end strain and plastic rate and the
// temperature it started from (the heating follows the return).
template <class Curve>
void checkReturnLandsOnCurve(const Material& card, double rate, double dt, double T0, double minPlasticRate,
                             Curve&& flowCurve) {
  const SolidMaterial m = makeSolidMaterial(card);
  const Mat3 D = pureShear(rate);
  PointState s = freshState(m, T0);
  int plasticSteps = 0;
  for (int i = 0; i < 2000 && s.plasticStrain < 0.05; ++i) {
    const double before = s.plasticStrain, T = s.temperature;
    m.update(s, D, kZero, dt, 0.0);
    const double plasticRate = (s.plasticStrain - before) / dt;
    if (plasticRate > minPlasticRate) {
      ++plasticSteps;
      CHECK(vonMises(s.stress) == relApprox(flowCurve(s.plasticStrain, plasticRate, T), 1e-8));
    }
  }
  CHECK(plasticSteps > 100);
  CHECK(s.plasticStrain >= 0.05);
}

}  // namespace

TEST_SUITE("constitutive") {

TEST_CASE("principalValues: diagonal and rotated diagonal matrices") {
  // Diagonal: the principal values are the diagonal, sorted largest first.
  const Eigen::Vector3d d = principalValues(Eigen::Vector3d(1.0e8, 5.0e8, -2.0e8).asDiagonal().toDenseMatrix());
  CHECK(d(0) == 5.0e8);
  CHECK(d(1) == 1.0e8);
  CHECK(d(2) == -2.0e8);

  // R diag(a, b, c) R^T has the eigenvalues a, b, c for any rotation R (similarity transform).
  const Mat3 R = rotation();
  const std::vector<Eigen::Vector3d> cases = {
      {3.0e8, -1.0e8, 5.0e7}, {-4.0e8, 2.5e8, 2.5e8} /* double root */, {1.0, 2.0, 3.0}, {-7e9, -7.5e9, -6e9}};
  for (const Eigen::Vector3d& abc : cases) {
    const Mat3 a = R * abc.asDiagonal() * R.transpose();
    Eigen::Vector3d expected = abc;
    std::sort(expected.data(), expected.data() + 3, std::greater<>());
    const Eigen::Vector3d got = principalValues(a);
    INFO("a, b, c = " << abc.transpose());
    for (int i = 0; i < 3; ++i) CHECK(std::fabs(got(i) - expected(i)) <= 1e-9 * expected.cwiseAbs().maxCoeff());
  }
}

TEST_CASE("MieGrueneisen: p = rho0 Us up on the Hugoniot, bulk modulus rho0 c0^2") {
  // OFHC copper (Marsh 1980): rho0 = 8960 kg/m3, c0 = 3940 m/s, s = 1.489, gamma0 = 2.02.
  const double rho0 = 8960, c0 = 3940, s = 1.489, gamma0 = 2.02;
  const MieGrueneisen eos(rho0, c0, s, gamma0);
  for (double mu : {1e-4, 0.01, 0.05, 0.1, 0.2, 0.35, 0.5}) {
    // Rankine-Hugoniot with the linear Us-up fit: eta = 1 - rho0/rho, Us = c0 / (1 - s eta), up = eta Us,
    // pH = rho0 Us up; the energy on the Hugoniot per reference volume is pH mu / (2 (1 + mu)).
    const double eta = mu / (1.0 + mu);
    const double us = c0 / (1.0 - s * eta);
    const double up = eta * us;
    const double pH = rho0 * us * up;
    const double E = pH * mu / (2.0 * (1.0 + mu));
    INFO("mu = " << mu);
    CHECK(eos.hugoniotPressure(mu) == relApprox(pH, 1e-12));
    CHECK(eos.pressure(mu, E) == relApprox(pH, 1e-12));
  }
  // Acoustic limit: K = rho0 c0^2.
  CHECK(eos.bulkModulus(0.0, 0.0) == relApprox(rho0 * c0 * c0, 1e-6));
  const MieGrueneisen al(2770, 5328, 1.11, 2.0);  // 2A12, seed 000 Table 3
  CHECK(al.bulkModulus(0.0, 0.0) == relApprox(2770 * 5328.0 * 5328.0, 1e-6));
  // Mie-Grueneisen's own bulk modulus is the base class's central difference to the last bit (it only saves the
  // virtual calls), in tension, across the kink at mu = 0, in compression and past the Hugoniot's asymptote.
  for (double mu : {-0.05, -1e-7, 0.0, 5e-7, 0.01, 0.3, 1.5})
    for (double E : {0.0, 1e8, 5e9}) {
      INFO("mu = " << mu << ", E = " << E);
      CHECK(eos.bulkModulus(mu, E) == eos.EquationOfState::bulkModulus(mu, E));
    }
}

TEST_CASE("LinearEos: bulk modulus rho dp/drho of p = K mu, so the sound speed is the same at every density") {
  // Independent of the class: rho dp/drho by the base class's central difference of its own pressure, and the
  // acoustic speed of p = K (rho / rho0 - 1), dp/drho = K / rho0, at any density.
  const double K = 160e9, rho0 = 7800;  // about steel
  const LinearEos eos(K);
  for (double mu : {-0.96, -0.5, -0.05, 0.0, 0.05, 0.3}) {
    INFO("mu = " << mu);
    CHECK(eos.bulkModulus(mu, 0.0) == relApprox(eos.EquationOfState::bulkModulus(mu, 0.0), 1e-8));
    const double rho = rho0 * (1.0 + mu);
    CHECK(std::sqrt(eos.bulkModulus(mu, 0.0) / rho) == relApprox(std::sqrt(K / rho0), 1e-12));
  }
}

TEST_CASE("JohnsonCookStrength: 2A12 card against the formula, melt and low rate") {
  const SolidMaterial m = makeSolidMaterial(MaterialLibrary::load().get("al_2a12"));
  REQUIRE(m.johnsonCook);
  const JohnsonCookStrength& jc = *m.johnsonCook;
  // Seed 000 Table 3: A = 265 MPa, B = 426 MPa, n = 0.34, C = 0.015, m = 1, T_m = 900 K; card: rate0 = 1/s,
  // T_room = 293 K. sigma = (A + B ep^n)(1 + C ln(rate/rate0))(1 - T*^m), T* = (T - T_room)/(T_m - T_room).
  const double A = 265e6, B = 426e6, n = 0.34, C = 0.015, mm = 1.0, Tr = 293, Tm = 900;
  const double ep = 0.1, rate = 1000, T = 400;
  const double byHand = (A + B * std::pow(ep, n)) * (1 + C * std::log(rate / 1.0)) *
                        (1 - std::pow((T - Tr) / (Tm - Tr), mm));
  CHECK(jc.yieldStress(ep, rate, T) == relApprox(byHand, 1e-12));
  CHECK(jc.homologousTemperature(T) == relApprox((T - Tr) / (Tm - Tr), 1e-12));
  // d sigma / d ep = B n ep^(n-1) times the rate and thermal factors.
  const StrengthModel::FlowStress fs = jc.flowStress(ep, rate, jc.thermalState(T));
  CHECK(fs.value == jc.yieldStress(ep, rate, T));
  CHECK(fs.dPlasticStrain == relApprox(B * n * std::pow(ep, n - 1) * (1 + C * std::log(rate)) *
                                           (1 - (T - Tr) / (Tm - Tr)), 1e-12));
  // d sigma / d rate = (A + B ep^n) C / rate times the thermal factor.
  CHECK(fs.dRate == relApprox((A + B * std::pow(ep, n)) * C / rate * (1 - (T - Tr) / (Tm - Tr)), 1e-12));
  // Below the reference rate the rate term is flat.
  CHECK(jc.flowStress(ep, 0.5, jc.thermalState(T)).dRate == 0.0);
  // At and above melting: no strength.
  CHECK(jc.yieldStress(ep, rate, Tm) == 0.0);
  CHECK(jc.yieldStress(ep, rate, 1500.0) == 0.0);
  // Below the reference rate the rate factor is 1 (the ln term is not allowed to soften); room temperature and
  // below: thermal factor 1.
  CHECK(jc.yieldStress(ep, 1e-3, Tr) == relApprox(A + B * std::pow(ep, n), 1e-12));
  CHECK(jc.yieldStress(ep, 0.0, 250.0) == relApprox(A + B * std::pow(ep, n), 1e-12));
  CHECK(jc.yieldStress(0.0, 0.5, Tr) == relApprox(A, 1e-12));

  // Modified Johnson-Cook (seed 003 Eq. 18), Q235 card: (A + B ep^n)(1 + rate/rate0)^C (1 - T*^m),
  // A = 229 MPa, B = 439 MPa, n = 0.503, C = 0.1, m = 0.55, rate0 = 1.1e-3 1/s, T_room = 300 K, T_m = 1795 K.
  const SolidMaterial q = makeSolidMaterial(MaterialLibrary::load().get("q235"));
  REQUIRE(q.johnsonCook);
  const double qHand = (229e6 + 439e6 * std::pow(0.05, 0.503)) * std::pow(1 + 10.0 / 1.1e-3, 0.1) *
                       (1 - std::pow((500.0 - 300.0) / (1795.0 - 300.0), 0.55));
  CHECK(q.johnsonCook->yieldStress(0.05, 10.0, 500.0) == relApprox(qHand, 1e-12));
  // The elastic trial's zero rate and room temperature: (1 + 0)^C = 1 and T* = 0.
  CHECK(q.johnsonCook->yieldStress(0.05, 0.0, 300.0) == relApprox(229e6 + 439e6 * std::pow(0.05, 0.503), 1e-12));
  // Its rate slope: C (1 + rate/rate0)^(C-1) / rate0 times the strain and thermal factors.
  CHECK(q.johnsonCook->flowStress(0.05, 10.0, q.johnsonCook->thermalState(500.0)).dRate ==
        relApprox(qHand * 0.1 / (1 + 10.0 / 1.1e-3) / 1.1e-3, 1e-12));
  // The same constants read with the classic rate term (card q235_jc): 1 + C ln(rate/rate0).
  const SolidMaterial qc = makeSolidMaterial(MaterialLibrary::load().get("q235_jc"));
  REQUIRE(qc.johnsonCook);
  const double qcHand = (229e6 + 439e6 * std::pow(0.05, 0.503)) * (1 + 0.1 * std::log(10.0 / 1.1e-3)) *
                        (1 - std::pow((500.0 - 300.0) / (1795.0 - 300.0), 0.55));
  CHECK(qc.johnsonCook->yieldStress(0.05, 10.0, 500.0) == relApprox(qcHand, 1e-12));
}

TEST_CASE("ZerilliArmstrongFccStrength: cu_ofhc_za card against the formula, low rate, room temperature") {
  const SolidMaterial m = makeSolidMaterial(MaterialLibrary::load().get("cu_ofhc_za"));
  const auto* za = dynamic_cast<const ZerilliArmstrongFccStrength*>(m.strength.get());
  REQUIRE(za != nullptr);
  // Zerilli and Armstrong 1987, fcc form, their OFHC copper: C0 = 65 MPa, C2 = 890 MPa, C3 = 0.0028 1/K,
  // C4 = 0.000115 1/K, rate in 1/s. sigma = C0 + C2 ep^0.5 exp(-C3 T + C4 T ln rate).
  const double C0 = 65e6, C2 = 890e6, C3 = 0.0028, C4 = 0.000115;
  const double ep = 0.25, rate = 1000, T = 400;
  const double factor = std::exp(-C3 * T + C4 * T * std::log(rate));
  CHECK(za->yieldStress(ep, rate, T) == relApprox(C0 + C2 * std::sqrt(ep) * factor, 1e-12));
  const StrengthModel::FlowStress fs = za->flowStress(ep, rate, za->thermalState(T));
  CHECK(fs.value == relApprox(C0 + C2 * std::sqrt(ep) * factor, 1e-12));
  CHECK(fs.dPlasticStrain == relApprox(0.5 * C2 / std::sqrt(ep) * factor, 1e-12));
  CHECK(fs.dRate == relApprox(C2 * std::sqrt(ep) * factor * C4 * T / rate, 1e-12));
  // Below the 1 1/s reference rate the ln term is 0 (the solver's clamp): the elastic trial at rate 0 is finite.
  CHECK(za->yieldStress(ep, 0.0, T) == relApprox(C0 + C2 * std::sqrt(ep) * std::exp(-C3 * T), 1e-12));
  // No plastic strain: the athermal C0 alone, whatever the rate and temperature.
  CHECK(za->yieldStress(0.0, 1e4, 800.0) == relApprox(C0, 1e-12));
  // The card's room temperature is where particles start.
  CHECK(m.roomTemperature == relApprox(294.0, 1e-12));
}

TEST_CASE("SolidMaterial::update: one elastic step of uniaxial strain") {
  const SolidMaterial m = fromCard(card("model = \"elastic\""), "elastic_test");
  CHECK(m.shearModulus == relApprox(kG, 1e-12));
  CHECK(m.bulkModulus == relApprox(kK, 1e-12));
  // Linear elasticity in uniaxial strain eps: sigma_xx = (K + 4G/3) eps, sigma_yy = sigma_zz = (K - 2G/3) eps.
  const double rate = 100.0, dt = 1e-9, eps = rate * dt;
  PointState s = freshState(m);
  s.density = kRho0 / (1.0 + eps);  // mass conservation over the step
  Mat3 D = Mat3::Zero();
  D(0, 0) = rate;
  const PointUpdate u = m.update(s, D, kZero, dt, 0.0);
  CHECK(s.stress(0, 0) == relApprox((kK + 4.0 * kG / 3.0) * eps, 1e-6));
  CHECK(s.stress(1, 1) == relApprox((kK - 2.0 * kG / 3.0) * eps, 1e-6));
  CHECK(s.stress(2, 2) == relApprox((kK - 2.0 * kG / 3.0) * eps, 1e-6));
  CHECK(std::fabs(s.stress(0, 1)) + std::fabs(s.stress(0, 2)) + std::fabs(s.stress(1, 2)) == 0.0);
  CHECK(s.plasticStrain == 0.0);
  CHECK(u.plasticWorkDensity == 0.0);
  // Longitudinal wave speed sqrt((K + 4G/3) / rho).
  CHECK(u.soundSpeed == relApprox(std::sqrt((kK + 4.0 * kG / 3.0) / s.density), 1e-6));
  CHECK(m.referenceWaveSpeed() == relApprox(std::sqrt((kK + 4.0 * kG / 3.0) / kRho0), 1e-12));
}

TEST_CASE("radial return, perfect plasticity: pure shear stays on the yield surface") {
  const double Y = 300e6;
  const SolidMaterial m =
      fromCard(card("model = \"bilinear\"\nyield_stress = \"300 MPa\"\ntangent_modulus = \"0 MPa\""), "perfect");
  const double g = 1e3, dt = 1e-7;  // shear strain per step g dt = 1e-4
  const Mat3 D = pureShear(g);
  // Pure shear D_xy = g: equivalent strain rate sqrt(2/3 D:D) = 2 g / sqrt(3); once on the yield surface the
  // whole deviatoric increment is plastic, so d ep = 2 g dt / sqrt(3) per step.
  const double depExpected = 2.0 * g * dt / std::sqrt(3.0);
  PointState s = freshState(m);
  int elasticSteps = 0, plasticSteps = 0;
  for (int i = 0; i < 100; ++i) {
    const double before = s.plasticStrain;
    const PointUpdate u = m.update(s, D, kZero, dt, 0.0);
    if (s.plasticStrain == 0) {
      ++elasticSteps;
      // Elastic: sigma_xy = 2 G gamma_xy/2 = 2 G g t.
      CHECK(s.stress(0, 1) == relApprox(2.0 * kG * g * dt * (i + 1), 1e-12));
      continue;
    }
    CHECK(vonMises(s.stress) == relApprox(Y, 1e-9));
    CHECK(u.plasticWorkDensity == relApprox(Y * (s.plasticStrain - before), 1e-12));
    if (before > 0) {
      ++plasticSteps;
      CHECK(s.plasticStrain - before == relApprox(depExpected, 1e-9));
    }
  }
  // Yield at sqrt(3) sigma_xy = Y, i.e. after Y / (sqrt(3) 2 G g dt) = 32.2 steps.
  CHECK(elasticSteps == static_cast<int>(Y / (std::sqrt(3.0) * 2.0 * kG * g * dt)));
  CHECK(plasticSteps > 50);
  CHECK(std::fabs(s.stress.trace()) <= 1e-9 * Y);  // no pressure in pure shear without an EOS energy term
}

TEST_CASE("radial return, bilinear hardening: von Mises = sigma_y0 + H ep") {
  const double Y0 = 300e6, Et = 7e9;
  const SolidMaterial m =
      fromCard(card("model = \"bilinear\"\nyield_stress = \"300 MPa\"\ntangent_modulus = \"7 GPa\""), "bilinear");
  // Plastic modulus from the tangent modulus of the uniaxial curve: H = E Et / (E - Et).
  const double H = kE * Et / (kE - Et);
  const Mat3 D = pureShear(1e3);
  PointState s = freshState(m);
  int plasticSteps = 0;
  for (int i = 0; i < 400 && s.plasticStrain < 0.02; ++i) {
    m.update(s, D, kZero, 1e-7, 0.0);
    if (s.plasticStrain > 0) {
      ++plasticSteps;
      CHECK(vonMises(s.stress) == relApprox(Y0 + H * s.plasticStrain, 1e-9));
    }
  }
  CHECK(plasticSteps > 100);
  CHECK(s.plasticStrain >= 0.02);
}

TEST_CASE("bilinear strength with a rate term: (sigma_y0 + H ep)(1 + C ln(rate/rate0)), none without C") {
  const double Y0 = 300e6, Et = 7e9, C = 0.05, rate0 = 1e-2;
  const double H = kE * Et / (kE - Et);
  const SolidMaterial m = fromCard(card("model = \"bilinear\"\nyield_stress = \"300 MPa\"\ntangent_modulus = \"7 GPa\"\n"
                                        "C = 0.05\nreference_strain_rate = \"0.01 1/s\""),
                                   "bilinear_rate");
  // The flow curve and its slope against Johnson-Cook's rate term written out.
  const double ep = 0.1, rate = 1e3;
  CHECK(m.strength->yieldStress(ep, rate, 293) == relApprox((Y0 + H * ep) * (1 + C * std::log(rate / rate0)), 1e-12));
  const StrengthModel::FlowStress fs = m.strength->flowStress(ep, rate, m.strength->thermalState(293));
  CHECK(fs.dPlasticStrain == relApprox(H * (1 + C * std::log(rate / rate0)), 1e-12));
  CHECK(fs.dRate == relApprox((Y0 + H * ep) * C / rate, 1e-12));
  // At or below the reference rate the term is 1: it hardens, never softens.
  CHECK(m.strength->yieldStress(ep, rate0, 293) == relApprox(Y0 + H * ep, 1e-12));
  CHECK(m.strength->yieldStress(ep, 0.0, 293) == relApprox(Y0 + H * ep, 1e-12));
  // The radial return lands on the rate-hardened curve at the plastic rate of each step: sigma_vm =
  // (Y0 + H ep)(1 + C ln((dep/dt) / rate0)).
  const double dt = 1e-7;
  const Mat3 D = pureShear(1e3);
  PointState s = freshState(m);
  int plasticSteps = 0;
  for (int i = 0; i < 400 && s.plasticStrain < 0.02; ++i) {
    const double before = s.plasticStrain;
    m.update(s, D, kZero, dt, 0.0);
    const double plasticRate = (s.plasticStrain - before) / dt;
    if (before > 0 && plasticRate > rate0) {
      ++plasticSteps;
      CHECK(vonMises(s.stress) == relApprox((Y0 + H * s.plasticStrain) * (1 + C * std::log(plasticRate / rate0)), 1e-6));
    }
  }
  CHECK(plasticSteps > 100);
  // Without C the card's curve is the rate-independent one, bit for bit.
  const SolidMaterial plain =
      fromCard(card("model = \"bilinear\"\nyield_stress = \"300 MPa\"\ntangent_modulus = \"7 GPa\""), "bilinear");
  CHECK(plain.strength->yieldStress(ep, rate, 293) == Y0 + H * ep);
  // A reference rate that is not positive is an error naming the key.
  std::string bad;
  try {
    fromCard(card("model = \"bilinear\"\nyield_stress = \"300 MPa\"\ntangent_modulus = \"7 GPa\"\nC = 0.05\n"
                  "reference_strain_rate = \"0 1/s\""),
             "bilinear_bad");
  } catch (const InputError& e) {
    bad = e.what();
  }
  CHECK(bad.find("strength.reference_strain_rate") != std::string::npos);
  CHECK(bad.find("must be positive") != std::string::npos);
}

TEST_CASE("radial return, Johnson-Cook: each step lands on the flow curve at its own plastic rate and temperature") {
  // 2A12 (seed 000 Table 3) in pure shear at 1e5 1/s from 400 K: (A + B ep^n)(1 + C ln(dep/dt / rate0))(1 - T*^m).
  const double A = 265e6, B = 426e6, n = 0.34, C = 0.015, Tr = 293, Tm = 900;
  checkReturnLandsOnCurve(MaterialLibrary::load().get("al_2a12"), 1e5, 2e-9, 400.0, 1.0,
                          [&](double ep, double rate, double T) {
                            return (A + B * std::pow(ep, n)) * (1 + C * std::log(rate)) * (1 - (T - Tr) / (Tm - Tr));
                          });
}

TEST_CASE("radial return, modified Johnson-Cook: lands on the flow curve with the steep rate term (1 + rate/rate0)^C") {
  // Q235 (seed 003 Table 1, Eq. 18): C = 0.1 on rate0 = 1.1e-3 1/s, so the flow stress climbs by a factor of 2 over
  // the first 1e-8 of plastic strain in a 20 ns step; the return must still land on the curve. Pure shear at
  // 1e4 1/s from room temperature.
  const double A = 229e6, B = 439e6, n = 0.503, C = 0.1, rate0 = 1.1e-3, mExp = 0.55, Tr = 300, Tm = 1795;
  checkReturnLandsOnCurve(MaterialLibrary::load().get("q235"), 1e4, 20e-9, 300.0, 0.0,
                          [&](double ep, double rate, double T) {
                            const double thermal = T > Tr ? 1 - std::pow((T - Tr) / (Tm - Tr), mExp) : 1.0;
                            return (A + B * std::pow(ep, n)) * std::pow(1 + rate / rate0, C) * thermal;
                          });
}

TEST_CASE("Johnson-Cook adiabatic heating: dT = chi W_p / (rho cp)") {
  const Material cardCu = MaterialLibrary::load().get("cu_ofhc");
  const SolidMaterial m = makeSolidMaterial(cardCu);
  REQUIRE(m.johnsonCook);
  CHECK(m.specificHeat == relApprox(383.0, 1e-12));  // Johnson and Cook 1983 Table 1
  CHECK(m.taylorQuinney == relApprox(0.9, 1e-12));
  CHECK(m.roomTemperature == relApprox(294.0, 1e-12));
  const double T0 = 294.0;
  PointState s = freshState(m, T0);
  const Mat3 D = pureShear(1e3);
  double work = 0;  // J/m^3
  for (int i = 0; i < 300; ++i) work += m.update(s, D, kZero, 1e-7, 0.0).plasticWorkDensity;
  REQUIRE(s.plasticStrain > 0.02);
  // Taylor-Quinney: a fraction chi = 0.9 of the plastic work heats the point, dT = chi W_p / (rho cp); pure shear
  // keeps the density at rho0 = 8960 kg/m3.
  CHECK(s.temperature - T0 == relApprox(0.9 * work / (8960.0 * 383.0), 1e-10));
  // The plastic work lies between the initial and the final flow stress times the plastic strain.
  const double rate = 2.0 * 1e3 / std::sqrt(3.0);
  CHECK(work > m.johnsonCook->yieldStress(0.0, rate, s.temperature) * s.plasticStrain);
  CHECK(work < m.johnsonCook->yieldStress(s.plasticStrain, rate, T0) * s.plasticStrain);
}

TEST_CASE("failure: max principal stress, a failed point carries compression only") {
  const SolidMaterial m = fromCard(
      card("model = \"elastic\"", "[failure]\nmodel = \"max-principal-stress\"\nmax_principal_stress = \"100 MPa\""),
      "mps");
  // Uniaxial strain eps with p = K mu, mu = -eps: the largest principal stress is (K + 4G/3) eps.
  const double M = kK + 4.0 * kG / 3.0;
  const auto stretchStep = [&](PointState& s, double eps) {
    s.density = kRho0 * (1.0 - eps);
    Mat3 D = Mat3::Zero();
    D(0, 0) = eps / 1e-8;
    m.update(s, D, kZero, 1e-8, 0.0);
  };
  PointState below = freshState(m);
  stretchStep(below, 0.98 * 100e6 / M);
  CHECK_FALSE(below.failed);
  CHECK(principalValues(below.stress)(0) == relApprox(0.98 * 100e6, 1e-9));

  PointState s = freshState(m);
  stretchStep(s, 1.02 * 100e6 / M);
  CHECK(s.failed);
  CHECK(s.stress == kZero);  // failed in tension: no stress left
  // Expanding further: still no stress.
  stretchStep(s, 2e-3);
  CHECK(s.stress == kZero);
  // Compressing (mu = +1e-3): a pure pressure p = K mu, zero deviator.
  s.density = kRho0 * 1.001;
  Mat3 D = Mat3::Zero();
  D(0, 0) = -1e5;
  m.update(s, D, kZero, 1e-8, 0.0);
  const double p = -s.stress.trace() / 3.0;
  CHECK(p == relApprox(kK * 1e-3, 1e-9));
  CHECK((s.stress + p * Mat3::Identity()).norm() <= 1e-12 * p);
}

TEST_CASE("failure: max principal strain from the deformation gradient") {
  const SolidMaterial m = fromCard(
      card("model = \"elastic\"", "[failure]\nmodel = \"max-principal-strain\"\nmax_principal_strain = 0.05"), "mpe");
  // F = diag(1 + e, 1, 1): largest principal stretch 1 + e, engineering strain e; also after a rigid rotation
  // (R F has the same stretches, (R F)(R F)^T = R F F^T R^T).
  for (const bool rotated : {false, true}) {
    for (const double e : {0.04, 0.049, 0.051, 0.06, -0.2}) {
      PointState s = freshState(m);
      s.deformationGradient = Eigen::Vector3d(1.0 + e, 1.0, 1.0).asDiagonal();
      if (rotated) s.deformationGradient = rotation() * s.deformationGradient;
      m.update(s, kZero, kZero, 1e-8, 0.0);
      INFO("e = " << e << ", rotated = " << rotated);
      CHECK(s.failed == (e > 0.05));
    }
  }
}

TEST_CASE("failure: Johnson-Cook damage, fracture strain and accumulation to 1") {
  // Weldox 460E, seed 002 Table 3: D1 = 0.0705, D2 = 1.732, D3 = -0.54, D4 = -0.015, D5 = 0, rate0 = 1/s.
  const SolidMaterial w = makeSolidMaterial(MaterialLibrary::load().get("weldox_460e"));
  const auto jcd = std::dynamic_pointer_cast<const JohnsonCookDamage>(w.failure);
  REQUIRE(jcd);
  // eps_f = [D1 + D2 exp(D3 s*)][1 + D4 ln rate*][1 + D5 T*]
  CHECK(jcd->fractureStrain(0.5, 100.0, 0.2) ==
        relApprox((0.0705 + 1.732 * std::exp(-0.54 * 0.5)) * (1 - 0.015 * std::log(100.0)), 1e-12));
  CHECK(jcd->fractureStrain(-0.33, 0.01, 0.0) == relApprox(0.0705 + 1.732 * std::exp(0.54 * 0.33), 1e-12));
  JohnsonCookDamage::Parameters p;
  p.D1 = 0.05; p.D2 = 0.4; p.D3 = -1.5; p.D4 = 0.02; p.D5 = 0.6; p.referenceRate = 2.0;
  CHECK(JohnsonCookDamage(p).fractureStrain(1.0 / 3.0, 200.0, 0.25) ==
        relApprox((0.05 + 0.4 * std::exp(-0.5)) * (1 + 0.02 * std::log(100.0)) * (1 + 0.6 * 0.25), 1e-12));

  // Accumulation: perfectly plastic pure shear under a fixed mean tension (mu = -0.005, p = K mu) is a path of
  // constant triaxiality s* = -p / Y, so D = ep / eps_f and the point fails when ep reaches eps_f.
  const double Y = 300e6;
  const SolidMaterial m = fromCard(
      card("model = \"bilinear\"\nyield_stress = \"300 MPa\"\ntangent_modulus = \"0 MPa\"",
           "[failure]\nmodel = \"johnson-cook-damage\"\nD1 = 0.05\nD2 = 0.4\nD3 = -1.5\nD4 = 0.02\nD5 = 0.6"),
      "jcd");
  const double mu = -0.005, g = 1e4, dt = 1e-7;
  const double triax = -kK * mu / Y;
  const double rate = 2.0 * g / std::sqrt(3.0);  // equivalent strain rate of pure shear; rate0 = 1/s by default
  // No Johnson-Cook strength, so T* = 0 and D5 drops out.
  const double ef = (0.05 + 0.4 * std::exp(-1.5 * triax)) * (1 + 0.02 * std::log(rate));
  PointState s = freshState(m);
  s.density = kRho0 * (1.0 + mu);
  // The rate in eps_f is the plastic strain rate dep/dt (seed 000 Eq. 9), which equals the pure-shear rate once
  // a step is plastic throughout; so each such step adds dD = dep / eps_f.
  int steps = 0;
  double before = 0, damageBefore = 0;
  for (; steps < 2000 && !s.failed; ++steps) {
    before = s.plasticStrain;
    damageBefore = s.damage;
    m.update(s, pureShear(g), kZero, dt, 0.0);
    if (!s.failed && before > 0) {
      CHECK(-(s.stress.trace() / 3.0) / vonMises(s.stress) == relApprox(-triax, 1e-9));
      CHECK(s.damage - damageBefore == relApprox((s.plasticStrain - before) / ef, 1e-9));
    }
  }
  REQUIRE(s.failed);
  INFO("eps_f = " << ef << ", ep before = " << before << ", after = " << s.plasticStrain);
  CHECK(damageBefore < 1.0);
  CHECK(s.damage >= 1.0);
  CHECK(s.plasticStrain == relApprox(ef, 2 * (s.plasticStrain - before) / ef));  // fails within a step of eps_f
  CHECK(s.stress == kZero);  // failed under mean tension
}

TEST_CASE("makeSolidMaterial on every card of the library") {
  const MaterialLibrary lib = MaterialLibrary::load();
  std::set<std::string> built;
  for (const std::string& id : lib.ids()) {
    INFO(id);
    try {
      const SolidMaterial m = makeSolidMaterial(lib.get(id));
      built.insert(id);
      CHECK(m.density > 0);
      CHECK(m.shearModulus > 0);
      CHECK(m.referenceWaveSpeed() > 0);
    } catch (const InputError& e) {
      // Only the models the solver does not have may stop a card.
      const std::string what = e.what();
      INFO(what);
      CHECK((what.find("johnson-holmquist-1") != std::string::npos || what.find("fluid") != std::string::npos ||
             what.find("polynomial") != std::string::npos));
    }
  }
  for (const char* id : {"al_2a12", "al_5a06", "outer_fabric", "mli_layer", "liner", "weldox_460e", "q235",
                         "cu_ofhc", "cu_ofhc_za", "steel_38crsi", "al_2024", "al_7075_t651"}) {
    INFO(id);
    CHECK(built.count(id) == 1);
  }
}

}  // TEST_SUITE("constitutive")

TEST_SUITE("verification") {

// Johnson-Cook with rate and adiabatic heating in a whole impact, against two other codes on the same problem:
// the axisymmetric Taylor bar of DynELA's documentation (pantale/DynELA-v3.0, Documentation/ImpactSamples.tex,
// "Axisymmetric Taylor impact"): 42CrMo4 steel, L0 = 32.4 mm, D0 = 6.4 mm, 287 m/s onto a rigid frictionless wall,
// 80 us; E 206.9 GPa, nu 0.3, rho 7830, A 806 MPa, B 614 MPa, n 0.168, C 0.0089, m 1.1, ref rate 1/s,
// T0 20 C, Tm 1540 C, cp 460, Taylor-Quinney 0.9, no EOS. Abaqus/Explicit gives L_f = 26.56 mm, D_f = 11.16 mm and,
// in the element at the centre of the impact face, T = 590.96 C and ep = 1.81 (DynELA: 26.52, 11.15, 582.34,
// 1.78). Without the rate term the bar ends 1.7 % shorter with a 3 % wider footprint; without heating the
// footprint is 8 % narrower; so these bounds test both terms.
TEST_CASE("sim: Johnson-Cook Taylor bar (42CrMo4 steel at 287 m/s) within 1 % in length and 2 % in footprint of Abaqus") {
  const Material steel = parseMaterial(
      "name = \"42CrMo4 steel\"\nsource = \"DynELA-v3.0 ImpactSamples.tex, Johnson-Cook parameters table\"\n"
      "density = \"7830 kg/m3\"\n[elastic]\nyoungs_modulus = \"206.9 GPa\"\npoisson_ratio = 0.3\n"
      "[strength]\nmodel = \"johnson-cook\"\nA = \"806 MPa\"\nB = \"614 MPa\"\nn = 0.168\nC = 0.0089\nm = 1.1\n"
      "reference_strain_rate = \"1 1/s\"\nroom_temperature = \"293.15 K\"\nmelt_temperature = \"1813.15 K\"\n"
      "[thermal]\nspecific_heat = \"460 J/kg/K\"\ntaylor_quinney = 0.9\n",
      "42crmo4.toml (test card)", "steel_42crmo4");
  TaylorBarCase c;
  c.velocity = 287.0;
  c.length = 32.4e-3;
  c.diameter = 6.4e-3;
  c.particlesPerDiameter = 20;
  SolverOptions o;
  o.threads = 1;
  auto solver = makeTaylorBarAxisymmetric(c, steel, o);
  RunOptions ro;
  ro.endTime = 80e-6;
  const RunResult r = run<2>(*solver, ro);
  REQUIRE(std::string(toString(r.status)) == "completed");
  const TaylorBarShape shape = measureTaylorBar<2>(*solver);
  CHECK(shape.length == relApprox(26.56e-3, 0.01));
  CHECK(shape.footprintDiameter == relApprox(11.16e-3, 0.02));
  // The point nearest the centre of the impact face: temperature rise and plastic strain within 3 %.
  const auto& P = solver->particles();
  std::size_t centre = 0;
  for (std::size_t p = 1; p < P.size(); ++p)
    if (P.position[p].norm() < P.position[centre].norm()) centre = p;
  CHECK(P.temperature[centre] - 293.15 == relApprox(590.96 - 20.0, 0.03));
  CHECK(P.plasticStrain[centre] == relApprox(1.81, 0.03));
}

}  // TEST_SUITE("verification")
