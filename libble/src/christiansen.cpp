#include "blt/ble/christiansen.hpp"

#include "blt/core/units.hpp"

namespace blt::ble {

ChristiansenCoefficients ChristiansenCoefficients::seed000Table8() {
  return {units::fromUnit(4.73, "km/s"), units::fromUnit(6.56, "km/s"), 13.0, 18.0, 0.12, 0.1, 0.48, 0.23};
}

ChristiansenCoefficients ChristiansenCoefficients::emu(double CL, double CH, double X) {
  return {units::fromUnit(5.1, "km/s"), units::fromUnit(6.95, "km/s"), CL, CH, 0.132, 0.45, X, 0.45};
}

}  // namespace blt::ble
