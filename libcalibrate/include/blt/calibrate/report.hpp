#pragma once
// The calibration report in a directory: report.md (the base errors, the diagnosis, the ranking of the effects
// with their fits and held-out checks, the decision and its rule, errors before and after), calibration.json
// (toJson of calibrate.hpp) and SVG plots of predicted against measured values before and after, one per
// measured quantity with a continuous value (residual_velocity.svg, hole_size.svg).

#include <string>
#include <vector>

#include "blt/calibrate/calibrate.hpp"

namespace blt::calibrate {

// Creates the directory when missing. Returns the files written. Throws InputError naming the directory when it
// cannot be written.
std::vector<std::string> writeReport(const std::string& directory, const CalibrationResult& result,
                                     const MeasuredData& data);

}  // namespace blt::calibrate
