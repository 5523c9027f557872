#pragma once
// The analytical base model: the Recht-Ipson / Lambert-Jonas residual velocity
// v_r = a (v^p - v_bl^p)^(1/p) (blt/analytic/residual_velocity.hpp) with given constants. It predicts outcomes
// (with the margin ln(v / v_bl)) and residual velocities, not hole sizes. Its effects:
//   plug_mass_ratio  m_pl / m_p in [0, 3]: a plug pushed out with the projectile (Recht-Ipson's momentum
//                    balance): a -> a / (1 + m_pl/m_p); the ballistic limit is unchanged.
//   strength_scale   target strength factor in [0.25, 4]: the ballistic limit of a plugging plate goes with the
//                    square root of its flow stress (Chen-Li, REFERENCE.md §4): v_bl -> v_bl sqrt(s).
//   exponent         p in [1, 5] (Lambert-Jonas' free exponent): how the energy is shared near the limit.

#include "blt/analytic/residual_velocity.hpp"
#include "blt/calibrate/model.hpp"

namespace blt::calibrate {

class AnalyticModel : public Model {
 public:
  AnalyticModel(analytic::ResidualVelocityModel kind, const analytic::ResidualVelocityParameters& base);

  std::string describe() const override;
  const std::vector<Effect>& effects() const override { return effects_; }
  void check(const MeasuredData& data) const override;
  std::vector<Prediction> predict(const MeasuredData& data, const std::vector<std::size_t>& cases,
                                  const EffectSetting& setting) override;
  int suggestedGridPoints() const override { return 41; }
  int suggestedRefineSteps() const override { return 40; }

  // The constants with the effect applied.
  analytic::ResidualVelocityParameters parametersWith(const EffectSetting& setting) const;

 private:
  analytic::ResidualVelocityModel kind_;
  analytic::ResidualVelocityParameters base_;
  std::vector<Effect> effects_;
};

}  // namespace blt::calibrate
