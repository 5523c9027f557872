#pragma once
// Update schemes as strategy objects: each is the order in which one explicit step calls the solver's stages.
// MUSL (seed 001 sec. 2) maps the updated particle momenta back to the grid before the strain increment is
// computed; USL uses the grid velocities of the momentum update directly.

#include "blt/sim/solver.hpp"

namespace blt::sim {

class UpdateSchemeBase {
 public:
  virtual ~UpdateSchemeBase() = default;
  virtual const char* name() const = 0;
};

template <int D>
class UpdateScheme : public UpdateSchemeBase {
 public:
  virtual void advance(Solver<D>& s) const = 0;
};

template <int D>
class Musl final : public UpdateScheme<D> {
 public:
  const char* name() const override { return "MUSL"; }
  void advance(Solver<D>& s) const override {
    s.computeShapeFunctions();
    s.particlesToGrid();
    s.integrateGrid();
    s.gridToParticles();
    s.remapMomentum();
    s.updateStress();
  }
};

template <int D>
class Usl final : public UpdateScheme<D> {
 public:
  const char* name() const override { return "USL"; }
  void advance(Solver<D>& s) const override {
    s.computeShapeFunctions();
    s.particlesToGrid();
    s.integrateGrid();
    s.gridToParticles();
    s.updateStress();
  }
};

}  // namespace blt::sim
