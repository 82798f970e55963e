#include "flexipde/scene.hpp"
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
  if (!objective.data()) PetscFunctionReturn(0);
  PetscCall(DMCreateGlobalVector(state_dm, U.out()));
  PetscCall(sim.forward(p_true, U));
  if (model->dof() == 1) PetscCall(VecCopy(U, objective.data()));
  else PetscCall(VecStrideGather(U, component_, objective.data(), INSERT_VALUES));
  PetscFunctionReturn(0);
}

} // namespace flexipde
