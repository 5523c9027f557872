#pragma once
// What the calibrator needs of a model: predictions for measured cases, with or without one extension
// (an "effect") switched on, and the registry of the effects it can add. The analytical residual-velocity
// model (analytic_model.hpp) and the MPM solver over scenario settings (solver_model.hpp) implement it; a
// campaign database can stand behind predict() without the calibrator knowing.

#include <optional>
#include <string>
#include <vector>

#include "blt/calibrate/measured.hpp"

namespace blt::calibrate {

// The one parameter of an effect. Values are SI inside; `unit` is how reports print them ("mm", "deg", "" for a
// ratio), `jsonKey` the key with its SI unit ("gap_m", "plug_mass_ratio").
struct EffectParameter {
  std::string name;
  std::string unit;
  std::string jsonKey;
  double lower = 0, upper = 0;  // SI, the range searched
  double neutral = 0;           // SI, the value at which the effect is off (the base model)
};

// A model extension the base lacks. `description` says how it changes the base model.
struct Effect {
  std::string name;  // what --effects names
  std::string description;
  EffectParameter parameter;
};

// The effect switched on at a value; no effect: the base model.
struct EffectSetting {
  const Effect* effect = nullptr;
  double value = 0;  // SI
};

// One case predicted. What the model cannot predict stays empty.
struct Prediction {
  bool perforated = false;
  // The share of runs that perforate, when the model averages several (the solver over grid alignments);
  // the outcome's predicted value is then this share instead of 0 or 1.
  std::optional<double> perforatedFraction;
  // ln of the case's distance from the model's ballistic limit, positive when it perforates (ln(V/V_bl) or
  // ln(d/d_c)); empty when the model only gives the outcome.
  std::optional<double> margin;
  std::optional<double> residualVelocity;  // m/s, 0 when stopped
  // Hole sizes (m) of the layer named by an observation; the model maps the name (layer name or number).
  std::vector<std::pair<std::string, std::pair<double, double>>> holes;  // layer as in the data -> (D_h, D_v)
};

class Model {
 public:
  virtual ~Model() = default;
  // "recht-ipson (a = 1, p = 2, v_bl = 133.8 m/s)", "scenario data/scenarios/x.toml".
  virtual std::string describe() const = 0;
  // The registry: every effect this model can add to its base.
  virtual const std::vector<Effect>& effects() const = 0;
  // Throws InputError naming the data file when the data hold something the model cannot predict (hole sizes
  // for an analytical model, a layer the scenario lacks, no diameters for the solver).
  virtual void check(const MeasuredData& data) const = 0;
  // Predictions for data.cases[i] for each i in `cases`, in that order, under `setting`.
  virtual std::vector<Prediction> predict(const MeasuredData& data, const std::vector<std::size_t>& cases,
                                          const EffectSetting& setting) = 0;
  // How many evaluations a 1-D fit may spend per effect: few for a costly model.
  virtual int suggestedGridPoints() const = 0;
  virtual int suggestedRefineSteps() const = 0;
};

// Looks an effect up by name; throws InputError naming `where` and listing the model's effects.
const Effect& findEffect(const Model& model, const std::string& name, const InputLocation& where);

}  // namespace blt::calibrate
