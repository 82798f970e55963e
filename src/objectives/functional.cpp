#include "flexipde/functional_objective.hpp"
#include <cmath>

namespace flexipde {

PetscErrorCode FunctionalObjective::setup(MPI_Comm comm, Model &model, DM state_dm, bool integrated) {
  char fname[64] = "";
  PetscFunctionBeginUser;
  model_ = &model;
  integrated_ = integrated;
  const std::string names = model.functional_names();
  PetscCheck(!names.empty(), comm, PETSC_ERR_ARG_WRONG,
             "-objective_type functional%s: model %s offers no functional", integrated ? "_integral" : "", model.name());
  name_ = names.substr(0, names.find(','));
  std::snprintf(fname, sizeof(fname), "%s", name_.c_str());
  PetscOptionsBegin(comm, nullptr, "Objective from a model functional", "Objective");
  PetscCall(PetscOptionsString("-objective_functional", ("Functional F of the state: " + names).c_str(), "Objective",
                               fname, fname, sizeof(fname), nullptr));
  PetscCall(PetscOptionsReal("-objective_sign", "Sign s of J = s F (-1 maximises F)", "Objective", sign_, &sign_, nullptr));
  if (!integrated)
    PetscCall(PetscOptionsReal("-objective_target", "Target F*: J = 0.5 (F(U(T))/F* - 1)^2 instead of s F(U(T))",
                               "Objective", target_, &target_, &has_target_));
  PetscOptionsEnd();
  name_ = fname;
  PetscCheck(sign_ == 1 || sign_ == -1, comm, PETSC_ERR_ARG_OUTOFRANGE, "-objective_sign must be 1 or -1, got %g",
             (double)sign_);
  PetscCheck(!has_target_ || target_ != 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-objective_target must be non-zero");
  { // an unknown name fails here, before any solve
    OwnedVec U;
    PetscReal F;
    PetscCall(DMCreateGlobalVector(state_dm, U.out()));
    PetscCall(VecSet(U, 0.0));
    PetscCall(model.functional(name_.c_str(), U, &F, nullptr));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode FunctionalObjective::terminal(Vec UT, PetscReal *J, Vec dJdU) {
  PetscFunctionBeginUser;
  if (integrated_) {
    *J = 0;
    if (dJdU) PetscCall(VecSet(dJdU, 0.0));
    PetscFunctionReturn(0);
  }
  PetscReal F;
  PetscCall(model_->functional(name_.c_str(), UT, &F, dJdU));
  if (has_target_) {
    const PetscReal r = F / target_ - 1;
    *J = 0.5 * r * r;
    if (dJdU) PetscCall(VecScale(dJdU, r / target_));
  } else {
    *J = sign_ * F;
    if (dJdU) PetscCall(VecScale(dJdU, sign_));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode FunctionalObjective::integrand(PetscReal, Vec U, PetscReal *r) {
  PetscFunctionBeginUser;
  PetscCall(model_->functional(name_.c_str(), U, r, nullptr));
  *r *= sign_;
  PetscFunctionReturn(0);
}

PetscErrorCode FunctionalObjective::integrand_dU(PetscReal, Vec U, Vec drdU) {
  PetscReal F;
  PetscFunctionBeginUser;
  PetscCall(model_->functional(name_.c_str(), U, &F, drdU));
  PetscCall(VecScale(drdU, sign_));
  PetscFunctionReturn(0);
}

} // namespace flexipde
