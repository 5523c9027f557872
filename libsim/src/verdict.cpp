#include "blt/sim/verdict.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <tuple>

namespace blt::sim {

namespace {

using Cell = long;
constexpr double kInfinity = std::numeric_limits<double>::infinity();
// A particle's domain, stretched by its deformation, covers at most this many voxels on each side of its
// centre: enough to bridge a stretched ligament, not enough for one smeared point to close a hole.
constexpr double kMaxFootprintVoxels = 3.0;
// Voxel grids larger than this are coarsened (a safeguard; a seed-resolution 3D layer needs about 2e6).
constexpr double kMaxVoxels = 4e7;

// Half-extents of particle p's deformed domain along each axis.
template <int D>
Vec<D> footprint(const Particles<D>& P, std::size_t p) {
  const Mat3& F = P.deformationGradient[p];
  const Mat3 b = F * F.transpose();
  Vec<D> h;
  for (int a = 0; a < D; ++a) h[a] = P.halfSize[p][a] * std::sqrt(b(a, a));
  return h;
}

// Occupancy of a set of particles on a voxel grid, its connected components (through voxel faces) and their
// masses (each particle counts in the component of the voxel that holds its centre). The grid starts at the
// model's symmetry planes (`floor`; -infinity on an axis without one): a domain stretched across a plane is cut
// there. Left free, the first voxel row would straddle the plane, mostly empty, and read as an opening along it.
template <int D>
class Voxels {
 public:
  Voxels(const Particles<D>& P, const std::vector<std::size_t>& members, double pitch, const Vec<D>& floor)
      : pitch_(pitch) {
    if (members.empty()) return;
    Vec<D> lo = Vec<D>::Constant(kInfinity), hi = Vec<D>::Constant(-kInfinity);
    for (std::size_t p : members) {
      const Vec<D> h = footprint(P, p).cwiseMin(Vec<D>::Constant(kMaxFootprintVoxels * pitch_));
      lo = lo.cwiseMin(P.position[p] - h);
      hi = hi.cwiseMax(P.position[p] + h);
    }
    lo = lo.cwiseMax(floor);
    if (!(hi - lo).allFinite() || (hi - lo).minCoeff() < 0) return;  // a non-finite particle: the run is unstable
    double total = 1;
    for (int a = 0; a < D; ++a) total *= (hi[a] - lo[a]) / pitch_ + 1;
    if (total > kMaxVoxels) pitch_ *= std::pow(total / kMaxVoxels, 1.0 / D);
    origin_ = lo;
    count_ = 1;
    for (int a = 0; a < D; ++a) {
      n_[a] = static_cast<long>(std::floor((hi[a] - lo[a]) / pitch_)) + 1;
      stride_[a] = count_;
      count_ *= n_[a];
    }
    label_.assign(static_cast<std::size_t>(count_), kEmpty);
    for (std::size_t p : members) {
      const Vec<D> h = 0.999 * footprint(P, p).cwiseMin(Vec<D>::Constant(kMaxFootprintVoxels * pitch_));
      Eigen::Array<long, D, 1> a0, a1;
      for (int a = 0; a < D; ++a) {
        a0[a] = clampIndex(a, (P.position[p][a] - h[a] - origin_[a]) / pitch_);
        a1[a] = clampIndex(a, (P.position[p][a] + h[a] - origin_[a]) / pitch_);
      }
      if constexpr (D == 3) {
        for (long k = a0[2]; k <= a1[2]; ++k)
          for (long j = a0[1]; j <= a1[1]; ++j)
            for (long i = a0[0]; i <= a1[0]; ++i) label_[i + j * stride_[1] + k * stride_[2]] = kOccupied;
      } else {
        for (long j = a0[1]; j <= a1[1]; ++j)
          for (long i = a0[0]; i <= a1[0]; ++i) label_[i + j * stride_[1]] = kOccupied;
      }
    }
    labelComponents();
    for (std::size_t p : members) {
      const int c = label_[cellOf(P.position[p])];
      if (c >= 0) mass_[c] += P.mass[p];
    }
  }

  bool empty() const { return mass_.empty(); }
  // The component of largest mass, or -1.
  int largest() const {
    int best = -1;
    for (std::size_t c = 0; c < mass_.size(); ++c)
      if (best < 0 || mass_[c] > mass_[best]) best = static_cast<int>(c);
    return best;
  }
  int componentAt(const Vec<D>& x) const { return label_.empty() ? -1 : label_[cellOf(x)]; }
  double pitch() const { return pitch_; }
  const Vec<D>& origin() const { return origin_; }
  const Eigen::Array<long, D, 1>& counts() const { return n_; }
  // Calls f(i, j..., label) over voxels; i the in-plane indices packed as a column number.
  long columns() const { return count_ > 0 ? count_ / n_[D - 1] : 0; }
  template <class F>
  void forEachVoxel(F&& f) const {
    const long cols = columns();
    for (long v = 0; v < count_; ++v) f(v % cols, v / cols, label_[v]);
  }

 private:
  static constexpr int kEmpty = -1, kOccupied = -2;

  long clampIndex(int a, double u) const {
    return std::clamp(static_cast<long>(std::floor(u)), 0L, n_[a] - 1);
  }
  Cell cellOf(const Vec<D>& x) const {
    Cell c = 0;
    for (int a = 0; a < D; ++a) c += clampIndex(a, (x[a] - origin_[a]) / pitch_) * stride_[a];
    return c;
  }
  void labelComponents() {
    std::vector<Cell> queue;
    int next = 0;
    for (Cell start = 0; start < count_; ++start) {
      if (label_[start] != kOccupied) continue;
      label_[start] = next;
      queue.assign(1, start);
      while (!queue.empty()) {
        const Cell c = queue.back();
        queue.pop_back();
        long rest = c;
        for (int a = 0; a < D; ++a) {
          const long i = rest % n_[a];
          rest /= n_[a];
          if (i > 0 && label_[c - stride_[a]] == kOccupied) label_[c - stride_[a]] = next, queue.push_back(c - stride_[a]);
          if (i + 1 < n_[a] && label_[c + stride_[a]] == kOccupied)
            label_[c + stride_[a]] = next, queue.push_back(c + stride_[a]);
        }
      }
      ++next;
    }
    mass_.assign(static_cast<std::size_t>(next), 0.0);
  }

  double pitch_;
  Vec<D> origin_ = Vec<D>::Zero();
  Eigen::Array<long, D, 1> n_ = Eigen::Array<long, D, 1>::Zero(), stride_ = Eigen::Array<long, D, 1>::Zero();
  Cell count_ = 0;
  std::vector<int> label_;
  std::vector<double> mass_;
};

// Columns (voxel rows along z) that component `comp` (any component when comp < 0) occupies, and its deepest
// (lowest z) point in each.
template <int D>
std::vector<double> rearSurface(const Voxels<D>& vox, int comp) {
  std::vector<double> surface(static_cast<std::size_t>(vox.columns()), kInfinity);
  vox.forEachVoxel([&](long col, long k, int label) {
    if (comp < 0 ? label >= 0 : label == comp)
      surface[col] = std::min(surface[col], vox.origin()[D - 1] + k * vox.pitch());
  });
  return surface;
}

// The opening of component `comp` around the shot line, projected on the layer plane (see verdict.hpp).
template <int D>
LayerHole holeAround(const Voxels<D>& vox, int comp, const ImpactModel<D>& model, double zPlane) {
  LayerHole hole;
  if (comp < 0) return hole;
  const std::vector<double> surface = rearSurface(vox, comp);
  const double p = vox.pitch();
  const Vec<D>& o = vox.origin();
  if constexpr (D == 2) {
    // Axisymmetric: the hole reaches from the axis to the material nearest to it.
    double r = kInfinity;
    for (long i = 0; i < vox.columns(); ++i)
      if (surface[i] < kInfinity) r = std::min(r, o[0] + i * p);
    if (r < kInfinity && r > 0.5 * p) hole.horizontal = hole.vertical = 2.0 * r;
    return hole;
  } else {
    const long nx = vox.counts()[0], ny = vox.counts()[1];
    const auto open = [&](long i, long j) { return surface[i + j * nx] == kInfinity; };
    const Vec<D> shot = model.shotLineAt(zPlane);
    const long si = static_cast<long>(std::floor((shot[0] - o[0]) / p));
    const long sj = static_cast<long>(std::floor((shot[1] - o[1]) / p));
    // The nearest open column within the projectile's radius of the shot line.
    const long reach = std::max(1L, static_cast<long>(std::ceil(0.5 * model.projectileDiameter / p)));
    long bi = -1, bj = -1;
    double best = kInfinity;
    for (long j = std::max(0L, sj - reach); j <= std::min(ny - 1, sj + reach); ++j)
      for (long i = std::max(0L, si - reach); i <= std::min(nx - 1, si + reach); ++i) {
        const double d2 = double(i - si) * (i - si) + double(j - sj) * (j - sj);
        if (open(i, j) && d2 <= double(reach) * reach && d2 < best) best = d2, bi = i, bj = j;
      }
    if (bi < 0) return hole;
    std::vector<char> seen(surface.size(), 0);
    std::vector<long> queue{bi + bj * nx};
    seen[queue[0]] = 1;
    long imin = bi, imax = bi, jmin = bj, jmax = bj;
    while (!queue.empty()) {
      const long c = queue.back();
      queue.pop_back();
      const long i = c % nx, j = c / nx;
      imin = std::min(imin, i), imax = std::max(imax, i), jmin = std::min(jmin, j), jmax = std::max(jmax, j);
      const long next[4][2] = {{i - 1, j}, {i + 1, j}, {i, j - 1}, {i, j + 1}};
      for (const auto& q : next) {
        if (q[0] < 0 || q[0] >= nx || q[1] < 0 || q[1] >= ny) continue;
        const long k = q[0] + q[1] * nx;
        if (!seen[k] && open(q[0], q[1])) seen[k] = 1, queue.push_back(k);
      }
    }
    // Extents; across a symmetry plane (x = 0 or y = 0, the grid's lower faces) the hole is mirrored.
    const auto extent = [&](long lo, long hi, int axis, bool mirrored) {
      const double a = o[axis] + lo * p, b = o[axis] + (hi + 1) * p;
      return mirrored && a <= 0.5 * p ? 2.0 * b : b - a;
    };
    hole.horizontal = extent(imin, imax, 0, model.mirrorX);
    hole.vertical = extent(jmin, jmax, 1, model.mirrorY);
    return hole;
  }
}

template <int D>
std::vector<std::size_t> bodyParticles(const Particles<D>& P, int body, bool withFailed) {
  std::vector<std::size_t> list;
  for (std::size_t p = 0; p < P.size(); ++p)
    if (P.active[p] && P.body[p] == body && (withFailed || !P.failed[p])) list.push_back(p);
  return list;
}

// Where the voxel grids start: the symmetry planes (the axis r = 0 in axisymmetric runs; y = 0, and x = 0 in a
// quarter model, in 3D).
template <int D>
Vec<D> symmetryFloor(const ImpactModel<D>& model) {
  Vec<D> floor = Vec<D>::Constant(-kInfinity);
  if constexpr (D == 2) floor[0] = 0.0;
  if constexpr (D == 3) {
    if (model.mirrorY) floor[1] = 0.0;
    if (model.mirrorX) floor[0] = 0.0;
  }
  return floor;
}

std::string percent(double f) {
  std::ostringstream s;
  s.precision(3);
  s << 100.0 * f << " %";
  return s.str();
}

}  // namespace

template <int D>
KineticReference kineticReference(const ImpactModel<D>& model) {
  const Particles<D>& P = model.solver->particles();
  KineticReference k;
  k.total = model.solver->energies().kinetic;
  for (std::size_t p = 0; p < P.size(); ++p) {
    const double vz = P.velocity[p][D - 1];
    if (P.active[p] && vz < 0) k.rearward += 0.5 * P.mass[p] * vz * vz;
  }
  return k;
}

template <int D>
PerforationVerdict assessPerforation(const ImpactModel<D>& model, const VerdictOptions& options,
                                     const KineticReference& initial, bool measureHoles) {
  const Solver<D>& solver = *model.solver;
  const Particles<D>& P = solver.particles();
  const double h = solver.grid().cellSize;
  const LayerBody& wallLayer = model.layers.back();
  PerforationVerdict v;

  // The rear wall: its largest connected piece, failed points included. Its rear surface per column is that of
  // its intact points: a strand of failed wall material drawn out behind the plate holds nothing back, and taken
  // as the surface it hid the projectile behind it (a 1 mm sphere through 1 mm of 5A06 at 3 km/s read as stopped).
  const std::vector<std::size_t> wallMembers = bodyParticles(P, wallLayer.body, true);
  const Vec<D> floor = symmetryFloor(model);
  const Voxels<D> wall(P, wallMembers, wallLayer.spacing, floor);
  const int wallPiece = wall.largest();
  std::vector<char> inWall(P.size(), 0);
  std::vector<std::size_t> intactWall;
  for (std::size_t p : wallMembers) {
    inWall[p] = wall.componentAt(P.position[p]) == wallPiece;
    if (inWall[p] && !P.failed[p]) intactWall.push_back(p);
  }
  const Voxels<D> intactVoxels(P, intactWall, wallLayer.spacing, floor);
  const std::vector<double> surface = intactWall.empty() ? std::vector<double>{} : rearSurface(intactVoxels, -1);

  // Material behind it: separated, moving rearward, or gone out through the grid's rear face.
  const double gridFloor = solver.grid().lower[D - 1] + h;
  const double gap = options.separationCells * h;
  double massBehind = 0, rearwardKinetic = 0;
  std::vector<std::size_t> behind;
  for (std::size_t p = 0; p < P.size(); ++p) {
    const Vec<D>& x = P.position[p];
    if (!P.active[p]) {
      if (x[D - 1] < gridFloor) massBehind += P.mass[p];
      continue;
    }
    const double vz = P.velocity[p][D - 1];
    if (vz >= 0) continue;
    const double rearward = 0.5 * P.mass[p] * vz * vz;
    if (inWall[p]) {
      rearwardKinetic += rearward;
      continue;
    }
    // Behind the wall's rear surface where the wall is; behind its original rear face through a hole.
    double local = wallLayer.rear;
    if (!surface.empty()) {
      long col = 0, stride = 1;
      bool within = true;
      for (int a = 0; a < D - 1; ++a) {
        const long i = static_cast<long>(std::floor((x[a] - intactVoxels.origin()[a]) / intactVoxels.pitch()));
        within &= i >= 0 && i < intactVoxels.counts()[a];
        col += i * stride;
        stride *= intactVoxels.counts()[a];
      }
      if (within && surface[col] < kInfinity) local = surface[col];
    }
    if (x[D - 1] + footprint(P, p)[D - 1] < local - gap) {
      massBehind += P.mass[p];
      behind.push_back(p);
    } else {
      rearwardKinetic += rearward;
    }
  }
  v.massBehindFraction = model.projectileMass > 0 ? massBehind / model.projectileMass : 0.0;
  v.massBehind = massBehind / model.modelledFraction;

  const LayerHole opening = holeAround(wall, wallPiece, model, 0.5 * (wallLayer.front + wallLayer.rear));
  v.rearOpening = opening.horizontal > 0 || opening.vertical > 0;
  v.kineticFraction = initial.total > 0 ? solver.energies().kinetic / initial.total : 0.0;
  v.rearwardKineticFraction = initial.rearward > 0 ? rearwardKinetic / initial.rearward : 0.0;

  if (v.massBehindFraction >= options.debrisMassFraction) {
    v.perforated = v.settled = true;
    v.reason = "material behind the rear wall: " + percent(v.massBehindFraction) + " of the projectile's mass";
  } else if (v.rearOpening) {
    v.perforated = true;
    v.reason = "through-thickness opening in the rear wall";
  } else {
    v.settled = v.rearwardKineticFraction < options.settledKineticFraction;
    v.reason = v.settled ? "stopped: rearward kinetic energy down to " + percent(v.rearwardKineticFraction) +
                               " of the initial (all kinetic energy: " + percent(v.kineticFraction) + ")"
                         : "rear wall intact so far";
  }

  // Residual velocity, once perforated: of the projectile when it is still mostly one piece (ordnance; a long
  // rod is still in the hole when the plug has left), else of the largest fragment behind the wall (debris).
  // Velocity components across symmetry planes cancel with the mirrored half and are dropped. A piece moving
  // back out of the target (v_z >= 0) has come through nowhere: none. Seed 003's T4 at 161.875 m/s opened its
  // wall (a plug out) and threw the projectile back at 22.9 m/s, which was reported as its residual velocity.
  // (mass, speed, moving rearward) of a piece of mass m and momentum `momentum`.
  const auto pieceOf = [&](double m, const Vec<D>& momentum) {
    Vec<D> u = m > 0 ? Vec<D>(momentum / m) : Vec<D>::Zero();
    if constexpr (D == 2) u[0] = 0.0;
    if constexpr (D == 3) {
      u[1] = 0.0;
      if (model.mirrorX) u[0] = 0.0;
    }
    return std::make_tuple(m, u.norm(), u[D - 1] < 0);
  };
  const auto largestPiece = [&](const std::vector<std::size_t>& members) {
    const Voxels<D> vox(P, members, model.projectileSpacing, floor);
    const int piece = vox.largest();
    double m = 0;
    Vec<D> momentum = Vec<D>::Zero();
    for (std::size_t p : members)
      if (vox.componentAt(P.position[p]) == piece) m += P.mass[p], momentum += P.mass[p] * P.velocity[p];
    return pieceOf(m, momentum);
  };
  if (v.perforated) {
    // Points that leave the grid are frozen as they left it. Where most of the projectile has gone out through the
    // rear face, its velocity is theirs: seed 003's T4 at 190 m/s sent the whole projectile out at 74.5 m/s
    // (the grid ends 25 mm behind the plate) and gave a plug's 14.0 m/s instead.
    double goneMass = 0;
    Vec<D> goneMomentum = Vec<D>::Zero();
    for (std::size_t p = 0; p < P.size(); ++p)
      if (!P.active[p] && P.body[p] == 0 && P.position[p][D - 1] < gridFloor)
        goneMass += P.mass[p], goneMomentum += P.mass[p] * P.velocity[p];
    auto piece = largestPiece(bodyParticles(P, 0, true));
    bool ofProjectile = true;
    if (std::get<0>(piece) < 0.5 * model.projectileMass) {
      if (goneMass >= 0.5 * model.projectileMass) {
        piece = pieceOf(goneMass, goneMomentum);
      } else if (!behind.empty()) {
        piece = largestPiece(behind);
        ofProjectile = false;
      }
    }
    if (std::get<2>(piece)) {
      v.residualVelocity = std::get<1>(piece);
      v.residualFragmentMass = std::get<0>(piece) / model.modelledFraction;
      v.residualFrom = ofProjectile ? "projectile" : "largest fragment";
    }
  }

  if (measureHoles)
    for (const LayerBody& layer : model.layers) {
      const std::vector<std::size_t> intact = bodyParticles(P, layer.body, false);
      const Voxels<D> vox(P, intact, layer.spacing, floor);
      LayerHole hole = holeAround(vox, vox.largest(), model, 0.5 * (layer.front + layer.rear));
      const Voxels<D> all(P, bodyParticles(P, layer.body, true), layer.spacing, floor);
      const LayerHole bare = holeAround(all, all.largest(), model, 0.5 * (layer.front + layer.rear));
      hole.openingHorizontal = bare.horizontal;
      hole.openingVertical = bare.vertical;
      hole.name = layer.name;
      v.holes.push_back(hole);
    }
  return v;
}

template KineticReference kineticReference<2>(const ImpactModel<2>&);
template KineticReference kineticReference<3>(const ImpactModel<3>&);
template PerforationVerdict assessPerforation<2>(const ImpactModel<2>&, const VerdictOptions&, const KineticReference&,
                                                 bool);
template PerforationVerdict assessPerforation<3>(const ImpactModel<3>&, const VerdictOptions&, const KineticReference&,
                                                 bool);

}  // namespace blt::sim
