#include "flexipde/scene.hpp"
#include "flexipde/survey.hpp"
#include <cstring>

namespace flexipde {

PetscErrorCode Scene::setup(MPI_Comm comm, const SceneDefaults &d) {
  char model_name[64];
  char component[64] = "";
  PetscFunctionBeginUser;
  comm_ = comm;
  std::strncpy(model_name, d.model.c_str(), sizeof(model_name) - 1);
  model_name[sizeof(model_name) - 1] = 0;
  PetscOptionsBegin(comm, nullptr, "Scene", "Scene");
  PetscCall(PetscOptionsString("-model", ("Model: " + model_names()).c_str(), "Scene", model_name, model_name,
                               sizeof(model_name), nullptr));
  PetscCall(PetscOptionsString("-objective_component", "Component of U(T) compared with the data (default: the first)",
                               "Scene", component, component, sizeof(component), nullptr));
  PetscOptionsEnd();
  PetscCall(create_model(comm, model_name, model));
  {
    GridOptions g = d.grid;
    g.dim = model->dim();
    model->grid_defaults(g);
    PetscCall(Grid::from_options(comm, model->stencil_width(comm), g, grid));
  }
  PetscCall(grid.create_dm(model->dof(), state_dm.out()));
  PetscCall(model->setup(grid, state_dm, params));
  PetscCall(params.finalize(grid));
  component_ = 0;
  if (component[0]) {
    component_ = -1;
    for (PetscInt c = 0; c < model->dof(); ++c)
      if (!std::strcmp(component, model->component_name(c))) component_ = c;
    PetscCheck(component_ >= 0, comm, PETSC_ERR_ARG_WRONG, "-objective_component %s: model %s has no such component",
               component, model->name());
  }
  PetscCall(objective.setup(grid, component_, model->dof(), model.get(), state_dm, params.global_size() > 0));
  PetscCall(sim.setup(*model, grid, state_dm, params));
  sim.set_default_time(d.dt, d.final_time);
  sim.set_objective(&objective);
  PetscFunctionReturn(0);
}

PetscErrorCode Scene::parameters_from_options(const char *prefix, Vec p) const {
  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < params.count(); ++k) {
    std::string key = std::string(prefix) + params.info(k).name;
    PetscCall(fill_from_options(params, k, key.c_str(), params.info(k).initial, p));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Scene::make_synthetic_data(Vec p_true) {
  OwnedVec U;
  PetscFunctionBeginUser;
  if (Survey *sv = objective.survey()) {
    // Observed traces from -survey_data_file, else recorded from p_true at every step.
    PetscBool read;
    PetscCall(sim.check_options()); // fixes dt and T
    PetscCall(sv->read_data(sim.stats().final_time, &read));
    if (read) PetscFunctionReturn(0);
    PetscCall(DMCreateGlobalVector(state_dm, U.out()));
    PetscCall(sv->begin_recording(sim.stats().dt, sim.stats().final_time));
    for (PetscInt s = 0; s < sv->shots(); ++s) {
      PetscReal J;
      PetscCall(sv->select_shot(s));
      PetscCall(sim.initial_condition(p_true, U));
      PetscCall(sv->record_initial(U));
      PetscCall(sim.value(p_true, &J));
    }
    PetscCall(sv->end_recording());
    PetscCall(sv->select_shot(0));
    PetscFunctionReturn(0);
  }
  if (!objective.data()) PetscFunctionReturn(0);
  PetscCall(DMCreateGlobalVector(state_dm, U.out()));
  PetscCall(sim.forward(p_true, U));
  if (model->dof() == 1) PetscCall(VecCopy(U, objective.data()));
  else PetscCall(VecStrideGather(U, component_, objective.data(), INSERT_VALUES));
  PetscFunctionReturn(0);
}

} // namespace flexipde

namespace flexipde {

PetscErrorCode Scene::value(Vec p, PetscReal *J) {
  Survey *sv = objective.survey();
  PetscFunctionBeginUser;
  if (!sv) {
    PetscCall(sim.value(p, J));
    PetscFunctionReturn(0);
  }
  *J = 0;
  for (PetscInt s = 0; s < sv->shots(); ++s) {
    PetscReal Js;
    PetscCall(sv->select_shot(s));
    PetscCall(sim.value(p, &Js));
    *J += Js;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Scene::gradient(Vec p, PetscReal *J, Vec grad_p) {
  Survey *sv = objective.survey();
  OwnedVec gs;
  PetscFunctionBeginUser;
  if (!sv || sv->shots() == 1) {
    if (sv) PetscCall(sv->select_shot(0));
    PetscCall(sim.gradient(p, J, grad_p, nullptr));
    PetscFunctionReturn(0);
  }
  *J = 0;
  if (grad_p) {
    PetscCall(VecSet(grad_p, 0.0));
    PetscCall(VecDuplicate(grad_p, gs.out()));
  }
  for (PetscInt s = 0; s < sv->shots(); ++s) {
    PetscReal Js;
    PetscCall(sv->select_shot(s));
    PetscCall(sim.gradient(p, &Js, gs, nullptr));
    *J += Js;
    if (grad_p) PetscCall(VecAXPY(grad_p, 1.0, gs));
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde
