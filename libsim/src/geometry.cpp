#include "blt/sim/geometry.hpp"

#include <cmath>
#include <stdexcept>

namespace blt::sim {

template <int D>
std::size_t fillRegion(Particles<D>& particles, const SolidMaterial& material, const BodyFill<D>& fill,
                       const Vec<D>& lower, const Vec<D>& upper, const std::function<bool(const Vec<D>&)>& inside) {
  const double s = fill.spacing;
  if (!(s > 0)) throw std::invalid_argument("particle spacing must be positive");
  Eigen::Array<long, D, 1> count;
  for (int a = 0; a < D; ++a) count[a] = std::max(0L, std::lround(std::floor((upper[a] - lower[a]) / s + 1e-9)));
  // Lattices that do not divide the box exactly are centred in it.
  Vec<D> start;
  for (int a = 0; a < D; ++a) start[a] = lower[a] + 0.5 * ((upper[a] - lower[a]) - (count[a] - 1) * s);
  const Vec<D> half = Vec<D>::Constant(0.5 * s);
  const double cellVolume = std::pow(s, D);
  std::size_t added = 0;
  Eigen::Array<long, D, 1> i = Eigen::Array<long, D, 1>::Zero();
  long total = 1;
  for (int a = 0; a < D; ++a) total *= count[a];
  particles.reserve(particles.size() + static_cast<std::size_t>(total));
  for (long k = 0; k < total; ++k) {
    long rest = k;
    Vec<D> x;
    for (int a = 0; a < D; ++a) {
      i[a] = rest % count[a];
      rest /= count[a];
      x[a] = start[a] + i[a] * s;
    }
    if (!inside(x)) continue;
    const double volume = (D == 2 && fill.axisymmetric) ? cellVolume * x[0] : cellVolume;
    particles.add(x, fill.velocity, volume, material.density, half, fill.material, fill.body,
                  material.roomTemperature);
    ++added;
  }
  return added;
}

template std::size_t fillRegion<2>(Particles<2>&, const SolidMaterial&, const BodyFill<2>&, const Vec<2>&,
                                   const Vec<2>&, const std::function<bool(const Vec<2>&)>&);
template std::size_t fillRegion<3>(Particles<3>&, const SolidMaterial&, const BodyFill<3>&, const Vec<3>&,
                                   const Vec<3>&, const std::function<bool(const Vec<3>&)>&);

}  // namespace blt::sim
