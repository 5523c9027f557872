#include "blt/calibrate/analytic_model.hpp"

#include <cmath>
#include <sstream>

#include "blt/core/error.hpp"

namespace blt::calibrate {

const Effect& findEffect(const Model& model, const std::string& name, const InputLocation& where) {
  std::string known;
  for (const Effect& e : model.effects()) {
    if (e.name == name) return e;
    known += (known.empty() ? "" : ", ") + e.name;
  }
  throw InputError(where, "'" + name + "' is not an effect of " + model.describe(), "one of: " + known);
}

AnalyticModel::AnalyticModel(analytic::ResidualVelocityModel kind, const analytic::ResidualVelocityParameters& base)
    : kind_(kind), base_(base) {
  // Validates the constants once, with the library's own ranges.
  analytic::residualVelocity(base_, base_.ballisticLimit);
  effects_ = {
      {"plug_mass_ratio", "a plug of mass m_pl leaves with the projectile: a -> a / (1 + m_pl/m_p)",
       {"m_pl/m_p", "", "plug_mass_ratio", 0.0, 3.0, 0.0}},
      {"strength_scale", "the target's strength is scaled by s: v_bl -> v_bl sqrt(s)",
       {"s", "", "strength_scale", 0.25, 4.0, 1.0}},
      {"exponent", "the exponent p of the residual-velocity relation differs from the base's",
       {"p", "", "p", 1.0, 5.0, base_.p}},
  };
}

std::string AnalyticModel::describe() const {
  std::ostringstream out;
  out << analytic::modelName(kind_) << " (a = " << base_.a << ", p = " << base_.p
      << ", v_bl = " << base_.ballisticLimit << " m/s)";
  return out.str();
}

void AnalyticModel::check(const MeasuredData& data) const {
  for (const Observation& o : data.observations) {
    if (isHole(o.kind))
      throw InputError(InputLocation::file(data.source, o.line, o.kind == ObservationKind::holeHorizontal ? "hole_h_mm" : "hole_v_mm"),
                       "the analytical model " + describe() + " predicts no hole sizes",
                       "outcomes and residual velocities, or a --scenario for the solver model");
  }
}

analytic::ResidualVelocityParameters AnalyticModel::parametersWith(const EffectSetting& setting) const {
  analytic::ResidualVelocityParameters p = base_;
  if (!setting.effect) return p;
  const std::string& name = setting.effect->name;
  if (name == "plug_mass_ratio")
    p.a = base_.a / (1.0 + setting.value);
  else if (name == "strength_scale")
    p.ballisticLimit = base_.ballisticLimit * std::sqrt(setting.value);
  else if (name == "exponent")
    p.p = setting.value;
  return p;
}

std::vector<Prediction> AnalyticModel::predict(const MeasuredData& data, const std::vector<std::size_t>& cases,
                                               const EffectSetting& setting) {
  const analytic::ResidualVelocityParameters p = parametersWith(setting);
  std::vector<Prediction> out;
  out.reserve(cases.size());
  for (std::size_t i : cases) {
    const double v = data.cases.at(i).velocity;
    Prediction pr;
    pr.residualVelocity = analytic::residualVelocity(p, v);
    pr.perforated = v > p.ballisticLimit;
    // A zero ballistic limit perforates at any speed; a large finite margin keeps the error finite.
    pr.margin = p.ballisticLimit > 0 ? std::log(v / p.ballisticLimit) : 10.0;
    out.push_back(std::move(pr));
  }
  return out;
}

}  // namespace blt::calibrate
