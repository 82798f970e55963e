#include "flexipde/objective.hpp"

namespace flexipde {

PetscErrorCode MeanSquare::setup(const Grid &grid, PetscInt component, PetscInt dof) {
  PetscFunctionBeginUser;
  component_ = component;
  dof_ = dof;
  n_ = grid.points();
  PetscCall(DMCreateGlobalVector(grid.dm(), work_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode MeanSquare::terminal(Vec UT, PetscReal *J, Vec dJdU) {
  PetscReal nrm;
  PetscFunctionBeginUser;
  if (dof_ == 1) PetscCall(VecCopy(UT, work_));
  else PetscCall(VecStrideGather(UT, component_, work_, INSERT_VALUES));
  PetscCall(VecNorm(work_, NORM_2, &nrm));
  *J = nrm * nrm / n_;
  if (dJdU) {
    PetscCall(VecScale(work_, 2.0 / n_));
    PetscCall(VecSet(dJdU, 0.0));
    if (dof_ == 1) PetscCall(VecCopy(work_, dJdU));
    else PetscCall(VecStrideScatter(work_, component_, dJdU, INSERT_VALUES));
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde
