#include "flexipde/simulation.hpp"
#include "flexipde/leapfrog.hpp"
#include "flexipde/rk_adjoint.hpp"
#include "flexipde/rk_step.hpp"
#include "flexipde/theta_adjoint.hpp"
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstring>
#include <functional>
#include <vector>
#include <petsc/private/petscimpl.h> // PetscObjectStateGet
#include <string>

namespace flexipde {

namespace {
// Y += a I for an AIJ matrix whose rows all hold their diagonal entry (the pointwise layer's Jacobians
// do), in place. PETSc 3.18's MatShift for AIJ adds each diagonal entry with a MatSetValues call of
// its own, which costs more than forming a stencil's Jacobian; implicit TS shift it at every step.
PetscErrorCode shift_aij_in_place(Mat Y, PetscScalar a) {
  Mat Ad = Y;
  PetscBool mpi, done;
  PetscInt n, missing = -1;
  const PetscInt *ia, *ja;
  PetscScalar *v;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject)Y, MATMPIAIJ, &mpi));
  if (mpi) PetscCall(MatMPIAIJGetSeqAIJ(Y, &Ad, nullptr, nullptr));
  PetscCall(MatGetRowIJ(Ad, 0, PETSC_FALSE, PETSC_FALSE, &n, &ia, &ja, &done));
  PetscCheck(done, PETSC_COMM_SELF, PETSC_ERR_SUP, "no row structure of the matrix to shift");
  PetscCall(MatSeqAIJGetArray(Ad, &v));
  for (PetscInt r = 0; r < n; ++r) { // (the diagonal block's columns are local: the diagonal is column r)
    const PetscInt *at = std::lower_bound(ja + ia[r], ja + ia[r + 1], r);
    if (at != ja + ia[r + 1] && *at == r) v[at - ja] += a;
    else if (missing < 0) missing = r;
  }
  PetscCall(MatSeqAIJRestoreArray(Ad, &v));
  PetscCall(MatRestoreRowIJ(Ad, 0, PETSC_FALSE, PETSC_FALSE, &n, &ia, &ja, &done));
  PetscCheck(missing < 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "local row %" PetscInt_FMT " of the Jacobian has no diagonal entry", missing);
  if (mpi) PetscCall(PetscObjectStateIncrease((PetscObject)Y));
  PetscFunctionReturn(0);
}

// The model's dG/dU as the Simulation holds it (J null: made now): the assembled matrix, or the
// applied one of a model with non-local maps.
PetscErrorCode make_jacobian(Model &model, OwnedMat &J) {
  PetscBool aij;
  PetscFunctionBeginUser;
  if (J) PetscFunctionReturn(0);
  PetscCall(model.create_jacobian(J.out()));
  PetscCall(PetscObjectTypeCompareAny((PetscObject)(Mat)J, &aij, MATSEQAIJ, MATMPIAIJ, ""));
  if (aij) PetscCall(MatSetOperation(J, MATOP_SHIFT, (void (*)(void))shift_aij_in_place));
  PetscFunctionReturn(0);
}
} // namespace

PetscErrorCode Simulation::setup(Model &model, const Grid &grid, DM state_dm, const Parameters &params) {
  PetscFunctionBeginUser;
  model_ = &model;
  grid_ = &grid;
  params_ = &params;
  dm_ = state_dm;
  // A model with a matrix-free dG/dU (linear, local) gets its assembled one only from the first TS
  // that needs it (implicit steps, the Jacobian-based leapfrog adjoint): explicit runs never make it,
  // neither its memory (stencil entries x components per row) nor the sweep that finds its pattern.
  PetscCall(model.create_jacobian_matrix_free(Jmf_.out()));
  if (!Jmf_) PetscCall(make_jacobian(model, J_));
  if (params.global_size() > 0) {
    PetscCall(model.create_jacobian_p(Jp_.out()));
    PetscCall(params.create_vec(mu_.out()));
  }
  PetscCall(DMCreateGlobalVector(dm_, lambda_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::rhs_cb(TS ts, PetscReal t, Vec U, Vec G, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscScalar *record = nullptr;
  PetscFunctionBeginUser;
  // An explicit RK's stage of a stored forward solve: G's evaluation also writes the stage's record
  // where full storage keeps it (Model::stage_record_size).
  if (sim->rk_stage_records_) PetscCall(rk_adjoint_record_target(ts, U, &record));
  if (record) PetscCall(sim->model_->rhs_record(t, U, G, record));
  else PetscCall(sim->model_->rhs(t, U, G));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::rhs_jacobian_cb(TS, PetscReal t, Vec U, Mat A, Mat B, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscObjectState state;
  PetscFunctionBeginUser;
  if (A == sim->Jmf_) PetscFunctionReturn(0); // applies the model's current parameters itself
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

// Implicit theta methods on a model with constant dG/dU (use_shifted_operator): F = U_t - G(t, U).
PetscErrorCode Simulation::ifunction_cb(TS, PetscReal t, Vec U, Vec Udot, Vec F, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(sim->model_->rhs(t, U, F));
  PetscCall(VecAYPX(F, -1.0, Udot));
  PetscFunctionReturn(0);
}

// dF/dU + shift dF/dU_t = shift*I - A. Refreshes A (J_) if the parameters changed and records the
// shift, which the shell A applies from then on; the assembled P is left alone: shifted_presolve
// makes it shift*I - A right before a solve, and only when it is not that already. TS's adjoint
// calls this with shifts it never solves with (theta's (theta-1)/dt, 0), which cost nothing now.
PetscErrorCode Simulation::ijacobian_cb(TS ts, PetscReal t, Vec U, Vec, PetscReal shift, Mat A, Mat P, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscObjectState before, after;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectStateGet((PetscObject)(Mat)sim->J_, &before));
  PetscCall(rhs_jacobian_cb(ts, t, U, sim->J_, sim->J_, ctx));
  PetscCall(PetscObjectStateGet((PetscObject)(Mat)sim->J_, &after));
  if (A == sim->shifted_ && (shift != sim->shift_ || after != before)) PetscCall(PetscObjectStateIncrease((PetscObject)A));
  sim->shift_ = shift;
  // Anything other than our pair (e.g. -snes_mf_operator's A with our P is fine; a foreign P is
  // not ours to defer): a P we do not own is assembled now.
  if (P != sim->shifted_pc_ && P != A) PetscCall(sim->assemble_shifted(P));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::check_operator_current() const {
  PetscObjectState state;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectStateGet((PetscObject)(Mat)J_, &state));
  PetscCheck(jac_param_version_ == param_version_ && state == jac_state_, grid_->comm(), PETSC_ERR_PLIB,
             "The shifted operator would apply dG/dU of other parameters: no IJacobian evaluation since they changed");
  PetscFunctionReturn(0);
}

// P = shift_*I - A, from J_ = A (current, checked), row by row: P keeps its own pattern (A's and
// the diagonal, entries of an earlier A that the current one lacks hold zeros).
PetscErrorCode Simulation::assemble_shifted(Mat P) {
  PetscBool assembled;
  PetscInt rstart, rend;
  std::vector<PetscInt> cols;
  std::vector<PetscScalar> vals;
  PetscFunctionBeginUser;
  PetscCall(check_operator_current());
  PetscCall(MatAssembled(P, &assembled));
  if (assembled) PetscCall(MatZeroEntries(P));
  PetscCall(MatGetOwnershipRange(J_, &rstart, &rend));
  for (PetscInt i = rstart; i < rend; ++i) {
    PetscInt nc;
    const PetscInt *c;
    const PetscScalar *v;
    PetscCall(MatGetRow(J_, i, &nc, &c, &v));
    cols.assign(c, c + nc);
    vals.resize(nc);
    bool diagonal = false;
    for (PetscInt k = 0; k < nc; ++k) {
      vals[k] = -v[k];
      if (c[k] == i) vals[k] += shift_, diagonal = true;
    }
    PetscCall(MatRestoreRow(J_, i, &nc, &c, &v));
    if (!diagonal) cols.push_back(i), vals.push_back(shift_);
    PetscCall(MatSetValues(P, 1, &i, (PetscInt)cols.size(), cols.data(), vals.data(), INSERT_VALUES));
  }
  PetscCall(MatAssemblyBegin(P, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(P, MAT_FINAL_ASSEMBLY));
  ++pc_builds_;
  PetscFunctionReturn(0);
}

// y = shift*x - A x (and its transpose) for the shift of the last IJacobian call. The transpose uses
// the model's matrix-free dG/dU (at its current parameters) when it has one: one sweep, where AIJ's
// transpose scatters row by row.
template <bool Transpose>
PetscErrorCode Simulation::shifted_apply(Mat M, Vec x, Vec y) {
  Simulation *sim;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(M, &sim));
  PetscCall(sim->check_operator_current());
  if (Transpose) PetscCall(MatMultTranspose(sim->Jmf_ ? (Mat)sim->Jmf_ : (Mat)sim->J_, x, y));
  else PetscCall(MatMult(sim->J_, x, y));
  PetscCall(VecAXPBY(y, sim->shift_, -1.0, x));
  PetscFunctionReturn(0);
}

// Runs before every KSPSolve / KSPSolveTranspose of the TS, ahead of KSPSetUp (which refactors P
// exactly when P's object state changed). P is rebuilt unless it was built from J_ in its current
// state (so for the current parameters), for exactly the same shift, and has not been modified
// since. Exactly: TSAdjoint takes each step's dt as the difference of two stored times, which
// differs from the forward's dt in the last bits now and then (a few dozen of 5000 steps at
// N = 512); P is then rebuilt for that step, as PETSc's own path would, so the gradient is the one
// of PETSc's forming at every step (-adjoint_petsc_step) to round-off. Reusing P across such last-bit
// differences would change the CN advection gradient by 1e-10 relative: not an exact adjoint any more.
PetscErrorCode Simulation::shifted_presolve(KSP ksp, Vec, Vec, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  Mat A, P;
  PetscObjectState jstate, pstate;
  PetscFunctionBeginUser;
  PetscCall(KSPGetOperators(ksp, &A, &P));
  if (P != sim->shifted_pc_) PetscFunctionReturn(0);
  PetscCall(sim->check_operator_current());
  PetscCall(PetscObjectStateGet((PetscObject)(Mat)sim->J_, &jstate));
  PetscCall(PetscObjectStateGet((PetscObject)P, &pstate));
  // The same decision on every rank (object states are per-rank counters), so that the rebuild
  // and the refactorisation it triggers are collective.
  int current = sim->shift_ == sim->pc_shift_ && jstate == sim->pc_from_state_ && pstate == sim->pc_state_ &&
                sim->pc_param_version_ == sim->param_version_;
  MPI_Comm comm = PetscObjectComm((PetscObject)P);
  PetscMPIInt size;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  if (size > 1) PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &current, 1, MPI_INT, MPI_MIN, comm));
  if (current) PetscFunctionReturn(0);
  PetscCall(sim->assemble_shifted(P));
  sim->pc_shift_ = sim->shift_;
  sim->pc_from_state_ = jstate;
  sim->pc_param_version_ = sim->param_version_;
  PetscCall(PetscObjectStateGet((PetscObject)P, &sim->pc_state_));
  PetscFunctionReturn(0);
}

// Switches an implicit theta TS (already configured with the RHS form) to F = U_t - G with the
// shell IJacobian and the lazily rebuilt P above.
PetscErrorCode Simulation::use_shifted_operator(TS ts) {
  OwnedDM dm;
  SNES snes;
  KSP ksp;
  PetscFunctionBeginUser;
  if (!shifted_) {
    PetscInt m, n, M, N;
    PetscCall(MatGetLocalSize(J_, &m, &n));
    PetscCall(MatGetSize(J_, &M, &N));
    PetscCall(MatCreateShell(grid_->comm(), m, n, M, N, this, shifted_.out()));
    PetscCall(MatShellSetOperation(shifted_, MATOP_MULT, (void (*)(void))shifted_apply<false>));
    PetscCall(MatShellSetOperation(shifted_, MATOP_MULT_TRANSPOSE, (void (*)(void))shifted_apply<true>));
  }
  // A new P for every TS (built on its first solve): nothing of an earlier TS's solver (e.g. a
  // MUMPS factorisation on 2 ranks) stays attached to it.
  PetscCall(model_->create_jacobian(shifted_pc_.out()));
  PetscCall(MatSetOption(shifted_pc_, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE));
  pc_state_ = -1;
  // The TS's callbacks live on its DM, and dm_ (shared by every TS of this Simulation) holds the RHS
  // ones, which TSComputeIJacobian would add to the IJacobian: this TS gets a clone of dm_ whose
  // DMTS holds only the implicit form. Setting the IFunction first gives the clone its own DMTS,
  // so TSSetDM does not copy dm_'s over.
  PetscCall(DMClone(dm_, dm.out()));
  PetscCall(DMTSSetIFunction(dm, ifunction_cb, this));
  PetscCall(TSSetDM(ts, dm));
  PetscCall(TSSetIFunction(ts, nullptr, ifunction_cb, this));
  PetscCall(TSSetIJacobian(ts, shifted_, shifted_pc_, ijacobian_cb, this));
  PetscCall(TSGetSNES(ts, &snes));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPSetPreSolve(ksp, shifted_presolve, this));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::adjoint_kick_cb(void *ctx, PetscReal t, Vec U, Vec lambda_q, Vec lambda_p, PetscReal w, Vec mu,
                                           PetscReal drift, const PetscScalar *prefetch) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(sim->model_->second_order_adjoint(t, U, lambda_q, lambda_p, w, mu, drift, prefetch));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::step_cb(void *ctx, PetscReal t, Vec U, PetscScalar *accel, const LeapfrogStepParts &parts) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(sim->model_->second_order_step(t, U, accel, parts));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::split_step_cb(void *ctx, PetscReal t, Vec Q, PetscScalar *v, const LeapfrogSplitParts &parts) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(sim->model_->second_order_split_step(t, Q, v, parts));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::stage_adjoint_cb(void *ctx, PetscReal t, Vec U, const PetscScalar *record,
                                            const StageCombination &x, Vec y, Vec mu) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(x.form(x.scratch));
  PetscCall(sim->model_->stage_adjoint(t, U, record, x.scratch, y, mu));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::quad_rhs_cb(TS, PetscReal t, Vec U, Vec F, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscReal r;
  PetscScalar *f;
  PetscFunctionBeginUser;
  // the leapfrog's split step hands an integrand that reads no velocity the positions alone: an objective
  // that adds its dr/dU in place reads them so (Objective::adds_integrand_dU), others see a state
  if (!sim->objective_->adds_integrand_dU()) PetscCall(sim->integrand_state(U, &U));
  PetscCall(sim->objective_->integrand(t, U, &r));
  PetscCall(VecGetArray(F, &f)); // F is sequential, one entry, on every rank alike
  f[0] = r;
  PetscCall(VecRestoreArray(F, &f));
  PetscFunctionReturn(0);
}

// The cost integrand's share of an RK adjoint stage: y += w dr/dU, mu += w dr/dp at the stage U, or at
// its positions when the record replaces the stage (set up so only for an integrand that reads them alone).
PetscErrorCode Simulation::integrand_stage_cb(void *ctx, PetscReal t, Vec U, Vec positions, PetscReal w, Vec y, Vec mu) {
  auto *sim = static_cast<Simulation *>(ctx);
  Objective &objective = *sim->objective_;
  PetscFunctionBeginUser;
  if (!U) {
    PetscCall(objective.integrand_dU_add(t, positions, w, y));
    PetscFunctionReturn(0);
  }
  if (objective.adds_integrand_dU()) PetscCall(objective.integrand_dU_add(t, U, w, y));
  else {
    PetscCall(objective.integrand_dU(t, U, sim->drdU_col_));
    PetscCall(VecAXPY(y, w, sim->drdU_col_));
  }
  if (mu && objective.integrand_reads_parameters()) {
    PetscCall(objective.integrand_dp(t, U, sim->drdp_col_));
    PetscCall(VecAXPY(mu, w, sim->drdp_col_));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::integrand_adjoint_cb(void *ctx, PetscReal t, Vec X, PetscReal w, Vec lambda) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(sim->objective_->integrand_dU_add(t, X, w, lambda));
  PetscFunctionReturn(0);
}

// The leapfrog's adjoint hands an integrand that reads no velocity the stored positions alone (m per
// grid point, leapfrog_positions_suffice): the objective sees them as a state with zero velocities.
PetscErrorCode Simulation::integrand_state(Vec X, Vec *U) {
  PetscInt n, nx;
  PetscFunctionBeginUser;
  *U = X;
  PetscCall(VecGetLocalSize(lambda_, &n));
  PetscCall(VecGetLocalSize(X, &nx));
  if (nx == n) PetscFunctionReturn(0);
  const PetscInt m = model_->second_order_pairs(), d = model_->dof();
  PetscCheck(m > 0 && nx * d == n * m, grid_->comm(), PETSC_ERR_PLIB, "integrand: a state of %" PetscInt_FMT " local entries",
             nx);
  if (!positions_state_) {
    PetscCall(VecDuplicate(lambda_, positions_state_.out()));
    PetscCall(VecSet(positions_state_, 0.0)); // the velocities stay 0
  }
  ConstArray x(X);
  Array u(positions_state_);
  PetscCall(x.error());
  PetscCall(u.error());
  const PetscScalar *__restrict q = x.data();
  PetscScalar *__restrict w = u.data();
  if (m == 1 && d == 2)
    for (PetscInt i = 0; i < nx; ++i) w[2 * i] = q[i];
  else
    for (PetscInt i = 0; i < nx / m; ++i)
      for (PetscInt c = 0; c < m; ++c) w[i * d + c] = q[i * m + c];
  *U = positions_state_;
  PetscFunctionReturn(0);
}

// The quadrature TS reads column 0 of these dense matrices (MatDenseGetColumn) with the layout of
// lambda (resp. mu), so the objective writes straight into that column.
PetscErrorCode Simulation::quad_jacobian_cb(TS, PetscReal t, Vec U, Mat A, Mat, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscScalar *col;
  PetscFunctionBeginUser;
  PetscCall(sim->integrand_state(U, &U));
  PetscCall(MatDenseGetColumn(A, 0, &col));
  PetscCall(VecPlaceArray(sim->drdU_col_, col));
  PetscCall(sim->objective_->integrand_dU(t, U, sim->drdU_col_));
  PetscCall(VecResetArray(sim->drdU_col_));
  PetscCall(MatDenseRestoreColumn(A, &col));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::quad_jacobian_p_cb(TS, PetscReal t, Vec U, Mat A, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscScalar *col;
  PetscFunctionBeginUser;
  PetscCall(sim->integrand_state(U, &U));
  PetscCall(MatDenseGetColumn(A, 0, &col));
  PetscCall(VecPlaceArray(sim->drdp_col_, col));
  PetscCall(sim->objective_->integrand_dp(t, U, sim->drdp_col_));
  PetscCall(VecResetArray(sim->drdp_col_));
  PetscCall(MatDenseRestoreColumn(A, &col));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::setup_quadrature(TS ts, bool with_adjoint) {
  TS quadts;
  Vec Q;
  PetscFunctionBeginUser;
  if (!objective_ || !objective_->has_integrand()) PetscFunctionReturn(0);
  // Forward accumulation (PETSC_TRUE): the integral is known when TSSolve returns, for value()
  // as for gradient(), and re-run steps of checkpointing do not touch it.
  PetscCall(TSCreateQuadratureTS(ts, PETSC_TRUE, &quadts));
  PetscCall(TSSetRHSFunction(quadts, nullptr, quad_rhs_cb, this));
  PetscCall(TSGetSolution(quadts, &Q));
  PetscCall(VecSet(Q, 0.0));
  MPI_Comm comm = grid_->comm();
  if (!drdU_) {
    PetscInt n;
    PetscCall(VecGetLocalSize(lambda_, &n));
    PetscCall(MatCreateDense(comm, n, PETSC_DECIDE, PETSC_DETERMINE, 1, nullptr, drdU_.out()));
    PetscCall(MatSetUp(drdU_));
    PetscCall(VecDuplicate(lambda_, drdU_col_.out()));
    if (mu_) {
      PetscCall(VecGetLocalSize(mu_, &n));
      PetscCall(MatCreateDense(comm, n, PETSC_DECIDE, PETSC_DETERMINE, 1, nullptr, drdp_.out()));
      PetscCall(MatSetUp(drdp_));
      PetscCall(VecDuplicate(mu_, drdp_col_.out()));
    }
  }
  // TSSetUp_RK asks for the quadrature TS's Jacobian even without an adjoint (and would try to
  // create one from the quadrature TS's shell DM), so it is set for value() too; only TSAdjoint
  // evaluates it.
  PetscCall(TSSetRHSJacobian(quadts, drdU_, drdU_, quad_jacobian_cb, this));
  if (!with_adjoint) PetscFunctionReturn(0);
  // Always set with parameters, even for an integrand that does not depend on them: the adjoint
  // steps read this matrix whenever mu is requested.
  if (drdp_) PetscCall(TSSetRHSJacobianP(quadts, drdp_, quad_jacobian_p_cb, this));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::integral(TS ts, PetscReal *value) {
  TS quadts;
  Vec Q;
  const PetscScalar *q;
  PetscFunctionBeginUser;
  *value = 0;
  PetscCall(TSGetQuadratureTS(ts, nullptr, &quadts));
  if (!quadts) PetscFunctionReturn(0);
  PetscCall(TSGetSolution(quadts, &Q));
  PetscCall(VecGetArrayRead(Q, &q));
  *value = PetscRealPart(q[0]);
  PetscCall(VecRestoreArrayRead(Q, &q));
  PetscFunctionReturn(0);
}

// A whole number of equal steps to T, the nearest to T / dt; dt becomes T / steps.
static PetscInt whole_steps(PetscReal T, PetscReal *dt) {
  const PetscInt nsteps = std::max<PetscInt>(1, (PetscInt)std::llround(T / *dt));
  *dt = T / nsteps;
  return nsteps;
}

PetscErrorCode Simulation::time_step(PetscReal *dt) const {
  PetscReal T = final_time_;
  PetscFunctionBeginUser;
  *dt = dt_;
  PetscCall(PetscOptionsGetReal(nullptr, nullptr, "-ts_dt", dt, nullptr));
  PetscCall(PetscOptionsGetReal(nullptr, nullptr, "-ts_max_time", &T, nullptr));
  if (*dt > 0 && T > 0) (void)whole_steps(T, dt); // (create_ts reports bad values)
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::initial_condition(Vec p, Vec U0) {
  PetscFunctionBeginUser;
  PetscCall(time_step(&start_dt_));
  model_->set_time_step(start_dt_);
  PetscCall(model_->set_parameters(p));
  PetscCall(model_->initial_condition(p, U0));
  PetscFunctionReturn(0);
}

// A second-order model's G_p = a(t, q) - sigma(x) p: sigma is -dG/dU applied to the unit velocities, in
// their rows (the Jacobian of any state: sigma depends on none, nor on the parameters; but the model
// holds its coefficients from its first set_parameters on, so it is found again for every TS).
PetscErrorCode Simulation::leapfrog_damping(Vec *sigma) {
  const PetscInt m = model_->second_order_pairs(), d = model_->dof();
  PetscScalar *a;
  PetscInt n;
  PetscReal largest;
  PetscFunctionBeginUser;
  *sigma = nullptr;
  if (!damping_) {
    PetscCall(DMCreateGlobalVector(dm_, damping_.out()));
    PetscCall(VecDuplicate(damping_, velocities_.out()));
    PetscCall(VecGetLocalSize(velocities_, &n));
    PetscCall(VecGetArrayWrite(velocities_, &a));
    for (PetscInt i = 0; i < n; ++i) a[i] = i % d >= m && i % d < 2 * m ? 1.0 : 0.0;
    PetscCall(VecRestoreArrayWrite(velocities_, &a));
  }
  if (Jmf_) PetscCall(MatMult(Jmf_, velocities_, damping_));
  else {
    OwnedVec zero;
    PetscCall(VecDuplicate(damping_, zero.out()));
    PetscCall(VecSet(zero, 0.0));
    PetscCall(model_->rhs_jacobian(0.0, zero, J_));
    PetscCall(MatMult(J_, velocities_, damping_));
    jac_state_ = -1; // assembled at another state: not the TS's
  }
  PetscCall(VecGetLocalSize(damping_, &n));
  PetscCall(VecGetArray(damping_, &a));
  for (PetscInt i = 0; i < n; ++i) a[i] = i % d >= m && i % d < 2 * m ? -a[i] : 0.0;
  PetscCall(VecRestoreArray(damping_, &a));
  PetscCall(VecNorm(damping_, NORM_INFINITY, &largest));
  if (largest == 0) PetscFunctionReturn(0);
  PetscReal smallest;
  PetscCall(VecMin(damping_, nullptr, &smallest));
  PetscCheck(smallest >= 0, grid_->comm(), PETSC_ERR_ARG_WRONG,
             "-ts_type leapfrog: model %s's velocity damping -dG_p/dp is negative somewhere (%g): it would amplify",
             model_->name(), (double)smallest);
  *sigma = damping_;
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::create_ts(bool with_adjoint, OwnedTS &ts, bool with_integral) {
  MPI_Comm comm = grid_->comm();
  PetscMPIInt size;
  PetscBool stability_check = PETSC_TRUE;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(TSCreate(comm, ts.out()));
  PetscCall(TSSetDM(ts, dm_));
  PetscCall(TSSetProblemType(ts, model_->linear() ? TS_LINEAR : TS_NONLINEAR));
  PetscCall(TSSetRHSFunction(ts, nullptr, rhs_cb, this));
  PetscCall(TSSetRHSJacobian(ts, J_, J_, rhs_jacobian_cb, this)); // (J_ null: set below once the type asks for it)
  PetscCall(TSSetType(ts, TSRK));
  PetscCall(TSRKSetType(ts, TSRK4));
  PetscCall(TSSetTimeStep(ts, dt_));
  PetscCall(TSSetMaxTime(ts, final_time_));
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
  { // fixed steps unless the user asks for adaptivity (-ts_adapt_type basic)
    TSAdapt adapt;
    PetscCall(TSGetAdapt(ts, &adapt));
    PetscCall(TSAdaptSetType(adapt, TSADAPTNONE));
  }
  { // implicit methods: a direct solve by default, so that adjoint gradients are exact
    SNES snes;
    KSP ksp;
    PC pc;
    PetscCall(TSGetSNES(ts, &snes));
    PetscCall(SNESGetKSP(snes, &ksp));
    PetscBool shell;
    PetscCall(KSPGetPC(ksp, &pc));
    PetscCall(PetscObjectTypeCompare((PetscObject)(Mat)J_, MATSHELL, &shell)); // (J_ null: an assembled one to come)
    if (shell) { // a matrix-free dG/dU (spectral) cannot be factored: unpreconditioned GMRES, tight
      PetscCall(KSPSetType(ksp, KSPGMRES));
      PetscCall(PCSetType(pc, PCNONE));
      PetscCall(KSPSetTolerances(ksp, 1e-13, 1e-50, PETSC_DEFAULT, 2000));
    } else {
      // On several ranks: up to -sim_redundant_lu_max unknowns every rank factors the whole matrix
      // (PCREDUNDANT, sequential LU; a solve is then one gather and a local solve), beyond that MUMPS.
      // A distributed factorisation of a small operator is all communication (and MUMPS refactors
      // every step here, below), while the redundant LU reuses its factors.
      PetscInt nglobal, redundant_max = 200000;
      PetscCall(VecGetSize(lambda_, &nglobal));
      PetscOptionsBegin(comm, nullptr, "Simulation: implicit solves", "Simulation");
      PetscCall(PetscOptionsInt("-sim_redundant_lu_max", "On several ranks, factor dG/dU-shifted systems of up to this many "
                                "unknowns whole on every rank (PCREDUNDANT LU); larger ones with MUMPS",
                                "Simulation", redundant_max, &redundant_max, nullptr));
      PetscOptionsEnd();
      PetscCall(KSPSetType(ksp, KSPPREONLY));
      if (size > 1 && nglobal <= redundant_max) PetscCall(PCSetType(pc, PCREDUNDANT)); // its inner solver: LU
      else {
        PetscCall(PCSetType(pc, PCLU));
        if (size > 1) PetscCall(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
      }
    }
  }
  if (with_adjoint) {
    // Full storage (every state, solution only), or binomial checkpointing within
    // -checkpoint_budget states (checkpoint.hpp); what it cost lands in checkpoint_stats_.
    PetscCall(setup_adjoint_trajectory(ts, &checkpoint_stats_));
    if (Jp_) PetscCall(TSSetRHSJacobianP(ts, Jp_, rhs_jacobian_p_cb, this));
  }
  if (with_integral) PetscCall(setup_quadrature(ts, with_adjoint));
  PetscCall(register_leapfrog_ts());
  PetscCall(TSSetFromOptions(ts));
  if (with_adjoint) {
    TSTrajectory tj;
    PetscCall(TSGetTrajectory(ts, &tj));
    PetscCall(store_trajectory_use_buffer(tj, &trajectory_buffer_));
  }
  PetscOptionsBegin(comm, nullptr, "Simulation", "Simulation");
  PetscCall(PetscOptionsBool("-sim_stability_check", "Refuse explicit steps beyond the stability limit", "Simulation",
                             stability_check, &stability_check, nullptr));
  PetscCall(PetscOptionsInt("-sim_blowup_check_every", "Stop with the time and step where the state first holds "
                            "NaN/Inf, checked every N steps (0 = only at the end)",
                            "Simulation", blowup_every_, &blowup_every_, nullptr));
  PetscCall(PetscOptionsBool("-adjoint_petsc_step", "Use PETSc's own TSAdjointStep (rk, theta, cn, beuler; implicit "
                             "methods on linear models then also form and factor shift*I - dG/dU at every step, as PETSc "
                             "does) instead of flexipde's adjoint steps, and the leapfrog's adjoint through the model's "
                             "Jacobians instead of its fused kick; slower, for checking", "Simulation", petsc_step_,
                             &petsc_step_, nullptr));
  PetscOptionsEnd();
  PetscCheck(blowup_every_ >= 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-sim_blowup_check_every must be non-negative");
  if (blowup_every_ > 0) {
    PetscCall(TSMonitorSet(ts, blowup_monitor, this, nullptr));
    PetscCall(leapfrog_monitor_forms_solution(ts, blowup_monitor));
  }

  TSType type;
  PetscCall(TSGetType(ts, &type));
  const bool leapfrog = is_leapfrog(ts);
  const bool has_adjoint = !std::strcmp(type, TSRK) || !std::strcmp(type, TSTHETA) || !std::strcmp(type, TSCN) ||
                           !std::strcmp(type, TSBEULER) || leapfrog;
  PetscCheck(!with_adjoint || has_adjoint, comm, PETSC_ERR_SUP,
             "-ts_type %s has no adjoint in flexipde: choose rk, theta, cn, beuler or leapfrog", type);
  // The leapfrog's adjoint through the model's fused kick when it has one (else through its Jacobians).
  leapfrog_fused_ = leapfrog && with_adjoint && model_->has_second_order_adjoint() && !petsc_step_;
  // Explicit RK applies Jmf_ (below), the leapfrog steps and its fused adjoint never form dG/dU: any
  // other TS gets the assembled one.
  const bool matrix_free = !std::strcmp(type, TSRK) || (leapfrog && (!with_adjoint || leapfrog_fused_));
  if (!J_ && !matrix_free) {
    PetscCall(make_jacobian(*model_, J_));
    PetscCall(TSSetRHSJacobian(ts, J_, J_, rhs_jacobian_cb, this));
  }
  {
    PetscBool shell;
    PetscCall(PetscObjectTypeCompare((PetscObject)(Mat)J_, MATSHELL, &shell));
    const bool theta = !std::strcmp(type, TSTHETA) || !std::strcmp(type, TSCN) || !std::strcmp(type, TSBEULER);
    // Not with MUMPS: with it the 2-rank unit suite hangs now and then inside MatSolve_MUMPS's first
    // VecScatterCreate after switching between theta TSs (cause unknown). The redundant LU
    // (several ranks, small operators) and the sequential one reuse their factors.
    PetscBool redundant = PETSC_FALSE; // (what the options left: -pc_type may have replaced it)
    if (theta && size > 1) {
      SNES snes;
      KSP ksp;
      PC pc;
      PetscCall(TSGetSNES(ts, &snes));
      PetscCall(SNESGetKSP(snes, &ksp));
      PetscCall(KSPGetPC(ksp, &pc));
      PetscCall(PetscObjectTypeCompare((PetscObject)pc, PCREDUNDANT, &redundant));
    }
    if (theta && !petsc_step_ && (size == 1 || redundant) && model_->linear() && model_->jacobian_constant() && !shell)
      PetscCall(use_shifted_operator(ts));
  }
  if (leapfrog) {
    PetscCheck(model_->second_order_pairs() > 0, comm, PETSC_ERR_ARG_WRONG,
               "-ts_type leapfrog needs a model in second-order form (q_t = p, p_t = a(t, q) - sigma p); model %s is "
               "not, with these options: choose -ts_type rk, theta, cn or beuler",
               model_->name());
    PetscCall(leapfrog_set_pairs(ts, model_->second_order_pairs()));
    Vec sigma;
    PetscCall(leapfrog_damping(&sigma));
    PetscCall(leapfrog_set_damping(ts, sigma));
    if (objective_ && objective_->has_integrand()) {
      bool velocities = false;
      for (PetscInt c = model_->second_order_pairs(); c < 2 * model_->second_order_pairs(); ++c)
        velocities = velocities || objective_->integrand_reads_component(c);
      PetscCall(leapfrog_set_integrand_reads(ts, velocities, objective_->integrand_reads_parameters()));
      if (objective_->adds_integrand_dU()) PetscCall(leapfrog_set_integrand_adjoint(ts, integrand_adjoint_cb, this));
    }
    if (leapfrog_fused_)
      PetscCall(leapfrog_set_adjoint_kick(ts, adjoint_kick_cb, this));
    const size_t state_bytes = (size_t)grid_->local_points() * model_->dof() * sizeof(PetscScalar);
    if (model_->has_second_order_step() && leapfrog_one_sweep_pays(state_bytes + state_bytes / 2)) // U and a
      PetscCall(leapfrog_set_step(ts, step_cb, this));
    if (model_->has_second_order_step()) PetscCall(leapfrog_set_split_step(ts, split_step_cb, this));
  }
  // An explicit RK only applies dG/dU (its adjoint: the transpose): the model's matrix-free operator
  // when it has one.
  if (Jmf_ && !std::strcmp(type, TSRK)) {
    PetscCall(TSSetRHSJacobian(ts, Jmf_, Jmf_, rhs_jacobian_cb, this));
    // PETSc's RK adjoint asks SNESComputeJacobian for dG/dU at every stage, which also runs its
    // -snes_test_* options checks each time; the matrix-free operator never needs recomputing (it
    // applies the model's current parameters), so the SNES evaluates it once and then reuses it.
    SNES snes;
    PetscCall(TSGetSNES(ts, &snes));
    PetscCall(SNESSetLagJacobian(snes, -2));
    PetscCall(SNESSetLagJacobianPersists(snes, PETSC_TRUE));
  }
  PetscCall(rk_step_install(ts)); // explicit RK: stages formed in one pass (rk_step.hpp)
  // flexipde's own adjoint steps (rk_adjoint.hpp, theta_adjoint.hpp) unless PETSc's are asked for.
  if (with_adjoint && !petsc_step_) // only theta types
    PetscCall(theta_adjoint_install(ts, model_->linear() && model_->jacobian_constant()));
  rk_stage_fused_ = with_adjoint && !petsc_step_ && !std::strcmp(type, TSRK) && model_->has_stage_adjoint();
  rk_stage_records_ = rk_stage_fused_ && model_->stage_record_size() > 0;
  if (rk_stage_fused_) {
    RkStageNeeds needs;
    if (rk_stage_records_) {
      needs.record_size = model_->stage_record_size();
      needs.record_replaces = model_->stage_record_replaces_state();
    }
    PetscCall(rk_adjoint_install(ts, stage_adjoint_cb, this, needs));
    if (objective_ && objective_->has_integrand()) {
      // A stage record that replaces the stage holds its positions (Model::stage_record_replaces_state):
      // enough for a sparse integrand of the positions alone (the receivers).
      const PetscInt m = model_->second_order_pairs();
      bool from_records = needs.record_replaces && m > 0 && needs.record_size == grid_->local_points() * m &&
                          objective_->adds_integrand_dU() && !objective_->integrand_reads_parameters();
      for (PetscInt c = m; c < model_->dof(); ++c) from_records = from_records && !objective_->integrand_reads_component(c);
      PetscCall(rk_adjoint_set_integrand(ts, integrand_stage_cb, this, from_records));
    }
  }
  if (with_adjoint && Jp_ && !std::strcmp(type, TSRK)) {
    // PETSc 3.18's TSAdjointStep_RK skips dG/dp for a stage whose weight b_i is zero (it rescales
    // a stale vector instead), so parameter gradients of such tableaux are wrong. The FSAL last
    // stage is skipped on purpose and is harmless.
    PetscInt s;
    const PetscReal *b;
    PetscBool fsal;
    TSRKType rktype;
    PetscCall(TSRKGetType(ts, &rktype));
    PetscCall(TSRKGetTableau(ts, &s, nullptr, &b, nullptr, nullptr, nullptr, nullptr, &fsal));
    for (PetscInt i = 0; i < s - (fsal ? 1 : 0); ++i)
      PetscCheck(b[i] != 0.0, comm, PETSC_ERR_SUP,
                 "-ts_rk_type %s has a zero weight b_%" PetscInt_FMT ", for which PETSc 3.18's adjoint gives wrong "
                 "parameter gradients: choose -ts_rk_type 1fe, 2a, 3, 3bs, 4 or an implicit -ts_type",
                 rktype, i + 1);
  }
  PetscReal dt, T;
  PetscCall(TSGetTimeStep(ts, &dt));
  PetscCall(TSGetMaxTime(ts, &T));
  PetscCheck(dt > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-ts_dt must be positive, got %g", (double)dt);
  PetscCheck(T > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-ts_max_time must be positive, got %g", (double)T);
  // A whole number of equal steps, so that forward and adjoint visit the same times; an adaptive
  // step (the user's choice) runs to T with as many steps as it needs.
  TSAdapt adapt;
  TSAdaptType adapt_type;
  PetscCall(TSGetAdapt(ts, &adapt));
  PetscCall(TSAdaptGetType(adapt, &adapt_type));
  adaptive_ = std::strcmp(adapt_type, TSADAPTNONE) != 0;
  PetscCheck(!(adaptive_ && leapfrog), comm, PETSC_ERR_SUP,
             "-ts_type leapfrog takes fixed steps only (it is symplectic for a constant dt): remove -ts_adapt_type %s",
             adapt_type);
  PetscReal fixed_dt = dt;
  const PetscInt nsteps = whole_steps(T, &fixed_dt);
  if (!adaptive_) {
    dt = fixed_dt;
    // the solve's initial condition, made just before, was made for this step (time_step read the options)
    PetscCheck(start_dt_ == 0 || dt == start_dt_, comm, PETSC_ERR_PLIB,
               "The integrator's step %.17g differs from the step %.17g the initial condition was made for", (double)dt,
               (double)start_dt_);
    PetscCall(TSSetTimeStep(ts, dt));
    PetscCall(TSSetMaxSteps(ts, nsteps));
  } else {
    PetscCall(TSSetMaxSteps(ts, PETSC_MAX_INT));
  }
  start_dt_ = 0;
  stats_.steps = nsteps;
  stats_.dt = dt;
  stats_.final_time = T;
  std::strncpy(stats_.ts_type, type, sizeof(stats_.ts_type) - 1);
  if (stability_check) PetscCall(check_stability(ts));
  PetscFunctionReturn(0);
}

// Stability of the chosen one-step method for dU/dt = lambda U: its stability function R(z) is
// checked along the imaginary and negative real axes up to z = dt * (spectral radius). RK tableaux
// give R(z) = 1 + z b^T (I - zA)^{-1} 1 (by stage recursion), theta methods
// R(z) = (1 + (1-theta) z) / (1 - theta z), explicit Euler 1 + z. Returns the largest stable
// |z| along the axis up to zmax (zmax itself when stable throughout).
static PetscReal axis_limit(const std::function<std::complex<double>(std::complex<double>)> &R, std::complex<double> dir,
                            PetscReal zmax) {
  const int n = 4000;
  const double dz = std::min<double>(zmax, 8.0) / n;
  double last_ok = 0;
  for (double r = dz; r <= zmax * (1 + 1e-12); r += (r < 8.0 ? dz : r * 1e-3)) {
    if (std::abs(R(r * dir)) > 1.0 + 1e-12) return last_ok;
    last_ok = r;
  }
  return zmax;
}

// Sampled eigenvalues (Spectrum::samples): every |R(dt lambda)| <= 1 at the given dt, else the
// largest stable dt by bisection (the stable set of these methods is star-shaped along each ray).
static bool all_stable(const std::function<std::complex<double>(std::complex<double>)> &R,
                       const std::vector<std::complex<PetscReal>> &ev, double t) {
  for (const auto &l : ev)
    if (std::abs(R(t * std::complex<double>(l))) > 1.0 + 1e-12) return false;
  return true;
}

static PetscErrorCode check_sampled_stability(const std::function<std::complex<double>(std::complex<double>)> &R,
                                              const std::string &method, const std::vector<std::complex<PetscReal>> &ev,
                                              PetscReal dt, MPI_Comm comm) {
  PetscFunctionBeginUser;
  if (all_stable(R, ev, dt)) PetscFunctionReturn(0);
  double lo = 0, hi = dt, rmax = 0;
  for (int k = 0; k < 60; ++k) {
    const double mid = 0.5 * (lo + hi);
    (all_stable(R, ev, mid) ? lo : hi) = mid;
  }
  for (const auto &l : ev) rmax = std::max<double>(rmax, std::abs(l));
  bool real = true, imag = true;
  for (const auto &l : ev) {
    if (std::fabs(l.imag()) > 1e-12 * rmax) real = false;
    if (std::fabs(l.real()) > 1e-12 * rmax) imag = false;
  }
  const char *what = imag ? "oscillatory (imaginary)" : real ? "diffusive (negative real)" : "mixed (complex)";
  PetscCheck(lo * rmax > 1e-2, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "%s is unstable for this model's %s spectrum at any dt; use -ts_rk_type 3, 4 or 5dp, or an implicit "
             "-ts_type (cn, beuler)",
             method.c_str(), what);
  SETERRQ(comm, PETSC_ERR_ARG_OUTOFRANGE,
          "Explicit step beyond the stability limit: dt = %g but %s is stable for this model's %s spectrum "
          "(radius %g, %zu sampled eigenvalues) only up to dt = %g",
          (double)dt, method.c_str(), what, rmax, ev.size(), lo);
}

PetscErrorCode Simulation::check_stability(TS ts) {
  TSType type;
  std::function<std::complex<double>(std::complex<double>)> R;
  std::string method;
  PetscFunctionBeginUser;
  PetscCall(TSGetType(ts, &type));
  if (!std::strcmp(type, TSRK)) {
    PetscInt s;
    const PetscReal *A, *b;
    TSRKType rktype;
    PetscCall(TSRKGetType(ts, &rktype));
    PetscCall(TSRKGetTableau(ts, &s, &A, &b, nullptr, nullptr, nullptr, nullptr, nullptr));
    std::vector<PetscReal> Av(A, A + s * s), bv(b, b + s);
    R = [s, Av, bv](std::complex<double> z) {
      std::vector<std::complex<double>> Y(s);
      std::complex<double> r = 1.0;
      for (PetscInt i = 0; i < s; ++i) {
        Y[i] = 1.0;
        for (PetscInt j = 0; j < i; ++j) Y[i] += z * Av[i * s + j] * Y[j];
        r += z * bv[i] * Y[i];
      }
      return r;
    };
    method = std::string("-ts_rk_type ") + rktype;
  } else if (!std::strcmp(type, TSEULER)) {
    R = [](std::complex<double> z) { return 1.0 + z; };
    method = "-ts_type euler";
  } else if (!std::strcmp(type, TSTHETA) || !std::strcmp(type, TSCN) || !std::strcmp(type, TSBEULER)) {
    PetscReal th = 1.0;
    if (!std::strcmp(type, TSCN)) th = 0.5;
    else if (!std::strcmp(type, TSTHETA)) PetscCall(TSThetaGetTheta(ts, &th));
    if (th >= 0.5) PetscFunctionReturn(0); // A-stable
    R = [th](std::complex<double> z) { return (1.0 + (1.0 - th) * z) / (1.0 - th * z); };
    method = "-ts_type theta with theta " + std::to_string(th);
  } else if (is_leapfrog(ts)) {
    // Stormer-Verlet on q'' = -omega^2 q is stable for dt omega < 2; omega is the imaginary radius.
    Spectrum sp;
    PetscCall(model_->spectrum(&sp));
    const PetscReal dt = stats_.dt, limit = 2.0 / sp.imag_radius;
    PetscCheck(sp.imag_radius <= 0 || dt < limit * (1 - 1e-12), grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "Explicit step beyond the stability limit: dt = %g but -ts_type leapfrog is stable only for "
               "dt * omega_max < 2, i.e. dt < %g here (omega_max = %g)",
               (double)dt, (double)limit, (double)sp.imag_radius);
    PetscFunctionReturn(0);
  } else {
    PetscFunctionReturn(0); // no stability function known here
  }
  Spectrum sp;
  PetscCall(model_->spectrum(&sp));
  const PetscReal dt = stats_.dt;
  if (!sp.samples.empty()) PetscCall(check_sampled_stability(R, method, sp.samples, dt, grid_->comm()));
  if (!sp.samples.empty()) PetscFunctionReturn(0);
  struct Axis {
    const char *what;
    PetscReal radius;
    std::complex<double> dir;
  } axes[2] = {{"oscillatory (imaginary)", sp.imag_radius, {0, 1}}, {"diffusive (negative real)", sp.real_radius, {-1, 0}}};
  for (auto &ax : axes) {
    if (ax.radius <= 0) continue;
    const PetscReal zmax = dt * ax.radius, lim = axis_limit(R, ax.dir, zmax);
    if (lim >= zmax) continue;
    PetscCheck(lim > 1e-2, grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE,
               "%s is unstable for this model's %s spectrum at any dt; use -ts_rk_type 3, 4 or 5dp, or an implicit "
               "-ts_type (cn, beuler)",
               method.c_str(), ax.what);
    SETERRQ(grid_->comm(), PETSC_ERR_ARG_OUTOFRANGE,
            "Explicit step beyond the stability limit: dt = %g but %s is stable for this model's %s spectrum "
            "(radius %g) only up to dt = %g",
            (double)dt, method.c_str(), ax.what, (double)ax.radius, (double)(lim / ax.radius));
  }
  PetscFunctionReturn(0);
}

// A monitor, so that it runs after every accepted step of TSSolve (and not in the steps the
// checkpointing trajectory re-runs, which repeat steps already checked).
PetscErrorCode Simulation::blowup_monitor(TS ts, PetscInt step, PetscReal t, Vec U, void *ctx) {
  auto *sim = static_cast<Simulation *>(ctx);
  PetscReal nrm;
  PetscFunctionBeginUser;
  if (step % sim->blowup_every_) PetscFunctionReturn(0);
  PetscCall(leapfrog_form_solution(ts)); // (U is the TS's solution)
  PetscCall(VecNorm(U, NORM_2, &nrm));
  PetscCheck(std::isfinite((double)nrm), sim->grid_->comm(), PETSC_ERR_FP,
             "The solution holds NaN/Inf at t = %g (step %" PetscInt_FMT " of %" PetscInt_FMT ", dt = %g): reduce -ts_dt, "
             "check the parameters, or use an implicit -ts_type (cn, beuler)",
             (double)t, step, sim->stats_.steps, (double)sim->stats_.dt);
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

PetscErrorCode Simulation::finish_solve(TS ts) {
  PetscReal t;
  PetscFunctionBeginUser;
  PetscCall(TSGetStepNumber(ts, &stats_.steps));
  PetscCall(TSGetSolveTime(ts, &t));
  PetscCheck(std::fabs(t - stats_.final_time) <= 1e-10 * std::max<PetscReal>(1.0, stats_.final_time), grid_->comm(),
             PETSC_ERR_NOT_CONVERGED, "The integrator stopped at t = %g before the final time %g after %" PetscInt_FMT " steps",
             (double)t, (double)stats_.final_time, stats_.steps);
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
  PetscCall(initial_condition(p, UT));
  PetscCall(create_ts(false, ts, false));
  PetscCall(TSSolve(ts, UT));
  PetscCall(finish_solve(ts));
  PetscCall(check_finite(UT, "forward solve"));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::value(Vec p, PetscReal *J) {
  OwnedTS ts;
  OwnedVec U;
  PetscReal integral_part;
  PetscFunctionBeginUser;
  PetscCheck(objective_, grid_->comm(), PETSC_ERR_ORDER, "Simulation::value needs an objective");
  ++param_version_;
  PetscCall(DMCreateGlobalVector(dm_, U.out()));
  PetscCall(initial_condition(p, U));
  PetscCall(create_ts(false, ts));
  PetscCall(TSSolve(ts, U));
  PetscCall(finish_solve(ts));
  PetscCall(check_finite(U, "forward solve"));
  PetscCall(objective_->terminal(U, J, nullptr));
  PetscCall(integral(ts, &integral_part));
  *J += integral_part;
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::gradient(Vec p, PetscReal *J, Vec grad_p, Vec grad_u0) {
  OwnedTS ts;
  OwnedVec U;
  PetscFunctionBeginUser;
  PetscCheck(objective_, grid_->comm(), PETSC_ERR_ORDER, "Simulation::gradient needs an objective");
  ++param_version_;
  PetscCall(DMCreateGlobalVector(dm_, U.out()));
  PetscCall(initial_condition(p, U));
  PetscCall(create_ts(true, ts));
  double t0 = MPI_Wtime();
  PetscCall(TSSolve(ts, U));
  stats_.solve_seconds = MPI_Wtime() - t0;
  PetscCall(finish_solve(ts));
  PetscCall(check_finite(U, "forward solve"));
  PetscCall(objective_->terminal(U, J, lambda_));
  {
    PetscReal integral_part;
    PetscCall(integral(ts, &integral_part));
    *J += integral_part;
  }
  Vec lam = lambda_, mu = mu_;
  if (mu) PetscCall(VecSet(mu, 0.0));
  PetscCall(TSSetCostGradients(ts, 1, &lam, mu ? &mu : nullptr));
  {
    // The leapfrog's fused kick adds to a scalar's gradient at every time level: those sums are
    // reduced once, after the adjoint, instead of once per level (a collective per step on 2 ranks).
    // An -ts_adjoint_monitor sees a scalar's entry of mu without them until the end.
    // So does an explicit RK adjoint through Model::stage_adjoint, once per stage.
    const bool defer = mu && ((is_leapfrog(ts) && leapfrog_fused_) || rk_stage_fused_);
    // The model's maps common to all its parameter sums are applied once, at the end (Model::begin_adjoint).
    struct Cancel { // an adjoint that fails leaves no deferral behind
      const Parameters *p;
      Model *m;
      ~Cancel() {
        if (p) p->defer_sums(nullptr);
        if (m) (void)m->end_adjoint(nullptr);
      }
    } cancel{defer ? params_ : nullptr, mu ? model_ : nullptr};
    if (defer) params_->defer_sums(mu);
    if (mu) model_->begin_adjoint();
    t0 = MPI_Wtime();
    PetscCall(TSAdjointSolve(ts));
    stats_.adjoint_seconds = MPI_Wtime() - t0;
    if (defer) PetscCall(params_->flush_sums());
    if (mu) {
      cancel.m = nullptr;
      PetscCall(model_->end_adjoint(mu));
    }
  }
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
