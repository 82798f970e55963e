#include "flexipde/simulation.hpp"
#include <cmath>
#include <complex>
#include <cstring>
#include <petsc/private/petscimpl.h> // PetscObjectStateGet
#include <string>

namespace flexipde {

PetscErrorCode Simulation::setup(Model &model, const Grid &grid, DM state_dm, const Parameters &params) {
  PetscFunctionBeginUser;
  model_ = &model;
  grid_ = &grid;
  params_ = &params;
  dm_ = state_dm;
  PetscCall(model.create_jacobian(J_.out()));
  if (params.global_size() > 0) {
    PetscCall(model.create_jacobian_p(Jp_.out()));
    PetscCall(params.create_vec(mu_.out()));
  }
  PetscCall(DMCreateGlobalVector(dm_, lambda_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::rhs_cb(TS, PetscReal t, Vec U, Vec G, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(sim->model_->rhs(t, U, G));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::rhs_jacobian_cb(TS, PetscReal t, Vec U, Mat A, Mat B, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscObjectState state;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectStateGet((PetscObject)A, &state));
  if (sim->model_->jacobian_constant() && sim->jac_param_version_ == sim->param_version_ && state == sim->jac_state_)
    PetscFunctionReturn(0);
  PetscCall(sim->model_->rhs_jacobian(t, U, A));
  if (B && B != A) PetscCall(MatCopy(A, B, SAME_NONZERO_PATTERN));
  PetscCall(PetscObjectStateGet((PetscObject)A, &sim->jac_state_));
  sim->jac_param_version_ = sim->param_version_;
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::rhs_jacobian_p_cb(TS, PetscReal t, Vec U, Mat Jp, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(sim->model_->rhs_jacobian_p(t, U, Jp));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::create_ts(bool with_adjoint, OwnedTS &ts) {
  MPI_Comm comm = grid_->comm();
  PetscMPIInt size;
  PetscBool stability_check = PETSC_TRUE;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(TSCreate(comm, ts.out()));
  PetscCall(TSSetDM(ts, dm_));
  PetscCall(TSSetProblemType(ts, model_->linear() ? TS_LINEAR : TS_NONLINEAR));
  PetscCall(TSSetRHSFunction(ts, nullptr, rhs_cb, this));
  PetscCall(TSSetRHSJacobian(ts, J_, J_, rhs_jacobian_cb, this));
  PetscCall(TSSetType(ts, TSRK));
  PetscCall(TSRKSetType(ts, TSRK4));
  PetscCall(TSSetTimeStep(ts, dt_));
  PetscCall(TSSetMaxTime(ts, final_time_));
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
  { // implicit methods: a direct solve by default, so that adjoint gradients are exact
    SNES snes;
    KSP ksp;
    PC pc;
    PetscCall(TSGetSNES(ts, &snes));
    PetscCall(SNESGetKSP(snes, &ksp));
    PetscCall(KSPSetType(ksp, KSPPREONLY));
    PetscCall(KSPGetPC(ksp, &pc));
    PetscCall(PCSetType(pc, PCLU));
    if (size > 1) PetscCall(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
  }
  if (with_adjoint) {
    TSTrajectory tj;
    PetscCall(TSSetSaveTrajectory(ts));
    PetscCall(TSGetTrajectory(ts, &tj));
    PetscCall(TSTrajectorySetType(tj, ts, TSTRAJECTORYMEMORY));
    if (Jp_) PetscCall(TSSetRHSJacobianP(ts, Jp_, rhs_jacobian_p_cb, this));
  }
  PetscCall(TSSetFromOptions(ts));
  PetscOptionsBegin(comm, nullptr, "Simulation", "Simulation");
  PetscCall(PetscOptionsBool("-sim_stability_check", "Refuse explicit steps beyond the stability limit", "Simulation",
                             stability_check, &stability_check, nullptr));
  PetscOptionsEnd();

  TSType type;
  PetscCall(TSGetType(ts, &type));
  const bool has_adjoint = !std::strcmp(type, TSRK) || !std::strcmp(type, TSTHETA) || !std::strcmp(type, TSCN) ||
                           !std::strcmp(type, TSBEULER);
  PetscCheck(!with_adjoint || has_adjoint, comm, PETSC_ERR_SUP,
             "-ts_type %s has no adjoint in flexipde: choose rk (any -ts_rk_type), theta, cn or beuler", type);
  PetscReal dt, T;
  PetscCall(TSGetTimeStep(ts, &dt));
  PetscCall(TSGetMaxTime(ts, &T));
  PetscCheck(dt > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-ts_dt must be positive, got %g", (double)dt);
  PetscCheck(T > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-ts_max_time must be positive, got %g", (double)T);
  // A whole number of equal steps, so that forward and adjoint visit the same times.
  const PetscInt nsteps = std::max<PetscInt>(1, (PetscInt)std::llround(T / dt));
  dt = T / nsteps;
  PetscCall(TSSetTimeStep(ts, dt));
  PetscCall(TSSetMaxSteps(ts, nsteps));
  stats_.steps = nsteps;
  stats_.dt = dt;
  stats_.final_time = T;
  std::strncpy(stats_.ts_type, type, sizeof(stats_.ts_type) - 1);
  if (stability_check) PetscCall(check_stability(ts));
  PetscFunctionReturn(0);
}

// Stability limit of an explicit RK tableau along the imaginary and negative real axes, from its
// stability function R(z) = 1 + z b^T (I - zA)^{-1} 1 evaluated by stage recursion.
static PetscReal rk_axis_limit(PetscInt s, const PetscReal *A, const PetscReal *b, std::complex<double> dir) {
  const double dz = 1e-3;
  double last_ok = 0;
  for (double r = dz; r < 8.0; r += dz) {
    const std::complex<double> z = r * dir;
    std::complex<double> Y[16], R = 1.0;
    for (PetscInt i = 0; i < s; ++i) {
      Y[i] = 1.0;
      for (PetscInt j = 0; j < i; ++j) Y[i] += z * A[i * s + j] * Y[j];
      R += z * b[i] * Y[i];
    }
    if (std::abs(R) > 1.0 + 1e-12) break;
    last_ok = r;
  }
  return last_ok;
}

PetscErrorCode Simulation::check_stability(TS ts) {
  TSType type;
  PetscFunctionBeginUser;
  PetscCall(TSGetType(ts, &type));
  if (std::strcmp(type, TSRK)) PetscFunctionReturn(0); // theta >= 1/2 is A-stable
  PetscInt s;
  const PetscReal *A, *b;
  TSRKType rktype;
  PetscCall(TSRKGetType(ts, &rktype));
  PetscCall(TSRKGetTableau(ts, &s, &A, &b, nullptr, nullptr, nullptr, nullptr, nullptr));
  Spectrum sp;
  PetscCall(model_->spectrum(&sp));
  const PetscReal dt = stats_.dt;
  struct Axis {
    const char *what;
    PetscReal radius;
    std::complex<double> dir;
  } axes[2] = {{"oscillatory (imaginary)", sp.imag_radius, {0, 1}}, {"diffusive (negative real)", sp.real_radius, {-1, 0}}};
  for (auto &ax : axes) {
    if (ax.radius <= 0) continue;
    const PetscReal lim = rk_axis_limit(s, A, b, ax.dir);
    PetscCheck(lim > 1e-2, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "-ts_rk_type %s is unstable for this model's %s spectrum at any dt; use -ts_rk_type 3, 4 or 5dp, or "
               "an implicit -ts_type (cn, beuler)",
               rktype, ax.what);
    PetscCheck(dt * ax.radius <= lim * (1 + 1e-9), grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "Explicit step beyond the stability limit: dt = %g but -ts_rk_type %s is stable for this model's %s "
               "spectrum (radius %g) only up to dt = %g",
               (double)dt, rktype, ax.what, (double)ax.radius, (double)(lim / ax.radius));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::check_finite(Vec U, const char *what) {
  PetscReal nrm;
  PetscFunctionBeginUser;
  PetscCall(VecNorm(U, NORM_2, &nrm));
  PetscCheck(std::isfinite((double)nrm), grid_->comm(), PETSC_ERR_FP,
             "The %s produced NaN/Inf by t = %g after %" PetscInt_FMT
             " steps of %g: reduce -ts_dt or use an implicit -ts_type (cn, beuler)",
             what, (double)stats_.final_time, stats_.steps, (double)stats_.dt);
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::check_options() {
  OwnedTS ts;
  PetscFunctionBeginUser;
  PetscCall(create_ts(objective_ != nullptr, ts));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::forward(Vec p, Vec UT) {
  OwnedTS ts;
  PetscFunctionBeginUser;
  ++param_version_;
  PetscCall(model_->initial_condition(p, UT)); // also sets the model's parameters
  PetscCall(create_ts(false, ts));
  PetscCall(TSSolve(ts, UT));
  PetscCall(check_finite(UT, "forward solve"));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::gradient(Vec p, PetscReal *J, Vec grad_p, Vec grad_u0) {
  OwnedTS ts;
  OwnedVec U;
  PetscFunctionBeginUser;
  PetscCheck(objective_, grid_->comm(), PETSC_ERR_ORDER, "Simulation::gradient needs an objective");
  ++param_version_;
  PetscCall(DMCreateGlobalVector(dm_, U.out()));
  PetscCall(model_->initial_condition(p, U));
  PetscCall(create_ts(true, ts));
  PetscCall(TSSolve(ts, U));
  PetscCall(check_finite(U, "forward solve"));
  PetscCall(objective_->terminal(U, J, lambda_));
  Vec lam = lambda_, mu = mu_;
  if (mu) PetscCall(VecSet(mu, 0.0));
  PetscCall(TSSetCostGradients(ts, 1, &lam, mu ? &mu : nullptr));
  PetscCall(TSAdjointSolve(ts));
  PetscCall(check_finite(lambda_, "adjoint solve"));
  if (grad_p) {
    if (mu) PetscCall(VecCopy(mu, grad_p));
    else PetscCall(VecSet(grad_p, 0.0));
    PetscCall(model_->initial_condition_transpose(p, lambda_, grad_p));
  }
  if (grad_u0) PetscCall(VecCopy(lambda_, grad_u0));
  PetscFunctionReturn(0);
}

} // namespace flexipde
