#include "flexipde/trajectory_misfit.hpp"
#include <algorithm>

namespace flexipde {

PetscErrorCode TrajectoryMisfit::setup(DM grid_dm, PetscInt component, PetscInt dof, PetscReal weight) {
  PetscFunctionBeginUser;
  dm_ = grid_dm, component_ = component, dof_ = dof, weight_ = weight;
  PetscCall(DMCreateGlobalVector(grid_dm, work_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode TrajectoryMisfit::add_snapshot(PetscReal t, Vec d) {
  OwnedVec c;
  PetscFunctionBeginUser;
  PetscCheck(times_.empty() || t > times_.back(), PetscObjectComm((PetscObject)d), PETSC_ERR_ARG_WRONG,
             "TrajectoryMisfit: snapshot at t = %g after one at t = %g: times must increase", (double)t, (double)times_.back());
  PetscCall(VecDuplicate(d, c.out()));
  PetscCall(VecCopy(d, c));
  times_.push_back(t);
  data_.push_back(std::move(c));
  PetscFunctionReturn(0);
}

PetscErrorCode TrajectoryMisfit::data_at(PetscReal t, Vec d) const {
  PetscFunctionBeginUser;
  PetscCheck(!times_.empty(), PetscObjectComm((PetscObject)d), PETSC_ERR_ORDER, "TrajectoryMisfit: no snapshots");
  const size_t n = times_.size();
  if (n == 1 || t <= times_.front()) PetscCall(VecCopy(data_.front(), d));
  else if (t >= times_.back()) PetscCall(VecCopy(data_.back(), d));
  else {
    const size_t k = std::upper_bound(times_.begin(), times_.end(), t) - times_.begin(); // times_[k-1] <= t < times_[k]
    const PetscReal s = (t - times_[k - 1]) / (times_[k] - times_[k - 1]);
    PetscCall(VecAXPBYPCZ(d, 1 - s, s, 0.0, data_[k - 1], data_[k]));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode TrajectoryMisfit::residual(PetscReal t, Vec U) {
  OwnedVec u;
  PetscFunctionBeginUser;
  PetscCall(data_at(t, work_));
  if (dof_ == 1) PetscCall(VecAYPX(work_, -1.0, U)); // u - d
  else {
    PetscCall(VecDuplicate(work_, u.out()));
    PetscCall(VecStrideGather(U, component_, u, INSERT_VALUES));
    PetscCall(VecAYPX(work_, -1.0, u));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode TrajectoryMisfit::terminal(Vec, PetscReal *J, Vec dJdU) {
  PetscFunctionBeginUser;
  *J = 0;
  if (dJdU) PetscCall(VecSet(dJdU, 0.0));
  PetscFunctionReturn(0);
}

PetscErrorCode TrajectoryMisfit::integrand(PetscReal t, Vec U, PetscReal *r) {
  PetscReal nrm;
  PetscFunctionBeginUser;
  PetscCall(residual(t, U));
  PetscCall(VecNorm(work_, NORM_2, &nrm));
  *r = 0.5 * weight_ * nrm * nrm;
  PetscFunctionReturn(0);
}

PetscErrorCode TrajectoryMisfit::integrand_dU(PetscReal t, Vec U, Vec drdU) {
  PetscFunctionBeginUser;
  PetscCall(residual(t, U));
  PetscCall(VecScale(work_, weight_));
  if (dof_ == 1) PetscCall(VecCopy(work_, drdU));
  else {
    PetscCall(VecSet(drdU, 0.0));
    PetscCall(VecStrideScatter(work_, component_, drdU, INSERT_VALUES));
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde
