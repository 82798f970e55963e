// Spatial differentiation on a Grid.
//
// SecondDerivative: centred finite differences of order 2 or 4 for d^2/dx^2.
//   order 2: (u_{i-1} - 2u_i + u_{i+1}) / h^2
//   order 4: (-u_{i-2} + 16u_{i-1} - 30u_i + 16u_{i+1} - u_{i+2}) / (12 h^2)
// Closures of a non-periodic grid:
//   OddReflection (default): u = 0 at x0 and x1, the two end points are walls without a row; values
//     beyond a wall are the odd reflection of the interior (u_{-k} = -u_k), which keeps the operator
//     symmetric and, for solutions with u = u_xx = 0 at the wall (the wave equation's), fourth-order
//     accurate up to the wall.
//   ZeroOutside: every one of the n points has a row and the values outside the grid are 0 (the
//     stencil is cut at the ends): the operator of a loop that updates all n points with zero
//     neighbours beyond them, symmetric as well.
// Periodic grids wrap. Options: -fd_order 2|4.
#pragma once
#include "flexipde/grid.hpp"
#include <array>

namespace flexipde {

struct StencilEntry {
  PetscInt j;       // global grid index in [0, n)
  PetscReal weight; // already divided by h^2
};

class SecondDerivative {
public:
  enum class Closure { OddReflection, ZeroOutside };
  static PetscErrorCode from_options(MPI_Comm comm, const char *prefix, PetscInt default_order, SecondDerivative &d);
  static PetscInt half_width_for(PetscInt order) { return order / 2; }
  PetscErrorCode set_order(PetscInt order);
  void set_closure(Closure c) { closure_ = c; }
  Closure closure() const { return closure_; }

  PetscInt order() const { return order_; }
  PetscInt half_width() const { return order_ / 2; }
  // The stencil of point i (with OddReflection not a wall point); returns the number of entries.
  // Reflected entries that land on the same index are merged.
  PetscInt row(const Grid &g, PetscInt i, std::array<StencilEntry, 5> &out) const;
  // Largest |eigenvalue| of the operator on grid spacing h (for stability limits).
  PetscReal spectral_radius(PetscReal h) const { return (order_ == 2 ? 4.0 : 16.0 / 3.0) / (h * h); }

private:
  PetscInt order_ = 2;
  Closure closure_ = Closure::OddReflection;
};

} // namespace flexipde
