// The implicit theta adjoint step of theta_adjoint.hpp.
#include "flexipde/theta_adjoint.hpp"
#include <petsc/private/kspimpl.h> // the forward KSP's pre-solve hook
#include <petsc/private/tsimpl.h>
#include <cstring>
#include <vector>

namespace flexipde {
namespace {

constexpr const char *kName = "flexipde_theta_adjoint";

struct ThetaAdjoint {
  PetscErrorCode (*petsc_step)(TS) = nullptr; // TSTHETA's own adjoint step, for what this one does not do
  std::vector<Vec> rhs, nu;                   // per cost: the transposed solve's right-hand side and solution
  std::vector<Vec> pending;                   // endpoint: h (1 - theta) nu of the step after, for its U_n
  Vec X0 = nullptr, Xdot = nullptr, dmu = nullptr;
  Vec held = nullptr; // endpoint: the U_n whose Jacobian the last step evaluated
  PetscInt ncost = 0;
  // The transposed solves through a factorisation of P^T (see solve_transpose): P^T (built from
  // P_from, a reference, in its state p_state), and a KSP of the forward's kind on it.
  // A = dG/dU the same at every t and U (theta_adjoint_install's constant_operator): the update of
  // lambda takes A^T nu from the transposed solve's equation instead of applying it again.
  bool constant_operator = false;
  Mat PT = nullptr, P_from = nullptr;
  PetscObjectState p_state = -1, p_nonzeros = -1;
  KSP kspT = nullptr;
  ~ThetaAdjoint() {
    release();
    (void)KSPDestroy(&kspT);
    (void)MatDestroy(&PT);
    (void)MatDestroy(&P_from);
  }
  void release() {
    for (Vec &v : rhs) (void)VecDestroy(&v);
    for (Vec &v : nu) (void)VecDestroy(&v);
    for (Vec &v : pending) (void)VecDestroy(&v);
    rhs.clear();
    nu.clear();
    pending.clear();
    (void)VecDestroy(&X0);
    (void)VecDestroy(&Xdot);
    (void)VecDestroy(&dmu);
    (void)VecDestroy(&held);
    ncost = 0;
  }
};

// The IJacobian at (t, U) with this shift, as the KSP's operators (what TSComputeSNESJacobian and
// KSPSetOperators do in PETSc's step, without SNESComputeJacobian).
PetscErrorCode ijacobian(TS ts, PetscReal t, Vec U, Vec Udot, PetscReal shift, Mat J, Mat P, KSP ksp) {
  PetscFunctionBegin;
  PetscCall(TSComputeIJacobian(ts, t, U, Udot, shift, J, P, PETSC_FALSE));
  PetscCall(KSPSetOperators(ksp, J, P));
  PetscFunctionReturn(0);
}

// y = a x (as PETSc's step: a copy and a scaling, whatever y held).
PetscErrorCode scaled_copy(Vec y, PetscReal a, Vec x) {
  PetscFunctionBegin;
  PetscCall(VecCopy(x, y));
  PetscCall(VecScale(y, a));
  PetscFunctionReturn(0);
}

// The PC that factors for pc: pc itself, or a PCREDUNDANT's inner one (and *inner its KSP).
PetscErrorCode factor_pc(PC pc, PC *factor, KSP *inner = nullptr) {
  PetscBool redundant;
  PetscFunctionBegin;
  *factor = pc;
  if (inner) *inner = nullptr;
  PetscCall(PetscObjectTypeCompare((PetscObject)pc, PCREDUNDANT, &redundant));
  if (!redundant) PetscFunctionReturn(0);
  KSP k;
  PetscCall(PCRedundantGetKSP(pc, &k));
  PetscCall(KSPGetPC(k, factor));
  if (inner) *inner = k;
  PetscFunctionReturn(0);
}

// The PC type when ksp solves with one sequential LU factorisation of PETSc's own (KSPPREONLY with
// PCLU on one rank, or PCREDUNDANT whose copies do that), else null.
PetscErrorCode sequential_lu(KSP ksp, PCType *type) {
  PetscBool preonly, lu;
  PC pc, factor;
  KSP inner;
  PetscFunctionBegin;
  *type = nullptr;
  PetscCall(PetscObjectTypeCompare((PetscObject)ksp, KSPPREONLY, &preonly));
  if (!preonly) PetscFunctionReturn(0);
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(factor_pc(pc, &factor, &inner));
  const bool redundant = inner != nullptr;
  PetscCall(PetscObjectTypeCompare((PetscObject)factor, PCLU, &lu));
  if (redundant) {
    PetscCall(PetscObjectTypeCompare((PetscObject)inner, KSPPREONLY, &preonly));
    if (!preonly) PetscFunctionReturn(0);
  } else {
    PetscMPIInt size;
    PetscCallMPI(MPI_Comm_size(PetscObjectComm((PetscObject)ksp), &size));
    if (size > 1) PetscFunctionReturn(0);
  }
  if (!lu) PetscFunctionReturn(0);
  MatSolverType st;
  PetscCall(PCFactorGetMatSolverType(factor, &st));
  if (st && std::strcmp(st, MATSOLVERPETSC)) PetscFunctionReturn(0);
  *type = redundant ? PCREDUNDANT : PCLU;
  PetscFunctionReturn(0);
}

// The ordering for P^T's LU: nested dissection (the forward's LU default) computed on the transpose of
// the matrix given, i.e. on P, with rows and columns swapped, so that P^T's factors are P's transposed
// in structure. nd on P^T itself reads a graph from P^T's lower triangle alone (MatGetRowIJ's
// symmetric form), which for a one-sided stencil holds little more than the periodic wrap.
constexpr const char *kTransposedND = "flexipde_transposed_nd";
PetscErrorCode transposed_nd(Mat mat, MatOrderingType, IS *row, IS *col) {
  Mat T;
  IS r, c;
  PetscFunctionBegin;
  PetscCall(MatTranspose(mat, MAT_INITIAL_MATRIX, &T));
  PetscCall(MatGetOrdering(T, MATORDERINGND, &r, &c));
  PetscCall(MatDestroy(&T));
  *row = c;
  *col = r;
  PetscFunctionReturn(0);
}
PetscErrorCode use_transposed_nd(PC factor) {
  PetscFunctionBegin;
  PetscCall(MatOrderingRegister(kTransposedND, transposed_nd)); // (idempotent: the same name replaces itself)
  PetscCall(PCFactorSetMatOrderingType(factor, kTransposedND));
  PetscFunctionReturn(0);
}

// nu_k = P^T \ rhs_k through a factorisation of P^T: P^T built again (MatTranspose) whenever P
// changes, and factored by a KSP of the forward's kind (options prefix -theta_adjoint_). PETSc's
// sequential MatSolveTranspose walks the factors column by column (scattered updates of the
// solution): slower than MatSolve's row sweeps, and more so when another process shares the memory
// system. For linear models P is built once per
// gradient, so P^T costs one more factorisation per gradient. Its LU uses P's ordering
// (transposed_nd), so its factors have the fill of P's. (2D upwind CN, field D, 128^2: adjoint 0.346 ->
// 0.330 s on 1 rank, 0.368 -> 0.325 s on 2, against solving with P's factors transposed.)
// type: the forward's PC type (sequential_lu), used when the KSP for P^T is made on the first call.
PetscErrorCode solve_factored_transpose(TS ts, KSP ksp, PCType type, ThetaAdjoint &c) {
  Mat A, P;
  PetscObjectState state;
  PetscFunctionBegin;
  // what KSPSolveTranspose would run first (the Simulation rebuilds a stale shifted P there)
  if (ksp->presolve) PetscCall((*ksp->presolve)(ksp, c.rhs[0], c.nu[0], ksp->prectx));
  PetscCall(KSPGetOperators(ksp, &A, &P));
  PetscObjectState nonzeros;
  PetscCall(PetscObjectStateGet((PetscObject)P, &state));
  PetscCall(MatGetNonzeroState(P, &nonzeros));
  if (P != c.P_from || nonzeros != c.p_nonzeros) { // (a new pattern: P^T built anew)
    PetscCall(MatDestroy(&c.PT));
    PetscCall(MatTranspose(P, MAT_INITIAL_MATRIX, &c.PT));
    PetscCall(PetscObjectReference((PetscObject)P));
    PetscCall(MatDestroy(&c.P_from));
    c.P_from = P;
    c.p_state = state;
    c.p_nonzeros = nonzeros;
    if (c.kspT) PetscCall(KSPSetOperators(c.kspT, c.PT, c.PT));
  }
  if (state != c.p_state) {
    PetscCall(MatTranspose(P, MAT_REUSE_MATRIX, &c.PT)); // (refactored by the KSP's next set-up)
    c.p_state = state;
  }
  if (!c.kspT) {
    PC pc;
    PetscCall(KSPCreate(PetscObjectComm((PetscObject)ksp), &c.kspT));
    PetscCall(KSPSetOptionsPrefix(c.kspT, "theta_adjoint_"));
    PetscCall(KSPSetType(c.kspT, KSPPREONLY));
    PetscCall(KSPGetPC(c.kspT, &pc));
    PetscCall(PCSetType(pc, type));
    PC factor;
    PetscCall(factor_pc(pc, &factor));
    PetscCall(PCSetType(factor, PCLU)); // (a redundant PC's inner one is LU by default)
    PetscCall(use_transposed_nd(factor)); // P's ordering for P^T
    PetscCall(KSPSetOperators(c.kspT, c.PT, c.PT));
    PetscCall(KSPSetFromOptions(c.kspT));
  }
  for (PetscInt k = 0; k < ts->numcost; ++k) {
    KSPConvergedReason reason;
    PetscCall(KSPSolve(c.kspT, c.rhs[k], c.nu[k]));
    PetscCall(KSPGetConvergedReason(c.kspT, &reason));
    if (reason < 0) {
      ts->reason = TSADJOINT_DIVERGED_LINEAR_SOLVE;
      PetscCall(PetscInfo(ts, "Step=%" PetscInt_FMT ", cost %" PetscInt_FMT ": transposed linear solve failed\n", ts->steps, k));
    }
  }
  PetscFunctionReturn(0);
}

// nu_k = (shift I - A)^T \ rhs_k for every cost (the operators are set).
// An iterative solve starts from the previous adjoint step's nu (adjoint states change little from
// one step to the next: GMRES then needs fewer iterations), a direct one ignores it. A sequential
// LU of PETSc's own goes through a factorisation of P^T instead (solve_factored_transpose).
PetscErrorCode solve_transpose(TS ts, KSP ksp, ThetaAdjoint &c) {
  PetscBool nonzero, preonly;
  PetscFunctionBegin;
  {
    PCType type = nullptr;
    if (!c.kspT) PetscCall(sequential_lu(ksp, &type)); // (decided once: kspT exists from then on)
    if (c.kspT || type) {
      PetscCall(solve_factored_transpose(ts, ksp, type, c));
      PetscFunctionReturn(0);
    }
  }
  PetscCall(KSPGetInitialGuessNonzero(ksp, &nonzero));
  PetscCall(PetscObjectTypeCompare((PetscObject)ksp, KSPPREONLY, &preonly));
  if (ts->adjoint_steps == 0)
    for (PetscInt k = 0; k < ts->numcost; ++k) PetscCall(VecZeroEntries(c.nu[k]));
  if (!preonly) PetscCall(KSPSetInitialGuessNonzero(ksp, PETSC_TRUE));
  for (PetscInt k = 0; k < ts->numcost; ++k) {
    KSPConvergedReason reason;
    PetscCall(KSPSolveTranspose(ksp, c.rhs[k], c.nu[k]));
    PetscCall(KSPGetConvergedReason(ksp, &reason));
    if (reason < 0) {
      ts->reason = TSADJOINT_DIVERGED_LINEAR_SOLVE;
      PetscCall(PetscInfo(ts, "Step=%" PetscInt_FMT ", cost %" PetscInt_FMT ": transposed linear solve failed\n", ts->steps, k));
    }
  }
  PetscCall(KSPSetInitialGuessNonzero(ksp, nonzero));
  PetscFunctionReturn(0);
}

// mu_k += w (-dF/dp)(t, U)^T v_k (v = nu by default), with the IJacobianP at this shift.
PetscErrorCode add_parameter_terms(TS ts, ThetaAdjoint &c, PetscReal t, Vec U, PetscReal shift, PetscReal w,
                                   const std::vector<Vec> *v = nullptr) {
  Mat Jp = ts->Jacp;
  PetscFunctionBegin;
  if (!ts->ijacobianp && ts->rhsjacobianp && ts->Jacprhs == ts->Jacp) {
    // Only dG/dp (the Simulation's form): what TSComputeIJacobianP gives, -dG/dp, is that matrix
    // scaled by -1, which a shell then has to undo at its next evaluation (a reassembly): the sign
    // goes into w instead, exactly.
    PetscCall(TSComputeRHSJacobianP(ts, t, U, ts->Jacprhs));
    w = -w;
  } else PetscCall(TSComputeIJacobianP(ts, t, U, c.Xdot, shift, Jp, PETSC_FALSE));
  for (PetscInt k = 0; k < ts->numcost; ++k) {
    PetscCall(MatMultTranspose(Jp, v ? (*v)[k] : c.nu[k], c.dmu));
    PetscCall(VecAXPY(ts->vecs_sensip[k], w, c.dmu));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode adjoint_step(TS ts) {
  ThetaAdjoint *c;
  PetscReal theta;
  PetscBool endpoint;
  TSEquationType eqtype;
  PetscFunctionBegin;
  PetscCall(attached_object((PetscObject)ts, kName, &c));
  PetscCheck(c, PetscObjectComm((PetscObject)ts), PETSC_ERR_PLIB, "theta_adjoint: context missing");
  PetscCall(TSThetaGetTheta(ts, &theta));
  PetscCall(TSThetaGetEndpoint(ts, &endpoint));
  PetscCall(TSGetEquationType(ts, &eqtype));
  if (ts->quadraturets || ts->vecs_sensi2 || ts->numcost < 1 || (theta == 1 && eqtype == TS_EQ_ODE_EXPLICIT)) {
    PetscCall(c->petsc_step(ts));
    PetscFunctionReturn(0);
  }
  if (c->ncost != ts->numcost) {
    c->release();
    c->rhs.assign(ts->numcost, nullptr);
    c->nu.assign(ts->numcost, nullptr);
    c->pending.assign(ts->numcost, nullptr);
    for (PetscInt k = 0; k < ts->numcost; ++k) {
      PetscCall(VecDuplicate(ts->vecs_sensi[0], &c->rhs[k]));
      PetscCall(VecDuplicate(ts->vecs_sensi[0], &c->nu[k]));
      PetscCall(VecDuplicate(ts->vecs_sensi[0], &c->pending[k]));
    }
    PetscCall(VecDuplicate(ts->vec_sol, &c->X0));
    PetscCall(VecDuplicate(ts->vec_sol, &c->Xdot));
    c->ncost = ts->numcost;
  }
  if (ts->vecs_sensip && !c->dmu) PetscCall(VecDuplicate(ts->vecs_sensip[0], &c->dmu));

  SNES snes;
  KSP ksp;
  Mat J, P;
  Vec *Y;
  PetscInt ns;
  PetscCall(TSGetSNES(ts, &snes));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(TSGetIJacobian(ts, &J, &P, nullptr, nullptr));
  PetscCall(TSGetStages(ts, &ns, &Y)); // endpoint forms: {U_n, U_{n+1}}; midpoint: {X}
  const PetscReal h = -ts->time_step, t1 = ts->ptime, t0 = ts->ptime + ts->time_step;
  const PetscInt ncost = ts->numcost;

  if (theta == 1) { // backward Euler (PETSc's TSAdjointStepBEuler_Private)
    Vec U0 = Y[0];
    for (PetscInt k = 0; k < ncost; ++k) PetscCall(scaled_copy(c->rhs[k], 1.0 / h, ts->vecs_sensi[k]));
    PetscCall(ijacobian(ts, t1, ts->vec_sol, c->Xdot, 1.0 / h, J, P, ksp));
    PetscCall(solve_transpose(ts, ksp, *c));
    if (c->constant_operator) // A^T nu = nu / h - rhs: lambda_n = h (rhs + A^T nu) = nu
      for (PetscInt k = 0; k < ncost; ++k) PetscCall(VecCopy(c->nu[k], ts->vecs_sensi[k]));
    else {
      PetscCall(ijacobian(ts, t1, ts->vec_sol, c->Xdot, 0.0, J, P, ksp)); // -A
      for (PetscInt k = 0; k < ncost; ++k) {
        PetscCall(VecScale(c->rhs[k], -1.0));
        PetscCall(MatMultTransposeAdd(J, c->nu[k], c->rhs[k], c->rhs[k]));
        PetscCall(scaled_copy(ts->vecs_sensi[k], -h, c->rhs[k]));
      }
    }
    if (ts->vecs_sensip) {
      PetscCall(VecAXPBYPCZ(c->Xdot, -1.0 / h, 1.0 / h, 0.0, U0, ts->vec_sol));
      PetscCall(add_parameter_terms(ts, *c, t1, ts->vec_sol, 1.0 / h, -h));
    }
    PetscFunctionReturn(0);
  }

  const PetscReal s1 = 1.0 / (theta * h); // the transposed solve's shift
  for (PetscInt k = 0; k < ncost; ++k) PetscCall(scaled_copy(c->rhs[k], s1, ts->vecs_sensi[k]));
  if (endpoint) { // CN and the endpoint theta methods
    Vec U0 = Y[0];
    // U_{n+1} is the U_n of the adjoint step before, whose Jacobian the operators still hold when
    // nothing ran in between (held: that U_n, the Vec it was evaluated at); at the same Vec and time
    // TSComputeIJacobian only shifts it again instead of evaluating it.
    PetscBool same = PETSC_FALSE;
    if (c->held) PetscCall(VecEqual(ts->vec_sol, c->held, &same));
    PetscCall(ijacobian(ts, t1, same ? c->held : ts->vec_sol, c->Xdot, s1, J, P, ksp));
    PetscCall(solve_transpose(ts, ksp, *c));
    const PetscReal s2 = 1.0 / ((theta - 1.0) * h);
    if (c->constant_operator) // A^T nu = s1 nu - rhs: lambda_n = ((s2 - s1) nu + rhs) / s2, rhs = s1 lambda
      for (PetscInt k = 0; k < ncost; ++k) PetscCall(VecAXPBY(ts->vecs_sensi[k], (s2 - s1) / s2, s1 / s2, c->nu[k]));
    else {
      if (!c->held) PetscCall(VecDuplicate(U0, &c->held));
      PetscCall(VecCopy(U0, c->held));
      PetscCall(ijacobian(ts, t0, c->held, c->Xdot, s2, J, P, ksp));
      for (PetscInt k = 0; k < ncost; ++k) {
        PetscCall(MatMultTranspose(J, c->nu[k], ts->vecs_sensi[k]));
        PetscCall(VecScale(ts->vecs_sensi[k], 1.0 / s2));
      }
    }
    if (ts->vecs_sensip) {
      // U_{n+1} takes h theta nu_n from this step and h (1 - theta) nu_{n+1} from the step after it
      // (done before: its U_n), in one product; only the last step applies its own U_n term.
      const bool first = ts->adjoint_steps == 0, last = ts->adjoint_steps + 1 >= ts->adjoint_max_steps;
      for (PetscInt k = 0; k < ncost; ++k) {
        if (first) PetscCall(scaled_copy(c->rhs[k], h * theta, c->nu[k]));
        else PetscCall(VecAXPBYPCZ(c->rhs[k], h * theta, 1.0, 0.0, c->nu[k], c->pending[k]));
        PetscCall(scaled_copy(c->pending[k], h * (1.0 - theta), c->nu[k]));
      }
      PetscCall(VecAXPBYPCZ(c->Xdot, -s1, s1, 0.0, U0, ts->vec_sol));
      PetscCall(add_parameter_terms(ts, *c, t1, ts->vec_sol, -s1, -1.0, &c->rhs));
      if (last) {
        PetscCall(VecZeroEntries(c->Xdot));
        PetscCall(add_parameter_terms(ts, *c, t0, U0, s2, -1.0, &c->pending));
      }
    }
    PetscFunctionReturn(0);
  }
  // midpoint: the stage X, and U_n recovered from it and U_{n+1}
  Vec X = Y[0];
  const PetscReal ts_stage = t1 - (1.0 - theta) * h;
  PetscCall(VecAXPBYPCZ(c->X0, 1.0 / (1.0 - theta), theta / (theta - 1.0), 0.0, X, ts->vec_sol));
  PetscCall(ijacobian(ts, ts_stage, X, c->Xdot, s1, J, P, ksp));
  PetscCall(solve_transpose(ts, ksp, *c));
  if (c->constant_operator) { // A^T nu = s1 nu - rhs: rhs - s1 nu is the -A^T nu below
    for (PetscInt k = 0; k < ncost; ++k) {
      PetscCall(VecAXPY(c->rhs[k], -s1, c->nu[k]));
      PetscCall(VecAXPY(ts->vecs_sensi[k], -h, c->rhs[k]));
    }
  } else {
    PetscCall(ijacobian(ts, ts_stage, X, c->Xdot, 0.0, J, P, ksp)); // -A(X)
    for (PetscInt k = 0; k < ncost; ++k) {
      PetscCall(MatMultTranspose(J, c->nu[k], c->rhs[k]));
      PetscCall(VecAXPY(ts->vecs_sensi[k], -h, c->rhs[k]));
    }
  }
  if (ts->vecs_sensip) {
    PetscCall(VecAXPBYPCZ(c->Xdot, -s1, s1, 0.0, c->X0, X));
    PetscCall(add_parameter_terms(ts, *c, ts_stage, X, s1, -h));
  }
  PetscFunctionReturn(0);
}

} // namespace

PetscErrorCode theta_adjoint_install(TS ts, bool constant_operator) {
  PetscBool theta;
  ThetaAdjoint *c;
  PetscFunctionBegin;
  PetscCall(PetscObjectTypeCompareAny((PetscObject)ts, &theta, TSTHETA, TSCN, TSBEULER, ""));
  if (!theta) PetscFunctionReturn(0);
  if (ts->ops->adjointstep == adjoint_step) {
    PetscCall(attached_object((PetscObject)ts, kName, &c));
    if (c) c->constant_operator = constant_operator;
    PetscFunctionReturn(0);
  }
  auto *ctx = new ThetaAdjoint();
  ctx->constant_operator = constant_operator;
  ctx->petsc_step = ts->ops->adjointstep;
  PetscCall(compose_owned((PetscObject)ts, kName, ctx));
  ts->ops->adjointstep = adjoint_step;
  PetscFunctionReturn(0);
}

} // namespace flexipde
