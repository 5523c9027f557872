#include "blt/calibrate/synthetic.hpp"

#include <algorithm>
#include <numeric>

#include "blt/calibrate/calibrate.hpp"
#include "blt/core/seeded_gaussian.hpp"

namespace blt::calibrate {

MeasuredData synthesize(Model& model, const MeasuredData& shape, const SyntheticOptions& options) {
  std::vector<std::size_t> cases(shape.cases.size());
  std::iota(cases.begin(), cases.end(), std::size_t{0});
  const std::vector<Prediction> predicted = model.predict(shape, cases, options.setting);
  MeasuredData out = shape;
  out.source = shape.source + " (synthetic: " + model.describe() +
               (options.setting.effect ? ", " + options.setting.effect->name : std::string(", no effect")) + ")";
  SeededGaussian gauss(options.seed);
  for (Observation& o : out.observations) {
    const Prediction& p = predicted[o.caseIndex];
    const double v = predictedValue(o, p);
    switch (o.kind) {
      case ObservationKind::outcome: o.value = p.perforated ? 1.0 : 0.0; break;
      case ObservationKind::residualVelocity:
        o.value = v > 0 ? std::max(v + options.velocityScatter * gauss(), 0.01) : 0.0;
        break;
      case ObservationKind::holeHorizontal:
      case ObservationKind::holeVertical:
        o.value = v > 0 ? std::max(v * (1 + options.holeScatter * gauss()), 1e-6) : 0.0;
        break;
    }
  }
  return out;
}

}  // namespace blt::calibrate
