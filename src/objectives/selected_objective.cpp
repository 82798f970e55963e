#include "flexipde/objective.hpp"

namespace flexipde {

PetscErrorCode SelectedObjective::setup(const Grid &grid, PetscInt component, PetscInt dof) {
  const char *types[] = {"l2sq", "l2", "mean_square"};
  PetscInt type = 0;
  PetscFunctionBeginUser;
  PetscOptionsBegin(grid.comm(), nullptr, "Objective", "Objective");
  PetscCall(PetscOptionsEList("-objective_type",
                              "Objective of U(T): l2sq = 0.5||u(T)-d||^2, l2 = ||u(T)-d|| (data d from the true "
                              "parameters), mean_square = mean_i u_i(T)^2 (no data)",
                              "Objective", types, 3, types[type], &type, nullptr));
  PetscOptionsEnd();
  misfit_ = nullptr;
  if (type == 2) {
    auto ms = std::make_unique<MeanSquare>();
    PetscCall(ms->setup(grid, component, dof));
    chosen_ = std::move(ms);
  } else {
    auto mf = std::make_unique<TerminalMisfit>();
    PetscCall(mf->setup(grid, component, dof));
    mf->set_kind(type == 1 ? TerminalMisfit::Kind::L2 : TerminalMisfit::Kind::L2Squared);
    misfit_ = mf.get();
    chosen_ = std::move(mf);
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SelectedObjective::terminal(Vec UT, PetscReal *J, Vec dJdU) {
  PetscFunctionBeginUser;
  PetscCheck(chosen_, PETSC_COMM_SELF, PETSC_ERR_ORDER, "SelectedObjective::setup() must come first");
  PetscCall(chosen_->terminal(UT, J, dJdU));
  PetscFunctionReturn(0);
}

} // namespace flexipde
