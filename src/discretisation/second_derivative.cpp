#include "flexipde/differentiator.hpp"

namespace flexipde {

PetscErrorCode SecondDerivative::from_options(MPI_Comm comm, const char *prefix, PetscInt default_order,
                                              SecondDerivative &d) {
  PetscInt order = default_order;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, prefix, "Finite-difference second derivative", "Differentiator");
  PetscCall(PetscOptionsInt("-fd_order", "Order of the centred second derivative (2, 4 or 8)", "SecondDerivative",
                            order, &order, nullptr));
  PetscOptionsEnd();
  PetscCall(d.set_order(order));
  PetscFunctionReturn(0);
}

PetscErrorCode SecondDerivative::set_order(PetscInt order) {
  PetscFunctionBeginUser;
  PetscCheck(order == 2 || order == 4 || order == 8, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
             "-fd_order %" PetscInt_FMT " is not offered: choose 2, 4 or 8", order);
  order_ = order;
  PetscFunctionReturn(0);
}

PetscInt SecondDerivative::row(const Grid &g, PetscInt i, Row &out) const {
  const PetscInt r = half_width(), n = g.n();
  const PetscReal ih2 = 1.0 / (g.h() * g.h());
  PetscInt m = 0;
  for (PetscInt k = -r; k <= r; ++k) {
    PetscInt j = i + k;
    PetscReal s = 1.0;
    if (g.periodic()) {
      j = (j % n + n) % n;
    } else if (closure_ == Closure::ZeroOutside) {
      if (j < 0 || j > n - 1) continue; // zero outside the grid
    } else if (j < 0) { // odd reflection about the wall at index 0
      j = -j;
      s = -1.0;
    } else if (j > n - 1) {
      j = 2 * (n - 1) - j;
      s = -1.0;
    }
    if (!g.periodic() && closure_ == Closure::OddReflection && (j == 0 || j == n - 1)) continue; // wall value is zero
    PetscReal wk = s * weight((int)order_, (int)(k < 0 ? -k : k)) * ih2;
    bool merged = false;
    for (PetscInt q = 0; q < m; ++q)
      if (out[q].j == j) {
        out[q].weight += wk;
        merged = true;
      }
    if (!merged) out[m++] = {j, wk};
  }
  return m;
}

} // namespace flexipde
