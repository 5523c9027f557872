// Chen-Li thick-plate ballistic limit: shear plugging (flat nose) and cavity-expansion hole enlargement
// (sharp noses), and the `blt analytic chen-li` command's input errors.
#include <doctest/doctest.h>

#include "run_blt.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <sys/wait.h>

#include "blt/analytic/chen_li.hpp"
#include "blt/core/materials.hpp"

using namespace blt;
using namespace blt::analytic;
using doctest::Approx;

namespace {

constexpr double pi = std::numbers::pi;

// Børvik's 12 mm Weldox 460E plate and 20 mm, 0.197 kg projectile (REFERENCE.md §4, seed 002 Table 3).
ChenLiInput borvikCase() {
  ChenLiInput in;
  in.plateThickness = 0.012;
  in.projectileDiameter = 0.020;
  in.projectileMass = 0.197;
  in.plateDensity = 7850;
  in.plateYieldStress = 490e6;
  return in;
}

// N* from its definition, N* = (2/a^2) * integral_0^a n_x(r)^2 r dr, by Simpson's rule, for a nose whose
// squared axial normal component at radius r is nx2(r). Independent of the closed forms in chen_li.cpp.
template <class F>
double noseFactorByQuadrature(double a, F nx2) {
  const int n = 20000;  // even
  const double h = a / n;
  double sum = 0;
  for (int i = 0; i <= n; ++i) {
    const double r = i * h;
    const double w = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
    sum += w * nx2(r) * r;
  }
  return 2 / (a * a) * sum * h / 3;
}

const std::string borvikFlags = "analytic chen-li --thickness 12mm --diameter 20mm --mass 0.197kg ";

}  // namespace

TEST_CASE("chen-li: blunt projectile on Borvik's 12 mm Weldox 460E plate") {
  // Reference: REFERENCE.md §4, seed 002 Eq. 20 with theta = 0 gives 173 m/s for this case (measured
  // 184.5 m/s, Borvik et al. 2002; the model is expected below the test because it ignores hardening).
  // Hand computation: chi = 12/20 = 0.6; plug mass = 7850 * pi * 0.02^2 * 0.012 / 4 = 0.0295938 kg,
  // eta = 0.0295938 / 0.197 = 0.150222; sqrt(sigma_y/rho) = sqrt(490e6/7850) = 249.841 m/s;
  // 2 chi eta (1 + eta)/sqrt(3) = 2 * 0.6 * 0.150222 * 1.150222 / 1.732051 = 0.119711, sqrt = 0.345993;
  // V_BL = 2 * 0.345993 * 249.841 = 172.887 m/s.
  const ChenLiResult r = chenLiBallisticLimit(borvikCase());
  CHECK(r.mechanism == PerforationMechanism::ShearPlugging);
  CHECK(r.chi == Approx(0.6));
  CHECK(r.eta == Approx(0.150222).epsilon(1e-5));
  CHECK(r.noseFactor == 1.0);
  CHECK(std::abs(r.ballisticLimit - 173.0) <= 2.0);
  CHECK(r.ballisticLimit == Approx(172.887).epsilon(1e-5));
}

TEST_CASE("chen-li: plugging residual velocity against the two-step momentum/energy balance") {
  // Hand computation at V_i = 250 m/s, done as the derivation in chen_li.hpp goes, not with Eq. 21:
  //  collision: V0 = 250 / 1.150222 = 217.349 m/s; kinetic energy of projectile + plug
  //             (1/2)(0.197 + 0.0295938) 217.349^2 = 5352.23 J;
  //  shear work W = (490e6/sqrt(3)) * pi * 0.020 * 0.012^2 = 2559.63 J;
  //  left: 2792.59 J = (1/2)(0.2265938) V_r^2  ->  V_r = 156.998 m/s.
  const ChenLiResult r = chenLiBallisticLimit(borvikCase());
  CHECK(chenLiResidualVelocity(r, 250.0) == Approx(156.998).epsilon(1e-5));
  // No perforation at or below the limit, and V_r starts from zero there.
  CHECK(chenLiResidualVelocity(r, 150.0) == 0.0);
  CHECK(chenLiResidualVelocity(r, r.ballisticLimit) == 0.0);
  CHECK(chenLiResidualVelocity(r, r.ballisticLimit * 1.0001) < 3.0);
  // Far above the limit the projectile and plug share the momentum: V_r -> V_i / (1 + eta).
  CHECK(chenLiResidualVelocity(r, 1.0e5) == Approx(1.0e5 / (1 + r.eta)).epsilon(1e-4));
}

TEST_CASE("chen-li: the ballistic limit grows with plate thickness") {
  for (NoseShape shape : {NoseShape::Flat, NoseShape::Conical, NoseShape::Ogival, NoseShape::Hemispherical}) {
    ChenLiInput in = borvikCase();
    in.nose = {shape, 20 * pi / 180, 3.0};
    in.plateYoungsModulus = 200e9;
    double previous = 0;
    for (double h = 0.004; h <= 0.040 + 1e-12; h += 0.002) {
      in.plateThickness = h;
      const double v = chenLiBallisticLimit(in).ballisticLimit;
      CHECK_MESSAGE(v > previous, noseShapeName(shape) << " nose, H = " << h);
      previous = v;
    }
  }
}

TEST_CASE("chen-li: nose-shape factors against the integral that defines them") {
  const double a = 1.0;
  // Hemisphere: n_x^2 = 1 - r^2/a^2.
  const double hemi = noseFactorByQuadrature(a, [a](double r) { return 1 - r * r / (a * a); });
  CHECK(hemi == Approx(0.5).epsilon(1e-8));
  CHECK(noseShapeFactor({NoseShape::Hemispherical}) == Approx(hemi).epsilon(1e-8));
  // Cone of half-angle theta0: n_x = sin(theta0) everywhere.
  for (double deg : {10.0, 18.0, 30.0, 60.0}) {
    const double t = deg * pi / 180;
    const double cone = noseFactorByQuadrature(a, [t](double) { return std::sin(t) * std::sin(t); });
    CHECK(noseShapeFactor({NoseShape::Conical, t}) == Approx(cone).epsilon(1e-8));
  }
  // Tangent ogive of CRH psi: arc of radius s = 2 psi a centred at radius a - s in the shank's end plane;
  // at radius r the point is at axial distance x = sqrt(s^2 - (r + s - a)^2) and n_x = x / s.
  for (double psi : {0.5, 1.0, 2.0, 3.0, 6.0}) {
    const double s = 2 * psi * a;
    const double ogive = noseFactorByQuadrature(a, [s, a](double r) {
      const double u = r + s - a;
      return (s * s - u * u) / (s * s);
    });
    CHECK_MESSAGE(noseShapeFactor({NoseShape::Ogival, 0, psi}) == Approx(ogive).epsilon(1e-7), "psi = " << psi);
  }
  CHECK(noseShapeFactor({NoseShape::Flat}) == 1.0);
  CHECK_THROWS_AS(noseShapeFactor({NoseShape::Conical, 0.0}), std::invalid_argument);
  CHECK_THROWS_AS(noseShapeFactor({NoseShape::Conical, pi / 2}), std::invalid_argument);
  CHECK_THROWS_AS(noseShapeFactor({NoseShape::Ogival, 0, 0.4}), std::invalid_argument);
}

TEST_CASE("chen-li: spherical cavity-expansion constant A") {
  // Hand computation, Weldox-like E = 200 GPa, nu = 0.33, sigma_y = 490 MPa:
  // E / (3 (1 - nu) sigma_y) = 200e9 / (3 * 0.67 * 490e6) = 203.0663; ln = 5.313534; A = (2/3)(6.313534) = 4.20902.
  CHECK(sphericalCavityConstant(200e9, 0.33, 490e6) == Approx(4.20902).epsilon(1e-5));
  // Incompressible limit, derived independently (quasi-static spherical cavity, elastic-perfectly plastic,
  // incompressible): elastic zone u = C/r^2 yields at the plastic radius c when 6 G C / c^3 = Y, so
  // sigma_r(c) = -2Y/3; in the plastic zone d sigma_r / dr = 2Y/r gives p = 2Y/3 + 2Y ln(c/a); volume
  // a^3 = 3 c^2 u(c) = Y c^3 / (2G) gives ln(c/a) = ln(2G/Y)/3. So p/Y = (2/3)(1 + ln(2G/Y)), G = E/3.
  const double E = 70e9, Y = 300e6, G = E / 3;
  CHECK(sphericalCavityConstant(E, 0.5, Y) == Approx((2.0 / 3.0) * (1 + std::log(2 * G / Y))).epsilon(1e-12));
  CHECK_THROWS_AS(sphericalCavityConstant(1e6, 0.3, 490e6), std::invalid_argument);
}

TEST_CASE("chen-li: hole enlargement against a hand computation and a numerical integration") {
  // Conical nose of half-angle 30 deg (N* = 0.25) on Borvik's plate, with A = 4 given and B = 1.5.
  // Hand computation: N = 0.197 / (0.25 * 7850 * 0.02^3) = 12.54777; pi B chi / (2N) = 2.827433 / 25.09554
  // = 0.1126668; I_BL = (12.54777 / 1.5)(exp(0.1126668) - 1) = 8.365180 * 0.1192585 = 0.997622;
  // V_BL = sqrt(0.997622 * 4 * 490e6 * 0.02^3 / 0.197) = sqrt(79404.9) = 281.788 m/s.
  ChenLiInput in = borvikCase();
  in.nose = {NoseShape::Conical, pi / 6};
  in.cavityConstant = 4.0;
  const ChenLiResult r = chenLiBallisticLimit(in);
  CHECK(r.mechanism == PerforationMechanism::HoleEnlargement);
  CHECK(r.noseFactor == Approx(0.25).epsilon(1e-12));
  CHECK(r.geometryFunction == Approx(12.54777).epsilon(1e-6));
  CHECK(r.impactFunctionAtLimit == Approx(0.997622).epsilon(1e-5));
  CHECK(r.ballisticLimit == Approx(281.788).epsilon(1e-5));

  // The same from the equation of motion, stepped numerically through the plate (RK4 on V^2 over x):
  // d(V^2)/dx = -(2/M)(pi d^2/4)(A sigma_y + B N* rho V^2). Starting at V_BL it must end at rest; starting
  // at 400 m/s it must end at the closed-form residual velocity.
  const double k = 2 / in.projectileMass * pi * 0.02 * 0.02 / 4;
  auto slope = [&](double u) { return -k * (4.0 * 490e6 + 1.5 * 0.25 * 7850 * u); };
  auto integrate = [&](double v0) {
    double u = v0 * v0;
    const int steps = 2000;
    const double h = in.plateThickness / steps;
    for (int i = 0; i < steps; ++i) {
      const double k1 = slope(u), k2 = slope(u + h / 2 * k1), k3 = slope(u + h / 2 * k2), k4 = slope(u + h * k3);
      u += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    }
    return u;
  };
  CHECK(std::abs(integrate(r.ballisticLimit)) < 1e-6 * r.ballisticLimit * r.ballisticLimit);
  CHECK(chenLiResidualVelocity(r, 400.0) == Approx(std::sqrt(integrate(400.0))).epsilon(1e-8));
  CHECK(chenLiResidualVelocity(r, 400.0) == Approx(268.343).epsilon(1e-5));  // hand: sqrt((400^2-281.788^2) e^-0.1126668)

  // Negligible nose inertia (very slender cone): the work is the quasi-static hole opening,
  // (1/2) M V_BL^2 = A sigma_y pi d^2 H / 4, i.e. I_BL -> pi chi / 2.
  in.nose.coneHalfAngle = 1e-4;
  const ChenLiResult slender = chenLiBallisticLimit(in);
  CHECK(slender.impactFunctionAtLimit == Approx(pi * 0.6 / 2).epsilon(1e-6));
}

TEST_CASE("chen-li: bad library input is rejected") {
  ChenLiInput in = borvikCase();
  in.plateThickness = -0.012;
  CHECK_THROWS_AS(chenLiBallisticLimit(in), std::invalid_argument);
  in = borvikCase();
  in.nose = {NoseShape::Hemispherical};  // sharp nose without E or A
  CHECK_THROWS_WITH_AS(chenLiBallisticLimit(in), doctest::Contains("Young's modulus"), std::invalid_argument);
}

TEST_CASE("chen-li: plate properties from a material card") {
  const std::string jc =
      "name = \"plate\"\nsource = \"test\"\ndensity = \"7850 kg/m3\"\n"
      "[elastic]\nshear_modulus = \"75 GPa\"\n"
      "[strength]\nmodel = \"johnson-cook\"\nA = \"490 MPa\"\nB = \"807 MPa\"\nn = 0.73\n";
  PlateProperties p = plateProperties(parseMaterial(jc, "plate.toml", "plate"));
  CHECK(p.density == Approx(7850));
  CHECK(p.yieldStress == Approx(490e6));
  CHECK(p.yieldSource == "strength.A (johnson-cook)");
  CHECK(p.shearModulus == Approx(75e9));
  CHECK(p.youngsModulus == 0.0);
  // An explicit quasi-static yield stress in [properties] wins over the Johnson-Cook A.
  p = plateProperties(parseMaterial(jc + "[properties]\nyield_stress = \"500 MPa\"\n", "p.toml", "p"));
  CHECK(p.yieldStress == Approx(500e6));
  CHECK(p.yieldSource == "properties.yield_stress");
}

TEST_CASE("chen-li CLI: results and units at the edges") {
  BltRun run = runBlt(borvikFlags + "--density 7.85g/cm3 --yield 0.49GPa --velocity 250m/s --json");
  REQUIRE(run.status == 0);
  CHECK(run.output.find("\"v_bl_m_s\": 172.88") != std::string::npos);
  CHECK(run.output.find("\"v_r_m_s\": 156.99") != std::string::npos);
  CHECK(run.output.find("\"chi\": 0.6") != std::string::npos);
  CHECK(run.output.find("\"model\": \"chen-li shear plugging\"") != std::string::npos);

  // A material card from a library directory of our own.
  const auto dir = std::filesystem::temp_directory_path() / "blt_test_chen_li_materials";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "plate_steel.toml") << "name = \"plate steel\"\nsource = \"test\"\ndensity = \"7850 kg/m3\"\n"
                                             "[strength]\nmodel = \"johnson-cook\"\nA = \"490 MPa\"\n";
  run = runBlt(borvikFlags + "--material plate_steel --json", "BLT_MATERIALS_DIR='" + dir.string() + "'");
  CHECK(run.status == 0);
  CHECK(run.output.find("\"v_bl_m_s\": 172.88") != std::string::npos);
  CHECK(run.output.find("strength.A (johnson-cook)") != std::string::npos);
  run = runBlt(borvikFlags + "--material no_such_steel", "BLT_MATERIALS_DIR='" + dir.string() + "'");
  CHECK(run.status == 2);
  CHECK(run.output.find("field 'no_such_steel': no material of that name (allowed: plate_steel)") != std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST_CASE("chen-li CLI: input errors name the flag, the value and what is allowed") {
  struct Case {
    std::string args, expected;
  };
  const Case cases[] = {
      {"analytic chen-li --diameter 20mm --mass 0.197kg --density 7850kg/m3 --yield 490MPa",
       "blt: error: flag --thickness: the plate thickness is required (allowed: e.g. --thickness 12mm)"},
      {"analytic chen-li --thickness -12mm --diameter 20mm --mass 0.197kg --density 7850kg/m3 --yield 490MPa",
       "flag --thickness: the plate thickness must be positive, got -12 mm (allowed: a value > 0)"},
      {borvikFlags + "--density 7850kg/m3 --yield 490", "flag --yield: '490' has no unit"},
      {borvikFlags + "--density 7850kg/m3 --yield 490mm", "flag --yield: '490mm' is a length, expected a pressure"},
      {borvikFlags + "--yield 490MPa", "flag --density: the plate density is required (allowed: --density"},
      {borvikFlags + "--density 7850kg/m3", "flag --yield: the plate yield stress is required"},
      {borvikFlags + "--density 7850kg/m3 --yield 490MPa --nose pointed",
       "flag --nose: unknown nose shape 'pointed' (allowed: flat (or blunt), hemispherical, conical, ogival)"},
      {borvikFlags + "--density 7850kg/m3 --yield 490MPa --nose conical --youngs-modulus 200GPa",
       "flag --nose-angle: the cone half-angle of a conical nose is required"},
      {borvikFlags + "--density 7850kg/m3 --yield 490MPa --nose conical --nose-angle 95deg --youngs-modulus 200GPa",
       "flag --nose-angle: the cone half-angle must lie between 0 and 90 deg, got 95 deg"},
      {borvikFlags + "--density 7850kg/m3 --yield 490MPa --nose ogival --crh 0.3 --youngs-modulus 200GPa",
       "flag --crh: the caliber-radius-head must be at least 0.5, got 0.3 (allowed: psi >= 0.5"},
      {borvikFlags + "--density 7850kg/m3 --yield 490MPa --nose ogival --crh 3",
       "flag --youngs-modulus: the ogival nose (hole enlargement) needs the plate's Young's modulus"},
      {borvikFlags + "--density 7850kg/m3 --yield 490MPa --crh 3",
       "flag --crh: a caliber-radius-head was given for a flat nose (allowed: --crh only with --nose ogival)"},
      {borvikFlags + "--density 7850kg/m3 --yield 490MPa --velocity -5m/s",
       "flag --velocity: the impact velocity must not be negative, got -5 m/s"},
  };
  for (const Case& c : cases) {
    const BltRun run = runBlt(c.args);
    CHECK_MESSAGE(run.status == 2, c.args);
    CHECK_MESSAGE(run.output.find(c.expected) != std::string::npos, c.args << "\n  got: " << run.output);
  }
}
