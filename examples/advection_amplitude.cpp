// Example: optimise the amplitude of an initial sinusoid so that the final field is smallest.
//
// Math. On the periodic interval [0, 2 pi) with 64 points, u_t + a u_x = (D u_x)_x with a = 1
// (D = 0 unless -advection_D is given) is integrated to T = 1 from u0 = A sin(x). The loss is
//     J(A) = (1/N) sum_i u_i(T)^2,
// and its gradient is the exact discrete adjoint of the integrator (TSAdjoint):
//     lambda(T) = 2 u(T) / N,  lambda' = -(dG/dU)^T lambda,  dJ/dA = (dU0/dA)^T lambda(0) = sum_i sin(x_i) lambda_i(0),
// A enters only through U0. The problem is linear, so J = M A^2 for a constant M: the adjoint must
// give dJ/dA = 2J/A, central differences agree to round-off, and TAO drives A to 0.
//
// Sample runs (as root add --allow-run-as-root to mpiexec):
//   mpiexec -n 2 build/advection_amplitude
//   mpiexec -n 2 build/advection_amplitude -advection_scheme upwind -ts_type cn -ts_dt 0.05 -tao_monitor
//   mpiexec -n 2 build/advection_amplitude -advection_scheme fd4 -advection_D 0.05 -advection_D_field 1
//   mpiexec -n 2 build/advection_amplitude -advection_scheme spectral     (FFTW-MPI Fourier differentiation)
//   build/advection_amplitude -help        lists every option
#include "flexipde/scene.hpp"
#include <cmath>

using namespace flexipde;

// The seed's choices, each overridable on the command line.
static PetscErrorCode default_option(const char *name, const char *value) {
  PetscBool set;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsHasName(nullptr, nullptr, name, &set));
  if (!set) PetscCall(PetscOptionsSetValue(nullptr, name, value));
  PetscFunctionReturn(0);
}

struct Problem {
  Scene *scene;
  Vec p, grad;   // all the scene's parameters and dJ/dp
  PetscInt kA;   // index of the amplitude among them
};

// TAO's view: one unknown, A. The other parameters (a, D) stay at their option values.
static PetscErrorCode loss_and_gradient(Tao, Vec x, PetscReal *J, Vec g, void *ctx) {
  auto *pb = static_cast<Problem *>(ctx);
  PetscScalar A;
  PetscReal dJdA;
  PetscFunctionBeginUser;
  PetscCall(VecSum(x, &A)); // the single entry, on every rank
  PetscCall(pb->scene->params.set_scalar(pb->p, pb->kA, PetscRealPart(A)));
  PetscCall(pb->scene->sim.gradient(pb->p, J, pb->grad, nullptr));
  PetscCall(pb->scene->params.scalar(pb->grad, pb->kA, &dJdA));
  PetscCall(VecSet(g, dJdA));
  PetscFunctionReturn(0);
}

static PetscErrorCode run() {
  MPI_Comm comm = PETSC_COMM_WORLD;
  PetscFunctionBeginUser;
  // 1. The scene: 64 periodic points on [0, 2 pi), the advection model with the amplitude of
  //    u0 = A sin(x) declared as a parameter, the mean-square loss, RK4 with dt = 0.01 to T = 1.
  PetscCall(default_option("-advection_ic_amplitude_param", "1"));
  PetscCall(default_option("-objective_type", "mean_square"));
  SceneDefaults defaults;
  defaults.model = "advection";
  defaults.grid.n = 64;
  defaults.grid.x0 = 0;
  defaults.grid.x1 = 2 * PETSC_PI;
  defaults.grid.periodic = PETSC_TRUE;
  defaults.dt = 0.01;
  defaults.final_time = 1.0;
  Scene scene;
  PetscCall(scene.setup(comm, defaults));

  // 2. Parameters from options (-advection_a, -advection_ic_amplitude, -advection_D ...).
  Problem pb{&scene, nullptr, nullptr, scene.params.find("advection_ic_amplitude")};
  PetscCheck(pb.kA >= 0, comm, PETSC_ERR_ARG_WRONG, "This example needs -advection_ic_amplitude_param 1");
  OwnedVec p, grad;
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.params.create_vec(grad.out()));
  PetscCall(scene.parameters_from_options("", p));
  pb.p = p;
  pb.grad = grad;
  PetscReal A0;
  PetscCall(scene.params.scalar(p, pb.kA, &A0));

  // 3. Loss and adjoint gradient: one forward and one backward sweep.
  PetscReal J0, dJdA;
  PetscCall(scene.sim.gradient(p, &J0, grad, nullptr));
  PetscCall(scene.params.scalar(grad, pb.kA, &dJdA));
  const SimulationStats &st = scene.sim.stats();
  PetscCall(PetscPrintf(comm, "%s, %" PetscInt_FMT " steps of %g to T = %g on %" PetscInt_FMT " points\n", st.ts_type,
                        st.steps, (double)st.dt, (double)st.final_time, scene.grid.n()));
  PetscCall(PetscPrintf(comm, "loss J = %.12e at amplitude %.6f\nadjoint dJ/dA = %.12e (2J/A = %.12e)\n", (double)J0,
                        (double)A0, (double)dJdA, (double)(2 * J0 / A0)));

  // 4. Check against central differences of the loss (forward solves only).
  const PetscReal h = 1e-4;
  PetscReal Jp, Jm;
  OwnedVec U;
  PetscCall(scene.sim.create_state(U.out()));
  PetscCall(scene.params.set_scalar(p, pb.kA, A0 + h));
  PetscCall(scene.sim.forward(p, U));
  PetscCall(scene.objective.terminal(U, &Jp, nullptr));
  PetscCall(scene.params.set_scalar(p, pb.kA, A0 - h));
  PetscCall(scene.sim.forward(p, U));
  PetscCall(scene.objective.terminal(U, &Jm, nullptr));
  const PetscReal fd = (Jp - Jm) / (2 * h);
  PetscCall(PetscPrintf(comm, "central difference = %.12e, relative difference = %.3e\n", (double)fd,
                        (double)(std::fabs(fd - dJdA) / std::max(std::fabs(fd), PETSC_SMALL))));

  // 5. Minimise J over A with TAO (LMVM unless -tao_type says otherwise), from A0.
  OwnedTao tao;
  OwnedVec x;
  PetscMPIInt rank;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(VecCreateMPI(comm, rank == 0 ? 1 : 0, 1, x.out()));
  PetscCall(VecSet(x, A0));
  PetscCall(TaoCreate(comm, tao.out()));
  PetscCall(TaoSetType(tao, TAOLMVM));
  PetscCall(TaoSetSolution(tao, x));
  PetscCall(TaoSetObjectiveAndGradient(tao, nullptr, loss_and_gradient, &pb));
  PetscCall(TaoSetFromOptions(tao));
  PetscCall(TaoSolve(tao));

  // 6. Report: the optimum is A = 0 (J = 0).
  PetscScalar A;
  PetscReal J;
  PetscInt its;
  TaoType type;
  TaoConvergedReason reason;
  PetscCall(VecSum(x, &A));
  PetscCall(TaoGetSolutionStatus(tao, &its, &J, nullptr, nullptr, nullptr, &reason));
  PetscCall(TaoGetType(tao, &type));
  PetscCall(PetscPrintf(comm, "TAO %s: amplitude %.6f -> %.3e, loss %.6e -> %.3e in %" PetscInt_FMT " iterations (%s)\n",
                        type, (double)A0, (double)PetscRealPart(A), (double)J0, (double)J, its,
                        TaoConvergedReasons[reason]));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, "Optimise the amplitude of an advected sinusoid\n"));
  // An error ends every rank at once with a non-zero exit (MPI_Abort), even if it was raised on
  // one rank only: no rank is left waiting in a collective call.
  PetscErrorCode ierr = run();
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr);
  PetscCall(PetscFinalize());
  return 0;
}
