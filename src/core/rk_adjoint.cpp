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
  Vec W = nullptr, dmu = nullptr;             // h W_i; (dG/dp)^T h W_i
  std::vector<PetscScalar> coef, ones;        // -h a_ji of one stage; s ones
  PetscInt s = 0, ncost = 0;
  ~RkAdjoint() { release(); }
  void release() {
    for (Vec &v : dlam) (void)VecDestroy(&v);
    dlam.clear();
    (void)VecDestroy(&W);
    (void)VecDestroy(&dmu);
    s = ncost = 0;
  }
};

PetscErrorCode destroy_context(void *ctx) {
  delete static_cast<RkAdjoint *>(ctx);
  return 0;
}

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
  PetscScalar *__restrict o = wa;
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
  for (PetscInt j = 0; j < m; ++j) PetscCall(VecRestoreArrayRead(X[j], &a[j]));
  PetscCall(VecRestoreArrayRead(x0, &a0));
  PetscCall(VecRestoreArrayWrite(w, &wa));
  PetscFunctionReturn(0);
}

PetscErrorCode adjoint_step(TS ts) {
  PetscContainer container;
  RkAdjoint *ctx;
  PetscInt s, pinterp;
  const PetscReal *A, *b, *c, *bembed, *binterp;
  PetscBool fsal;
  PetscFunctionBegin;
  PetscCall(PetscObjectQuery((PetscObject)ts, kName, (PetscObject *)&container));
  PetscCheck(container, PetscObjectComm((PetscObject)ts), PETSC_ERR_PLIB, "rk_adjoint: context missing");
  PetscCall(PetscContainerGetPointer(container, (void **)&ctx));
  PetscCall(TSRKGetTableau(ts, &s, &A, &b, &c, &bembed, &pinterp, &binterp, &fsal));
  (void)bembed, (void)pinterp, (void)binterp;
  if (fsal || ts->quadraturets || ts->vecs_sensi2 || ts->numcost < 1) {
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
    ctx->ones.assign(s, 1.0);
  }
  if (ts->vecs_sensip && !ctx->dmu) PetscCall(VecDuplicate(ts->vecs_sensip[0], &ctx->dmu));

  Mat J, Jpre;
  Vec *Y;
  PetscCall(TSGetRHSJacobian(ts, &J, &Jpre, nullptr, nullptr));
  PetscCall(TSGetStages(ts, nullptr, &Y));
  const PetscReal t = ts->ptime, h = ts->time_step; // h < 0: the adjoint runs backwards
  std::vector<PetscScalar> &coef = ctx->coef;
  for (PetscInt i = s - 1; i >= 0; --i) {
    const PetscReal stage_time = t + h * (1.0 - c[i]);
    PetscCall(TSComputeRHSJacobian(ts, stage_time, Y[i], J, Jpre));
    if (ts->vecs_sensip) PetscCall(TSComputeRHSJacobianP(ts, stage_time, Y[i], ts->Jacprhs));
    const PetscInt m = s - 1 - i;
    for (PetscInt j = i + 1; j < s; ++j) coef[j - i - 1] = -h * A[j * s + i];
    for (PetscInt k = 0; k < ts->numcost; ++k) {
      Vec *dl = &ctx->dlam[(size_t)k * s];
      PetscCall(combine(ctx->W, -h * b[i], ts->vecs_sensi[k], m, coef.data(), dl + i + 1)); // dt W_i
      PetscCall(MatMultTranspose(J, ctx->W, dl[i]));
      if (ts->vecs_sensip) {
        PetscCall(MatMultTranspose(ts->Jacprhs, ctx->W, ctx->dmu));
        PetscCall(VecAXPY(ts->vecs_sensip[k], 1.0, ctx->dmu));
      }
    }
  }
  for (PetscInt k = 0; k < ts->numcost; ++k) PetscCall(VecMAXPY(ts->vecs_sensi[k], s, ctx->ones.data(), &ctx->dlam[(size_t)k * s]));
  PetscFunctionReturn(0);
}

} // namespace

PetscErrorCode rk_adjoint_install(TS ts) {
  PetscBool rk;
  PetscContainer container;
  PetscFunctionBegin;
  PetscCall(PetscObjectTypeCompare((PetscObject)ts, TSRK, &rk));
  if (!rk || ts->ops->adjointstep == adjoint_step) PetscFunctionReturn(0);
  auto *ctx = new RkAdjoint();
  ctx->petsc_step = ts->ops->adjointstep;
  PetscCall(PetscContainerCreate(PetscObjectComm((PetscObject)ts), &container));
  PetscCall(PetscContainerSetPointer(container, ctx));
  PetscCall(PetscContainerSetUserDestroy(container, destroy_context));
  PetscCall(PetscObjectCompose((PetscObject)ts, kName, (PetscObject)container));
  PetscCall(PetscContainerDestroy(&container));
  ts->ops->adjointstep = adjoint_step;
  PetscFunctionReturn(0);
}

} // namespace flexipde
