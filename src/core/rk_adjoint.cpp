// The explicit RK adjoint step of rk_adjoint.hpp.
#include "flexipde/rk_adjoint.hpp"
#include <petsc/private/tsimpl.h>
#include <vector>

namespace flexipde {
namespace {

constexpr const char *kName = "flexipde_rk_adjoint";

struct RkAdjoint {
  PetscErrorCode (*petsc_step)(TS) = nullptr; // TSRK's own adjoint step, for what this one does not do
  std::vector<Vec> dlam;                      // dLambda_i of every cost: s per cost
  Vec W = nullptr;                            // scratch for the stage hook (StageCombination::scratch)
  std::vector<PetscScalar> coef, ones;        // -h a_ji != 0 of one stage; s ones
  std::vector<Vec> terms;                     // ... and their dLambda_j
  RkStageAdjoint stage = nullptr;             // the model's fused stage products
  void *stage_ctx = nullptr;
  RkIntegrandAdjoint integrand = nullptr;     // the cost integrand's share of a stage (null: none handled)
  void *integrand_ctx = nullptr;
  bool integrand_from_records = false;
  Vec record_view = nullptr;                  // a stage's record as a Vec, for the integrand hook
  // Stage records (Model::stage_record_size): `record_size` entries per stage, replacing the stage when
  // record_replaces. Forward: armed at arm_base (stage i at arm_base + i * arm_stride), for the RHS
  // evaluations at the stage Vecs. Adjoint: placed at rec_base.
  PetscInt record_size = 0;
  bool record_replaces = false;
  PetscScalar *arm_base = nullptr;
  PetscInt arm_stride = 0;
  const PetscScalar *rec_base = nullptr;
  PetscInt rec_stride = 0;
  PetscInt s = 0, ncost = 0;
  ~RkAdjoint() {
    release();
    (void)VecDestroy(&record_view);
  }
  void release() {
    for (Vec &v : dlam) (void)VecDestroy(&v);
    dlam.clear();
    (void)VecDestroy(&W);
    s = ncost = 0;
  }
};

// w = c0 x0 + sum_{j < m} c[j] X[j], one pass.
PetscErrorCode combine(Vec w, PetscScalar c0, Vec x0, PetscInt m, const PetscScalar *c, const Vec *X) {
  PetscScalar *wa;
  const PetscScalar *a0, *a[3];
  PetscInt n;
  PetscFunctionBegin;
  if (m > 3) { // rare (more than four stages): two passes
    PetscCall(VecAXPBY(w, c0, 0.0, x0));
    PetscCall(VecMAXPY(w, m, c, const_cast<Vec *>(X)));
    PetscFunctionReturn(0);
  }
  PetscCall(VecGetLocalSize(w, &n));
  PetscCall(VecGetArrayWrite(w, &wa));
  PetscCall(VecGetArrayRead(x0, &a0));
  for (PetscInt j = 0; j < m; ++j) PetscCall(VecGetArrayRead(X[j], &a[j]));
  StageCombination::form_local(n, c0, a0, m, c, a, wa);
  for (PetscInt j = 0; j < m; ++j) PetscCall(VecRestoreArrayRead(X[j], &a[j]));
  PetscCall(VecRestoreArrayRead(x0, &a0));
  PetscCall(VecRestoreArrayWrite(w, &wa));
  PetscFunctionReturn(0);
}

PetscErrorCode adjoint_step(TS ts) {
  RkAdjoint *ctx;
  PetscInt s, pinterp;
  const PetscReal *A, *b, *c, *bembed, *binterp;
  PetscBool fsal;
  PetscFunctionBegin;
  PetscCall(attached_object((PetscObject)ts, kName, &ctx));
  PetscCheck(ctx, PetscObjectComm((PetscObject)ts), PETSC_ERR_PLIB, "rk_adjoint: context missing");
  PetscCall(TSRKGetTableau(ts, &s, &A, &b, &c, &bembed, &pinterp, &binterp, &fsal));
  (void)bembed, (void)pinterp, (void)binterp;
  const bool integrand = ts->quadraturets != nullptr;
  if (fsal || (integrand && (!ctx->integrand || ts->numcost != 1)) || ts->vecs_sensi2 || ts->numcost < 1) {
    // (the store keeps records only for what this step handles: rk_adjoint_stage_needs)
    PetscCheck(!(ctx->rec_base && ctx->record_replaces), PetscObjectComm((PetscObject)ts), PETSC_ERR_PLIB,
               "rk_adjoint: only the stages' records were stored, which this adjoint (FSAL tableau, cost integrand "
               "or second-order sensitivities) cannot use");
    PetscCall(ctx->petsc_step(ts));
    PetscFunctionReturn(0);
  }
  if (ctx->s != s || ctx->ncost != ts->numcost) {
    ctx->release();
    ctx->dlam.assign((size_t)s * ts->numcost, nullptr);
    for (Vec &v : ctx->dlam) PetscCall(VecDuplicate(ts->vecs_sensi[0], &v));
    PetscCall(VecDuplicate(ts->vecs_sensi[0], &ctx->W));
    ctx->s = s;
    ctx->ncost = ts->numcost;
    ctx->coef.assign(s, 0.0);
    ctx->terms.assign(s, nullptr);
    ctx->ones.assign(s, 1.0);
  }

  Vec *Y;
  PetscCall(TSGetStages(ts, nullptr, &Y));
  const PetscReal t = ts->ptime, h = ts->time_step; // h < 0: the adjoint runs backwards
  std::vector<PetscScalar> &coef = ctx->coef;
  std::vector<Vec> &terms = ctx->terms;
  for (PetscInt i = s - 1; i >= 0; --i) {
    const PetscReal stage_time = t + h * (1.0 - c[i]);
    for (PetscInt k = 0; k < ts->numcost; ++k) {
      Vec *dl = &ctx->dlam[(size_t)k * s];
      PetscInt m = 0;
      for (PetscInt j = i + 1; j < s; ++j)
        if (A[j * s + i] != 0) coef[m] = -h * A[j * s + i], terms[m++] = dl[j];
      // the hook forms h W_i where it reads it
      StageCombination x;
      x.c0 = -h * b[i];
      x.x0 = ts->vecs_sensi[k];
      x.m = m;
      x.c = coef.data();
      x.X = terms.data();
      x.scratch = ctx->W;
      const PetscScalar *record = ctx->rec_base ? ctx->rec_base + (size_t)i * ctx->rec_stride : nullptr;
      Vec U = record && ctx->record_replaces ? nullptr : Y[i];
      Vec mu = ts->vecs_sensip ? ts->vecs_sensip[k] : nullptr;
      PetscCall(ctx->stage(ctx->stage_ctx, stage_time, U, record, x, dl[i], mu));
      if (integrand && U) PetscCall(ctx->integrand(ctx->integrand_ctx, stage_time, U, nullptr, -h * b[i], dl[i], mu));
      else if (integrand) {
        PetscCheck(ctx->integrand_from_records, PetscObjectComm((PetscObject)ts), PETSC_ERR_PLIB,
                   "rk_adjoint: the integrand hook needs whole stages, but only their records were stored");
        if (!ctx->record_view)
          PetscCall(VecCreateMPIWithArray(PetscObjectComm((PetscObject)ts), 1, ctx->record_size, PETSC_DECIDE, nullptr,
                                          &ctx->record_view));
        PetscCall(VecPlaceArray(ctx->record_view, record));
        PetscCall(ctx->integrand(ctx->integrand_ctx, stage_time, nullptr, ctx->record_view, -h * b[i], dl[i], mu));
        PetscCall(VecResetArray(ctx->record_view));
      }
    }
  }
  for (PetscInt k = 0; k < ts->numcost; ++k)
    PetscCall(add_weighted(ts->vecs_sensi[k], s, ctx->ones.data(), &ctx->dlam[(size_t)k * s]));
  PetscFunctionReturn(0);
}

// The context of an installed adjoint step, else null.
PetscErrorCode installed(TS ts, RkAdjoint **ctx) {
  PetscFunctionBegin;
  *ctx = nullptr;
  if (ts->ops->adjointstep == adjoint_step) PetscCall(attached_object((PetscObject)ts, kName, ctx));
  PetscFunctionReturn(0);
}

} // namespace

void StageCombination::form_local(PetscInt n, PetscScalar c0, const PetscScalar *a0, PetscInt m, const PetscScalar *c,
                                  const PetscScalar *const *a, PetscScalar *out) {
  PetscScalar *__restrict o = out;
  const PetscScalar *__restrict p0 = a0;
  switch (m) {
  case 0:
    for (PetscInt k = 0; k < n; ++k) o[k] = c0 * p0[k];
    break;
  case 1: {
    const PetscScalar *__restrict p1 = a[0];
    for (PetscInt k = 0; k < n; ++k) o[k] = c0 * p0[k] + c[0] * p1[k];
  } break;
  case 2: {
    const PetscScalar *__restrict p1 = a[0], *__restrict p2 = a[1];
    for (PetscInt k = 0; k < n; ++k) o[k] = c0 * p0[k] + c[0] * p1[k] + c[1] * p2[k];
  } break;
  default: {
    const PetscScalar *__restrict p1 = a[0], *__restrict p2 = a[1], *__restrict p3 = a[2];
    for (PetscInt k = 0; k < n; ++k) o[k] = c0 * p0[k] + c[0] * p1[k] + c[1] * p2[k] + c[2] * p3[k];
  } break;
  }
}

PetscErrorCode StageCombination::form(Vec w) const { return combine(w, c0, x0, m, c, X); }

PetscErrorCode add_weighted(Vec x, PetscInt s, const PetscScalar *w, const Vec *K) {
  PetscScalar *xa;
  const PetscScalar *k[4];
  PetscInt n;
  PetscFunctionBegin;
  if (s > 4) {
    PetscCall(VecMAXPY(x, s, w, const_cast<Vec *>(K)));
    PetscFunctionReturn(0);
  }
  PetscCall(VecGetLocalSize(x, &n));
  PetscCall(VecGetArray(x, &xa));
  for (PetscInt j = 0; j < s; ++j) PetscCall(VecGetArrayRead(K[j], &k[j]));
  PetscScalar *__restrict o = xa;
  const PetscScalar *__restrict k0 = k[0];
  switch (s) {
  case 1:
    for (PetscInt i = 0; i < n; ++i) o[i] += w[0] * k0[i];
    break;
  case 2: {
    const PetscScalar *__restrict k1 = k[1];
    for (PetscInt i = 0; i < n; ++i) o[i] += w[0] * k0[i] + w[1] * k1[i];
  } break;
  case 3: {
    const PetscScalar *__restrict k1 = k[1], *__restrict k2 = k[2];
    for (PetscInt i = 0; i < n; ++i) o[i] += w[0] * k0[i] + w[1] * k1[i] + w[2] * k2[i];
  } break;
  default: {
    const PetscScalar *__restrict k1 = k[1], *__restrict k2 = k[2], *__restrict k3 = k[3];
    for (PetscInt i = 0; i < n; ++i) o[i] += w[0] * k0[i] + w[1] * k1[i] + w[2] * k2[i] + w[3] * k3[i];
  } break;
  }
  for (PetscInt j = 0; j < s; ++j) PetscCall(VecRestoreArrayRead(K[j], &k[j]));
  PetscCall(VecRestoreArray(x, &xa));
  PetscCall(PetscLogFlops(2.0 * s * n));
  PetscFunctionReturn(0);
}

PetscErrorCode rk_adjoint_install(TS ts, RkStageAdjoint stage, void *stage_ctx, RkStageNeeds needs) {
  PetscBool rk;
  RkAdjoint *ctx;
  PetscFunctionBegin;
  PetscCall(PetscObjectTypeCompare((PetscObject)ts, TSRK, &rk));
  if (!rk) PetscFunctionReturn(0);
  PetscCheck(stage, PetscObjectComm((PetscObject)ts), PETSC_ERR_ARG_NULL, "rk_adjoint: a stage hook is required");
  PetscCall(installed(ts, &ctx));
  if (!ctx) {
    ctx = new RkAdjoint();
    ctx->petsc_step = ts->ops->adjointstep;
    PetscCall(compose_owned((PetscObject)ts, kName, ctx));
    ts->ops->adjointstep = adjoint_step;
  }
  ctx->stage = stage;
  ctx->stage_ctx = stage_ctx;
  ctx->integrand = nullptr;
  ctx->integrand_ctx = nullptr;
  ctx->integrand_from_records = false;
  if (ctx->record_size != needs.record_size) PetscCall(VecDestroy(&ctx->record_view));
  ctx->record_size = needs.record_size;
  ctx->record_replaces = ctx->record_size > 0 && needs.record_replaces;
  ctx->arm_base = nullptr;
  ctx->rec_base = nullptr;
  PetscFunctionReturn(0);
}

PetscErrorCode rk_adjoint_set_integrand(TS ts, RkIntegrandAdjoint integrand, void *integrand_ctx, bool from_records) {
  RkAdjoint *ctx;
  PetscFunctionBegin;
  PetscCall(installed(ts, &ctx));
  PetscCheck(ctx, PetscObjectComm((PetscObject)ts), PETSC_ERR_ORDER, "rk_adjoint: install the adjoint step first");
  ctx->integrand = integrand;
  ctx->integrand_ctx = integrand_ctx;
  ctx->integrand_from_records = integrand && from_records;
  PetscFunctionReturn(0);
}

PetscErrorCode rk_adjoint_stage_needs(TS ts, RkStageNeeds *needs) {
  RkAdjoint *ctx;
  PetscInt s;
  const PetscReal *A, *b, *c;
  PetscBool fsal = PETSC_FALSE;
  PetscFunctionBegin;
  *needs = RkStageNeeds{};
  PetscCall(installed(ts, &ctx));
  if (!ctx || (ts->quadraturets && !ctx->integrand)) PetscFunctionReturn(0);
  PetscCall(TSRKGetTableau(ts, &s, &A, &b, &c, nullptr, nullptr, nullptr, &fsal));
  if (fsal) PetscFunctionReturn(0);
  // an integrand hook that reads whole stages: no records in their place
  if (ts->quadraturets && ctx->record_replaces && !ctx->integrand_from_records) PetscFunctionReturn(0);
  needs->record_size = ctx->record_size;
  needs->record_replaces = ctx->record_replaces;
  PetscFunctionReturn(0);
}

PetscErrorCode rk_adjoint_arm_records(TS ts, PetscScalar *base, PetscInt stride) {
  RkAdjoint *ctx;
  PetscFunctionBegin;
  PetscCall(installed(ts, &ctx));
  if (!ctx) PetscFunctionReturn(0);
  PetscCheck(!base || ctx->record_size > 0, PetscObjectComm((PetscObject)ts), PETSC_ERR_ORDER, "rk_adjoint: no records to arm");
  ctx->arm_base = base;
  ctx->arm_stride = stride;
  PetscFunctionReturn(0);
}

PetscErrorCode rk_adjoint_record_target(TS ts, Vec U, PetscScalar **record) {
  RkAdjoint *ctx;
  PetscFunctionBegin;
  *record = nullptr;
  PetscCall(installed(ts, &ctx));
  if (!ctx || !ctx->arm_base) PetscFunctionReturn(0);
  PetscInt s;
  Vec *Y;
  PetscCall(TSGetStages(ts, &s, &Y));
  for (PetscInt i = 0; i < s; ++i)
    if (Y[i] == U) *record = ctx->arm_base + (size_t)i * ctx->arm_stride;
  PetscFunctionReturn(0);
}

PetscErrorCode rk_adjoint_place_records(TS ts, const PetscScalar *base, PetscInt stride) {
  RkAdjoint *ctx;
  PetscFunctionBegin;
  PetscCall(installed(ts, &ctx));
  if (!ctx && !base) PetscFunctionReturn(0);
  PetscCheck(ctx && (!base || ctx->record_size > 0), PetscObjectComm((PetscObject)ts), PETSC_ERR_ORDER,
             "rk_adjoint: no records to place");
  ctx->rec_base = base;
  ctx->rec_stride = stride;
  PetscFunctionReturn(0);
}

} // namespace flexipde
