// Units module: parsing, conversion and the errors a user sees. Reference values are the SI definitions
// (1 ksi = 6.894757 MPa, 1 in = 25.4 mm: NIST SP 811).
#include <doctest/doctest.h>

#include "approx.hpp"

#include "blt/core/units.hpp"

using namespace blt;

TEST_CASE("units: the values named in the design card parse to SI") {
  CHECK(units::parse("1.2 mm", units::length) == relApprox(1.2e-3));
  CHECK(units::parse("6.5 km/s", units::velocity) == relApprox(6500.0));
  CHECK(units::parse("45 deg", units::angle) == relApprox(0.7853981633974483));
  CHECK(units::parse("2770 kg/m3", units::density) == relApprox(2770.0));
  CHECK(units::parse("490 MPa", units::pressure) == relApprox(490e6));
  CHECK(units::parse("0.197 kg", units::mass) == relApprox(0.197));
}

TEST_CASE("units: spacing, prefixes, powers and compound units") {
  CHECK(units::parse("6.5km/s", units::velocity) == relApprox(6500.0));
  CHECK(units::parse("  2.77e-3 g/mm3 ", units::density) == relApprox(2770.0));
  CHECK(units::parse("2.8 g/cm^3", units::density) == relApprox(2800.0));
  CHECK(units::parse("904 J/kg/K", units::specificHeat) == relApprox(904.0));
  CHECK(units::parse("1 1/s", units::rate) == relApprox(1.0));
  CHECK(units::parse("1 s^-1", units::rate) == relApprox(1.0));
  CHECK(units::parse("40 ksi", units::pressure) == relApprox(40 * 6.894757293168361e6));
  CHECK(units::parse("1 in", units::length) == relApprox(0.0254));
  CHECK(units::parse("18 um", units::length) == relApprox(18e-6));
  CHECK(units::parse("18 \xC2\xB5m", units::length) == relApprox(18e-6));
  CHECK(units::parse("4 us", units::time) == relApprox(4e-6));
  CHECK(units::parse("5 mm/min", units::velocity) == relApprox(5e-3 / 60));
  CHECK(units::parse("0.3", units::dimensionless) == relApprox(0.3));
  CHECK(units::parse("1 rad", units::angle) == relApprox(1.0));
}

TEST_CASE("units: conversion back for printing") {
  CHECK(units::toUnit(6500.0, "km/s") == relApprox(6.5));
  CHECK(units::fromUnit(1.2, "mm") == relApprox(1.2e-3));
  CHECK(units::format(0.0012, "mm") == "1.2 mm");
}

TEST_CASE("units: a missing unit is an error that names the flag") {
  try {
    units::parse("6.5", units::velocity, InputLocation::flag("--velocity"));
    FAIL("expected an error");
  } catch (const InputError& e) {
    const std::string msg = e.what();
    CHECK(msg.find("flag --velocity") != std::string::npos);
    CHECK(msg.find("unit is required") != std::string::npos);
    CHECK(msg.find("km/s") != std::string::npos);  // shows an example of what is allowed
  }
}

TEST_CASE("units: a wrong dimension is an error naming file, line and field") {
  try {
    units::parse("6.5 km", units::velocity, InputLocation::file("tests.csv", 4, "velocity"));
    FAIL("expected an error");
  } catch (const InputError& e) {
    const std::string msg = e.what();
    CHECK(msg.find("file tests.csv, line 4, field 'velocity'") != std::string::npos);
    CHECK(msg.find("is a length, expected a velocity") != std::string::npos);
  }
}

TEST_CASE("units: unknown units and malformed values are rejected") {
  CHECK_THROWS_WITH_AS(units::parse("3 furlongs", units::length), doctest::Contains("unknown symbol 'furlongs'"),
                       InputError);
  CHECK_THROWS_WITH_AS(units::parse("fast", units::velocity), doctest::Contains("does not start with a number"),
                       InputError);
  CHECK_THROWS_AS(units::parse("", units::length), InputError);
  CHECK_THROWS_AS(units::parse("3 m//s", units::velocity), InputError);
  CHECK_THROWS_AS(units::parse("3 m/", units::velocity), InputError);
  CHECK_THROWS_AS(units::parse("45 mm", units::angle), InputError);
}
