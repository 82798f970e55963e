#include "flexipde/taylor.hpp"
#include <cmath>

namespace flexipde {

PetscErrorCode taylor_test(const ValueAndGradient &f, Vec p, Vec d, PetscReal eps0, PetscInt levels, TaylorResult &out) {
  OwnedVec g, q, gq;
  PetscReal J0;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(p, g.out()));
  PetscCall(VecDuplicate(p, q.out()));
  PetscCall(VecDuplicate(p, gq.out()));
  PetscCall(f(p, &J0, g));
  PetscScalar gd;
  PetscCall(VecDot(g, d, &gd));
  out = TaylorResult();
  out.gd = PetscRealPart(gd);
  PetscReal eps = eps0;
  for (PetscInt k = 0; k < levels; ++k, eps *= 0.5) {
    PetscReal J;
    PetscCall(VecWAXPY(q, eps, d, p));
    PetscCall(f(q, &J, gq));
    out.eps.push_back(eps);
    out.r1.push_back(std::fabs(J - J0));
    out.r2.push_back(std::fabs(J - J0 - eps * out.gd));
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde
