// Example: 1D full-waveform inversion of a wave speed from a final snapshot.
//
// Math. The acoustic wave equation u_tt = c(x)^2 u_xx on [0,1] with u = 0 at both ends is written
// as the first-order system U = (u, v), u_t = v, v_t = c^2 u_xx, and integrated by PETSc's TS.
// From data d = u(T; c_true) we minimise
//     J(c) = 0.5 ||u(T; c) - d||^2   (+ 0.5 alpha sum (c_{i+1} - c_i)^2 / h  for a field c)
// with TAO. The gradient dJ/dc is the exact discrete adjoint of the integrator (TSAdjoint):
//     lambda(T) = dJ/dU(T),  lambda' = -(dG/dU)^T lambda,  dJ/dc = int (dG/dc)^T lambda dt + (dU0/dc)^T lambda(0),
// one backward sweep whatever the number of unknowns in c.
//
// Sample runs (as root add --allow-run-as-root to mpiexec):
//   mpiexec -n 2 build/fwi_1d -da_grid_x 201 -ts_max_time 0.3 -ts_dt 1e-3 -wave_c 0.8 -true_wave_c 1.0 -tao_monitor
//   mpiexec -n 2 build/fwi_1d -da_grid_x 201 -ts_max_time 0.6 -ts_dt 1e-3 -wave_c_field 1 -wave_c 1.0 \
//           -true_wave_c_profile gaussian -true_wave_c 1.0 -true_wave_c_bump 0.1 -inv_tikhonov 1e-3 \
//           -inv_lower 0.5 -inv_upper 2 -tao_max_it 30 -tao_monitor
#include "flexipde/inversion.hpp"
#include "flexipde/io.hpp"
#include "flexipde/scene.hpp"

using namespace flexipde;

static PetscErrorCode run() {
  MPI_Comm comm = PETSC_COMM_WORLD;
  PetscFunctionBeginUser;
  // 1. The scene: grid, wave model, parameter layout, objective, integrator, all from options.
  Scene scene;
  PetscCall(scene.setup(comm));

  // 2. Parameters: the true ones make the data, the initial ones start the inversion.
  OwnedVec p, p_true, g;
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.params.create_vec(p_true.out()));
  PetscCall(scene.params.create_vec(g.out()));
  PetscCall(scene.parameters_from_options("", p));
  PetscCall(scene.parameters_from_options("true_", p_true));

  // 3. Synthetic data d = u(T; c_true).
  PetscCall(scene.make_synthetic_data(p_true));

  // 4. One gradient, as a user would inspect it before optimising.
  PetscReal J, gnorm;
  PetscCall(scene.sim.gradient(p, &J, g, nullptr));
  PetscCall(VecNorm(g, NORM_2, &gnorm));
  PetscCall(PetscPrintf(comm, "initial J = %.6e, ||dJ/dc|| = %.6e, %" PetscInt_FMT " steps of %s\n", (double)J,
                        (double)gnorm, scene.sim.stats().steps, scene.sim.stats().ts_type));

  // 5. Invert with TAO (BLMVM unless -tao_type says otherwise).
  Inversion inv;
  PetscReal e0, e1;
  PetscCall(inv.setup(scene, p_true));
  PetscCall(inv.rmse(p, &e0));
  PetscCall(inv.solve(p));
  PetscCall(inv.rmse(p, &e1));
  PetscCall(PetscPrintf(comm, "parameter RMSE %.3e -> %.3e in %zu iterations\n", (double)e0, (double)e1,
                        inv.history().size() - 1));

  // 6. Save the recovered field (or scalar) next to the truth for plotting.
  char out[PETSC_MAX_PATH_LEN] = "";
  PetscCall(PetscOptionsGetString(nullptr, nullptr, "-output", out, sizeof(out), nullptr));
  if (out[0]) {
    H5Writer w;
    PetscCall(w.open(comm, out));
    PetscCall(w.write_coordinates(scene.grid));
    PetscCall(w.write_vec("/parameters", "recovered", p));
    PetscCall(w.write_vec("/parameters", "true", p_true));
    PetscCall(w.close());
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, "1D full-waveform inversion example\n"));
  // An error ends every rank at once with a non-zero exit (MPI_Abort), even if it was raised on
  // one rank only: no rank is left waiting in a collective call.
  PetscErrorCode ierr = run();
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr);
  PetscCall(PetscFinalize());
  return 0;
}
