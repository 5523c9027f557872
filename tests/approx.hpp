#pragma once
// doctest::Approx compares with |a - b| < eps (scale + max(|a|, |b|)) and scale defaults to 1, which makes it an
// absolute tolerance of ~1e-5 on small SI values (1.2e-3 m would pass as 1.21e-3). relApprox is purely relative.
#include <doctest/doctest.h>

inline doctest::Approx relApprox(double expected, double relativeTolerance = 1e-9) {
  return doctest::Approx(expected).epsilon(relativeTolerance).scale(0.0);
}
