#include "flexipde/scene.hpp"
#include "flexipde/survey.hpp"
#include <array>
#include <cstring>
#include <map>

namespace flexipde {

PetscErrorCode Scene::setup(MPI_Comm comm, const SceneDefaults &d) {
  char model_name[64];
  char component[64] = "";
  PetscFunctionBeginUser;
  comm_ = comm;
  std::strncpy(model_name, d.model.c_str(), sizeof(model_name) - 1);
  model_name[sizeof(model_name) - 1] = 0;
  PetscOptionsBegin(comm, nullptr, "Scene", "Scene");
  if (!in_group_)
    PetscCall(PetscOptionsInt("-shot_groups", "Split the ranks into this many groups, each running a block of the "
                              "shots on its own copy of the grid (-objective_type receivers)", "Scene", groups_, &groups_,
                              nullptr));
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
  if (groups_ != 1) PetscCall(setup_groups(d));
  PetscFunctionReturn(0);
}

Scene::~Scene() {
  group_.reset();
  if (to_group_) (void)PetscSFDestroy(&to_group_);
  if (group_comm_ != MPI_COMM_NULL) (void)MPI_Comm_free(&group_comm_);
}

PetscInt Scene::end_shot() const {
  const Survey *sv = objective.survey();
  return end_shot_ >= 0 ? end_shot_ : sv ? sv->shots() : 1;
}

PetscErrorCode Scene::setup_groups(const SceneDefaults &d) {
  PetscMPIInt size, rank;
  Survey *sv = objective.survey();
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm_, &size));
  PetscCallMPI(MPI_Comm_rank(comm_, &rank));
  PetscCheck(groups_ >= 1 && size % groups_ == 0, comm_, PETSC_ERR_ARG_OUTOFRANGE,
             "-shot_groups %" PetscInt_FMT ": the %d ranks do not split into that many groups of equal size", groups_, size);
  PetscCheck(sv, comm_, PETSC_ERR_ARG_WRONG, "-shot_groups needs shots: -objective_type receivers with -survey_sources_x");
  PetscCheck(sv->shots() >= groups_, comm_, PETSC_ERR_ARG_OUTOFRANGE,
             "-shot_groups %" PetscInt_FMT " with %" PetscInt_FMT " shots: a group would have none", groups_, sv->shots());
  const PetscMPIInt per_group = size / (PetscMPIInt)groups_, color = rank / per_group;
  PetscCallMPI(MPI_Comm_split(comm_, color, rank, &group_comm_));
  group_ = std::make_unique<Scene>();
  group_->in_group_ = true;
  group_->first_shot_ = color * sv->shots() / groups_;
  group_->end_shot_ = (color + 1) * sv->shots() / groups_;
  PetscCall(group_->setup(group_comm_, d));
  group_->objective.survey()->fire_only(group_->first_shot_, group_->end_shot_);
  PetscCall(group_->params.create_vec(group_p_.out()));
  PetscCall(VecDuplicate(group_p_, group_g_.out()));

  // Where each of the group's parameter entries lives in this scene's layout: the scalars and vectors
  // at the same offsets on rank 0, a field's value at point (i, j, k) on the rank that owns (i, j, k),
  // at that field's offset there plus the point's index in its box.
  struct Box {
    PetscInt xs, ys, zs, xm, ym, zm, first_field; // owned box, and the local offset of the first field
  };
  constexpr int box_ints = sizeof(Box) / sizeof(PetscInt);
  PetscInt first_field = params.local_size();
  for (PetscInt k = 0; k < params.count(); ++k)
    if (params.info(k).kind == ParamKind::Field) first_field = std::min(first_field, params.info(k).local_offset);
  Box mine = {grid.xs(), grid.ys(), grid.zs(), grid.xm(), grid.ym(), grid.zm(), first_field};
  std::vector<Box> boxes(size);
  PetscCallMPI(MPI_Allgather(&mine, box_ints, MPIU_INT, boxes.data(), box_ints, MPIU_INT, comm_));
  // a box's first index for each column, row and layer
  std::vector<PetscInt> column(grid.n()), row(grid.ny()), layer(grid.nz());
  std::map<std::array<PetscInt, 3>, PetscMPIInt> owner;
  for (PetscMPIInt r = 0; r < size; ++r) {
    const Box &b = boxes[r];
    for (PetscInt i = b.xs; i < b.xs + b.xm; ++i) column[i] = b.xs;
    for (PetscInt j = b.ys; j < b.ys + b.ym; ++j) row[j] = b.ys;
    for (PetscInt k = b.zs; k < b.zs + b.zm; ++k) layer[k] = b.zs;
    owner[{b.xs, b.ys, b.zs}] = r;
  }
  const Grid &gg = group_->grid;
  const Parameters &gp = group_->params;
  std::vector<PetscSFNode> remote((size_t)gp.local_size());
  PetscInt field_ordinal = 0;
  for (PetscInt k = 0; k < gp.count(); ++k) {
    const ParamInfo &info = gp.info(k);
    if (info.kind != ParamKind::Field) {
      for (PetscInt e = 0; e < info.local_size; ++e) remote[info.local_offset + e] = {0, params.info(k).local_offset + e};
      continue;
    }
    for (PetscInt q = 0; q < info.local_size; ++q) {
      const PetscInt i = gg.xs() + q % gg.xm(), j = gg.ys() + (q / gg.xm()) % gg.ym();
      const PetscInt k = gg.zs() + q / (gg.xm() * gg.ym());
      const PetscMPIInt r = owner[{column[i], row[j], layer[k]}];
      const Box &b = boxes[r];
      remote[info.local_offset + q] = {r, b.first_field + field_ordinal * b.xm * b.ym * b.zm +
                                              ((k - b.zs) * b.ym + (j - b.ys)) * b.xm + (i - b.xs)};
    }
    ++field_ordinal;
  }
  PetscCall(PetscSFCreate(comm_, &to_group_));
  PetscCall(PetscSFSetGraph(to_group_, params.local_size(), gp.local_size(), nullptr, PETSC_COPY_VALUES, remote.data(),
                            PETSC_COPY_VALUES));
  PetscCall(PetscSFSetUp(to_group_));
  PetscFunctionReturn(0);
}

PetscErrorCode Scene::set_frequency_band(PetscReal f_c) {
  PetscFunctionBeginUser;
  PetscCheck(objective.survey(), comm_, PETSC_ERR_ARG_WRONG, "Frequency bands need a survey: -objective_type receivers");
  if (group_) PetscCall(group_->set_frequency_band(f_c));
  else PetscCall(objective.survey()->set_band(f_c));
  PetscFunctionReturn(0);
}

PetscErrorCode Scene::to_group(Vec p) {
  PetscFunctionBeginUser;
  ConstArray a(p);
  Array b(group_p_);
  PetscCall(a.error());
  PetscCall(b.error());
  PetscCall(PetscSFBcastBegin(to_group_, MPIU_SCALAR, a.data(), b.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(to_group_, MPIU_SCALAR, a.data(), b.data(), MPI_REPLACE));
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
  if (group_) {
    // Each group records (or reads) the traces of its shots; this scene gathers them (and writes them).
    PetscCall(to_group(p_true));
    PetscCall(group_->make_synthetic_data(group_p_));
    PetscCall(objective.survey()->gather_recording(*group_->objective.survey()));
    PetscFunctionReturn(0);
  }
  if (Survey *sv = objective.survey()) {
    // Observed traces from -survey_data_file, else recorded from p_true at every step.
    PetscBool read;
    PetscCall(sim.check_options()); // fixes dt and T
    PetscCall(sv->read_data(sim.stats().final_time, &read));
    if (read) PetscFunctionReturn(0);
    PetscCall(DMCreateGlobalVector(state_dm, U.out()));
    PetscCall(sv->begin_recording(sim.stats().dt, sim.stats().final_time));
    for (PetscInt s = first_shot(); s < end_shot(); ++s) {
      PetscReal J;
      PetscCall(sv->select_shot(s));
      PetscCall(sim.initial_condition(p_true, U));
      PetscCall(sv->record_initial(U));
      PetscCall(sim.value(p_true, &J));
    }
    PetscCall(sv->end_recording());
    PetscCall(sv->select_shot(first_shot()));
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

// The sum over the groups of a value every rank of each group holds (collective on the scene's ranks).
static PetscErrorCode sum_over_groups(MPI_Comm comm, MPI_Comm group, PetscReal *v) {
  PetscMPIInt grank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(group, &grank));
  PetscReal mine = grank == 0 ? *v : 0;
  PetscCallMPI(MPI_Allreduce(&mine, v, 1, MPIU_REAL, MPI_SUM, comm));
  PetscFunctionReturn(0);
}

PetscErrorCode Scene::value(Vec p, PetscReal *J) {
  Survey *sv = objective.survey();
  PetscFunctionBeginUser;
  if (group_) {
    PetscCall(to_group(p));
    PetscCall(group_->value(group_p_, J));
    PetscCall(sum_over_groups(comm_, group_comm_, J));
    PetscFunctionReturn(0);
  }
  if (!sv) {
    PetscCall(sim.value(p, J));
    PetscFunctionReturn(0);
  }
  *J = 0;
  for (PetscInt s = first_shot(); s < end_shot(); ++s) {
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
  if (group_) {
    PetscCall(to_group(p));
    PetscCall(group_->gradient(group_p_, J, grad_p ? group_g_.get() : nullptr));
    PetscCall(sum_over_groups(comm_, group_comm_, J));
    if (grad_p) {
      PetscCall(VecSet(grad_p, 0.0));
      ConstArray a(group_g_);
      Array b(grad_p);
      PetscCall(a.error());
      PetscCall(b.error());
      PetscCall(PetscSFReduceBegin(to_group_, MPIU_SCALAR, a.data(), b.data(), MPI_SUM));
      PetscCall(PetscSFReduceEnd(to_group_, MPIU_SCALAR, a.data(), b.data(), MPI_SUM));
    }
    PetscFunctionReturn(0);
  }
  if (!sv || end_shot() - first_shot() == 1) {
    if (sv) PetscCall(sv->select_shot(first_shot()));
    PetscCall(sim.gradient(p, J, grad_p, nullptr));
    PetscFunctionReturn(0);
  }
  *J = 0;
  if (grad_p) {
    PetscCall(VecSet(grad_p, 0.0));
    PetscCall(VecDuplicate(grad_p, gs.out()));
  }
  for (PetscInt s = first_shot(); s < end_shot(); ++s) {
    PetscReal Js;
    PetscCall(sv->select_shot(s));
    PetscCall(sim.gradient(p, &Js, gs, nullptr));
    *J += Js;
    if (grad_p) PetscCall(VecAXPY(grad_p, 1.0, gs));
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde
