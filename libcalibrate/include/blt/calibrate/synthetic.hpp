#pragma once
// "Measured" data made by a model, for checking the calibrator on data whose effect is known: the cases and
// the kinds of observation of a template (a real measured file), each value replaced by the model's prediction
// with an effect switched on, and seeded scatter added. Only the data go to the calibrator.

#include <cstdint>
#include <string>
#include <vector>

#include "blt/calibrate/measured.hpp"
#include "blt/calibrate/model.hpp"

namespace blt::calibrate {

struct SyntheticOptions {
  EffectSetting setting;             // the effect that makes the data (none: the base model's own data)
  double holeScatter = 0;            // relative standard deviation of hole sizes (0.05: 5 %)
  double velocityScatter = 0;        // m/s, standard deviation of residual velocities of perforating shots
  std::uint32_t seed = 1;
};

// Outcomes stay binary: the model's verdict, or, where it gives a perforating share p strictly between 0 and 1,
// perforated with probability p (seeded). Hole sizes and residual velocities stay positive.
MeasuredData synthesize(Model& model, const MeasuredData& shape, const SyntheticOptions& options);

// The template with both hole extents in each of `layers` for every case that has a hole measured in any layer:
// synthetic data can measure the layers a test could not (seed 000 Table 5 gives the outer layer and the plate
// only, where gaps in front of the plate and gaps inside the coating look alike). The added observations come
// after the template's own, so synthesize draws the same scatter for those as without them.
MeasuredData withHolesInLayers(const MeasuredData& shape, const std::vector<std::string>& layers);

}  // namespace blt::calibrate
