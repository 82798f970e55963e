// Example: find the temperature ratio of a two-stream plasma that gives a target field energy.
//
// Math. Two counter-streaming electron beams (src/models/vlasov.cpp, -vlasov_ic two_stream),
//     f0 = (1 + alpha cos(k x)) [M(v - v0; vt) + M(v + v0; vt sqrt(r))] / 2,
// evolve by f_t + v f_x - E f_v = 0, E_x = 1 - int f dv. The colder the second beam (small r), the
// faster the instability grows (dispersion relation, k = 0.2, v0 = 2.4, vt = 1: gamma = 0.259 at
// r = 0.5, 0.226 at r = 1, 0.169 at r = 2). The loss compares the field energy at T with a target
// W* made by a run with r* (-true_vlasov_temperature_ratio):
//     J(r) = 0.5 (W(T; r) / W* - 1)^2           (-objective_type functional -objective_target W*)
// dJ/dr is exact for the discrete scheme: the adjoint lambda(T) = (W/W* - 1)/W* dW/df goes back
// through (dG/dU)^T (including the field's dependence on f) to lambda(0), and
//     dJ/dr = sum_ij lambda_ij(0) d f0_ij / dr.
// TAO's BLMVM (bounded limited-memory quasi-Newton) searches r in [-r_lower, -r_upper] from the
// start -vlasov_temperature_ratio. With -maximise 1 instead, J = -W(T; r): the growth is largest for
// the coldest beam, so BLMVM stops on the lower bound.
//
// Sample runs (as root add --allow-run-as-root --oversubscribe to mpiexec):
//   mpiexec -n 2 build/vlasov_temperature_ratio
//   mpiexec -n 2 build/vlasov_temperature_ratio -true_vlasov_temperature_ratio 0.6 -tao_monitor
//   mpiexec -n 2 build/vlasov_temperature_ratio -maximise 1
//   build/vlasov_temperature_ratio -help        lists every option
#include "flexipde/scene.hpp"
#include <cmath>
#include <cstdio>

using namespace flexipde;

static PetscErrorCode default_option(const char *name, const char *value) {
  PetscBool set;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsHasName(nullptr, nullptr, name, &set));
  if (!set) PetscCall(PetscOptionsSetValue(nullptr, name, value));
  PetscFunctionReturn(0);
}

struct Problem {
  Scene *scene;
  Vec p, grad;
  PetscInt kr; // index of the temperature ratio among the parameters
};

// TAO's view: one unknown, r; alpha, v0 and vt stay at their option values.
static PetscErrorCode loss_and_gradient(Tao, Vec x, PetscReal *J, Vec g, void *ctx) {
  auto *pb = static_cast<Problem *>(ctx);
  PetscScalar r;
  PetscReal dJdr;
  PetscFunctionBeginUser;
  PetscCall(VecSum(x, &r));
  PetscCall(pb->scene->params.set_scalar(pb->p, pb->kr, PetscRealPart(r)));
  PetscCall(pb->scene->sim.gradient(pb->p, J, pb->grad, nullptr));
  PetscCall(pb->scene->params.scalar(pb->grad, pb->kr, &dJdr));
  PetscCall(VecSet(g, dJdr));
  PetscFunctionReturn(0);
}

static PetscErrorCode run() {
  MPI_Comm comm = PETSC_COMM_WORLD;
  PetscReal r_lower = 0.25, r_upper = 4.0, r_true = 2.0;
  PetscBool maximise = PETSC_FALSE;
  PetscFunctionBeginUser;
  // 1. Options: the two-stream set-up on a 32 x 64 phase-space grid, RK4 with dt = 0.1 to T = 15
  //    (linear growth phase), the field energy at T as the objective.
  PetscOptionsBegin(comm, nullptr, "Two-stream temperature ratio example", "Example");
  PetscCall(PetscOptionsBool("-maximise", "Maximise W(T) instead of matching the target", "Example", maximise,
                             &maximise, nullptr));
  PetscCall(PetscOptionsReal("-r_lower", "Lower bound on the temperature ratio", "Example", r_lower, &r_lower, nullptr));
  PetscCall(PetscOptionsReal("-r_upper", "Upper bound on the temperature ratio", "Example", r_upper, &r_upper, nullptr));
  PetscCall(PetscOptionsReal("-true_vlasov_temperature_ratio", "Ratio r* that makes the target W*", "Example", r_true,
                             &r_true, nullptr));
  PetscOptionsEnd();
  PetscCheck(0 < r_lower && r_lower < r_upper, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "Need 0 < -r_lower < -r_upper, got %g and %g", (double)r_lower, (double)r_upper);
  PetscCall(default_option("-vlasov_ic", "two_stream"));
  PetscCall(default_option("-da_grid_x", "32"));
  PetscCall(default_option("-da_grid_y", "64"));
  PetscCall(default_option("-objective_type", "functional"));
  PetscCall(default_option("-objective_functional", "field_energy"));
  if (maximise) PetscCall(default_option("-objective_sign", "-1"));
  SceneDefaults defaults;
  defaults.model = "vlasov";
  defaults.dt = 0.1;
  defaults.final_time = 15;

  // 2. The target W* = W(T; r*), unless maximising: one forward run of a scene without a target.
  PetscReal W_target = 0;
  if (!maximise) {
    Scene probe;
    OwnedVec p, U;
    PetscCall(probe.setup(comm, defaults));
    PetscCall(probe.params.create_vec(p.out()));
    PetscCall(probe.parameters_from_options("", p));
    PetscCall(probe.params.set_scalar(p, probe.params.find("vlasov_temperature_ratio"), r_true));
    PetscCall(probe.sim.create_state(U.out()));
    PetscCall(probe.sim.forward(p, U));
    PetscCall(probe.model->functional("field_energy", U, &W_target, nullptr));
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.17g", (double)W_target);
    PetscCall(default_option("-objective_target", buf));
    PetscCall(PetscOptionsGetReal(nullptr, nullptr, "-objective_target", &W_target, nullptr));
  }
  Scene scene;
  PetscCall(scene.setup(comm, defaults));
  Problem pb{&scene, nullptr, nullptr, scene.params.find("vlasov_temperature_ratio")};
  PetscCheck(pb.kr >= 0, comm, PETSC_ERR_ARG_WRONG, "This example needs -vlasov_ic two_stream");
  OwnedVec p, grad;
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.params.create_vec(grad.out()));
  PetscCall(scene.parameters_from_options("", p));
  pb.p = p;
  pb.grad = grad;
  PetscReal r0;
  PetscCall(scene.params.scalar(p, pb.kr, &r0));

  // 3. Loss and adjoint gradient at the start, checked against central differences.
  PetscReal J0, dJdr, Jp, Jm;
  const PetscReal h = 1e-5;
  PetscCall(scene.sim.gradient(p, &J0, grad, nullptr));
  PetscCall(scene.params.scalar(grad, pb.kr, &dJdr));
  PetscCall(scene.params.set_scalar(p, pb.kr, r0 + h));
  PetscCall(scene.sim.value(p, &Jp));
  PetscCall(scene.params.set_scalar(p, pb.kr, r0 - h));
  PetscCall(scene.sim.value(p, &Jm));
  PetscCall(scene.params.set_scalar(p, pb.kr, r0));
  const PetscReal fd = (Jp - Jm) / (2 * h);
  const SimulationStats &st = scene.sim.stats();
  PetscCall(PetscPrintf(comm, "two-stream, %" PetscInt_FMT " x %" PetscInt_FMT " phase space, %s, %" PetscInt_FMT
                        " steps of %g to T = %g\n",
                        scene.grid.n(), scene.grid.ny(), st.ts_type, st.steps, (double)st.dt, (double)st.final_time));
  if (!maximise)
    PetscCall(PetscPrintf(comm, "target W* = %.6e (r* = %g)\n", (double)W_target, (double)r_true));
  PetscCall(PetscPrintf(comm, "J = %.10e at r = %g: adjoint dJ/dr = %.10e, central difference = %.10e, relative difference = %.3e\n",
                        (double)J0, (double)r0, (double)dJdr, (double)fd,
                        (double)(std::fabs(fd - dJdr) / std::max(std::fabs(fd), PETSC_SMALL))));

  // 4. BLMVM within the bounds.
  OwnedTao tao;
  OwnedVec x, lo, hi;
  PetscMPIInt rank;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(VecCreateMPI(comm, rank == 0 ? 1 : 0, 1, x.out()));
  PetscCall(VecDuplicate(x, lo.out()));
  PetscCall(VecDuplicate(x, hi.out()));
  PetscCall(VecSet(x, r0));
  PetscCall(VecSet(lo, r_lower));
  PetscCall(VecSet(hi, r_upper));
  PetscCall(TaoCreate(comm, tao.out()));
  PetscCall(TaoSetType(tao, TAOBLMVM));
  PetscCall(TaoSetSolution(tao, x));
  PetscCall(TaoSetVariableBounds(tao, lo, hi));
  PetscCall(TaoSetObjectiveAndGradient(tao, nullptr, loss_and_gradient, &pb));
  PetscCall(TaoSetTolerances(tao, 1e-12, 1e-8, 0));
  PetscCall(TaoSetFromOptions(tao));
  PetscCall(TaoSolve(tao));

  // 5. Report.
  PetscScalar r;
  PetscReal J;
  PetscInt its;
  TaoConvergedReason reason;
  PetscCall(VecSum(x, &r));
  PetscCall(TaoGetSolutionStatus(tao, &its, &J, nullptr, nullptr, nullptr, &reason));
  const PetscReal rr = PetscRealPart(r);
  const char *where = std::fabs(rr - r_lower) < 1e-10 ? " (on the lower bound)" : std::fabs(rr - r_upper) < 1e-10 ? " (on the upper bound)" : "";
  PetscCall(PetscPrintf(comm, "TAO blmvm: r %.6f -> %.6f%s, J %.6e -> %.3e in %" PetscInt_FMT " iterations (%s)\n",
                        (double)r0, (double)rr, where, (double)J0, (double)J, its, TaoConvergedReasons[reason]));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, "Two-stream instability: fit the temperature ratio with TAO BLMVM\n"));
  PetscErrorCode ierr = run();
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr);
  PetscCall(PetscFinalize());
  return 0;
}
