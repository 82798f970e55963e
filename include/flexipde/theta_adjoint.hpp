// The adjoint step of an implicit theta TS (TSTHETA, TSCN, TSBEULER) without SNESComputeJacobian.
//
// PETSc 3.18's TSAdjointStep_Theta (and TSAdjointStepBEuler_Private) evaluates the IJacobian
// shift*I - dG/dU through TSComputeSNESJacobian, i.e. SNESComputeJacobian, twice per step; besides
// the callback that runs SNESTestJacobian and the -snes_compare_* option lookups and composes the
// linearisation point onto the matrix. On a 512-point advection problem with a factored operator
// that is a third of an adjoint step. This step does the same arithmetic, first-order adjoints
// only, calling TSComputeIJacobian directly:
//
//   endpoint (CN, theta in (0,1)), h = step, lambda = lambda_{n+1}:
//     (s1 I - A)^T nu = lambda / (theta h),  s1 = 1 / (theta h)                A = dG/dU
//     lambda_n = (s2 I - A)^T nu / s2,        s2 = 1 / ((theta - 1) h)
//     mu += h theta (dG/dp)(U_{n+1})^T nu + h (1 - theta) (dG/dp)(U_n)^T nu
//   midpoint (theta in (0,1), stage X = theta U_{n+1} + (1 - theta) U_n at t_n + theta h):
//     (s1 I - A(X))^T nu = lambda / (theta h);  lambda_n = lambda + h A(X)^T nu;  mu += h (dG/dp)(X)^T nu
//   backward Euler (theta = 1):
//     (I/h - A)^T nu = lambda / h;  lambda_n = h (lambda / h + A^T nu);  mu += h (dG/dp)(U_{n+1})^T nu
//
// (mu's terms through TSComputeIJacobianP, i.e. -dF/dp.) The endpoint form's two parameter products
// per step are one: U_{n+1} gets h theta nu_n and, from the adjoint step before (for the forward step
// after), h (1 - theta) nu_{n+1} together (dG/dp is linear in what it is applied to), so the
// gradient equals PETSc's to round-off rather than bitwise. It assumes, as the Simulation's implicit
// form F = U_t - G(t, U) gives, an IJacobian that does not depend on U_t. Cost integrands and
// second-order adjoints go to PETSc's own step (everything does with -adjoint_petsc_step, read by the
// Simulation).
#pragma once
#include "flexipde/petsc.hpp"
#include <petscts.h>

namespace flexipde {

// After the TS's type is final: if it is a theta type (theta, cn, beuler), its adjoint step becomes
// the one above (idempotent). When the forward solves with one sequential LU of PETSc's own (one rank,
// or PCREDUNDANT), the transposed solves use a factorisation of P^T (KSPSolve with MatSolve's
// row-oriented sweeps) instead of KSPSolveTranspose on P's factors; options prefix -theta_adjoint_ for
// that KSP. constant_operator: A = dG/dU is the same at every t and U (a linear model whose Jacobian
// depends on the parameters alone); the update of lambda then takes A^T nu from the transposed solve's
// own equation, A^T nu = s1 nu - lambda / (theta h), instead of applying A^T once more: one operator
// product per step fewer, the same gradient to the solve's tolerance.
PetscErrorCode theta_adjoint_install(TS ts, bool constant_operator = false);

} // namespace flexipde
