// Adam as a TAO type (see include/flexipde/tao_adam.hpp for the method and its options).
#include "flexipde/tao_adam.hpp"
#include <cmath>
#include <petsc/private/taoimpl.h>

namespace flexipde {
namespace {

struct TaoAdam {
  PetscReal lr = 1e-3, beta1 = 0.9, beta2 = 0.999, epsilon = 1e-8;
  Vec m = nullptr, v = nullptr, work = nullptr, gproj = nullptr;
};

PetscErrorCode gradient_norm(Tao tao, PetscReal *gnorm) {
  auto *a = static_cast<TaoAdam *>(tao->data);
  PetscFunctionBeginUser;
  if (tao->XL && tao->XU) {
    PetscCall(VecBoundGradientProjection(tao->gradient, tao->solution, tao->XL, tao->XU, a->gproj));
    PetscCall(VecNorm(a->gproj, NORM_2, gnorm));
  } else {
    PetscCall(VecNorm(tao->gradient, NORM_2, gnorm));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode solve_adam(Tao tao) {
  auto *a = static_cast<TaoAdam *>(tao->data);
  PetscReal f, gnorm;
  PetscFunctionBeginUser;
  PetscCheck(a->lr > 0 && a->beta1 >= 0 && a->beta1 < 1 && a->beta2 >= 0 && a->beta2 < 1 && a->epsilon >= 0,
             PetscObjectComm((PetscObject)tao), PETSC_ERR_ARG_OUTOFRANGE,
             "Adam needs -tao_adam_lr > 0, 0 <= beta1, beta2 < 1 and epsilon >= 0 (got lr %g, beta1 %g, beta2 %g, "
             "epsilon %g)",
             (double)a->lr, (double)a->beta1, (double)a->beta2, (double)a->epsilon);
  if (tao->XL && tao->XU) PetscCall(VecMedian(tao->XL, tao->solution, tao->XU, tao->solution));
  PetscCall(VecSet(a->m, 0.0));
  PetscCall(VecSet(a->v, 0.0));
  PetscCall(TaoComputeObjectiveAndGradient(tao, tao->solution, &f, tao->gradient));
  PetscCall(gradient_norm(tao, &gnorm));
  PetscCheck(!PetscIsInfOrNanReal(f) && !PetscIsInfOrNanReal(gnorm), PetscObjectComm((PetscObject)tao), PETSC_ERR_USER,
             "The objective or its gradient is Inf or NaN at the initial point");
  tao->reason = TAO_CONTINUE_ITERATING;
  PetscCall(TaoLogConvergenceHistory(tao, f, gnorm, 0.0, tao->ksp_its));
  PetscCall(TaoMonitor(tao, tao->niter, f, gnorm, 0.0, 0.0));
  PetscUseTypeMethod(tao, convergencetest, tao->cnvP);
  PetscReal b1t = 1, b2t = 1; // beta^t
  while (tao->reason == TAO_CONTINUE_ITERATING) {
    PetscTryTypeMethod(tao, update, tao->niter, tao->user_update);
    b1t *= a->beta1;
    b2t *= a->beta2;
    // m and v, then the step -lr mhat / (sqrt(vhat) + eps) into work
    PetscCall(VecAXPBY(a->m, 1.0 - a->beta1, a->beta1, tao->gradient));
    PetscCall(VecPointwiseMult(a->work, tao->gradient, tao->gradient));
    PetscCall(VecAXPBY(a->v, 1.0 - a->beta2, a->beta2, a->work));
    PetscCall(VecCopy(a->v, a->work));
    PetscCall(VecScale(a->work, 1.0 / (1.0 - b2t)));
    PetscCall(VecSqrtAbs(a->work));
    PetscCall(VecShift(a->work, a->epsilon));
    PetscCall(VecPointwiseDivide(a->work, a->m, a->work));
    PetscCall(VecAXPY(tao->solution, -a->lr / (1.0 - b1t), a->work));
    if (tao->XL && tao->XU) PetscCall(VecMedian(tao->XL, tao->solution, tao->XU, tao->solution));
    PetscCall(TaoComputeObjectiveAndGradient(tao, tao->solution, &f, tao->gradient));
    PetscCall(gradient_norm(tao, &gnorm));
    PetscCheck(!PetscIsInfOrNanReal(f) && !PetscIsInfOrNanReal(gnorm), PetscObjectComm((PetscObject)tao),
               PETSC_ERR_NOT_CONVERGED, "Adam diverged: Inf or NaN after %" PetscInt_FMT " iterations; lower -tao_adam_lr",
               tao->niter + 1);
    tao->niter++;
    PetscCall(TaoLogConvergenceHistory(tao, f, gnorm, 0.0, tao->ksp_its));
    PetscCall(TaoMonitor(tao, tao->niter, f, gnorm, 0.0, a->lr));
    PetscUseTypeMethod(tao, convergencetest, tao->cnvP);
  }
  PetscFunctionReturn(0);
}

PetscErrorCode setup_adam(Tao tao) {
  auto *a = static_cast<TaoAdam *>(tao->data);
  PetscFunctionBeginUser;
  if (!tao->gradient) PetscCall(VecDuplicate(tao->solution, &tao->gradient));
  if (!a->m) PetscCall(VecDuplicate(tao->solution, &a->m));
  if (!a->v) PetscCall(VecDuplicate(tao->solution, &a->v));
  if (!a->work) PetscCall(VecDuplicate(tao->solution, &a->work));
  if (!a->gproj) PetscCall(VecDuplicate(tao->solution, &a->gproj));
  PetscFunctionReturn(0);
}

PetscErrorCode destroy_adam(Tao tao) {
  auto *a = static_cast<TaoAdam *>(tao->data);
  PetscFunctionBeginUser;
  PetscCall(VecDestroy(&a->m));
  PetscCall(VecDestroy(&a->v));
  PetscCall(VecDestroy(&a->work));
  PetscCall(VecDestroy(&a->gproj));
  delete a;
  tao->data = nullptr;
  PetscFunctionReturn(0);
}

PetscErrorCode set_from_options_adam(Tao tao, PetscOptionItems *PetscOptionsObject) {
  auto *a = static_cast<TaoAdam *>(tao->data);
  PetscFunctionBeginUser;
  PetscOptionsHeadBegin(PetscOptionsObject, "Adam (flexipde)");
  PetscCall(PetscOptionsReal("-tao_adam_lr", "Learning rate (step size)", "TaoAdam", a->lr, &a->lr, nullptr));
  PetscCall(PetscOptionsReal("-tao_adam_beta1", "Decay of the first moment", "TaoAdam", a->beta1, &a->beta1, nullptr));
  PetscCall(PetscOptionsReal("-tao_adam_beta2", "Decay of the second moment", "TaoAdam", a->beta2, &a->beta2, nullptr));
  PetscCall(PetscOptionsReal("-tao_adam_epsilon", "Added to sqrt(v) in the denominator", "TaoAdam", a->epsilon,
                             &a->epsilon, nullptr));
  PetscOptionsHeadEnd();
  PetscFunctionReturn(0);
}

PetscErrorCode view_adam(Tao tao, PetscViewer viewer) {
  auto *a = static_cast<TaoAdam *>(tao->data);
  PetscBool ascii;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject)viewer, PETSCVIEWERASCII, &ascii));
  if (ascii)
    PetscCall(PetscViewerASCIIPrintf(viewer, "  Adam: lr %g, beta1 %g, beta2 %g, epsilon %g\n", (double)a->lr,
                                     (double)a->beta1, (double)a->beta2, (double)a->epsilon));
  PetscFunctionReturn(0);
}

PetscErrorCode create_adam(Tao tao) {
  PetscFunctionBeginUser;
  tao->ops->setup = setup_adam;
  tao->ops->solve = solve_adam;
  tao->ops->view = view_adam;
  tao->ops->setfromoptions = set_from_options_adam;
  tao->ops->destroy = destroy_adam;
  tao->data = new TaoAdam();
  if (!tao->max_it_changed) tao->max_it = 1000;
  if (!tao->max_funcs_changed) tao->max_funcs = 10000;
  PetscFunctionReturn(0);
}

} // namespace

PetscErrorCode register_tao_adam() {
  static bool done = false;
  PetscFunctionBeginUser;
  if (done) PetscFunctionReturn(0);
  PetscCall(TaoRegister("adam", create_adam));
  done = true;
  PetscFunctionReturn(0);
}

} // namespace flexipde
