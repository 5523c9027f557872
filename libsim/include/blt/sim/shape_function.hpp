#pragma once
// Shape functions on a regular background grid, evaluated per axis and combined as a tensor product.
// - linear: the standard MPM hat function (support one cell each side); has cell-crossing noise.
// - uGIMP: the generalized interpolation material point function for a particle domain of half-width lp
//   that keeps its initial size (Bardenhagen and Kober 2004; seed 001 sec. 2). Its gradient is continuous,
//   which removes the noise when particles cross cell faces. Support h + lp each side.
// Both are evaluated on a fixed three-node stencil per axis starting at `base`, so the scatter and gather
// loops have one shape; the linear function leaves the third weight zero.

#include <cmath>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace blt::sim {

enum class ShapeFunctionKind { linear, uGimp };

inline constexpr int kStencil = 3;  // nodes per axis touched by one particle

// One node's weight N_I and gradient dN_I/dx for the signed distance d = x_p - x_I (m), cell size h, invH = 1/h.
inline void linearNode(double d, double h, double invH, double& w, double& g) {
  const double ad = std::fabs(d);
  if (ad < h) {
    w = 1.0 - ad * invH;
    g = d < 0 ? invH : -invH;
  } else {
    w = 0.0;
    g = 0.0;
  }
}

// uGIMP for a particle of half-width lp (requires lp <= h/2 so that three nodes cover the support h + lp).
// invH = 1/h and invHLp = 1/(h lp) come from the caller, which divides once per particle and axis instead of
// twice per node.
inline void uGimpNode(double d, double h, double lp, double invH, double invHLp, double& w, double& g) {
  const double ad = std::fabs(d);
  const double sgn = d < 0 ? -1.0 : 1.0;
  if (ad < lp) {
    w = 1.0 - (d * d + lp * lp) * (0.5 * invHLp);
    g = -d * invHLp;
  } else if (ad < h - lp) {
    w = 1.0 - ad * invH;
    g = -sgn * invH;
  } else if (ad < h + lp) {
    const double r = h + lp - ad;
    w = r * r * (0.25 * invHLp);
    g = -sgn * r * (0.5 * invHLp);
  } else {
    w = 0.0;
    g = 0.0;
  }
}

// max(x, 0) as one instruction: GCC compiles std::max(x, 0.0) to a compare and a branch, which here is taken at
// random.
inline double positivePart(double x) {
#if defined(__SSE2__)
  return _mm_cvtsd_f64(_mm_max_sd(_mm_set_sd(x), _mm_setzero_pd()));
#else
  return x > 0 ? x : 0.0;
#endif
}

// uGIMP's weights and gradients at the three nodes base, base + 1, base + 2 for coordinate xi (relative to node 0),
// where the particle's domain [xi - lp, xi + lp] lies within them (stencilBase's base). The same function as
// uGimpNode, in a form without branches: disturbed material puts each node in a different piece of uGimpNode at
// random, and the mispredicted branches cost more than the arithmetic (the 3D benchmark with points moved by a
// quarter cell spent 1.05 s in this stage with uGimpNode and 0.63 s with this form, 2 threads). For an outer node
// at distance d >= lp, w = (r^2 - e^2) / (4 h lp) with r = max(h + lp - d, 0) and e = max(h - lp - d, 0): the hat function's integral
// over the domain, which is uGimpNode's third piece where e = 0 and its linear piece where e > 0; the middle node
// takes what the outer two leave (partition of unity). An outer node is exactly zero exactly where uGimpNode's is
// (d >= h + lp, compared alike), so the stencil's 2-node compaction is unchanged; other values agree with
// uGimpNode to rounding.
inline void uGimpStencil(double xi, double h, double lp, int base, double invHLp, double w[3], double g[3]) {
  const double outer = h + lp, inner = h - lp;
  const double dFirst = xi - base * h;               // >= lp, up to rounding
  const double dLast = -(xi - (base + 2) * h);       // > h - lp
  const double rFirst = positivePart(outer - dFirst), eFirst = positivePart(inner - dFirst);
  const double rLast = positivePart(outer - dLast), eLast = positivePart(inner - dLast);
  const double quarter = 0.25 * invHLp, half = 0.5 * invHLp;
  w[0] = (rFirst - eFirst) * (rFirst + eFirst) * quarter;
  g[0] = -(rFirst - eFirst) * half;
  w[2] = (rLast - eLast) * (rLast + eLast) * quarter;
  g[2] = (rLast - eLast) * half;
  w[1] = 1.0 - w[0] - w[2];
  g[1] = -(g[0] + g[2]);
}

// Nodes per axis that a particle touches.
inline int stencilSize(ShapeFunctionKind k) { return k == ShapeFunctionKind::linear ? 2 : 3; }

// First node of the stencil for coordinate xi (relative to node 0), clamped to [0, nodes - size].
inline int stencilBase(ShapeFunctionKind k, double xi, double h, double lp, int nodes) {
  const double s = k == ShapeFunctionKind::linear ? xi / h : (xi - lp) / h;
  const int b = static_cast<int>(std::floor(s));
  const int size = stencilSize(k);
  return b < 0 ? 0 : (b > nodes - size ? nodes - size : b);
}

// Weight and gradient of the stencil's node k.
inline void stencilNode(ShapeFunctionKind k, double xi, double h, double lp, double invH, double invHLp, int node,
                        double& w, double& g) {
  if (k == ShapeFunctionKind::linear)
    linearNode(xi - node * h, h, invH, w, g);
  else
    uGimpNode(xi - node * h, h, lp, invH, invHLp, w, g);
}

}  // namespace blt::sim
