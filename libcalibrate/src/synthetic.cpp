#include "blt/calibrate/synthetic.hpp"

#include <algorithm>
#include <numeric>
#include <random>

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
  // A model that gives a perforating share (the solver over grid alignments) draws the outcome from it: a shot
  // that perforates at half the alignments is a coin flip, not the majority's verdict. Own engine, so the
  // scatter of the other observations is the same whether or not outcomes are drawn.
  std::mt19937 draw(options.seed ^ 0x9e3779b9u);
  for (Observation& o : out.observations) {
    const Prediction& p = predicted[o.caseIndex];
    const double v = predictedValue(o, p);
    switch (o.kind) {
      case ObservationKind::outcome:
        if (p.perforatedFraction && *p.perforatedFraction > 0 && *p.perforatedFraction < 1)
          o.value = (static_cast<double>(draw()) + 0.5) / 4294967296.0 < *p.perforatedFraction ? 1.0 : 0.0;
        else
          o.value = p.perforated ? 1.0 : 0.0;
        break;
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

MeasuredData withHolesInLayers(const MeasuredData& shape, const std::vector<std::string>& layers) {
  MeasuredData out = shape;
  std::vector<std::size_t> casesWithHoles;
  for (const Observation& o : shape.observations)
    if (isHole(o.kind) && std::find(casesWithHoles.begin(), casesWithHoles.end(), o.caseIndex) == casesWithHoles.end())
      casesWithHoles.push_back(o.caseIndex);
  for (std::size_t c : casesWithHoles)
    for (const std::string& layer : layers)
      for (ObservationKind kind : {ObservationKind::holeHorizontal, ObservationKind::holeVertical}) {
        const bool measured = std::any_of(shape.observations.begin(), shape.observations.end(), [&](const Observation& o) {
          return o.caseIndex == c && o.kind == kind && o.layer == layer;
        });
        if (!measured) out.observations.push_back({c, kind, 0.0, layer, shape.cases[c].line});
      }
  return out;
}

}  // namespace blt::calibrate
