#pragma once
// Filling simple solids with material points on a regular lattice (spacing s, particle domain s per axis, so
// uGIMP half-width s/2). Scenario files (issue 5) compose these. In axisymmetric runs (D = 2, r = axis 0)
// shapes are solids of revolution about the z axis: a box [0, R] x [z0, z1] is a disc or cylinder, a sphere
// is centred on the axis; each particle's volume and mass are per radian (V = r s^2).

#include <functional>

#include "blt/sim/constitutive.hpp"
#include "blt/sim/particles.hpp"

namespace blt::sim {

template <int D>
struct BodyFill {
  int material = 0;                   // index into the solver's material list
  int body = 0;                       // body id, for contact
  Vec<D> velocity = Vec<D>::Zero();   // m/s
  double spacing = 0;                 // m, lattice spacing
  bool axisymmetric = (D == 2);       // D = 2: volumes per radian (false: plane strain, per unit thickness)
};

// Adds the lattice points of the box [lower, upper] for which `inside(x)` holds; returns how many were added.
template <int D>
std::size_t fillRegion(Particles<D>& particles, const SolidMaterial& material, const BodyFill<D>& fill,
                       const Vec<D>& lower, const Vec<D>& upper, const std::function<bool(const Vec<D>&)>& inside);

template <int D>
std::size_t fillBox(Particles<D>& particles, const SolidMaterial& material, const BodyFill<D>& fill,
                    const Vec<D>& lower, const Vec<D>& upper) {
  return fillRegion<D>(particles, material, fill, lower, upper, [](const Vec<D>&) { return true; });
}

template <int D>
std::size_t fillSphere(Particles<D>& particles, const SolidMaterial& material, const BodyFill<D>& fill,
                       const Vec<D>& centre, double radius) {
  const Vec<D> r = Vec<D>::Constant(radius);
  Vec<D> lower = centre - r;
  if (D == 2 && fill.axisymmetric) lower[0] = 0.0;
  return fillRegion<D>(particles, material, fill, lower, centre + r,
                       [&](const Vec<D>& x) { return (x - centre).squaredNorm() <= radius * radius; });
}

// A cylinder with its axis along the last coordinate (z), base at centre[D-1], height `length`.
template <int D>
std::size_t fillCylinder(Particles<D>& particles, const SolidMaterial& material, const BodyFill<D>& fill,
                         const Vec<D>& baseCentre, double radius, double length) {
  Vec<D> lower = baseCentre, upper = baseCentre;
  for (int a = 0; a < D - 1; ++a) {
    lower[a] -= radius;
    upper[a] += radius;
  }
  if (D == 2 && fill.axisymmetric) lower[0] = 0.0;
  upper[D - 1] += length;
  return fillRegion<D>(particles, material, fill, lower, upper, [&](const Vec<D>& x) {
    double r2 = 0;
    for (int a = 0; a < D - 1; ++a) r2 += (x[a] - baseCentre[a]) * (x[a] - baseCentre[a]);
    return r2 <= radius * radius;
  });
}

}  // namespace blt::sim
