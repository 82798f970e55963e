// Spatial differentiation on a Grid.
//
// SecondDerivative: centred finite differences of order 2, 4 or 8 for d^2/dx^2,
//   (w_0 u_i + sum_{k=1..R} w_k (u_{i-k} + u_{i+k})) / h^2,  R = order / 2:
//   order 2: w = 1 (-2, 1)
//   order 4: w = 1/12 (-30, 16, -1)
//   order 8: w = (-205/72, 8/5, -1/5, 8/315, -1/560)
// Closures of a non-periodic grid:
//   OddReflection (default): u = 0 at x0 and x1, the two end points are walls without a row; values
//     beyond a wall are the odd reflection of the interior (u_{-k} = -u_k), which keeps the operator
//     symmetric and, for solutions whose even derivatives vanish at the wall (u = u_xx = ... = 0, the
//     wave equation's standing modes), of the design order up to the wall.
//   ZeroOutside: every one of the n points has a row and the values outside the grid are 0 (the
//     stencil is cut at the ends): the operator of a loop that updates all n points with zero
//     neighbours beyond them, symmetric as well.
// Periodic grids wrap. Options: -fd_order 2|4|8.
//
// FirstDerivative: the centred first differences of the same orders for d/dx,
//   sum_{k=1..R} c_k (u_{i+k} - u_{i-k}) / h:
//   order 2: c = (1/2);  order 4: c = (2/3, -1/12);  order 8: c = (4/5, -1/5, 4/105, -1/280)
#pragma once
#include "flexipde/grid.hpp"
#include <array>

namespace flexipde {

struct StencilEntry {
  PetscInt j;       // global grid index in [0, n)
  PetscReal weight; // already divided by h^2
};

struct FirstDerivative {
  // c_k of the centred stencil of this order (2, 4 or 8), 1 <= k <= order / 2.
  static constexpr PetscReal weight(int order, int k) {
    constexpr PetscReal c2[1] = {0.5}, c4[2] = {2.0 / 3, -1.0 / 12}, c8[4] = {4.0 / 5, -1.0 / 5, 4.0 / 105, -1.0 / 280};
    return order == 2 ? c2[k - 1] : order == 4 ? c4[k - 1] : c8[k - 1];
  }
};

class SecondDerivative {
public:
  enum class Closure { OddReflection, ZeroOutside };
  static PetscErrorCode from_options(MPI_Comm comm, const char *prefix, PetscInt default_order, SecondDerivative &d);
  static PetscInt half_width_for(PetscInt order) { return order / 2; }
  static constexpr int max_half_width = 4;
  using Row = std::array<StencilEntry, 2 * max_half_width + 1>;
  // w_k of the centred stencil of this order (2, 4 or 8), 0 <= k <= order / 2.
  static constexpr PetscReal weight(int order, int k) {
    constexpr PetscReal w2[2] = {-2.0, 1.0}, w4[3] = {-30.0 / 12, 16.0 / 12, -1.0 / 12},
                        w8[5] = {-205.0 / 72, 8.0 / 5, -1.0 / 5, 8.0 / 315, -1.0 / 560};
    return order == 2 ? w2[k] : order == 4 ? w4[k] : w8[k];
  }
  PetscErrorCode set_order(PetscInt order);
  void set_closure(Closure c) { closure_ = c; }
  Closure closure() const { return closure_; }

  PetscInt order() const { return order_; }
  PetscInt half_width() const { return order_ / 2; }
  // The stencil of point i (with OddReflection not a wall point); returns the number of entries.
  // Reflected entries that land on the same index are merged.
  PetscInt row(const Grid &g, PetscInt i, Row &out) const;
  // Largest |eigenvalue| of the operator on grid spacing h (for stability limits): its symbol
  // -(w_0 + 2 sum_k w_k cos k theta) / h^2 at theta = pi, where it is largest (4, 16/3 and 6.50 / h^2).
  PetscReal spectral_radius(PetscReal h) const {
    PetscReal s = -weight((int)order_, 0);
    for (int k = 1; k <= half_width(); ++k) s -= 2 * weight((int)order_, k) * (k % 2 ? -1.0 : 1.0);
    return s / (h * h);
  }

private:
  PetscInt order_ = 2;
  Closure closure_ = Closure::OddReflection;
};

} // namespace flexipde
