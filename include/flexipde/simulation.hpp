// Simulation: the PETSc TS that integrates a Model forward and, with TSAdjoint, backward.
//
// Forward: U(0) = U0(p), dU/dt = G(t, U; p) to T. Gradient: with the trajectory stored, TSAdjoint
// integrates lambda' = -(dG/dU)^T lambda from lambda(T) = dJ/dU(T) and accumulates
// mu = int (dG/dp)^T lambda dt; then dJ/dp = mu + (dU0/dp)^T lambda(0) and dJ/dU0 = lambda(0).
// The cost is one forward and one backward sweep whatever the number of parameters.
//
// Time-integrated objectives J = J_T(U(T)) + int_0^T r(t, U) dt (Objective::has_integrand): a
// quadrature TS (TSCreateQuadratureTS) integrates r during the forward solve with the integrator's
// own weights (RK: the stages with b_i; theta: its endpoint or midpoint rule), and TSAdjoint adds
// dr/dU to lambda and dr/dp to mu through its dense N x 1 Jacobians. The integral is accumulated
// by TSSolve only, never by the steps that checkpointing re-runs, so binomial checkpointing
// gives the same gradient as full storage.
//
// Integrators with an adjoint here: -ts_type rk (any -ts_rk_type), theta, cn, beuler. Explicit
// steps beyond the stability limit of the model's spectrum are refused before the run, with the
// largest stable dt. Options: PETSc's -ts_dt, -ts_max_time, -ts_type, -ts_rk_type, -ts_monitor,
// -ts_trajectory_type, -sim_stability_check 0 to run an unstable explicit step anyway, and
// -sim_blowup_check_every N (NaN/Inf check every N steps, reporting where it first appears).
#pragma once
#include "flexipde/checkpoint.hpp"
#include "flexipde/model.hpp"
#include "flexipde/rk_adjoint.hpp"
#include "flexipde/objective.hpp"

namespace flexipde {

struct SimulationStats {
  PetscInt steps = 0;
  PetscReal dt = 0, final_time = 0;
  char ts_type[64] = "";
  // Wall time (this rank) of the last gradient's two parts: the forward solve that stores the
  // trajectory, and the adjoint solve.
  double solve_seconds = 0, adjoint_seconds = 0;
};

class Simulation {
public:
  PetscErrorCode setup(Model &model, const Grid &grid, DM state_dm, const Parameters &params);
  void set_objective(Objective *objective) { objective_ = objective; }
  void set_default_time(PetscReal dt, PetscReal final_time) {
    dt_ = dt;
    final_time_ = final_time;
  }

  PetscErrorCode create_state(Vec *U) const { return DMCreateGlobalVector(dm_, U); }
  // U0(p) as the solves start from it: the model is first told the step the integrator will take
  // (Model::set_time_step; the step of -ts_dt and -ts_max_time, rounded to a whole number of steps).
  PetscErrorCode initial_condition(Vec p, Vec U0);
  // That step, from the options (a TS takes the same -ts_dt and -ts_max_time).
  PetscErrorCode time_step(PetscReal *dt) const;
  // U(T) for parameters p.
  PetscErrorCode forward(Vec p, Vec UT);
  // J(p) = J_T(U(T)) + int_0^T r dt without the adjoint (no trajectory is stored).
  PetscErrorCode value(Vec p, PetscReal *J);
  // J(p) and its gradient; grad_u0 (state-shaped, may be null) receives dJ/dU0.
  PetscErrorCode gradient(Vec p, PetscReal *J, Vec grad_p, Vec grad_u0);
  const SimulationStats &stats() const { return stats_; }
  // Stored states and recomputed steps of the last gradient's adjoint (-checkpoint_budget).
  const CheckpointStats &checkpoint_stats() const { return checkpoint_stats_; }
  // Times the shifted matrix of an implicit theta method was assembled for factoring since setup
  // (the reused factorisation of linear models; 0 on the other paths).
  PetscInt shifted_operator_builds() const { return pc_builds_; }
  // Creates (and discards) the integrator as a gradient would: lists its options under -help and
  // reports a bad integrator choice before any work is done.
  PetscErrorCode check_options();

private:
  // with_integral: attach the objective's integrand, if any (forward() alone does not need it).
  PetscErrorCode create_ts(bool with_adjoint, OwnedTS &ts, bool with_integral = true);
  // Attaches the objective's integrand to ts as its quadrature TS (a no-op without integrand);
  // integral() reads the accumulated value after the solve.
  PetscErrorCode setup_quadrature(TS ts, bool with_adjoint);
  PetscErrorCode integral(TS ts, PetscReal *value);
  static PetscErrorCode quad_rhs_cb(TS, PetscReal, Vec, Vec, void *);
  static PetscErrorCode quad_jacobian_cb(TS, PetscReal, Vec, Mat, Mat, void *);
  static PetscErrorCode quad_jacobian_p_cb(TS, PetscReal, Vec, Mat, void *);
  PetscErrorCode check_stability(TS ts);
  static PetscErrorCode rhs_cb(TS, PetscReal, Vec, Vec, void *);
  static PetscErrorCode rhs_jacobian_cb(TS, PetscReal, Vec, Mat, Mat, void *);
  static PetscErrorCode rhs_jacobian_p_cb(TS, PetscReal, Vec, Mat, void *);
  static PetscErrorCode adjoint_kick_cb(void *, PetscReal, Vec, Vec, Vec, PetscReal, Vec, PetscReal, const PetscScalar *);
  static PetscErrorCode step_cb(void *, PetscReal, Vec, PetscScalar *, const LeapfrogStepParts &);
  static PetscErrorCode split_step_cb(void *, PetscReal, Vec, PetscScalar *, const LeapfrogSplitParts &);
  static PetscErrorCode stage_adjoint_cb(void *, PetscReal, Vec, const PetscScalar *, const StageCombination &, Vec, Vec);
  static PetscErrorCode integrand_stage_cb(void *, PetscReal, Vec, Vec, PetscReal, Vec, Vec);
  PetscErrorCode check_finite(Vec U, const char *what);
  static PetscErrorCode blowup_monitor(TS, PetscInt, PetscReal, Vec, void *);
  PetscInt blowup_every_ = 100;
  OwnedMat Jmf_; // the model's matrix-free dG/dU, for explicit integrators (null if none)
  // -adjoint_petsc_step: PETSc's own adjoint steps (and forming of implicit operators), the leapfrog's
  // through the Jacobians: the reference path, for checking
  PetscBool petsc_step_ = PETSC_FALSE;
  bool leapfrog_fused_ = false; // the last TS's leapfrog adjoint calls Model::second_order_adjoint
  // The leapfrog's damping sigma = -dG_p/dp in the velocity rows of damping_ (*sigma null: none).
  PetscErrorCode leapfrog_damping(Vec *sigma);
  OwnedVec damping_, velocities_;
  PetscErrorCode integrand_state(Vec X, Vec *U);
  static PetscErrorCode integrand_adjoint_cb(void *, PetscReal, Vec, PetscReal, Vec);
  OwnedVec positions_state_; // integrand_state's state
  bool rk_stage_fused_ = false; // the last adjoint TS's RK stages call Model::stage_adjoint
  bool rk_stage_records_ = false; // ... and its RHS evaluations may record (Model::stage_record_size)
  PetscErrorCode finish_solve(TS ts);
  bool adaptive_ = false;

  // Implicit theta methods (theta, cn, beuler) on a linear model with constant dG/dU = A(p) (one rank,
  // or the redundant LU of several, see create_ts; not with -adjoint_petsc_step). TS gets F = U_t - G(U)
  // and the IJacobian shift*I - A as two matrices: a MatShell that applies shift*I - A exactly for the
  // shift of the last IJacobian call (J_ holds A, refreshed when the parameters change), and
  // shifted_pc_, the assembled matrix the PC factors. The IJacobian callback only records the shift; a KSP pre-solve hook makes
  // shifted_pc_ equal to shift*I - A before every solve, rebuilding it only when the shift, A or
  // shifted_pc_ itself changed since it was built. So the factorisation is redone once per
  // (dt, p) instead of at every step (forward) and twice per step (the CN adjoint, which also
  // forms (theta-1)-shifted matrices it only multiplies with).
  PetscErrorCode use_shifted_operator(TS ts);
  static PetscErrorCode ifunction_cb(TS, PetscReal, Vec, Vec, Vec, void *);
  static PetscErrorCode ijacobian_cb(TS, PetscReal, Vec, Vec, PetscReal, Mat, Mat, void *);
  template <bool Transpose>
  static PetscErrorCode shifted_apply(Mat, Vec, Vec);
  static PetscErrorCode shifted_presolve(KSP, Vec, Vec, void *);
  PetscErrorCode check_operator_current() const;
  PetscErrorCode assemble_shifted(Mat P);
  OwnedMat shifted_, shifted_pc_;
  PetscReal shift_ = 0;     // shift of the last IJacobian call (what shifted_ applies)
  PetscReal pc_shift_ = 0;  // shift shifted_pc_ was built with
  PetscObjectState pc_from_state_ = -1, pc_state_ = -1; // J_'s state it was built from, and its own
  PetscInt pc_param_version_ = -1;
  PetscInt pc_builds_ = 0; // how often shifted_pc_ was (re)built, for tests

  Model *model_ = nullptr;
  const Grid *grid_ = nullptr;
  const Parameters *params_ = nullptr;
  Objective *objective_ = nullptr;
  DM dm_ = nullptr;
  PetscReal dt_ = 1e-3, final_time_ = 1.0;
  PetscReal start_dt_ = 0; // the step the model was told for the initial condition of the solve being set up (0: none)
  OwnedMat J_, Jp_;
  OwnedVec lambda_, mu_;
  // The integrand's dr/dU and dr/dp as the dense N x 1 matrices the quadrature TS expects, and
  // state/parameter-shaped vectors placed on their columns.
  OwnedMat drdU_, drdp_;
  OwnedVec drdU_col_, drdp_col_;
  // dG/dU of a model whose Jacobian is constant in (t, U) is reassembled only when the parameters
  // changed or TS shifted the matrix (implicit methods), detected through PETSc's object state.
  PetscObjectState jac_state_ = -1;
  PetscInt param_version_ = 0, jac_param_version_ = -1;
  SimulationStats stats_;
  CheckpointStats checkpoint_stats_;
  // Full-storage trajectory ("store"): kept between gradients, so it is allocated once.
  StateBuffer trajectory_buffer_;
};

} // namespace flexipde
