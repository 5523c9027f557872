#pragma once
// Standard normal deviates for synthetic data (tests, benchmarks), the same on every platform: a fixed-seed
// mt19937 (its output is fixed by the standard, std::normal_distribution's is not) through Box-Muller.
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

namespace blt {

class SeededGaussian {
 public:
  explicit SeededGaussian(uint32_t seed) : engine_(seed) {}
  double operator()() {
    const double u1 = (static_cast<double>(engine_()) + 0.5) / 4294967296.0;
    const double u2 = (static_cast<double>(engine_()) + 0.5) / 4294967296.0;
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }

 private:
  std::mt19937 engine_;
};

}  // namespace blt
