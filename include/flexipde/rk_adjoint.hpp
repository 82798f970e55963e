// The adjoint step of an explicit Runge-Kutta TS (TSRK), with fewer passes over the state.
//
// For U_{n+1} = U_n + h sum_i b_i K_i, K_i = G(t_n + c_i h, Y_i), Y_i = U_n + h sum_{j<i} a_ij K_j, the
// discrete adjoint of one step is, for i = s-1, ..., 0,
//   W_i        = b_i lambda_{n+1} + sum_{j>i} a_ji dLambda_j
//   dLambda_i  = h (dG/dU)(Y_i)^T W_i,        mu += h (dG/dp)(Y_i)^T W_i
// and then lambda_n = lambda_{n+1} + sum_i dLambda_i. PETSc 3.18's TSAdjointStep_RK computes the same
// numbers (it divides W_i by b_i and multiplies back) with a copy, a multi-AXPY and two scalings per
// stage. Here h W_i is formed in one pass over the state and handed to the transposes unscaled, so a
// stage costs one pass plus the model's products, which it fuses (Model::stage_adjoint): one call per
// stage gives (dG/dU)^T and (dG/dp)^T of the same vector, instead of evaluating and applying both
// Jacobians (no Jacobian callbacks, no copy of the parameter product). Stages with b_i = 0 are handled
// by the same formula (PETSc's skips their dG/dp). Zero a_ji are skipped.
//
// A cost integrand int r(t, U) dt (PETSc's quadrature TS, integrated forward with the RK's own weights)
// adds its share to each stage, dLambda_i += h b_i (dr/dU)(Y_i)^T and mu += h b_i (dr/dp)(Y_i)^T, through
// an integrand hook (rk_adjoint_set_integrand), so a sparse dr/dU (receivers) costs a few entries
// instead of a dense column and a pass over the state.
//
// Used for first-order adjoints of non-FSAL tableaux, for models with the fused stage products and,
// with a cost integrand, an integrand hook; anything else goes to TSRK's own adjoint step, as
// everything does with -adjoint_petsc_step (read by the Simulation).
#pragma once
#include "flexipde/petsc.hpp"
#include <petscts.h>

namespace flexipde {

// The vector x = h W_i of an adjoint stage, handed to a stage hook unformed: x = c0 x0 + sum_{j<m} c[j] X[j]
// (for the classical RK4, one term besides x0). A model that copies x anyway (into a ghosted array,
// say) forms it there in the same pass; any other calls form() into `scratch` (a Vec like x0, free for
// the hook's use) first.
struct StageCombination {
  PetscScalar c0 = 0;
  Vec x0 = nullptr;
  PetscInt m = 0;
  const PetscScalar *c = nullptr;
  const Vec *X = nullptr;
  Vec scratch = nullptr;
  // w = the combination, in one pass (w may be scratch).
  PetscErrorCode form(Vec w) const;
  // The same on raw local arrays: out[k] = c0 a0[k] + sum_j c[j] a[j][k], k < n (m <= 3 in one pass).
  static void form_local(PetscInt n, PetscScalar c0, const PetscScalar *a0, PetscInt m, const PetscScalar *c,
                         const PetscScalar *const *a, PetscScalar *out);
};

// x += sum_{j<s} w[j] K[j] (an RK step's closing sum, or the adjoint's sum of the stages' increments).
// For s <= 4 in a loop of its own that keeps VecMAXPY's order of operations, x + (((w0 K0 + w1 K1) +
// w2 K2) + w3 K3), so the same numbers, without the pointer loop of PETSc 3.18's kernel that the
// compiler does not vectorise; else VecMAXPY.
PetscErrorCode add_weighted(Vec x, PetscInt s, const PetscScalar *w, const Vec *K);

// A stage's products in one call, at stage state U: y = (dG/dU)^T x and, unless mu is null,
// mu += (dG/dp)^T x (Model::stage_adjoint), with x given as its combination. `record`: what evaluating
// G at the stage recorded of it in the forward solve (Model::stage_record_size; null when nothing was
// recorded); U is null when the record replaces the stage (Model::stage_record_replaces_state).
typedef PetscErrorCode (*RkStageAdjoint)(void *ctx, PetscReal t, Vec U, const PetscScalar *record,
                                         const StageCombination &x, Vec y, Vec mu);

// What a stage hook can read of each stage besides its state: record_size > 0 when it reads a record of
// record_size local entries per stage that the forward's own evaluations of G write
// (Model::stage_record_size), replacing the stage itself when record_replaces (full storage then keeps
// the records alone, trajectory_store.cpp).
struct RkStageNeeds {
  PetscInt record_size = 0;
  bool record_replaces = false;
};

// After the TS's type is final: if it is TSRK, its adjoint step becomes the one above (idempotent), each
// stage calling the stage hook (required). lambda_n = lambda_{n+1} + sum_i dLambda_i goes in a
// vectorisable pass of its own for s <= 4 (the same numbers as VecMAXPY's, whose pointer loop is not
// vectorised), else VecMAXPY.
PetscErrorCode rk_adjoint_install(TS ts, RkStageAdjoint stage, void *stage_ctx, RkStageNeeds needs = {});
// The cost integrand's share of one stage, at the stage's time t: y += w (dr/dU)(t, U)^T and, unless mu
// is null, mu += w (dr/dp)(t, U)^T, with w = h b_i, at the stage U or, when the stage's record replaces it
// (U null; only for a hook set with from_records), at the record, handed as a Vec on the TS's
// communicator (record_size local entries).
typedef PetscErrorCode (*RkIntegrandAdjoint)(void *ctx, PetscReal t, Vec U, Vec record, PetscReal w, Vec y, Vec mu);

// After rk_adjoint_install: the hook for a cost integrand (one cost function); without one, a TS with a
// cost integrand takes TSRK's own adjoint step. from_records: the hook works from a stage's record alone
// (else, when the records would replace the stages, whole stages are kept).
PetscErrorCode rk_adjoint_set_integrand(TS ts, RkIntegrandAdjoint integrand, void *integrand_ctx, bool from_records);
// What the installed adjoint can work from for a non-FSAL tableau (else all zero: whole stages needed,
// no records).
PetscErrorCode rk_adjoint_stage_needs(TS ts, RkStageNeeds *needs);
// Records. Forward: the evaluations of G at stage i of the following steps write their record to
// base + i * stride (base = null: no records), rk_adjoint_record_target telling an RHS evaluation at U
// where (null unless U is a stage Vec and records are armed). Adjoint: the next adjoint step hands its
// hook stage i's record at base + i * stride (base = null: none).
PetscErrorCode rk_adjoint_arm_records(TS ts, PetscScalar *base, PetscInt stride);
PetscErrorCode rk_adjoint_record_target(TS ts, Vec U, PetscScalar **record);
PetscErrorCode rk_adjoint_place_records(TS ts, const PetscScalar *base, PetscInt stride);

} // namespace flexipde
