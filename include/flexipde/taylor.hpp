// Taylor test of a gradient: along a direction d, with eps halving,
//   r1(eps) = |J(p + eps d) - J(p)|                  falls like eps   (ratio ~2 per halving)
//   r2(eps) = |J(p + eps d) - J(p) - eps g(p).d|     falls like eps^2 (ratio ~4 per halving)
// if and only if g is the derivative of J.
#pragma once
#include "flexipde/petsc.hpp"
#include <functional>
#include <vector>

namespace flexipde {

using ValueAndGradient = std::function<PetscErrorCode(Vec p, PetscReal *J, Vec g)>;

struct TaylorResult {
  std::vector<PetscReal> eps, r1, r2;
  PetscReal gd = 0; // directional derivative g.d
  PetscReal ratio1(size_t k) const { return r1[k - 1] / r1[k]; }
  PetscReal ratio2(size_t k) const { return r2[k - 1] / r2[k]; }
};

PetscErrorCode taylor_test(const ValueAndGradient &f, Vec p, Vec d, PetscReal eps0, PetscInt levels, TaylorResult &out);

} // namespace flexipde
