// A Scene is what a user sets up with options: grid, model, parameters, objective, simulation.
// It creates only what the chosen model declares (a scalar parameter allocates no field).
//
// Options: -model wave (see model_names()), the grid's (-da_grid_x, -grid_x0, -grid_x1,
// -grid_periodic), the model's (-wave_*), parameter values (-wave_c, -wave_c_profile ...) and the
// values that generate synthetic data (-true_wave_c, -true_wave_c_profile ...), -objective_type
// (l2sq, l2: misfit with data; mean_square, time_variation: no data), -objective_component, and
// PETSc's -ts_* for the integrator.
//
// Shots in parallel (-shot_groups G, for -objective_type receivers): the ranks split into G groups of
// equal size (MPI_Comm_split), each holding its own copy of the scene on its ranks and running a
// contiguous block of the shots. value() and gradient() take p in this scene's layout (every rank's),
// hand it to the groups, and sum the misfits and gradients of all groups back into it (a PetscSF
// between the two layouts), so that TAO and everything else see one scene. Monitors (-ts_monitor)
// print once per group.
#pragma once
#include "flexipde/model.hpp"
#include "flexipde/objective.hpp"
#include "flexipde/simulation.hpp"
#include <memory>

namespace flexipde {

struct SceneDefaults {
  std::string model = "wave";
  GridOptions grid;
  PetscReal dt = 5e-4, final_time = 2.5;
};

class Scene {
public:
  PetscErrorCode setup(MPI_Comm comm, const SceneDefaults &defaults = SceneDefaults());

  // Parameter values from options: "" gives the working/initial values (-wave_c ...), "true_"
  // the values that generate synthetic data (-true_wave_c ...).
  PetscErrorCode parameters_from_options(const char *prefix, Vec p) const;
  // Runs the model with p_true and stores the objective's component of U(T) as the data; an
  // objective without data (mean_square) needs none, and nothing is run.
  PetscErrorCode make_synthetic_data(Vec p_true);
  // J(p) (and its gradient) of the scene: the Simulation's, summed over the shots of a survey
  // (-objective_type receivers), one forward (and adjoint) solve per shot.
  PetscErrorCode value(Vec p, PetscReal *J);
  PetscErrorCode gradient(Vec p, PetscReal *J, Vec grad_p);
  // The survey's data and sources low-pass filtered at f_c (Survey::set_band; f_c <= 0: the whole
  // band), after make_synthetic_data. Refused without a survey.
  PetscErrorCode set_frequency_band(PetscReal f_c);

  MPI_Comm comm() const { return comm_; }
  // The simulation that ran the last shots (the group's with -shot_groups), for its statistics.
  const Simulation &solver() const { return group_ ? group_->sim : sim; }
  PetscInt shot_groups() const { return groups_; }
  Grid grid;
  OwnedDM state_dm;
  std::unique_ptr<Model> model;
  Parameters params;
  SelectedObjective objective;
  Simulation sim;

  ~Scene();

private:
  // The shots [first, end) this scene runs (all of them when not a group's).
  PetscInt first_shot() const { return first_shot_; }
  PetscInt end_shot() const;
  PetscErrorCode setup_groups(const SceneDefaults &defaults);
  PetscErrorCode to_group(Vec p); // group_p_ = p in the group's layout

  MPI_Comm comm_ = MPI_COMM_NULL;
  PetscInt component_ = 0;
  PetscInt groups_ = 1, first_shot_ = 0, end_shot_ = -1;
  bool in_group_ = false;
  MPI_Comm group_comm_ = MPI_COMM_NULL; // owned, freed after group_
  std::unique_ptr<Scene> group_;
  PetscSF to_group_ = nullptr; // roots: this scene's parameter entries; leaves: the group's
  OwnedVec group_p_, group_g_;
};

} // namespace flexipde
