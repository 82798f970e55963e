// Example: the diffusion coefficient that minimises the time variation of a transported wave.
//
// Math. On the periodic interval [0, 2 pi) with 32 points, u_t + a u_x = D u_xx with a = 0.5 is
// integrated to T = 4 from u0 = A sin(m x) (A = 1, m = 1). The objective is the time variation
//     J(D) = int_0^T ||u_t||^2 dt = int_0^T ||G(t, U; D)||^2 dt      (plain sum over the points),
// a time integral, not a function of U(T): the Simulation integrates it with a quadrature TS that
// uses the integrator's own stage weights, and TSAdjoint adds the integrand's derivatives to the
// adjoint, r = ||G||^2:
//     lambda(T) = 0,   lambda' = -(dG/dU)^T lambda - dr/dU,   dr/dU = 2 (dG/dU)^T G,
//     dJ/dD = int_0^T [ (dG/dD)^T lambda + dr/dD ] dt,         dr/dD = 2 (dG/dD)^T G.
// Why an interior optimum: without diffusion the wave travels unchanged and u_t = -a u_x never
// decays; diffusion damps it, but a large D makes the profile itself change fast (u_t = D u_xx).
// For one Fourier mode the semi-discrete problem is solvable: with the fd2 symbols
// s1 = sin(mh)/h (advection) and s2 = 4 sin^2(mh/2)/h^2 (diffusion),
//     J(D) = A^2 N/2 (a^2 s1^2 + D^2 s2^2) (1 - exp(-2 D s2 T)) / (2 D s2),
// which tends to a^2 s1^2 T A^2 N/2 as D -> 0 with slope -a^2 s1^2 s2 T^2 A^2 N/2 < 0, and grows
// like D for large D: the minimum is interior, near D = a s1 / s2 (about a / m) for long times
// and near D = a^2 s1^2 T / (2 s2) (about a^2 T / 2) for short ones. The example prints this
// reference minimiser next to TAO's so that the optimum can be checked, not just believed
// (default run: D* = 0.449860 from D = 0.05). For other initial profiles (e.g. -advection_ic
// gaussian) every mode has its own balance and the optimum is a compromise (0.2817). A very short
// time (-ts_max_time 0.004 -ts_dt 0.001) puts the minimiser below -td_D_lower: J then increases
// with D on the whole interval and TAO stops on the lower bound, the right answer for that box.
//
// Steps: 1. scene, 2. J(D) and dJ/dD by one forward and one adjoint sweep, 3. check against central
// differences of J (forward solves only, Simulation::value), 4. TAO blmvm within bounds on D,
// 5. report with the reference minimiser.
//
// Sample runs (as root add --allow-run-as-root to mpiexec):
//   mpiexec -n 2 build/transport_diffusion
//   mpiexec -n 2 build/transport_diffusion -ts_type cn -ts_dt 0.05 -checkpoint_budget 5
//   mpiexec -n 2 build/transport_diffusion -advection_ic gaussian -advection_ic_width 0.8 -tao_monitor
//   mpiexec -n 2 build/transport_diffusion -ts_max_time 0.004 -ts_dt 0.001      (optimum on the bound)
//   mpiexec -n 2 build/transport_diffusion -advection_scheme spectral -ts_type cn -ts_dt 0.05   (FFTW, GMRES)
//   build/transport_diffusion -help        lists every option (-td_* are this example's)
#include "flexipde/scene.hpp"
#include <cmath>
#include <cstring>

using namespace flexipde;

// The example's choices, each overridable on the command line.
static PetscErrorCode default_option(const char *name, const char *value) {
  PetscBool set;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsHasName(nullptr, nullptr, name, &set));
  if (!set) PetscCall(PetscOptionsSetValue(nullptr, name, value));
  PetscFunctionReturn(0);
}

struct Problem {
  Scene *scene;
  Vec p, grad; // all the scene's parameters and dJ/dp
  PetscInt kD; // index of D among them
};

// TAO's view: one unknown, D. The other parameters stay at their option values.
static PetscErrorCode objective_and_gradient(Tao, Vec x, PetscReal *J, Vec g, void *ctx) {
  auto *pb = static_cast<Problem *>(ctx);
  PetscScalar D;
  PetscReal dJdD;
  PetscFunctionBeginUser;
  PetscCall(VecSum(x, &D)); // the single entry, on every rank
  PetscCall(pb->scene->params.set_scalar(pb->p, pb->kD, PetscRealPart(D)));
  PetscCall(pb->scene->sim.gradient(pb->p, J, pb->grad, nullptr));
  PetscCall(pb->scene->params.scalar(pb->grad, pb->kD, &dJdD));
  PetscCall(VecSet(g, dJdD));
  PetscFunctionReturn(0);
}

// The semi-discrete J(D) of one sinusoidal mode (header), exact in time.
struct Reference {
  PetscReal amp2_half_n, a2s1s1, s2, T;
  PetscReal J(PetscReal D) const {
    const PetscReal decay = 2 * D * s2 * T;
    const PetscReal integral = decay > 1e-12 ? -std::expm1(-decay) / (2 * D * s2) : T;
    return amp2_half_n * (a2s1s1 + D * D * s2 * s2) * integral;
  }
  // Golden-section search on [lo, hi] (J is unimodal there for one mode).
  PetscReal argmin(PetscReal lo, PetscReal hi) const {
    const PetscReal g = 0.5 * (std::sqrt(5.0) - 1);
    PetscReal x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
    for (int it = 0; it < 200 && hi - lo > 1e-12; ++it) {
      if (J(x1) < J(x2)) hi = x2, x2 = x1, x1 = hi - g * (hi - lo);
      else lo = x1, x1 = x2, x2 = lo + g * (hi - lo);
    }
    return 0.5 * (lo + hi);
  }
};

static PetscErrorCode run() {
  MPI_Comm comm = PETSC_COMM_WORLD;
  PetscReal lower = 1e-3, upper = 1.0, fd_step = 1e-5;
  PetscFunctionBeginUser;
  // 1. The scene: 32 periodic points on [0, 2 pi), advection with a scalar diffusivity D, the
  //    time-variation objective, RK4 with dt = 0.02 to T = 4.
  PetscCall(default_option("-advection_a", "0.5"));
  PetscCall(default_option("-advection_D", "0.05"));
  PetscCall(default_option("-objective_type", "time_variation"));
  PetscOptionsBegin(comm, nullptr, "Transport-diffusion example", "td");
  PetscCall(PetscOptionsReal("-td_D_lower", "Lower bound on D for TAO", "td", lower, &lower, nullptr));
  PetscCall(PetscOptionsReal("-td_D_upper", "Upper bound on D for TAO", "td", upper, &upper, nullptr));
  PetscCall(PetscOptionsReal("-td_fd_step", "Step of the central difference check", "td", fd_step, &fd_step, nullptr));
  PetscOptionsEnd();
  PetscCheck(lower > 0 && upper > lower, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "Need 0 < -td_D_lower < -td_D_upper, got %g and %g", (double)lower, (double)upper);
  SceneDefaults defaults;
  defaults.model = "advection";
  defaults.grid.n = 32;
  defaults.grid.x0 = 0;
  defaults.grid.x1 = 2 * PETSC_PI;
  defaults.grid.periodic = PETSC_TRUE;
  defaults.dt = 0.02;
  defaults.final_time = 4.0;
  Scene scene;
  PetscCall(scene.setup(comm, defaults));
  PetscCheck(scene.objective.has_integrand(), comm, PETSC_ERR_ARG_WRONG,
             "This example is about a time-integrated objective: keep -objective_type time_variation");

  // 2. Parameters from options, then J(D) and dJ/dD: one forward and one backward sweep.
  Problem pb{&scene, nullptr, nullptr, scene.params.find("advection_D")};
  PetscCheck(pb.kD >= 0 && scene.params.info(pb.kD).kind == ParamKind::Scalar, comm, PETSC_ERR_ARG_WRONG,
             "This example needs a scalar diffusivity (-advection_D, not -advection_D_field 1)");
  OwnedVec p, grad, q;
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.params.create_vec(grad.out()));
  PetscCall(scene.parameters_from_options("", p));
  pb.p = p;
  pb.grad = grad;
  PetscReal D0, a, J0, dJdD;
  PetscCall(scene.params.scalar(p, pb.kD, &D0));
  PetscCall(scene.params.scalar(p, scene.params.find("advection_a"), &a));
  PetscCall(scene.sim.gradient(p, &J0, grad, nullptr));
  PetscCall(scene.params.scalar(grad, pb.kD, &dJdD));
  const SimulationStats &st = scene.sim.stats();
  PetscCall(PetscPrintf(comm, "%s, %" PetscInt_FMT " steps of %g to T = %g on %" PetscInt_FMT " points, a = %g\n",
                        st.ts_type, st.steps, (double)st.dt, (double)st.final_time, scene.grid.n(), (double)a));
  PetscCall(PetscPrintf(comm, "time variation J = %.12e at D = %g\nadjoint dJ/dD = %.12e\n", (double)J0, (double)D0,
                        (double)dJdD));

  // 3. Central differences of J (value(): forward solves with the quadrature, no adjoint).
  PetscReal Jp, Jm;
  PetscCall(VecDuplicate(p, q.out()));
  PetscCall(VecCopy(p, q));
  PetscCall(scene.params.set_scalar(q, pb.kD, D0 + fd_step));
  PetscCall(scene.sim.value(q, &Jp));
  PetscCall(scene.params.set_scalar(q, pb.kD, D0 - fd_step));
  PetscCall(scene.sim.value(q, &Jm));
  const PetscReal fd = (Jp - Jm) / (2 * fd_step);
  PetscCall(PetscPrintf(comm, "central difference = %.12e, relative difference = %.3e\n", (double)fd,
                        (double)(std::fabs(fd - dJdD) / std::max(std::fabs(fd), PETSC_SMALL))));

  // 4. Minimise J over D in [lower, upper] with TAO (blmvm unless -tao_type says otherwise).
  OwnedTao tao;
  OwnedVec x, xl, xu;
  PetscMPIInt rank;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(VecCreateMPI(comm, rank == 0 ? 1 : 0, 1, x.out()));
  PetscCall(VecDuplicate(x, xl.out()));
  PetscCall(VecDuplicate(x, xu.out()));
  PetscCall(VecSet(x, D0));
  PetscCall(VecSet(xl, lower));
  PetscCall(VecSet(xu, upper));
  PetscCall(TaoCreate(comm, tao.out()));
  PetscCall(TaoSetType(tao, TAOBLMVM));
  PetscCall(TaoSetSolution(tao, x));
  PetscCall(TaoSetVariableBounds(tao, xl, xu));
  PetscCall(TaoSetObjectiveAndGradient(tao, nullptr, objective_and_gradient, &pb));
  PetscCall(TaoSetTolerances(tao, 1e-10, 1e-8, 0));
  PetscCall(TaoSetFromOptions(tao));
  PetscCall(TaoSolve(tao));

  // 5. Report, with the semi-discrete reference when the scene is the one-mode problem it solves
  //    (sinusoid, centred fd2 advection, second-order diffusion).
  PetscScalar D;
  PetscReal J;
  PetscInt its;
  TaoType type;
  TaoConvergedReason reason;
  PetscCall(VecSum(x, &D));
  PetscCall(TaoGetSolutionStatus(tao, &its, &J, nullptr, nullptr, nullptr, &reason));
  PetscCall(TaoGetType(tao, &type));
  const PetscReal Dopt = PetscRealPart(D);
  const char *where = Dopt <= lower * (1 + 1e-8) ? " (on the lower bound)"
                      : Dopt >= upper * (1 - 1e-8) ? " (on the upper bound)"
                                                   : " (interior)";
  PetscCall(PetscPrintf(comm, "TAO %s: D %.6f -> %.6f%s, J %.6e -> %.6e in %" PetscInt_FMT " iterations (%s)\n", type,
                        (double)D0, (double)Dopt, where, (double)J0, (double)J, its, TaoConvergedReasons[reason]));
  char ic[32] = "sinusoid", scheme[32] = "fd2";
  PetscInt mode = 1, order = 2;
  PetscReal amplitude = 1.0;
  PetscCall(PetscOptionsGetString(nullptr, nullptr, "-advection_ic", ic, sizeof(ic), nullptr));
  PetscCall(PetscOptionsGetString(nullptr, nullptr, "-advection_scheme", scheme, sizeof(scheme), nullptr));
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-advection_ic_mode", &mode, nullptr));
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-fd_order", &order, nullptr));
  PetscCall(PetscOptionsGetReal(nullptr, nullptr, "-advection_ic_amplitude", &amplitude, nullptr));
  if (!std::strcmp(ic, "sinusoid") && !std::strcmp(scheme, "fd2") && order == 2) {
    const PetscReal h = scene.grid.h(), n = scene.grid.n();
    const PetscReal s1 = std::sin(mode * h) / h, s2 = 4 * std::pow(std::sin(0.5 * mode * h), 2) / (h * h);
    const Reference ref{amplitude * amplitude * n / 2, a * a * s1 * s1, s2, st.final_time};
    const PetscReal Dref = ref.argmin(lower, upper);
    PetscCall(PetscPrintf(comm,
                          "semi-discrete reference (exact in time): D* = %.6f, J(D*) = %.6e; TAO's D differs by %.2e "
                          "(the integrator's time error)\n",
                          (double)Dref, (double)ref.J(Dref), (double)std::fabs(Dopt - Dref)));
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, "Diffusivity that minimises the time variation of a transported wave\n"));
  // An error ends every rank at once with a non-zero exit (MPI_Abort), even if it was raised on
  // one rank only: no rank is left waiting in a collective call.
  PetscErrorCode ierr = run();
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr);
  PetscCall(PetscFinalize());
  return 0;
}
