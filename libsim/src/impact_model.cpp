#include "blt/sim/impact_model.hpp"

#include <cmath>
#include <map>

#include "blt/core/units.hpp"
#include "blt/sim/geometry.hpp"

namespace blt::sim {

namespace {

// Radius of the projectile's cross-section at distance u behind its nose tip (a cylinder; 0 outside it).
double profileRadius(const ProjectileSpec& p, double u) {
  const double r = 0.5 * p.diameter;
  if (u < 0 || u > p.length) return 0.0;
  if (u >= p.noseLength) return r;
  switch (p.nose) {
    case NoseShape::flat: return r;
    case NoseShape::hemispherical: return std::sqrt(std::max(0.0, r * r - (r - u) * (r - u)));
    case NoseShape::conical: return r * u / p.noseLength;
    case NoseShape::ogival: {
      const double R = p.noseCaliberRadius * p.diameter;
      const double dz = p.noseLength - u;
      return std::max(0.0, std::sqrt(R * R - dz * dz) - (R - r));
    }
  }
  return r;
}

// Volume of the whole solid, m^3 (Simpson's rule over the nose profile; the profiles are smooth).
double projectileVolume(const ProjectileSpec& p) {
  const double r = 0.5 * p.diameter;
  if (p.shape == ProjectileShape::sphere) return 4.0 / 3.0 * M_PI * r * r * r;
  const int n = 2000;
  const double du = p.noseLength / n;
  double nose = 0;
  for (int i = 0; i <= n; ++i) {
    const double rad = profileRadius(p, i * du);
    nose += (i == 0 || i == n ? 1 : (i % 2 ? 4 : 2)) * rad * rad;
  }
  nose *= M_PI * du / 3.0;
  return nose + M_PI * r * r * (p.length - p.noseLength);
}

// Scales the volumes and masses of particles [begin, end) so that they add up to `volume`.
template <int D>
void scaleToVolume(Particles<D>& P, std::size_t begin, std::size_t end, double volume) {
  double lattice = 0;
  for (std::size_t i = begin; i < end; ++i) lattice += P.initialVolume[i];
  if (!(lattice > 0)) return;
  const double f = volume / lattice;
  for (std::size_t i = begin; i < end; ++i) {
    P.initialVolume[i] *= f;
    P.volume[i] *= f;
    P.mass[i] *= f;
  }
}

}  // namespace

template <int D>
Vec<D> ImpactModel<D>::shotLineAt(double z) const {
  const double t = (z - projectileStart[D - 1]) / direction[D - 1];
  Vec<D> x = projectileStart + t * direction;
  if constexpr (D == 2) x[0] = 0.0;
  return x;
}

template <int D>
ImpactModel<D> buildImpactModel(const ImpactScenario& sc, int threads) {
  ImpactModel<D> m;
  const ProjectileSpec& pj = sc.projectile;
  const double h = sc.cellSize();
  const double theta = pj.angle;
  const double tilt = pj.angle + pj.yaw;  // of the projectile's axis from the target normal
  const bool axisymmetric = D == 2;
  Vec<D> axis;  // the projectile's axis, nose forward
  if constexpr (D == 3) {
    m.direction = Vec<D>(std::sin(theta), 0.0, -std::cos(theta));
    axis = Vec<D>(std::sin(tilt), 0.0, -std::cos(tilt));
    m.mirrorY = true;
    m.mirrorX = std::fabs(theta) < 1e-12 && std::fabs(pj.yaw) < 1e-12;
  } else {
    if (std::fabs(theta) > 1e-12)
      throw InputError(InputLocation::file(sc.path, std::nullopt, "projectile.angle"),
                       "an axisymmetric model needs a normal impact", "angle = \"0 deg\", or run.mode = \"3d\"");
    if (std::fabs(pj.yaw) > 1e-12)
      throw InputError(InputLocation::file(sc.path, std::nullopt, "projectile.yaw"),
                       "an axisymmetric model needs a projectile without yaw", "yaw = \"0 deg\", or run.mode = \"3d\"");
    m.direction = Vec<D>(0.0, -1.0);
    axis = m.direction;
  }
  m.modelledFraction = axisymmetric ? 1.0 / (2.0 * M_PI) : (m.mirrorX ? 0.25 : 0.5);
  m.projectileDiameter = pj.diameter;
  m.projectileSpacing = sc.projectileSpacing();
  if (sc.target.layers.size() + 1 > 16)
    throw InputError(InputLocation::file(sc.path, std::nullopt, "target.layer"), "too many layers for the contact",
                     "at most 15 layers");

  // Materials, each resolved once.
  std::vector<SolidMaterial> materials;
  std::map<std::string, int> materialIndex;
  const auto material = [&](const std::string& name, const std::string& key) {
    auto it = materialIndex.find(name);
    if (it != materialIndex.end()) return it->second;
    materials.push_back(makeSolidMaterial(resolveMaterial(name, InputLocation::file(sc.path, std::nullopt, key))));
    return materialIndex[name] = static_cast<int>(materials.size()) - 1;
  };
  const int projectileMaterial = material(pj.material, "projectile.material");
  std::vector<int> layerMaterial;
  for (std::size_t i = 0; i < sc.target.layers.size(); ++i)
    layerMaterial.push_back(material(sc.target.layers[i].material, "target.layer." + std::to_string(i + 1) + ".material"));

  // Grid: the target's lateral extent, the target's depth with room behind it, the projectile in front.
  const double half = 0.5 * sc.target.lateralSize;
  const double depth = sc.target.totalDepth();
  const double radius = 0.5 * pj.diameter;
  const double length = pj.shape == ProjectileShape::sphere ? pj.diameter : pj.length;
  const double projectileHeight = pj.shape == ProjectileShape::sphere
                                      ? pj.diameter
                                      : length * std::cos(tilt) + pj.diameter * std::sin(std::fabs(tilt));
  const double behind = std::max(20.0 * h, 2.0 * pj.diameter) + sc.resolution.gridOffset * h;
  GridSpec<D> grid;
  grid.cellSize = h;
  const BoundaryKind edge = sc.target.edge;
  if constexpr (D == 3) {
    grid.lower = Vec<D>(m.mirrorX ? 0.0 : -half, 0.0, -depth - behind);
    grid.upper = Vec<D>(half, half, h + projectileHeight + 2.0 * h);
    grid.boundary = {m.mirrorX ? BoundaryKind::symmetry : edge, edge, BoundaryKind::symmetry, edge,
                     BoundaryKind::free, BoundaryKind::free};
  } else {
    grid.lower = Vec<D>(0.0, -depth - behind);
    grid.upper = Vec<D>(half, h + projectileHeight + 2.0 * h);
    grid.boundary = {BoundaryKind::symmetry, edge, BoundaryKind::free, BoundaryKind::free};
  }
  SolverOptions options = sc.solver;
  options.axisymmetric = true;
  options.threads = threads;
  m.solver = std::make_unique<Solver<D>>(grid, options, materials);
  Particles<D>& P = m.solver->particles();
  const auto& mats = m.solver->materials();

  // Layers, front to rear.
  double front = 0;
  for (std::size_t i = 0; i < sc.target.layers.size(); ++i) {
    const LayerSpec& l = sc.target.layers[i];
    LayerBody lb{l.name, static_cast<int>(i) + 1, front - l.gapBefore, front - l.gapBefore - l.thickness,
                 sc.layerSpacing(i)};
    front = lb.rear;
    BodyFill<D> fill;
    fill.material = layerMaterial[i];
    fill.body = lb.body;
    fill.spacing = lb.spacing;
    Vec<D> lower = grid.lower, upper = grid.upper;
    lower[D - 1] = lb.rear;
    upper[D - 1] = lb.front;
    const std::size_t begin = P.size();
    fillBox<D>(P, mats[fill.material], fill, lower, upper);
    double exact = l.thickness;
    for (int a = 0; a < D - 1; ++a) exact *= upper[a] - lower[a];
    if (axisymmetric) exact = 0.5 * half * half * l.thickness;
    scaleToVolume<D>(P, begin, P.size(), exact);
    m.layers.push_back(lb);
  }

  // Projectile: filled around the origin (sphere: its centre; cylinder: its nose tip, body behind along -axis)
  // on a lattice symmetric about the symmetry planes, then moved to one cell in front of the target.
  BodyFill<D> fill;
  fill.material = projectileMaterial;
  fill.body = 0;
  fill.spacing = m.projectileSpacing;
  fill.velocity = pj.velocity * m.direction;
  const double s = m.projectileSpacing;
  const double reach = s * std::ceil((pj.shape == ProjectileShape::sphere ? radius : length + radius) / s);
  Vec<D> lower = Vec<D>::Constant(-reach), upper = Vec<D>::Constant(reach);
  if (axisymmetric || m.mirrorX) lower[0] = 0.0;
  if (D == 3) lower[1] = 0.0;
  const auto inside = [&](const Vec<D>& x) {
    if (pj.shape == ProjectileShape::sphere) return x.squaredNorm() <= radius * radius;
    const double u = -x.dot(axis);  // distance behind the tip along the axis
    const double rho = (x + u * axis).norm();
    return rho <= profileRadius(pj, u);
  };
  const std::size_t begin = P.size();
  fillRegion<D>(P, mats[fill.material], fill, lower, upper, inside);
  if (P.size() == begin)
    throw InputError(InputLocation::file(sc.path, std::nullopt, "projectile.diameter"),
                     "the projectile holds no particle at this spacing", "a diameter of several particle spacings");
  scaleToVolume<D>(P, begin, P.size(), projectileVolume(pj) * m.modelledFraction);
  double lowest = 1e300, mass = 0;
  Vec<D> centre = Vec<D>::Zero();
  for (std::size_t i = begin; i < P.size(); ++i) {
    lowest = std::min(lowest, P.position[i][D - 1] - 0.5 * s);
    mass += P.mass[i];
    centre += P.mass[i] * P.position[i];
  }
  centre /= mass;
  Vec<D> shift = Vec<D>::Zero();
  shift[D - 1] = h - lowest;
  if constexpr (D == 3) {
    // The shot line through the centre of mass meets the front face at x = aim_offset (0: the target's centre);
    // across the symmetry plane y = 0.
    const double zc = centre[2] + shift[2];
    if (!m.mirrorX) shift[0] = pj.aimOffset - (centre[0] + zc * std::tan(theta));
  }
  for (std::size_t i = begin; i < P.size(); ++i) {
    P.position[i] += shift;
    // An oblique rod reaches far back across the target; the grid spans the target's lateral extent only.
    for (int a = 0; a < D - 1; ++a)
      if (P.position[i][a] < grid.lower[a] || P.position[i][a] > grid.upper[a])
        throw InputError(InputLocation::file(sc.path, std::nullopt, "target.lateral_size"),
                         "the projectile reaches beyond the model's lateral extent at this angle",
                         "a lateral size of at least twice " +
                             units::format(std::fabs(P.position[i][a]) + s, "mm", 4));
  }
  m.projectileStart = centre + shift;
  if constexpr (D == 3) m.projectileStart[1] = 0.0;
  if (m.mirrorX || axisymmetric) m.projectileStart[0] = 0.0;
  m.projectileMass = mass;
  m.solver->initialise();
  return m;
}

template struct ImpactModel<2>;
template struct ImpactModel<3>;
template ImpactModel<2> buildImpactModel<2>(const ImpactScenario&, int);
template ImpactModel<3> buildImpactModel<3>(const ImpactScenario&, int);

}  // namespace blt::sim
