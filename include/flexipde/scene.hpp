// A Scene is what a user sets up with options: grid, model, parameters, objective, simulation.
// It creates only what the chosen model declares (a scalar parameter allocates no field).
//
// Options: -model wave (see model_names()), the grid's (-da_grid_x, -grid_x0, -grid_x1,
// -grid_periodic), the model's (-wave_*), parameter values (-wave_c, -wave_c_profile ...) and the
// values that generate synthetic data (-true_wave_c, -true_wave_c_profile ...), -objective_type
// (l2sq, l2: misfit with data; mean_square, time_variation: no data), -objective_component, and
// PETSc's -ts_* for the integrator.
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

  MPI_Comm comm() const { return comm_; }
  Grid grid;
  OwnedDM state_dm;
  std::unique_ptr<Model> model;
  Parameters params;
  SelectedObjective objective;
  Simulation sim;

private:
  MPI_Comm comm_ = MPI_COMM_NULL;
  PetscInt component_ = 0;
};

} // namespace flexipde
