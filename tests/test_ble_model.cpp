// The BLE forms of libble against independent numbers: REFERENCE §1's worked table (computed from seed 000
// Eq. 12 with the Table 8 coefficients) and REFERENCE §2's check of the NASA Whipple BLE on the pyBLOSSUM
// Whipple database (830 of 1135 shots classified right).
#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <filesystem>

#include "blt/ble/christiansen.hpp"
#include "blt/ble/nasa.hpp"
#include "blt/core/csv.hpp"
#include "blt/core/units.hpp"
#include "approx.hpp"

using namespace blt;

TEST_CASE("ble: seed 000 Table 8 coefficients reproduce REFERENCE §1's table to 1e-4 mm") {
  const auto c = ble::ChristiansenCoefficients::seed000Table8();
  const double rho = 2770.0;  // 2A12 projectile, seed 000 Table 3
  const std::array<double, 8> velocitiesKmS{2, 3, 4, 5, 6, 7, 8, 9};
  const std::array<double, 3> anglesDeg{0, 45, 60};
  const double expectedMm[3][8] = {
      {1.5560, 1.1875, 0.9802, 0.8912, 0.9455, 0.9346, 0.8550, 0.7904},
      {1.8377, 1.4024, 1.1577, 1.0079, 1.0218, 1.0122, 0.9260, 0.8560},
      {2.1703, 1.6562, 1.3672, 1.1782, 1.1277, 1.0940, 1.0028, 0.9271},
  };
  for (size_t a = 0; a < anglesDeg.size(); ++a) {
    for (size_t v = 0; v < velocitiesKmS.size(); ++v) {
      const double dc = ble::criticalDiameter(c, units::fromUnit(velocitiesKmS[v], "km/s"),
                                              units::fromUnit(anglesDeg[a], "deg"), rho);
      CAPTURE(anglesDeg[a]);
      CAPTURE(velocitiesKmS[v]);
      CHECK(std::abs(units::toUnit(dc, "mm") - expectedMm[a][v]) < 1e-4);
    }
  }
}

TEST_CASE("ble: the generalized form is continuous at V1 and V2") {
  // REFERENCE §1: the form is continuous at the regime boundaries, at any angle.
  const auto c = ble::ChristiansenCoefficients::seed000Table8();
  for (double deg : {0.0, 30.0, 60.0, 75.0}) {
    const double th = units::fromUnit(deg, "deg");
    const double V1 = c.VL / std::pow(std::cos(th), c.SL);
    const double V2 = c.VH / std::pow(std::cos(th), c.SH);
    CHECK(ble::criticalDiameter(c, V1 * (1 - 1e-9), th, 2770) == relApprox(ble::criticalDiameter(c, V1 * (1 + 1e-9), th, 2770), 1e-7));
    CHECK(ble::criticalDiameter(c, V2 * (1 - 1e-9), th, 2770) == relApprox(ble::criticalDiameter(c, V2 * (1 + 1e-9), th, 2770), 1e-7));
  }
}

TEST_CASE("ble: single-wall Cour-Palais BLE against a hand computation") {
  // 0.3175 cm Al wall (BHN 95, ρt 2.713 g/cm³, c_t 5.1 km/s), Al projectile ρp 2.796 g/cm³ at 6 km/s, θ = 0.
  // By hand: ρp/ρt = 1.030593 (< 1.5, exponent ½) -> 1.015181; BHN^-¼ = 0.320309; (6/5.1)^⅔ = 1.114433;
  // 1.8 · 5.24 · 0.320309 · 1.015181 · 1.114433 = 3.417989; d^(19/18) = 0.3175/3.417989 = 0.0928909;
  // d = 0.0928909^(18/19) = 0.105267 cm.
  ble::SingleWallTarget wall{units::fromUnit(0.3175, "cm"), 2713.0, 95.0, 5100.0};
  const double dc = ble::singleWallCriticalDiameter(wall, 2796.0, 6000.0, 0.0);
  CHECK(units::toUnit(dc, "cm") == relApprox(0.105267, 1e-5));
}

TEST_CASE("ble: NASA Whipple BLE classifies 830 of 1135 pyBLOSSUM Whipple shots right (REFERENCE §2)") {
  const std::string path = std::string(BLT_SHARED_DIR) + "/data/pyblossum/database_whipple_pyBLOSSUM.csv";
  REQUIRE_MESSAGE(std::filesystem::exists(path), "needs ../shared beside the checkout: " << path);
  const auto t = csv::Table::read(path, {.unitRow = true});
  auto col = [&](const char* name) { return t.column(name); };
  auto si = [&](size_t r, const char* name) { return t.quantity(r, col(name), t.unitOf(col(name))); };
  int right = 0;
  for (size_t r = 0; r < t.rowCount(); ++r) {
    ble::WhippleShield shield{si(r, "bumper_thick"), si(r, "bumper_density"), si(r, "wall_thick"), si(r, "wall_yield"),
                              si(r, "standoff")};
    const double dc = ble::whippleCriticalDiameter(shield, si(r, "proj_density"), si(r, "velocity"), si(r, "angle"));
    const bool predicted = si(r, "proj_diam") > dc;
    if (predicted == t.flag(r, col("perforated_class"))) ++right;
  }
  CHECK(t.rowCount() == 1135);
  CHECK(right == 830);
}

TEST_CASE("ble: the margin ln(d/d_c) of a shot has the sign of the expected outcome") {
  // At 0 deg and 7 km/s REFERENCE §1's table gives d_c = 0.9346 mm for the seed coefficients.
  const auto c = ble::ChristiansenCoefficients::seed000Table8();
  CHECK(ble::margin(c, 1.2e-3, 7000.0, 0.0, 2770.0) == relApprox(std::log(1.2 / 0.9346), 1e-4));
  CHECK(ble::margin(c, 0.8e-3, 7000.0, 0.0, 2770.0) < 0.0);
}
