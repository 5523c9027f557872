#include "blt/sim/particles.hpp"

namespace blt::sim {

template <int D>
void Particles<D>::reserve(std::size_t n) {
  forEachArray([n](auto& v) { v.reserve(n); });
}

template <int D>
std::size_t Particles<D>::add(const Vec<D>& x, const Vec<D>& v, double particleVolume, double density,
                              const Vec<D>& half, int materialId, int bodyId, double roomTemperature) {
  position.push_back(x);
  velocity.push_back(v);
  halfSize.push_back(half);
  mass.push_back(density * particleVolume);
  initialVolume.push_back(particleVolume);
  volume.push_back(particleVolume);
  deformationGradient.push_back(Mat3::Identity());
  stress.push_back(Mat3::Zero());
  viscousPressure.push_back(0.0);
  specificEnergy.push_back(0.0);
  temperature.push_back(roomTemperature);
  plasticStrain.push_back(0.0);
  damage.push_back(0.0);
  soundSpeed.push_back(0.0);
  plasticWork.push_back(0.0);
  viscousWork.push_back(0.0);
  failed.push_back(0);
  active.push_back(1);
  material.push_back(materialId);
  body.push_back(bodyId);
  return position.size() - 1;
}

template <int D>
std::size_t Particles<D>::bytes() const {
  const std::size_t n = position.capacity();
  return n * (3 * sizeof(Vec<D>) + 2 * sizeof(Mat3) + 10 * sizeof(double) + 2 * sizeof(std::uint8_t) +
              2 * sizeof(int));
}

namespace {
template <class T>
void applyOrder(std::vector<T>& v, const std::vector<int>& order) {
  std::vector<T> out(v.size());
  for (std::size_t i = 0; i < order.size(); ++i) out[i] = v[static_cast<std::size_t>(order[i])];
  v.swap(out);
}
}  // namespace

template <int D>
void Particles<D>::permute(const std::vector<int>& order) {
  forEachArray([&](auto& v) { applyOrder(v, order); });
}

template struct Particles<2>;
template struct Particles<3>;

}  // namespace blt::sim
