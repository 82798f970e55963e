// The explicit RK forward step of rk_step.hpp.
#include "flexipde/rk_step.hpp"
#include "flexipde/rk_adjoint.hpp" // StageCombination, add_weighted
#include <petsc/private/tsimpl.h>
#include <vector>

namespace flexipde {
namespace {

constexpr const char *kName = "flexipde_rk_step";

struct RkStep {
  PetscErrorCode (*petsc_step)(TS) = nullptr; // TSRK's own step, for what this one does not do
  std::vector<Vec> K;                         // the slopes K_i
  std::vector<Vec> X;                         // a stage's slopes with a nonzero a_ij
  std::vector<PetscScalar> w;
  ~RkStep() { release(); }
  void release() {
    for (Vec &v : K) (void)VecDestroy(&v);
    K.clear();
  }
};

// Whether this step applies (else PETSc's): see rk_step.hpp.
PetscErrorCode applies(TS ts, PetscBool fsal, bool *ok) {
  TSAdapt adapt;
  PetscBool none, multirate;
  PetscFunctionBegin;
  PetscCall(TSGetAdapt(ts, &adapt));
  PetscCall(PetscObjectTypeCompare((PetscObject)adapt, TSADAPTNONE, &none));
  PetscCall(TSRKGetMultirate(ts, &multirate));
  *ok = none && !fsal && !multirate && !ts->event && ts->exact_final_time != TS_EXACTFINALTIME_INTERPOLATE &&
        !ts->costintegralfwd && !ts->use_splitrhsfunction;
  PetscFunctionReturn(0);
}

PetscErrorCode step(TS ts) {
  RkStep *ctx;
  PetscInt s, order;
  const PetscReal *A, *b, *c;
  PetscBool fsal;
  bool ok;
  PetscFunctionBegin;
  PetscCall(attached_object((PetscObject)ts, kName, &ctx));
  PetscCall(TSRKGetTableau(ts, &s, &A, &b, &c, nullptr, nullptr, nullptr, &fsal));
  PetscCall(applies(ts, fsal, &ok));
  if (!ok) {
    PetscCall(ctx->petsc_step(ts));
    PetscFunctionReturn(0);
  }
  if ((PetscInt)ctx->K.size() != s) {
    ctx->release();
    ctx->K.assign(s, nullptr);
    for (Vec &v : ctx->K) PetscCall(VecDuplicate(ts->vec_sol, &v));
    ctx->w.assign(s, 0.0);
    ctx->X.assign(s, nullptr);
  }
  Vec *Y;
  PetscCall(TSGetStages(ts, &s, &Y));
  const PetscReal t = ts->ptime, h = ts->time_step;
  for (PetscInt i = 0; i < s; ++i) {
    PetscInt m = 0;
    for (PetscInt j = 0; j < i; ++j)
      if (A[i * s + j] != 0.0) ctx->w[m] = h * A[i * s + j], ctx->X[m++] = ctx->K[j];
    PetscCall(TSPreStage(ts, t + h * c[i]));
    StageCombination stage; // Y_i = U_n + sum of the nonzero h a_ij K_j, one pass for up to three
    stage.c0 = 1.0, stage.x0 = ts->vec_sol, stage.m = m, stage.c = ctx->w.data(), stage.X = ctx->X.data();
    PetscCall(stage.form(Y[i]));
    PetscCall(TSPostStage(ts, t + h * c[i], i, Y));
    PetscCall(TSComputeRHSFunction(ts, t + h * c[i], Y[i], ctx->K[i]));
  }
  for (PetscInt i = 0; i < s; ++i) ctx->w[i] = h * b[i];
  PetscCall(add_weighted(ts->vec_sol, s, ctx->w.data(), ctx->K.data()));
  // The step size after this one, as TSStep_RK asks its (non-adaptive) controller, which also shortens
  // the last step to end at the final time.
  TSAdapt adapt;
  TSRKType type;
  PetscReal next_h = h;
  PetscBool accept = PETSC_TRUE;
  PetscCall(TSRKGetType(ts, &type));
  PetscCall(TSRKGetOrder(ts, &order));
  PetscCall(TSGetAdapt(ts, &adapt));
  PetscCall(TSAdaptCandidatesClear(adapt));
  PetscCall(TSAdaptCandidateAdd(adapt, type, order, 1, 1.0, (PetscReal)s, PETSC_TRUE));
  PetscCall(TSAdaptChoose(adapt, ts, h, nullptr, &next_h, &accept));
  PetscCheck(accept, PetscObjectComm((PetscObject)ts), PETSC_ERR_PLIB, "rk_step: a fixed step was rejected");
  ts->ptime += h;
  ts->time_step = next_h;
  PetscFunctionReturn(0);
}

} // namespace

PetscErrorCode rk_step_install(TS ts) {
  PetscBool rk;
  RkStep *ctx;
  PetscFunctionBegin;
  PetscCall(PetscObjectTypeCompare((PetscObject)ts, TSRK, &rk));
  if (!rk) PetscFunctionReturn(0);
  if (ts->ops->step == step) PetscFunctionReturn(0);
  PetscCall(attached_object((PetscObject)ts, kName, &ctx));
  if (!ctx) {
    ctx = new RkStep();
    PetscCall(compose_owned((PetscObject)ts, kName, ctx));
  }
  ctx->petsc_step = ts->ops->step; // (TSSetType makes the ops anew)
  ts->ops->step = step;
  PetscFunctionReturn(0);
}

} // namespace flexipde
