#include "flexipde/objective.hpp"

namespace flexipde {

PetscErrorCode TerminalMisfit::setup(const Grid &grid, PetscInt component, PetscInt dof) {
  PetscFunctionBeginUser;
  component_ = component;
  dof_ = dof;
  PetscCall(DMCreateGlobalVector(grid.dm(), data_.out()));
  PetscCall(VecDuplicate(data_, work_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode TerminalMisfit::terminal(Vec UT, PetscReal *J, Vec dJdU) {
  PetscReal nrm;
  PetscFunctionBeginUser;
  if (dof_ == 1) PetscCall(VecCopy(UT, work_));
  else PetscCall(VecStrideGather(UT, component_, work_, INSERT_VALUES));
  PetscCall(VecAXPY(work_, -1.0, data_));
  PetscCall(VecNorm(work_, NORM_2, &nrm));
  *J = kind_ == Kind::L2 ? nrm : 0.5 * nrm * nrm;
  if (dJdU) {
    if (kind_ == Kind::L2) PetscCall(VecScale(work_, nrm > 0 ? 1.0 / nrm : 0.0));
    PetscCall(VecSet(dJdU, 0.0));
    if (dof_ == 1) PetscCall(VecCopy(work_, dJdU));
    else PetscCall(VecStrideScatter(work_, component_, dJdU, INSERT_VALUES));
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde
