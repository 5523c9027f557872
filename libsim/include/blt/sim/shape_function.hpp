#pragma once
// Shape functions on a regular background grid, evaluated per axis and combined as a tensor product.
// - linear: the standard MPM hat function (support one cell each side); has cell-crossing noise.
// - uGIMP: the generalized interpolation material point function for a particle domain of half-width lp
//   that keeps its initial size (Bardenhagen and Kober 2004; seed 001 sec. 2). Its gradient is continuous,
//   which removes the noise when particles cross cell faces. Support h + lp each side.
// Both are evaluated on a fixed three-node stencil per axis starting at `base`, so the scatter and gather
// loops have one shape; the linear function leaves the third weight zero.

#include <cmath>

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
