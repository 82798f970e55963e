// Training a coarse-grid Burgers scheme through the solver's exact adjoint (Bar-Sinai et al. 2019).
//
// The flux weights theta of -model learned_burgers (src/models/learned_burgers.cpp) are fitted so that
// the coarse grid reproduces the fine-grid Burgers solution averaged onto its cells:
//
//   J(theta) = 1/(K T) sum_{k=1}^{K} int_0^T 0.5 h sum_i (u_i^k(t; theta) - ubar_i^k(t))^2 dt,
//
// u^k the coarse solution from the k-th random start (seed -train_seed + k), ubar^k the -model burgers
// solution on a grid -train_refine times finer (step dt / refine, RK4) cell-averaged at every coarse step
// and half step and linear in time between (TrajectoryMisfit). Each trajectory is one scene with its
// own forward and adjoint solve, like the shots of a survey; TAO (BLMVM by default) minimises the sum.
// sqrt(2 J) is the space-time RMS error. theta, its start and the history go to -output.
//
//   ./learned_burgers_train -tao_monitor                                  one stencil for the grid, 3 weights
//   mpiexec -n 2 ./learned_burgers_train -learned_burgers_weights network -tao_monitor -tao_max_it 60
//           -output results/learned_burgers.h5                           a network of 227 weights
//   ./learned_burgers_train -help                                        every option
// Defaults: 32 cells on [0, 1), nu = 0.01, dt = 0.005, T = 0.5, 4 trajectories from 3-mode starts of
// amplitude 1 (shocks form by t ~ 0.1), the reference 32 times finer (1024 cells: the Engquist-Osher
// reference is first order, and 8 times finer it is still about 3e-3 from the converged solution).
#include "flexipde/io.hpp"
#include "learned_burgers_common.hpp"
#include "flexipde/trajectory_misfit.hpp"
#include <cstring>
#include <memory>

using namespace flexipde;
using namespace learned;

static const char help[] = "Train the flux weights of -model learned_burgers against a fine-grid Burgers reference.\n";

struct Training {
  std::vector<std::unique_ptr<Scene>> scenes;
  std::vector<std::unique_ptr<TrajectoryMisfit>> misfits;
  std::vector<PetscReal> iteration, objective, gradient_norm, rmse, seconds;
  OwnedVec g_scene;
  double start = 0;
  PetscInt evaluations = 0;
};

// J and dJ/dtheta: one forward and one adjoint solve per trajectory.
static PetscErrorCode objective_gradient(Tao, Vec p, PetscReal *f, Vec g, void *ctx) {
  auto *tr = static_cast<Training *>(ctx);
  PetscFunctionBeginUser;
  *f = 0;
  PetscCall(VecSet(g, 0.0));
  for (auto &s : tr->scenes) {
    PetscReal J;
    PetscCall(s->gradient(p, &J, tr->g_scene));
    *f += J;
    PetscCall(VecAXPY(g, 1.0, tr->g_scene));
  }
  ++tr->evaluations;
  PetscFunctionReturn(0);
}

static PetscErrorCode monitor(Tao tao, void *ctx) {
  auto *tr = static_cast<Training *>(ctx);
  PetscInt its;
  PetscReal f, gnorm;
  PetscFunctionBeginUser;
  PetscCall(TaoGetSolutionStatus(tao, &its, &f, &gnorm, nullptr, nullptr, nullptr));
  tr->iteration.push_back(its), tr->objective.push_back(f), tr->gradient_norm.push_back(gnorm);
  tr->rmse.push_back(std::sqrt(2 * f)), tr->seconds.push_back(MPI_Wtime() - tr->start);
  PetscFunctionReturn(0);
}

static PetscErrorCode run(MPI_Comm comm) {
  PetscInt trajectories = 4, seed = 1, refine = 32;
  char output[PETSC_MAX_PATH_LEN] = "learned_burgers.h5";
  Settings s;
  Training tr;
  PetscFunctionBeginUser;
  // 1. Options: the training's own, and the coarse scene's (-da_grid_x, -ts_dt, -learned_burgers_*)
  PetscOptionsBegin(comm, nullptr, "Training a learned Burgers flux", "learned_burgers_train");
  PetscCall(PetscOptionsInt("-train_trajectories", "Number of reference trajectories (random starts)", "", trajectories,
                            &trajectories, nullptr));
  PetscCall(PetscOptionsInt("-train_seed", "Trajectory k starts from the random start of seed train_seed + k", "", seed,
                            &seed, nullptr));
  PetscCall(PetscOptionsInt("-train_refine", "Reference grid: this many times finer in space and time (even)", "", refine,
                            &refine, nullptr));
  PetscCall(PetscOptionsString("-output", "HDF5 file for theta and the history", "", output, output, sizeof(output), nullptr));
  PetscOptionsEnd();
  PetscCheck(trajectories > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-train_trajectories must be positive, got %" PetscInt_FMT,
             trajectories);
  PetscCheck(refine >= 2 && refine % 2 == 0, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "-train_refine must be even and at least 2 (snapshots at every coarse half step), got %" PetscInt_FMT, refine);
  {
    char model[64] = "learned_burgers";
    PetscCall(PetscOptionsGetString(nullptr, nullptr, "-model", model, sizeof(model), nullptr));
    PetscCheck(!std::strcmp(model, "learned_burgers"), comm, PETSC_ERR_ARG_WRONG,
               "learned_burgers_train trains -model learned_burgers, not %s", model);
  }
  PetscCall(s.from_options(comm));

  // 2. One coarse scene per trajectory, each with the fine reference averaged onto its cells as data
  const PetscReal weight = 1.0 / (s.n * trajectories * s.T); // h / (K T)
  for (PetscInt k = 0; k < trajectories; ++k) {
    auto scene = std::make_unique<Scene>();
    auto misfit = std::make_unique<TrajectoryMisfit>();
    std::vector<PetscReal> times;
    std::vector<OwnedVec> snaps;
    PetscCall(coarse_scene(comm, *scene, s.n, s.dt, s.T, seed + k, refine));
    PetscCall(fine_reference(comm, s, refine, seed + k, s.T, refine / 2, scene->grid, times, snaps));
    PetscCall(misfit->setup(scene->grid.dm(), 0, 1, weight));
    for (size_t m = 0; m < times.size(); ++m) PetscCall(misfit->add_snapshot(times[m], snaps[m]));
    scene->sim.set_objective(misfit.get());
    tr.scenes.push_back(std::move(scene));
    tr.misfits.push_back(std::move(misfit));
  }
  Scene &first = *tr.scenes[0];
  const PetscInt ktheta = first.params.find("learned_burgers_theta");
  OwnedVec p, p0;
  PetscCall(first.params.create_vec(p.out()));
  PetscCall(first.params.create_vec(tr.g_scene.out()));
  PetscCall(first.parameters_from_options("", p));
  PetscCall(VecDuplicate(p, p0.out()));
  PetscCall(VecCopy(p, p0));
  PetscCall(PetscPrintf(comm, "learned_burgers_train: %" PetscInt_FMT " cells, %" PetscInt_FMT " weights, %" PetscInt_FMT
                              " trajectories of %" PetscInt_FMT " steps, reference %" PetscInt_FMT " cells\n",
                        s.n, first.params.info(ktheta).entries, trajectories, s.steps(), s.n * refine));

  // 3. TAO minimises J; -tao_type, -tao_max_it, -tao_monitor, ... as usual
  OwnedTao tao;
  PetscCall(TaoCreate(comm, tao.out()));
  PetscCall(TaoSetType(tao, TAOBLMVM));
  PetscCall(TaoSetSolution(tao, p));
  PetscCall(TaoSetObjectiveAndGradient(tao, nullptr, objective_gradient, &tr));
  PetscCall(TaoSetMonitor(tao, monitor, &tr, nullptr));
  PetscCall(TaoSetMaximumIterations(tao, 40));
  PetscCall(TaoSetTolerances(tao, 1e-9, 1e-6, 0.0));
  PetscCall(TaoSetFromOptions(tao));
  PetscBool help = PETSC_FALSE;
  PetscCall(PetscOptionsHasHelp(nullptr, &help));
  if (help) PetscFunctionReturn(0);
  tr.start = MPI_Wtime();
  PetscCall(TaoSolve(tao));
  TaoConvergedReason reason;
  PetscCall(TaoGetConvergedReason(tao, &reason));
  PetscCheck(!tr.rmse.empty(), comm, PETSC_ERR_NOT_CONVERGED, "TAO stopped before its first iterate");
  PetscCall(PetscPrintf(comm,
                        "learned_burgers_train: %s after %" PetscInt_FMT " iterations, %" PetscInt_FMT
                        " gradients, %.1f s; space-time RMS error %.6e -> %.6e\n",
                        TaoConvergedReasons[reason], (PetscInt)tr.iteration.back(), tr.evaluations, MPI_Wtime() - tr.start,
                        (double)tr.rmse.front(), (double)tr.rmse.back()));

  // 4. theta, its start and the history
  std::vector<PetscReal> theta, theta0;
  PetscCall(first.params.vector_values(p, ktheta, theta));
  PetscCall(first.params.vector_values(p0, ktheta, theta0));
  if (theta.size() <= 8) {
    PetscCall(PetscPrintf(comm, "learned_burgers_train: theta ="));
    for (PetscReal x : theta) PetscCall(PetscPrintf(comm, " %.6f", (double)x));
    PetscCall(PetscPrintf(comm, "\n"));
  }
  if (output[0]) {
    H5Writer w;
    PetscCall(w.open(comm, output));
    PetscCall(w.write_series("/vectors", "learned_burgers_theta", theta));
    PetscCall(w.write_series("/vectors", "learned_burgers_theta_initial", theta0));
    PetscCall(w.write_series("/history", "iteration", tr.iteration));
    PetscCall(w.write_series("/history", "objective", tr.objective));
    PetscCall(w.write_series("/history", "gradient_norm", tr.gradient_norm));
    PetscCall(w.write_series("/history", "rmse", tr.rmse));
    PetscCall(w.write_series("/history", "seconds", tr.seconds));
    PetscCall(w.write_series("/train", "settings", {(PetscReal)s.n, s.dt, s.T, s.nu, s.amplitude, (PetscReal)s.modes,
                                                    (PetscReal)trajectories, (PetscReal)seed, (PetscReal)refine}));
    PetscCall(w.close());
    PetscCall(PetscPrintf(comm, "learned_burgers_train: theta and history written to %s (-learned_burgers_theta_file %s reads it)\n",
                          output, output));
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, help));
  PetscErrorCode ierr = run(PETSC_COMM_WORLD);
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr); // one clear error, every rank stops
  PetscCall(PetscFinalize());
  return 0;
}
