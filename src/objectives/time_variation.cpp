#include "flexipde/objective.hpp"

namespace flexipde {

PetscErrorCode TimeVariation::setup(Model &model, DM state_dm, bool with_parameters) {
  PetscFunctionBeginUser;
  model_ = &model;
  PetscCall(DMCreateGlobalVector(state_dm, G_.out()));
  PetscCall(model.create_jacobian(J_.out()));
  if (with_parameters) PetscCall(model.create_jacobian_p(Jp_.out()));
  PetscFunctionReturn(0);
}

// No terminal part: the whole objective is the integral.
PetscErrorCode TimeVariation::terminal(Vec, PetscReal *J, Vec dJdU) {
  PetscFunctionBeginUser;
  *J = 0;
  if (dJdU) PetscCall(VecSet(dJdU, 0.0));
  PetscFunctionReturn(0);
}

PetscErrorCode TimeVariation::integrand(PetscReal t, Vec U, PetscReal *r) {
  PetscReal nrm;
  PetscFunctionBeginUser;
  PetscCall(model_->rhs(t, U, G_));
  PetscCall(VecNorm(G_, NORM_2, &nrm));
  *r = nrm * nrm;
  PetscFunctionReturn(0);
}

// 2 (dG/dU)^T G. The Jacobian is assembled at every call: TSAdjoint asks at each stage, and the
// objective cannot tell whether the parameters changed since the last call.
PetscErrorCode TimeVariation::integrand_dU(PetscReal t, Vec U, Vec drdU) {
  PetscFunctionBeginUser;
  PetscCall(model_->rhs(t, U, G_));
  PetscCall(model_->rhs_jacobian(t, U, J_));
  PetscCall(MatMultTranspose(J_, G_, drdU));
  PetscCall(VecScale(drdU, 2.0));
  PetscFunctionReturn(0);
}

// 2 (dG/dp)^T G. A model's dG/dp may be a shell that records the state in the model itself
// (advection does); TSAdjoint asks for the model's and the integrand's dG/dp at the same (t, U)
// one after the other, so the recorded state is the same either way.
PetscErrorCode TimeVariation::integrand_dp(PetscReal t, Vec U, Vec drdp) {
  PetscFunctionBeginUser;
  if (!Jp_) {
    PetscCall(VecSet(drdp, 0.0));
    PetscFunctionReturn(0);
  }
  PetscCall(model_->rhs(t, U, G_));
  PetscCall(model_->rhs_jacobian_p(t, U, Jp_));
  PetscCall(MatMultTranspose(Jp_, G_, drdp));
  PetscCall(VecScale(drdp, 2.0));
  PetscFunctionReturn(0);
}

} // namespace flexipde
