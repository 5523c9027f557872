// The command line's small shared helpers (apps/cli_support.hpp): progress estimates and number formats.
#include <doctest/doctest.h>

#include <cmath>

#include "cli_support.hpp"

using namespace blt;

TEST_CASE("cli: a run's remaining wall time is the pace so far carried to the end time") {
  sim::RunProgress p;
  p.endTime = 100e-6;
  p.wallSeconds = 30.0;
  CHECK(std::isinf(cli::remainingWallSeconds(p)));  // no simulated time yet: no pace to go by
  p.time = 25e-6;  // a quarter of the run in 30 s: the other three quarters take 90 s
  CHECK(cli::remainingWallSeconds(p) == doctest::Approx(90.0));
  p.time = 100e-6;
  CHECK(cli::remainingWallSeconds(p) == 0.0);
  p.time = 100.5e-6;  // the last step overshoots the end time
  CHECK(cli::remainingWallSeconds(p) == 0.0);
}

TEST_CASE("cli: wall clock text is m:ss below an hour, h:mm:ss from an hour, ? when unknown") {
  CHECK(cli::wallClock(0.4) == "0:00");
  CHECK(cli::wallClock(59.6) == "1:00");
  CHECK(cli::wallClock(754) == "12:34");
  CHECK(cli::wallClock(3600) == "1:00:00");
  CHECK(cli::wallClock(5025) == "1:23:45");
  CHECK(cli::wallClock(INFINITY) == "?");
  CHECK(cli::wallClock(NAN) == "?");
}

TEST_CASE("cli: number() gives the significant digits asked for") {
  CHECK(cli::number(197.94, 4) == "197.9");
  CHECK(cli::number(0.000123456, 3) == "0.000123");
  CHECK(cli::number(1234567.0, 3) == "1.23e+06");
}

TEST_CASE("cli: a progress line gives step, times in us and ns, particles, wall time and ETA, kinetic energy on request") {
  sim::RunProgress p;
  p.step = 726;
  p.time = 15e-6;
  p.endTime = 30e-6;
  p.timeStep = 23.2e-9;
  p.activeParticles = 6590;
  p.wallSeconds = 2.0;
  p.energy.kinetic = 1234.4;
  CHECK(cli::progressLine(p, false) ==
        "  step 726  t = 15.00 / 30.00 us  dt = 23.2 ns  6590 particles  wall 2.0 s  ETA 0:02\n");
  CHECK(cli::progressLine(p, true) ==
        "  step 726  t = 15.00 / 30.00 us  dt = 23.2 ns  kinetic 1234 J  6590 particles  wall 2.0 s  ETA 0:02\n");
}
