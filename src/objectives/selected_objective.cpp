#include "flexipde/functional_objective.hpp"
#include "flexipde/objective.hpp"
#include "flexipde/survey.hpp"
#include <cstring>

namespace flexipde {

PetscErrorCode SelectedObjective::setup(const Grid &grid, PetscInt component, PetscInt dof, Model *model, DM state_dm,
                                        bool with_parameters) {
  const char *types[] = {"l2sq", "l2", "mean_square", "time_variation", "receivers", "functional", "functional_integral"};
  PetscInt type = 0;
  PetscFunctionBeginUser;
  PetscOptionsBegin(grid.comm(), nullptr, "Objective", "Objective");
  PetscCall(PetscOptionsEList("-objective_type",
                              "Objective of U(T): l2sq = 0.5||u(T)-d||^2, l2 = ||u(T)-d|| (data d from the true "
                              "parameters), mean_square = mean_i u_i(T)^2 (no data), time_variation = int_0^T "
                              "||u_t||^2 dt (no data), receivers = sum_shots 0.5 int sum_r (u(x_r,t)-d_r(t))^2 dt "
                              "(-survey_* options), functional = a functional F of U(T) named by -objective_functional (e.g. "
                              "vlasov's field_energy), functional_integral = int_0^T F dt",
                              "Objective", types, 7, types[type], &type, nullptr));
  PetscOptionsEnd();
  misfit_ = nullptr;
  survey_ = nullptr;
  if (!std::strcmp(types[type], "functional") || !std::strcmp(types[type], "functional_integral")) {
    PetscCheck(model && state_dm, grid.comm(), PETSC_ERR_ARG_WRONG,
               "-objective_type %s needs the model (SelectedObjective::setup with a Model)", types[type]);
    auto fo = std::make_unique<FunctionalObjective>();
    PetscCall(fo->setup(grid.comm(), *model, state_dm, !std::strcmp(types[type], "functional_integral")));
    chosen_ = std::move(fo);
  } else if (type == 4) {
    PetscCheck(model && state_dm, grid.comm(), PETSC_ERR_ARG_WRONG,
               "-objective_type receivers needs the model (SelectedObjective::setup with a Model)");
    auto sv = std::make_unique<Survey>();
    PetscCall(sv->setup(grid, *model, state_dm, component, dof));
    survey_ = sv.get();
    chosen_ = std::move(sv);
  } else if (type == 3) {
    PetscCheck(model && state_dm, grid.comm(), PETSC_ERR_ARG_WRONG,
               "-objective_type time_variation needs the model (SelectedObjective::setup with a Model)");
    auto tv = std::make_unique<TimeVariation>();
    PetscCall(tv->setup(*model, state_dm, with_parameters));
    chosen_ = std::move(tv);
  } else if (type == 2) {
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
