#include "blt/sim/solver.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "blt/sim/contact.hpp"
#include "blt/sim/update_scheme.hpp"

namespace blt::sim {

const char* toString(ShapeFunctionKind k) { return k == ShapeFunctionKind::linear ? "linear" : "uGIMP"; }
const char* toString(UpdateSchemeKind k) { return k == UpdateSchemeKind::musl ? "MUSL" : "USL"; }
const char* toString(BoundaryKind k) {
  switch (k) {
    case BoundaryKind::free: return "free";
    case BoundaryKind::fixed: return "fixed";
    case BoundaryKind::symmetry: return "symmetry";
    case BoundaryKind::nonReflecting: return "non-reflecting";
  }
  return "?";
}

template <int D>
Solver<D>::Solver(const GridSpec<D>& grid, const SolverOptions& options, std::vector<SolidMaterial> materials)
    : spec_(grid), options_(options), materials_(std::move(materials)) {
  if (!(spec_.cellSize > 0)) throw std::invalid_argument("grid cell size must be positive");
  for (int a = 0; a < D; ++a) {
    const double span = spec_.upper[a] - spec_.lower[a];
    if (!(span > 0)) throw std::invalid_argument("grid upper corner must lie above the lower corner on every axis");
    nodes_[a] = static_cast<int>(std::ceil(span / spec_.cellSize - 1e-9)) + 1;
    nodes_[a] = std::max(nodes_[a], 3);
    spec_.upper[a] = spec_.lower[a] + (nodes_[a] - 1) * spec_.cellSize;
  }
  if (options_.scheme == UpdateSchemeKind::musl)
    scheme_ = std::make_unique<Musl<D>>();
  else
    scheme_ = std::make_unique<Usl<D>>();
}

template <int D>
Solver<D>::~Solver() = default;

namespace {
int threadCount(const SolverOptions& o) { return o.threads > 0 ? o.threads : omp_get_max_threads(); }
// Below this many particles a step is too short for threads to pay for their barriers, so small runs stay
// serial. (On a machine whose cores are busy with other work a descheduled thread stalls every barrier: runs
// sharing a machine should each use threads = 1.)
constexpr std::size_t kParallelThreshold = 4000;
// Steps between reorderings of the particles in memory (sortParticles).
constexpr long kReorderInterval = 25;
// Share of a node's volume (nodal mass over the body's density) below which a body takes no part in the
// momentum exchange of the contact correction there (a sliver; see correctSlivers).
constexpr double kContactVolumeFraction = 0.05;
// Bits of corrected_: the node's velocity was changed by the contact correction, by the dashpots.
// kBySliver: changed by the sliver correction only (tallied as contact work, but not a node whose corrected
// velocity the MUSL remap keeps).
constexpr std::uint8_t kByContact = 1, kByBoundary = 2, kBySliver = 4;

// Adds the wall time of its scope to a stage's total.
class StageClock {
 public:
  explicit StageClock(double& total) : total_(total), start_(omp_get_wtime()) {}
  ~StageClock() { total_ += omp_get_wtime() - start_; }
  StageClock(const StageClock&) = delete;
  StageClock& operator=(const StageClock&) = delete;

 private:
  double& total_;
  double start_;
};
}  // namespace

template <int D>
void Solver<D>::initialise() {
  const std::size_t n = particles_.size();
  nodeCount_ = 1;
  for (int a = 0; a < D; ++a) {
    strides_[a] = static_cast<long>(nodeCount_);
    nodeCount_ *= static_cast<std::size_t>(nodes_[a]);
  }
  int maxBody = 0;
  for (std::size_t p = 0; p < n; ++p) {
    maxBody = std::max(maxBody, particles_.body[p]);
    const int mat = particles_.material[p];
    if (mat < 0 || mat >= static_cast<int>(materials_.size()))
      throw std::invalid_argument("particle material index out of range");
  }
  bodies_ = options_.contact.mode == ContactMode::multiField ? maxBody + 1 : 1;
  const std::size_t fields = nodeCount_ * static_cast<std::size_t>(bodies_);
  scatter_.assign(fields, ScatterNode<D>{});
  velocity_.assign(fields, Vec<D>::Zero());
  velocityChange_.assign(fields, Vec<D>::Zero());
  remappedMomentum_.assign(fields, Vec<D>::Zero());
  if (bodies_ > 1) {
    contactDelta_.assign(fields, Vec<D>::Zero());
  }
  if (bodies_ > 1 && options_.contact.strain == ContactStrain::perParticle && options_.scheme == UpdateSchemeKind::musl)
    correctedVelocity_.assign(fields, Vec<D>::Zero());
  else
    correctedVelocity_.clear();
  trackBoundary_ = false;
  for (auto f : spec_.boundary) trackBoundary_ |= f == BoundaryKind::nonReflecting;
  for (int f = 0; f < 2 * D; ++f)
    walls_[f] = spec_.boundary[f] == BoundaryKind::fixed || spec_.boundary[f] == BoundaryKind::symmetry;
  if (trackBoundary_) boundaryDelta_.assign(fields, Vec<D>::Zero());
  if (bodies_ > 1 || trackBoundary_)
    corrected_.assign(fields, 0);
  else
    corrected_.clear();
  stencilBox_.assign(static_cast<std::size_t>(bodies_), NodeBox<D>::none());
  writtenBox_ = gridBox_ = stencilBox_;
  stencil_.resize(n);
  stencilGradient_.resize(n);
  slabOf_.assign(n, 0);
  order_.assign(n, 0);
  slabAxis_ = 0;
  for (int a = 1; a < D; ++a)
    if (nodes_[a] > nodes_[slabAxis_]) slabAxis_ = a;
  // Slabs two cells wide along the longest axis: a particle of slab s writes nodes of slabs s and s+1 only
  // (three-node stencil), so slabs of one parity can scatter concurrently without locks.
  slabCount_ = (nodes_[slabAxis_] + 1) / 2;
  slabStart_.assign(static_cast<std::size_t>(slabCount_) + 1, 0);

  double minMass = std::numeric_limits<double>::infinity();
  for (std::size_t p = 0; p < n; ++p) minMass = std::min(minMass, particles_.mass[p]);
  massEpsilon_ = n ? 1e-9 * minMass : 0.0;

  bodyWaveSpeeds();
  // First step from the undeformed wave speeds.
  double dtMin = std::numeric_limits<double>::infinity();
  for (std::size_t p = 0; p < n; ++p) {
    const double c = materials_[particles_.material[p]].referenceWaveSpeed();
    particles_.soundSpeed[p] = c;
    dtMin = std::min(dtMin, spec_.cellSize / (c + particles_.velocity[p].norm()));
  }
  dt_ = options_.timeStepSafety * dtMin;
  erosionSoundSpeedLimit_ = options_.erosionSoundSpeed * *std::max_element(bodyWaveSpeed_.begin(), bodyWaveSpeed_.end());
  activeCount_ = n;
  threads_ = threadCount(options_);
  parallel_ = threads_ > 1 && n >= kParallelThreshold;
}

template <int D>
void Solver<D>::bodyWaveSpeeds() {
  bodyWaveSpeed_.assign(bodies_, 0.0);
  bodyShearSpeed_.assign(bodies_, 0.0);
  bodyDensity_.assign(bodies_, 0.0);
  for (std::size_t p = 0; p < particles_.size(); ++p) {
    const int b = bodies_ > 1 ? particles_.body[p] : 0;
    const SolidMaterial& m = materials_[particles_.material[p]];
    bodyWaveSpeed_[b] = std::max(bodyWaveSpeed_[b], m.referenceWaveSpeed());
    bodyShearSpeed_[b] = std::max(bodyShearSpeed_[b], std::sqrt(m.shearModulus / m.density));
    bodyDensity_[b] = std::max(bodyDensity_[b], m.density);
  }
}

template <int D>
void Solver<D>::step() {
  if (steps_ % kReorderInterval == 0) {
    const StageClock clock(stageTimes_.reorder);
    sortParticles();
  }
  static_cast<const UpdateScheme<D>&>(*scheme_).advance(*this);
}

// Puts the particles in the order of their cells, the slab axis varying slowest, so that the slab bins of
// computeShapeFunctions are runs of consecutive particles and each pass streams through memory.
template <int D>
void Solver<D>::sortParticles() {
  const std::size_t n = particles_.size();
  std::vector<long>& key = sortKey_;
  key.resize(n);
  const double h = spec_.cellSize;
  for (std::size_t p = 0; p < n; ++p) {
    long k = 0;
    for (int a = D - 1; a >= 0; --a) {
      const int axis = a == D - 1 ? slabAxis_ : (a == slabAxis_ ? D - 1 : a);  // slab axis most significant
      const long c = std::clamp(static_cast<long>((particles_.position[p][axis] - spec_.lower[axis]) / h), 0L,
                                static_cast<long>(nodes_[axis]) - 1);
      k = k * nodes_[axis] + c;
    }
    key[p] = particles_.active[p] ? k : std::numeric_limits<long>::max();
  }
  std::vector<int>& perm = order_;
  for (std::size_t p = 0; p < n; ++p) perm[p] = static_cast<int>(p);
  std::stable_sort(perm.begin(), perm.end(), [&](int a, int b) { return key[a] < key[b]; });
  bool identity = true;
  for (std::size_t p = 0; p < n && identity; ++p) identity = perm[p] == static_cast<int>(p);
  if (!identity) particles_.permute(perm);
}

// ---------------------------------------------------------------------------------------------------------
// Stage 1: stencils and thread bins.
template <int D>
void Solver<D>::computeShapeFunctions() {
  const StageClock clock(stageTimes_.shapeFunctions);
  const std::size_t n = particles_.size();
  const double h = spec_.cellSize;
  const ShapeFunctionKind kind = options_.shapeFunction;
  const int ns = stencilSize(kind);
  const double invH = 1.0 / h;
  const int B = bodies_;
  threadBox_.assign(static_cast<std::size_t>(std::max(threads_, 1) * B), NodeBox<D>::none());
#pragma omp parallel num_threads(threads_) if (parallel_)
  {
    NodeBox<D>* box = &threadBox_[static_cast<std::size_t>(omp_get_thread_num() * B)];
#pragma omp for schedule(static)
    for (long p = 0; p < static_cast<long>(n); ++p) {
      if (!particles_.active[p]) {
        slabOf_[p] = -1;
        continue;
      }
      const Vec<D>& x = particles_.position[p];
      Stencil<D>& st = stencil_[p];
      StencilGradient<D>& sg = stencilGradient_[p];
      long node = 0;
      int first[D];  // the stencil's first node on each axis
      bool inside = true;
      for (int a = 0; a < D; ++a) {
        const double len = (nodes_[a] - 1) * h;
        double xi = x[a] - spec_.lower[a];
        if (!(xi >= -0.5 * h && xi <= len + 0.5 * h)) {  // also catches NaN
          inside = false;
          break;
        }
        // A particle within its half-width of a face is evaluated as touching the face from inside.
        const double lp = kind == ShapeFunctionKind::linear ? 0.0 : particles_.halfSize[p][a];
        xi = std::clamp(xi, lp, len - lp - 1e-12 * h);
        const int base = stencilBase(kind, xi, h, lp, nodes_[a]);
        const double invHLp = kind == ShapeFunctionKind::linear ? 0.0 : 1.0 / (h * lp);
        if (kind == ShapeFunctionKind::uGimp) {
          uGimpStencil(xi, h, lp, base, invHLp, st.w[a], sg.g[a]);
        } else {
          for (int k = 0; k < kStencil; ++k) {
            if (k < ns)
              stencilNode(kind, xi, h, lp, invH, invHLp, base + k, st.w[a][k], sg.g[a][k]);
            else
              st.w[a][k] = sg.g[a][k] = 0.0;
          }
        }
        node += base * strides_[a];
        first[a] = base;
        if (a == slabAxis_) slabOf_[p] = base / 2;
      }
      if (!inside) {
        particles_.active[p] = 0;
        slabOf_[p] = -1;
        continue;
      }
      // Two nodes on an axis carry weight where the domain [x - lp, x + lp] lies within one cell along it, and the
      // stages skip the third (each axis on its own: a point off the fill lattice has 2 on about half its axes). On a
      // quarter point (where the initial lattice puts a point) the domain's edge lies exactly on a node, and the
      // rounding of stencilBase decides whether the first node or the third carries nothing; where it is the first,
      // the stencil starts one node later on that axis. The stencil stays within base..base + 2, so the slab bins hold.
      for (int a = 0; a < D; ++a) {
        st.size[a] = static_cast<std::uint8_t>(ns);
        if (ns != kStencil) continue;
        if (st.w[a][0] == 0.0 && sg.g[a][0] == 0.0) {
          for (int k = 0; k + 1 < kStencil; ++k) {
            st.w[a][k] = st.w[a][k + 1];
            sg.g[a][k] = sg.g[a][k + 1];
          }
          st.w[a][kStencil - 1] = sg.g[a][kStencil - 1] = 0.0;
          node += strides_[a];
          ++first[a];
          st.size[a] = 2;
        } else if (st.w[a][2] == 0.0 && sg.g[a][2] == 0.0) {
          st.size[a] = 2;
        }
      }
      st.node = static_cast<int>(node);
      NodeBox<D>& b = box[B > 1 ? particles_.body[p] : 0];
      for (int a = 0; a < D; ++a) {
        b.lo[a] = std::min(b.lo[a], first[a]);
        b.hi[a] = std::max(b.hi[a], first[a] + st.size[a] - 1);
      }
    }
  }
  for (int b = 0; b < B; ++b) {
    stencilBox_[b] = NodeBox<D>::none();
    for (std::size_t t = 0; t < threadBox_.size() / B; ++t) stencilBox_[b].include(threadBox_[t * B + b]);
  }
  // Counting sort of the active particles by slab.
  std::fill(slabStart_.begin(), slabStart_.end(), 0);
  for (std::size_t p = 0; p < n; ++p)
    if (slabOf_[p] >= 0) ++slabStart_[slabOf_[p] + 1];
  for (int s = 0; s < slabCount_; ++s) slabStart_[s + 1] += slabStart_[s];
  activeCount_ = static_cast<std::size_t>(slabStart_[slabCount_]);
  // slabOf_ is reused as the running cursor of each particle's slab.
  std::vector<int>& cursor = cursor_;
  cursor.assign(slabStart_.begin(), slabStart_.end() - 1);
  for (std::size_t p = 0; p < n; ++p)
    if (slabOf_[p] >= 0) order_[static_cast<std::size_t>(cursor[slabOf_[p]]++)] = static_cast<int>(p);
}

// The stencil's nodes come in rows along axis 0. Node a of a row has the weight w0[a] * w and the gradient
// (g0[a] * w, w0[a] * g1, w0[a] * g2): the factors across axis 0 are the same along the whole row, so the stages
// below work on a row's factors once and touch each node with a few products of w0[a] and g0[a].
// Calls f(rowNode, w, g1, g2) for every row of the stencil: rowNode is the row's first node, w the product of
// the weights on axes 1..D-1, gk the same product with axis k's gradient in place of its weight (g2 = 0 in
// 2D). Sizes: the nodes per axis (Sizes::n0, n1, n2), known at compile time so that the loops unroll.
// A rule for the hot loops: GCC assembles a small vector from separately computed scalars (or a vector with one
// element changed) on the stack, and the wide load after the narrow stores stalls store forwarding, which cost
// the scatter 30 to 60 %. Keep such values scalar, or write whole-vector expressions (see particlesToGrid).
template <int N0, int N1, int N2>
struct StencilSizes {
  static constexpr int n0 = N0, n1 = N1, n2 = N2;
};

template <int D, class Sizes, class F>
inline void forEachRowOf(Sizes, const Stencil<D>& st, const StencilGradient<D>& sg,
                         const Eigen::Array<long, D, 1>& strides, F&& f) {
  if constexpr (D == 3) {
    for (int c = 0; c < Sizes::n2; ++c)
      for (int b = 0; b < Sizes::n1; ++b)
        f(st.node + c * strides[2] + b * strides[1], st.w[1][b] * st.w[2][c], sg.g[1][b] * st.w[2][c],
          st.w[1][b] * sg.g[2][c]);
  } else {
    for (int b = 0; b < Sizes::n1; ++b) f(st.node + b * strides[1], st.w[1][b], sg.g[1][b], 0.0);
  }
}

// The same rows for the stages that need only the weights: f(rowNode, w).
template <int D, class Sizes, class F>
inline void forEachWeightRowOf(Sizes, const Stencil<D>& st, const Eigen::Array<long, D, 1>& strides, F&& f) {
  if constexpr (D == 3) {
    for (int c = 0; c < Sizes::n2; ++c)
      for (int b = 0; b < Sizes::n1; ++b) f(st.node + c * strides[2] + b * strides[1], st.w[1][b] * st.w[2][c]);
  } else {
    for (int b = 0; b < Sizes::n1; ++b) f(st.node + b * strides[1], st.w[1][b]);
  }
}

// Runs stage(StencilSizes<...>{}) with the stencil's nodes per axis as compile-time constants.
template <int D, class F>
inline void withStencilSizes(const Stencil<D>& st, F&& stage) {
  const int code = (st.size[0] == 3) | (st.size[1] == 3) << 1 | (D == 3 && st.size[D - 1] == 3) << 2;
  if constexpr (D == 3) {
    switch (code) {
      case 0: return stage(StencilSizes<2, 2, 2>{});
      case 1: return stage(StencilSizes<3, 2, 2>{});
      case 2: return stage(StencilSizes<2, 3, 2>{});
      case 3: return stage(StencilSizes<3, 3, 2>{});
      case 4: return stage(StencilSizes<2, 2, 3>{});
      case 5: return stage(StencilSizes<3, 2, 3>{});
      case 6: return stage(StencilSizes<2, 3, 3>{});
      default: return stage(StencilSizes<3, 3, 3>{});
    }
  } else {
    switch (code) {
      case 0: return stage(StencilSizes<2, 2, 1>{});
      case 1: return stage(StencilSizes<3, 2, 1>{});
      case 2: return stage(StencilSizes<2, 3, 1>{});
      default: return stage(StencilSizes<3, 3, 1>{});
    }
  }
}

// Runs body(p) for every active particle, slab parity by parity, so that scatters from concurrent threads
// never touch the same node.
template <int D>
template <class F>
void Solver<D>::scatterByColour(F&& body) {
#pragma omp parallel num_threads(threads_) if (parallel_)
  for (int colour = 0; colour < 2; ++colour) {
#pragma omp for schedule(dynamic, 1)
    for (int s = colour; s < slabCount_; s += 2)
      for (int i = slabStart_[s]; i < slabStart_[s + 1]; ++i) body(order_[static_cast<std::size_t>(i)]);
  }
}

// Sets each body's entries of `field` within its grid box to `zero`, a row of the box at a time.
template <int D>
template <class T>
void Solver<D>::clearInBoxes(std::vector<T>& field, const T& zero) {
  const long N = static_cast<long>(nodeCount_);
  for (int b = 0; b < bodies_; ++b) {
    const NodeBox<D>& box = gridBox_[b];
    const long rows = box.rows();
    if (rows == 0) continue;  // an empty box's bounds are the int limits: no length to take
    const long length = static_cast<long>(box.hi[0]) - box.lo[0] + 1;
#pragma omp parallel for schedule(static) num_threads(threads_) if (parallel_)
    for (long k = 0; k < rows; ++k) {
      int index[D];
      index[0] = box.lo[0];
      box.rowIndex(k, index);
      long start = b * N;
      for (int a = 0; a < D; ++a) start += index[a] * strides_[a];
      std::fill_n(field.begin() + start, length, zero);
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
// Stage 2: particles to grid.
template <int D>
void Solver<D>::particlesToGrid() {
  const StageClock clock(stageTimes_.particlesToGrid);
  for (int b = 0; b < bodies_; ++b) {
    gridBox_[b] = writtenBox_[b];
    gridBox_[b].include(stencilBox_[b]);
    writtenBox_[b] = stencilBox_[b];
  }
  clearInBoxes(scatter_, ScatterNode<D>{});
  const bool hoop = D == 2 && options_.axisymmetric;
  const bool gradients = bodies_ > 1;
  scatterByColour([&](int p) {
    const long off = bodies_ > 1 ? static_cast<long>(particles_.body[p]) * static_cast<long>(nodeCount_) : 0;
    const double m = particles_.mass[p];
    const Vec<D> mv = m * particles_.velocity[p];
    const double V = particles_.volume[p];
    const Mat3& sig = particles_.stress[p];
    const double q = particles_.viscousPressure[p];
    // f_I = -V ((sigma - q) grad N_I), plus -V (sigma_tt - q) N_I / r on the radial component in axisymmetric
    // runs.
    const double hoopForce = hoop ? V * (q - sig(2, 2)) / hoopRadius(p) : 0.0;
    const Eigen::Matrix<double, D, D> minusVs =
        V * (q * Eigen::Matrix<double, D, D>::Identity() - sig.template topLeftCorner<D, D>());
    const Stencil<D>& st = stencil_[p];
    const StencilGradient<D>& sg = stencilGradient_[p];
    withStencilSizes(st, [&](auto sizes) {
      constexpr int NS = decltype(sizes)::n0;
      forEachRowOf<D>(sizes, st, sg, strides_, [&](long row, double rw, double g1, double g2) {
        const double mw = m * rw;
        const Vec<D> mvw = rw * mv;
        const Vec<D> fx = rw * minusVs.col(0);
        Vec<D> ft = g1 * minusVs.col(1);
        if constexpr (D == 3) ft += g2 * minusVs.col(D - 1);
        if constexpr (D == 2) ft += (hoopForce * rw) * Vec<D>::UnitX();
        const double mg1 = m * g1, mg2 = m * g2;
        for (int a = 0; a < NS; ++a) {
          const double w0 = st.w[0][a], g0 = sg.g[0][a];
          ScatterNode<D>& n = scatter_[off + row + a];
          n.mass += w0 * mw;
          n.momentum += w0 * mvw;
          n.force += g0 * fx + w0 * ft;
          if (gradients) {
            n.gradient[0] += g0 * mw;
            n.gradient[1] += w0 * mg1;
            if constexpr (D == 3) n.gradient[D - 1] += w0 * mg2;
          }
        }
      });
    });
  });
}

// ---------------------------------------------------------------------------------------------------------
// Stage 3: grid momentum update, contact, boundaries.

// Imposes the face conditions on one nodal velocity and returns the part of the change made by the dashpots
// (the energy they absorb is tallied on the particles). Fixed faces and symmetry planes do no work.
template <int D>
static Vec<D> applyFaceConditions(Vec<D>& v, const std::array<BoundaryKind, 2 * D>& faces, const int* index,
                                  const Eigen::Array<int, D, 1>& nodes, double dashpotNormal, double dashpotShear) {
  Vec<D> dashpot = Vec<D>::Zero();
  for (int a = 0; a < D; ++a) {
    for (int side = 0; side < 2; ++side) {
      if (index[a] != (side == 0 ? 0 : nodes[a] - 1)) continue;
      switch (faces[2 * a + side]) {
        case BoundaryKind::free: break;
        case BoundaryKind::fixed: v.setZero(); break;
        case BoundaryKind::symmetry: v[a] = 0.0; break;
        case BoundaryKind::nonReflecting: {
          // Implicit dashpot (unconditionally stable): v_n / (1 + 2 c_d dt / h), same with c_s tangentially.
          const Vec<D> before = v;
          for (int c = 0; c < D; ++c) v[c] /= 1.0 + (c == a ? dashpotNormal : dashpotShear);
          dashpot += v - before;
          break;
        }
      }
    }
  }
  return dashpot;
}

template <int D>
void Solver<D>::applyVelocityConditions(bool integrate) {
  const double dt = dt_;
  const double h = spec_.cellSize;
  const int B = bodies_;
  const long N = static_cast<long>(nodeCount_);
  bool anyBoundary = false;
  for (auto f : spec_.boundary) anyBoundary |= f != BoundaryKind::free;
  const bool contact = B > 1;
  const double mu = options_.contact.friction;
  const bool keepCorrected = !correctedVelocity_.empty();  // ContactStrain::perParticle
  // USL takes the strain increment from these velocities, MUSL from those of the remap (this function again).
  const bool strainFromIntegration = options_.scheme == UpdateSchemeKind::usl;
  double strainWork = 0;
  constexpr int kMaxBodies = 16;
  NodeBox<D> all = NodeBox<D>::none();
  for (int b = 0; b < B; ++b) all.include(gridBox_[b]);
  const long rows = all.rows();
#pragma omp parallel for schedule(static) reduction(+ : strainWork) num_threads(threads_) if (parallel_)
  for (long row = 0; row < rows; ++row) {
    int index[D];
    index[0] = all.lo[0];
    all.rowIndex(row, index);
    long rowStart = 0;
    for (int a = 1; a < D; ++a) rowStart += index[a] * strides_[a];
    // Each body's columns on this row; outside them its entries have no mass and hold zeros (gridBox_).
    int firstColumn[kMaxBodies], lastColumn[kMaxBodies];
    for (int b = 0; b < B; ++b) {
      const bool onRow = gridBox_[b].containsRow(index);
      firstColumn[b] = onRow ? gridBox_[b].lo[0] : 1;
      lastColumn[b] = onRow ? gridBox_[b].hi[0] : 0;
    }
    for (int column = all.lo[0]; column <= all.hi[0]; ++column) {
      index[0] = column;
      const long n = rowStart + column;
      Vec<D> v[kMaxBodies];
      Vec<D> normal[kMaxBodies];
      double m[kMaxBodies];
      int ids[kMaxBodies];
      int count = 0;
      for (int b = 0; b < B; ++b) {
        if (column < firstColumn[b] || column > lastColumn[b]) {
          m[b] = 0.0;
          continue;
        }
        const long i = b * N + n;
        m[b] = scatter_[i].mass;
        if (integrate && !corrected_.empty()) corrected_[i] = 0;
        if (m[b] <= massEpsilon_) {
          velocity_[i].setZero();
          velocityChange_[i].setZero();
          continue;
        }
        if (integrate) {
          const Vec<D> vOld = scatter_[i].momentum / m[b];
          v[b] = (scatter_[i].momentum + dt * scatter_[i].force) / m[b];
          velocityChange_[i] = vOld;  // holds the old velocity until the end of this node's update
        } else {
          v[b] = remappedMomentum_[i] / m[b];
        }
        if (count < kMaxBodies) ids[count++] = b;
      }
      if (count == 0) continue;
      // Contact among the bodies that carry a real share of the node's volume: a body touching a node with a sliver
      // of weight has an ill-defined nodal velocity there (its force over its tiny mass) and would upset the
      // exchange. Without this filter the 3D quarter model and the axisymmetric run of the verification impact
      // differ by 5.8 %, with it by 3.7 %. Slivers are still kept from passing into the others (correctSlivers):
      // without that, failed fabric spray of one twentieth of a node's volume went through a 1.4 mm aluminium plate.
      // Volume, not mass: a light body (fabric on aluminium) is no sliver for being light.
      int touching[kMaxBodies], slivers[kMaxBodies];
      int contactCount = 0, sliverCount = 0;
      if (integrate && contact && count > 1) {
        double vt = 0;
        for (int k = 0; k < count; ++k) vt += m[ids[k]] / bodyDensity_[ids[k]];
        for (int k = 0; k < count; ++k)
          if (m[ids[k]] / bodyDensity_[ids[k]] >= kContactVolumeFraction * vt)
            touching[contactCount++] = ids[k];
          else
            slivers[sliverCount++] = ids[k];
      }
      // The contact acts in the update only. The MUSL remap is not corrected: where the update corrected a node, the
      // strain increment takes that node's corrected velocity (kept below); elsewhere the plain remap. The strain
      // velocity is then either the one that moved the particles (USL-like) or the remap of their new velocities,
      // and the contact cannot raise a step's energy, the slivers' correction aside (docs/validation/README.md,
      // stop 43). Correcting the remap as well let the
      // strain take, at nodes the update had left alone, velocities from a second correction that no particle
      // received: seed 003's T4T4T4 at 348.2 m/s gained 18 J (5 %) that way and went unstable at 435 us.
      if (integrate && (contactCount > 1 || (contactCount == 1 && sliverCount > 0))) {
        Vec<D> total = Vec<D>::Zero();
        for (int k = 0; k < contactCount; ++k) total += scatter_[touching[k] * N + n].gradient;
        // sum_p m_p grad N_I(x_p) points from a body towards the node, i.e. along the body's outward normal at its
        // surface. Body b's normal uses its own gradient minus the others', so two bodies get opposite normals.
        for (int k = 0; k < contactCount; ++k) {
          const int b = touching[k];
          Vec<D> g = 2.0 * scatter_[b * N + n].gradient - total;
          // On a symmetry plane the mirrored half is missing from the sum; by symmetry the true normal lies in the
          // plane, so the component across it is dropped.
          if (anyBoundary)
            for (int a = 0; a < D; ++a)
              if ((index[a] == 0 && spec_.boundary[2 * a] == BoundaryKind::symmetry) ||
                  (index[a] == nodes_[a] - 1 && spec_.boundary[2 * a + 1] == BoundaryKind::symmetry))
                g[a] = 0.0;
          const double len = g.norm();
          normal[b] = len > 0 ? Vec<D>(g / len) : Vec<D>::Zero();
        }
        Vec<D> before[kMaxBodies];
        for (int k = 0; k < count; ++k) before[ids[k]] = v[ids[k]];
        if (contactCount > 1) {
          correctContact<D>(v, m, normal, touching, contactCount, mu);
          for (int k = 0; k < contactCount; ++k)
            if (!(v[touching[k]] - before[touching[k]]).isZero(0.0)) corrected_[touching[k] * N + n] |= kByContact;
        }
        if (sliverCount > 0) {
          int dominant = touching[0];
          double mt = 0;
          Vec<D> p = Vec<D>::Zero();
          for (int k = 0; k < contactCount; ++k) {
            const int b = touching[k];
            if (m[b] > m[dominant]) dominant = b;
            mt += m[b];
            p += m[b] * v[b];
          }
          // The slivers' momentum velocities, which velocityChange_ holds during the update. Their correction is not
          // kept through the MUSL remap (see correctSlivers). What they lose, the bodies they struck gain, as a common
          // velocity.
          Vec<D> momentumVelocity[kMaxBodies];
          for (int k = 0; k < sliverCount; ++k) momentumVelocity[slivers[k]] = velocityChange_[slivers[k] * N + n];
          const Vec<D> taken =
              correctSlivers<D>(v, m, momentumVelocity, slivers, sliverCount, p / mt, -normal[dominant]);
          for (int k = 0; k < contactCount; ++k) v[touching[k]] -= taken / mt;
        }
        // The work of both corrections is tallied on the particles (gridToParticles) from the change they made here.
        for (int k = 0; k < count; ++k) {
          const long i = ids[k] * N + n;
          contactDelta_[i] = v[ids[k]] - before[ids[k]];
          if (!(corrected_[i] & kByContact) && !contactDelta_[i].isZero(0.0)) corrected_[i] |= kBySliver;
          if (strainFromIntegration) strainWork -= dt * scatter_[i].force.dot(contactDelta_[i]);
        }
      }
      if (anyBoundary) {
        for (int k = 0; k < count; ++k) {
          const int b = ids[k];
          const double cn = integrate ? 2.0 * bodyWaveSpeed_[b] * dt / h : 0.0;
          const double cs = integrate ? 2.0 * bodyShearSpeed_[b] * dt / h : 0.0;
          const Vec<D> dashpot = applyFaceConditions<D>(v[b], spec_.boundary, index, nodes_, cn, cs);
          if (integrate && trackBoundary_ && !dashpot.isZero(0.0)) {
            boundaryDelta_[b * N + n] = dashpot;
            corrected_[b * N + n] |= kByBoundary;
          }
        }
      }
      for (int k = 0; k < count; ++k) {
        const int b = ids[k];
        const long i = b * N + n;
        if (integrate) velocityChange_[i] = v[b] - velocityChange_[i];
        if (integrate && keepCorrected) correctedVelocity_[i] = v[b];
        // MUSL remap: where the contact correction acted in this step, the body keeps the corrected velocity. The
        // remapped one re-mixes momenta that FLIP left off the contact constraint, and a strain increment taken
        // from it gained energy (two elastic spheres rebounded with 10 % more than they had).
        if (integrate || keepCorrected || !(contact && (corrected_[i] & kByContact))) velocity_[i] = v[b];
        // The strain increment takes these velocities; where the corrections changed them from the plain remap, the
        // stress power they add (or take) is work of the contact, not of the internal forces (see EnergyBalance).
        // Per-particle contact strain tallies it on the particles instead (updateStress). A node of one body was
        // not corrected: its velocity is the plain one.
        if (!integrate && contact && !keepCorrected && count > 1) {
          Vec<D> plain = remappedMomentum_[i] / m[b];
          if (anyBoundary) applyFaceConditions<D>(plain, spec_.boundary, index, nodes_, 0.0, 0.0);
          strainWork -= dt * scatter_[i].force.dot(velocity_[i] - plain);
        }
      }
    }
  }
  contactDissipation_ -= strainWork;
}

template <int D>
void Solver<D>::integrateGrid() {
  const StageClock clock(stageTimes_.grid);
  applyVelocityConditions(true);
}

// ---------------------------------------------------------------------------------------------------------
// Stage 4: grid to particles.
template <int D>
void Solver<D>::gridToParticles() {
  const StageClock clock(stageTimes_.gridToParticles);
  const double dt = dt_;
  const double flip = options_.flipFraction;
  const long N = static_cast<long>(nodeCount_);
  const long count = static_cast<long>(activeCount_);
  const bool axisymmetric = D == 2 && options_.axisymmetric;
  const bool contact = bodies_ > 1, boundary = trackBoundary_, corrections = contact || boundary;
  double contactSum = 0, boundarySum = 0;
#pragma omp parallel for schedule(static) reduction(+ : contactSum, boundarySum) num_threads(threads_) if (parallel_)
  for (long k = 0; k < count; ++k) {
    const int p = order_[static_cast<std::size_t>(k)];
    const long off = bodies_ > 1 ? particles_.body[p] * N : 0;
    Vec<D> vGrid = Vec<D>::Zero(), dv = Vec<D>::Zero(), dContact = Vec<D>::Zero(), dBoundary = Vec<D>::Zero();
    const Stencil<D>& st = stencil_[p];
    withStencilSizes(st, [&](auto sizes) {
      constexpr int NS = decltype(sizes)::n0;
      forEachWeightRowOf<D>(sizes, st, strides_, [&](long row, double rw) {
        for (int a = 0; a < NS; ++a) {
          const double w = st.w[0][a] * rw;
          const long i = off + row + a;
          vGrid += w * velocity_[i];
          dv += w * velocityChange_[i];
          if (corrections && corrected_[i]) {
            if (corrected_[i] & (kByContact | kBySliver)) dContact += w * contactDelta_[i];
            if (corrected_[i] & kByBoundary) dBoundary += w * boundaryDelta_[i];
          }
        }
      });
    });
    Vec<D>& v = particles_.velocity[p];
    const Vec<D> vStart = v;
    v = flip * (v + dv) + (1.0 - flip) * vGrid;
    // The particle's kinetic energy changes by m dv . (vStart + v) / 2, exactly, and that is linear in dv: the
    // share of the contact correction (dContact) and of the dashpots (dBoundary) is the work they did on it.
    // (Charging each with the kinetic energy the particle would have had without it, less what it has, is not
    // additive: in a flyer-plate impact across a contact it tallied 10 % of the impact energy that was never lost.)
    const double m = particles_.mass[p];
    const Vec<D> vMean = 0.5 * (vStart + v);
    if (contact) contactSum -= m * dContact.dot(vMean);
    if (boundary) boundarySum -= m * dBoundary.dot(vMean);
    Vec<D>& x = particles_.position[p];
    x += dt * vGrid;
    if (axisymmetric && x[0] < 0) x[0] = -x[0];  // a point crossing the axis reappears on the other side
    // A wall (fixed face or symmetry plane) holds its nodes, but a point near it moves with the interpolated
    // velocity of the nodes behind and can drift through; material stays on its side of the wall.
    for (int a = 0; a < D; ++a) {
      if (walls_[2 * a] && x[a] < spec_.lower[a]) x[a] = spec_.lower[a];
      if (walls_[2 * a + 1] && x[a] > spec_.upper[a]) x[a] = spec_.upper[a];
    }
  }
  contactDissipation_ += contactSum;
  boundaryWork_ += boundarySum;
}

// ---------------------------------------------------------------------------------------------------------
// Stage 5 (MUSL): map the updated momenta back to the grid.
template <int D>
void Solver<D>::remapMomentum() {
  const StageClock clock(stageTimes_.remap);
  clearInBoxes(remappedMomentum_, Vec<D>::Zero().eval());
  scatterByColour([&](int p) {
    const long off = bodies_ > 1 ? static_cast<long>(particles_.body[p]) * static_cast<long>(nodeCount_) : 0;
    const Vec<D> mv = particles_.mass[p] * particles_.velocity[p];
    const Stencil<D>& st = stencil_[p];
    withStencilSizes(st, [&](auto sizes) {
      constexpr int NS = decltype(sizes)::n0;
      forEachWeightRowOf<D>(sizes, st, strides_, [&](long row, double rw) {
        const Vec<D> mvw = rw * mv;
        for (int a = 0; a < NS; ++a) remappedMomentum_[off + row + a] += st.w[0][a] * mvw;
      });
    });
  });
  applyVelocityConditions(false);
}

// ---------------------------------------------------------------------------------------------------------
// Stage 6: strain increment and constitutive update; the next time step.
template <int D>
void Solver<D>::updateStress() {
  const StageClock clock(stageTimes_.stress);
  const double dt = dt_;
  const double h = spec_.cellSize;
  const long N = static_cast<long>(nodeCount_);
  const long count = static_cast<long>(activeCount_);
  const bool hoop = D == 2 && options_.axisymmetric;
  const BulkViscosity visc = options_.viscosity;
  // The fastest signal (sound speed plus particle speed) sets the next step: h over its maximum is the minimum of
  // h over each, to the last bit, as division rounds monotonically; one division instead of one per point.
  double fastest = 0.0, strainWork = 0.0;
  const bool keptEroded = options_.keepErodedMass;
  const bool perParticle = !correctedVelocity_.empty();
  // Whether a node of particle p's stencil (in its body's field) that carries weight was corrected by the
  // contact in this step.
  const auto touchesCorrectedNode = [&](int p) {
    const long off = static_cast<long>(particles_.body[p]) * N;
    bool touched = false;
    withStencilSizes(stencil_[p], [&](auto sizes) {
      constexpr int NS = decltype(sizes)::n0;
      forEachWeightRowOf<D>(sizes, stencil_[p], strides_, [&](long row, double) {
        for (int a = 0; a < NS; ++a) touched |= (corrected_[off + row + a] & kByContact) != 0;
      });
    });
    return touched;
  };
#pragma omp parallel for schedule(static) reduction(max : fastest) reduction(+ : strainWork) num_threads(threads_) if (parallel_)
  for (long k = 0; k < count; ++k) {
    const int p = order_[static_cast<std::size_t>(k)];
    if (keptEroded && particles_.failed[p] == kEroded) {  // a stress-free mass point: only its speed limits the step
      fastest = std::max(fastest, particles_.velocity[p].norm());
      continue;
    }
    const long off = bodies_ > 1 ? particles_.body[p] * N : 0;
    const Stencil<D>& st = stencil_[p];
    const StencilGradient<D>& sg = stencilGradient_[p];
    const auto velocityGradient = [&](const Vec<D>* nodeVelocity) {
      Mat3 L = Mat3::Zero();
      double vr = 0;
      withStencilSizes(st, [&](auto sizes) {
        constexpr int NS = decltype(sizes)::n0;
        forEachRowOf<D>(sizes, st, sg, strides_, [&](long row, double rw, double g1, double g2) {
          // L = sum v g^T; along a row g = (g0 rw, w0 g1, w0 g2), so two sums of v along the row suffice.
          Vec<D> byWeight = Vec<D>::Zero(), byGradient = Vec<D>::Zero();
          for (int a = 0; a < NS; ++a) {
            const Vec<D>& v = nodeVelocity[off + row + a];
            byWeight += st.w[0][a] * v;
            byGradient += sg.g[0][a] * v;
          }
          L.template block<D, 1>(0, 0) += rw * byGradient;
          L.template block<D, 1>(0, 1) += g1 * byWeight;
          if constexpr (D == 3) L.template block<D, 1>(0, D - 1) += g2 * byWeight;
          if constexpr (D == 2) vr += rw * byWeight[0];
        });
      });
      if (hoop) L(2, 2) = vr / hoopRadius(p);
      return L;
    };
    Mat3 L;
    if (perParticle && touchesCorrectedNode(p)) {
      L = velocityGradient(correctedVelocity_.data());
      // The part of this step's stress power that the corrected velocities make, paired with the stress the
      // internal forces of this step came from (see EnergyBalance).
      const Mat3 extra = L - velocityGradient(velocity_.data());
      strainWork += particles_.volume[p] * dt *
                    (particles_.stress[p] - particles_.viscousPressure[p] * Mat3::Identity()).cwiseProduct(extra).sum();
    } else {
      L = velocityGradient(velocity_.data());
    }

    Mat3& F = particles_.deformationGradient[p];
    F = (Mat3::Identity() + dt * L) * F;
    const double J = F.determinant();
    // Failed points carry no tension and, expanded, no pressure, so nothing stops their lattice from folding
    // over in a debris cloud. One turned inside out (J <= 0) has no volume left to mean anything: it is eroded.
    if (particles_.failed[p] && !(J > 0 && std::isfinite(J))) {
      if (erode(p)) fastest = std::max(fastest, particles_.velocity[p].norm());
      continue;
    }
    const double V = particles_.initialVolume[p] * J;
    particles_.volume[p] = V;
    const double rho = particles_.mass[p] / V;
    const Mat3 Dm = 0.5 * (L + L.transpose());
    const Mat3 W = 0.5 * (L - L.transpose());
    const double trD = Dm.trace();
    const double c = particles_.soundSpeed[p];
    // Failed material less dense than it was is loose fragments: no bulk viscosity, as no pressure. Its velocity
    // gradient is that of a few scattered points, large without meaning, and q from it threw fabric spray about.
    const bool loose = particles_.failed[p] && J > 1.0;
    const double q = trD < 0 && !loose ? rho * h * (visc.quadratic * h * trD * trD - visc.linear * c * trD) : 0.0;

    const SolidMaterial& mat = materials_[particles_.material[p]];
    PointState s{.stress = particles_.stress[p],
                 .density = rho,
                 .specificEnergy = particles_.specificEnergy[p],
                 .temperature = particles_.temperature[p],
                 .plasticStrain = particles_.plasticStrain[p],
                 .damage = particles_.damage[p],
                 .failed = particles_.failed[p] != 0,
                 .deformationGradient = F};
    const PointUpdate u = mat.update(s, Dm, W, dt, q);
    // A point eroded for the state this step gave it goes with the state it had: that update is what the rules
    // reject (crushed past the Mie-Grueneisen singularity it reached 1e20 Pa and -7.6e10 J/kg in one step), and its
    // energy, kept, would stay in the energy history for the rest of the run (seed 000 at 60 deg, 0.1 mm: -43 J).
    if ((options_.erosionExpansion > 0 && s.failed && J > options_.erosionExpansion) ||
        (s.failed && erosionSoundSpeedLimit_ > 0 && u.soundSpeed > erosionSoundSpeedLimit_)) {
      particles_.failed[p] = 1;
      if (erode(p)) fastest = std::max(fastest, particles_.velocity[p].norm());
      continue;
    }
    particles_.stress[p] = s.stress;
    particles_.specificEnergy[p] = s.specificEnergy;
    particles_.temperature[p] = s.temperature;
    particles_.plasticStrain[p] = s.plasticStrain;
    particles_.damage[p] = s.damage;
    particles_.failed[p] = s.failed ? 1 : 0;
    particles_.viscousPressure[p] = q;
    particles_.plasticWork[p] += u.plasticWorkDensity * V;
    particles_.viscousWork[p] += -q * trD * dt * V;
    particles_.soundSpeed[p] = u.soundSpeed;
    // Seed 001 Eq. 8; the viscosity stiffens the step like an extra sound speed.
    const double cEff = u.soundSpeed + (q > 0 ? 2.0 * visc.quadratic * h * std::fabs(trD) : 0.0);
    fastest = std::max(fastest, cEff + particles_.velocity[p].norm());
  }
  contactDissipation_ -= strainWork;
  time_ += dt_;
  ++steps_;
  const double dtMin = h / fastest;
  if (std::isfinite(dtMin) && dtMin > 0) dt_ = options_.timeStepSafety * dtMin;
}

template <int D>
bool Solver<D>::erode(int p) {
  if (!options_.keepErodedMass) {
    particles_.active[p] = 0;
    return false;
  }
  particles_.failed[p] = kEroded;
  particles_.stress[p].setZero();
  particles_.viscousPressure[p] = 0.0;
  particles_.soundSpeed[p] = 0.0;
  return true;
}

// ---------------------------------------------------------------------------------------------------------
template <int D>
EnergyBalance Solver<D>::energies() const {
  EnergyBalance e;
  double ke = 0, ie = 0, pw = 0, vw = 0;
  const long n = static_cast<long>(particles_.size());
#pragma omp parallel for schedule(static) reduction(+ : ke, ie, pw, vw) num_threads(threads_) if (parallel_)
  for (long p = 0; p < n; ++p) {
    ke += 0.5 * particles_.mass[p] * particles_.velocity[p].squaredNorm();
    ie += particles_.mass[p] * particles_.specificEnergy[p];
    pw += particles_.plasticWork[p];
    vw += particles_.viscousWork[p];
  }
  e.kinetic = ke;
  e.internal = ie;
  e.plasticWork = pw;
  e.viscousWork = vw;
  e.contactDissipation = contactDissipation_;
  e.boundaryWork = boundaryWork_;
  return e;
}

template <int D>
bool Solver<D>::offGrid(const Vec<D>& x) const {
  const double h = spec_.cellSize;
  for (int a = 0; a < D; ++a) {
    const double xi = x[a] - spec_.lower[a];
    if (!(xi >= -0.5 * h && xi <= (nodes_[a] - 1) * h + 0.5 * h)) return true;
  }
  return false;
}

template <int D>
int Solver<D>::exitFace(const Vec<D>& x) const {
  if (!x.allFinite() || !offGrid(x)) return -1;
  int face = -1;
  double farthest = 0;
  for (int a = 0; a < D; ++a) {
    const double below = spec_.lower[a] - x[a], above = x[a] - spec_.upper[a];
    if (below > farthest) farthest = below, face = 2 * a;
    if (above > farthest) farthest = above, face = 2 * a + 1;
  }
  return face;
}

template <int D>
long Solver<D>::firstNonFiniteParticle() const {
  for (std::size_t p = 0; p < particles_.size(); ++p) {
    if (!particles_.position[p].allFinite() || !particles_.velocity[p].allFinite() ||
        !particles_.stress[p].allFinite())
      return static_cast<long>(p);
  }
  return -1;
}

template <int D>
std::size_t Solver<D>::memoryBytes() const {
  const std::size_t grid = scatter_.capacity() * sizeof(ScatterNode<D>) +
                           (velocity_.capacity() + velocityChange_.capacity() + remappedMomentum_.capacity() + contactDelta_.capacity() +
                            boundaryDelta_.capacity() + correctedVelocity_.capacity()) *
                               sizeof(Vec<D>) +
                           corrected_.capacity();
  const std::size_t caches = stencil_.capacity() * sizeof(Stencil<D>) +
                             stencilGradient_.capacity() * sizeof(StencilGradient<D>) +
                             (slabOf_.capacity() + order_.capacity() + slabStart_.capacity() + cursor_.capacity()) *
                                 sizeof(int);
  return particles_.bytes() + grid + caches;
}

template class Solver<2>;
template class Solver<3>;

}  // namespace blt::sim
