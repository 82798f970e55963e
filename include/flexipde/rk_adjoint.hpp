// The adjoint step of an explicit Runge-Kutta TS (TSRK), with fewer passes over the state.
//
// For U_{n+1} = U_n + h sum_i b_i K_i, K_i = G(t_n + c_i h, Y_i), Y_i = U_n + h sum_{j<i} a_ij K_j, the
// discrete adjoint of one step is, for i = s-1, ..., 0,
//   W_i        = b_i lambda_{n+1} + sum_{j>i} a_ji dLambda_j
//   dLambda_i  = h (dG/dU)(Y_i)^T W_i,        mu += h (dG/dp)(Y_i)^T W_i
// and then lambda_n = lambda_{n+1} + sum_i dLambda_i. PETSc 3.18's TSAdjointStep_RK computes the same
// numbers (it divides W_i by b_i and multiplies back) with a copy, a multi-AXPY and two scalings per
// stage. Here h W_i is formed in one pass over the state and handed to the transposes unscaled, so a
// stage costs one pass plus the model's products: the same Jacobian transposes in the same order
// (J^T, then (dG/dp)^T of the same unchanged vector, so a model may fuse the two). Stages with b_i = 0
// are handled by the same formula (PETSc's skips their dG/dp).
//
// Used for first-order adjoints of non-FSAL tableaux without a cost integrand; anything else goes to
// TSRK's own adjoint step. -rk_fused_adjoint 0 (read by the Simulation) keeps TSRK's throughout.
#pragma once
#include "flexipde/petsc.hpp"
#include <petscts.h>

namespace flexipde {

// After the TS's type is final: if it is TSRK, its adjoint step becomes the one above (idempotent).
PetscErrorCode rk_adjoint_install(TS ts);

} // namespace flexipde
