// The forward step of an explicit Runge-Kutta TS (TSRK) with one pass per stage combination.
//
// PETSc 3.18's TSStep_RK forms each stage Y_i = U_n + h sum_{j<i} a_ij K_j by copying U_n into Y_i and
// adding every earlier slope, zero coefficients included (VecCopy + VecMAXPY: two passes over Y_i and
// a read of each K_j). This step forms Y_i in one pass from U_n and the slopes with nonzero a_ij (for
// the classical RK4, one each), then evaluates K_i = G(t_n + c_i h, Y_i) and U_{n+1} = U_n + h sum_i
// b_i K_i as PETSc does. The stages stay TSGetStages' Vecs, so trajectories and the adjoint read them
// as before; the slopes are the step's own Vecs.
//
// Fixed steps only: with an adaptive controller, events, an interpolated final time, a cost integral
// integrated forward, a FSAL tableau or a multirate RK, each step is PETSc's own.
#pragma once
#include "flexipde/petsc.hpp"
#include <petscts.h>

namespace flexipde {

// After the TS's type is final: if it is TSRK, its step becomes the one above (idempotent).
PetscErrorCode rk_step_install(TS ts);

} // namespace flexipde
