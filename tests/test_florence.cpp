// Florence's ceramic/metal ballistic limit (seed 002 Eq. 22) and the `blt analytic florence` command.
#include <doctest/doctest.h>

#include "run_blt.hpp"

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <stdexcept>
#include <string>
#include <sys/wait.h>

#include "blt/analytic/florence.hpp"

using namespace blt::analytic;
using doctest::Approx;

namespace {

// SiC-like front plate on an aluminium back plate, 20 mm projectile of 0.197 kg (densities of seed 002
// Tables 2-3; strength and breaking strain are round test values, not from a seed).
FlorenceInput sampleCase() {
  FlorenceInput in;
  in.projectileRadius = 0.010;
  in.projectileMass = 0.197;
  in.ceramicThickness = 0.006;
  in.ceramicDensity = 3227;
  in.backingThickness = 0.004;
  in.backingDensity = 2810;
  in.backingTensileStrength = 500e6;
  in.backingFailureStrain = 0.10;
  return in;
}

const std::string sampleFlags =
    "analytic florence --projectile-radius 10mm --projectile-mass 0.197kg --ceramic-thickness 6mm "
    "--ceramic-density 3227kg/m3 --backing-density 2810kg/m3 --backing-strength 500MPa "
    "--backing-failure-strain 0.1 ";

}  // namespace

TEST_CASE("florence: ballistic limit against a hand computation") {
  // Hand computation, SI:
  //  loaded radius R + 2 b1 = 0.010 + 0.012 = 0.022 m;  z = pi 0.022^2 = 1.520531e-3 m^2
  //  areal mass rho1 b1 + rho2 b2 = 3227 * 0.006 + 2810 * 0.004 = 19.362 + 11.240 = 30.602 kg/m^2
  //  target mass 30.602 * 1.520531e-3 = 0.0465313 kg;  bracket = 0.0465313 + 0.197 = 0.2435313 kg
  //  eps2 sigma2 b2 z = 0.1 * 500e6 * 0.004 * 1.520531e-3 = 304.1062
  //  numerator 304.1062 * 0.2435313 = 74.05937;  denominator 0.91 * 0.197^2 = 0.03531619
  //  v_bl^2 = 2097.037 m^2/s^2  ->  v_bl = 45.7934 m/s
  const FlorenceResult r = florenceBallisticLimit(sampleCase());
  CHECK(r.loadedRadius == Approx(0.022));
  CHECK(r.loadedArea == Approx(1.520531e-3).epsilon(1e-6));
  CHECK(r.targetMass == Approx(0.0465313).epsilon(1e-5));
  CHECK(r.ballisticLimit == Approx(45.7934).epsilon(1e-5));
}

TEST_CASE("florence: limits and trends of the formula") {
  // Thicker back plate: more membrane energy and more mass, so v_bl grows with b2.
  FlorenceInput in = sampleCase();
  double previous = 0;
  for (double b2 = 0.001; b2 <= 0.020 + 1e-12; b2 += 0.001) {
    in.backingThickness = b2;
    const double v = florenceBallisticLimit(in).ballisticLimit;
    CHECK_MESSAGE(v > previous, "b2 = " << b2);
    previous = v;
  }
  // Thicker ceramic spreads the load over a wider disc (and adds mass), so v_bl grows with b1 too.
  in = sampleCase();
  previous = 0;
  for (double b1 = 0.0; b1 <= 0.020 + 1e-12; b1 += 0.002) {
    in.ceramicThickness = b1;
    const double v = florenceBallisticLimit(in).ballisticLimit;
    CHECK_MESSAGE(v > previous, "b1 = " << b1);
    previous = v;
  }
  // v_bl^2 is linear in eps2 and in sigma2.
  in = sampleCase();
  const double base = florenceBallisticLimit(in).ballisticLimit;
  in.backingFailureStrain *= 4;
  CHECK(florenceBallisticLimit(in).ballisticLimit == Approx(2 * base).epsilon(1e-12));
  in = sampleCase();
  in.backingTensileStrength *= 9;
  CHECK(florenceBallisticLimit(in).ballisticLimit == Approx(3 * base).epsilon(1e-12));
  // Heavy projectile (m >> target mass): v_bl^2 -> eps2 sigma2 b2 z / (0.91 m), falling as 1/sqrt(m).
  in = sampleCase();
  in.projectileMass = 1.0e4;
  const double z = std::numbers::pi * 0.022 * 0.022;
  CHECK(florenceBallisticLimit(in).ballisticLimit ==
        Approx(std::sqrt(0.1 * 500e6 * 0.004 * z / (0.91 * 1.0e4))).epsilon(1e-5));
  // No ceramic: the load acts on the projectile's own footprint, z = pi R^2.
  in = sampleCase();
  in.ceramicThickness = 0;
  CHECK(florenceBallisticLimit(in).loadedArea == Approx(std::numbers::pi * 1e-4));
}

TEST_CASE("florence: bad library input is rejected") {
  FlorenceInput in = sampleCase();
  in.backingThickness = -0.004;
  CHECK_THROWS_AS(florenceBallisticLimit(in), std::invalid_argument);
  in = sampleCase();
  in.ceramicThickness = -0.001;
  CHECK_THROWS_AS(florenceBallisticLimit(in), std::invalid_argument);
  in = sampleCase();
  in.backingFailureStrain = 0;
  CHECK_THROWS_AS(florenceBallisticLimit(in), std::invalid_argument);
}

TEST_CASE("florence CLI: result, and input errors that name the flag") {
  BltRun run = runBlt(sampleFlags + "--backing-thickness 0.4cm --velocity 50m/s --json");
  REQUIRE(run.status == 0);
  CHECK(run.output.find("\"v_bl_m_s\": 45.793") != std::string::npos);
  CHECK(run.output.find("\"perforated\": true") != std::string::npos);
  CHECK(run.output.find("v_r_m_s") == std::string::npos);  // the model has no residual velocity

  struct Case {
    std::string args, expected;
  };
  const Case cases[] = {
      {sampleFlags, "blt: error: flag --backing-thickness: the backing (back plate) thickness is required "
                    "(allowed: e.g. --backing-thickness 4mm)"},
      {sampleFlags + "--backing-thickness -4mm",
       "flag --backing-thickness: the backing (back plate) thickness must be positive, got -4 mm (allowed: a value > 0)"},
      {sampleFlags + "--backing-thickness 4", "flag --backing-thickness: '4' has no unit"},
      {sampleFlags + "--backing-thickness 4mm --velocity 50mm", "flag --velocity: '50mm' is a length, expected a velocity"},
      {"analytic florence --projectile-radius 10mm --projectile-mass 0.197kg --ceramic-thickness -1mm "
       "--backing-thickness 4mm --backing-density 2810kg/m3 --backing-strength 500MPa --backing-failure-strain 0.1",
       "flag --ceramic-thickness: the ceramic (front plate) thickness must be zero or positive, got -1 mm"},
      {"analytic florence --projectile-radius 10mm --projectile-mass 0.197kg --ceramic-thickness 6mm "
       "--backing-thickness 4mm --backing-density 2810kg/m3 --backing-strength 500MPa --backing-failure-strain 0.1",
       "flag --ceramic-density: the ceramic density is required"},
  };
  for (const Case& c : cases) {
    run = runBlt(c.args);
    CHECK_MESSAGE(run.status == 2, c.args);
    CHECK_MESSAGE(run.output.find(c.expected) != std::string::npos, c.args << "\n  got: " << run.output);
  }
}
