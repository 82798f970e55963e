// Adam (Kingma & Ba 2015) as a TAO type: -tao_type adam, registered by flexipde.
//
// With g_k the gradient at x_k and t = k + 1:
//   m = beta1 m + (1 - beta1) g,   v = beta2 v + (1 - beta2) g.^2,
//   x_{k+1} = P[ x_k - lr (m / (1 - beta1^t)) ./ (sqrt(v / (1 - beta2^t)) + epsilon) ],
// P the projection onto the variable bounds when TaoSetVariableBounds gave any (projected Adam).
// The first step is therefore x_1 = P[x_0 - lr g_0 ./ (|g_0| + epsilon)]. One objective-and-gradient
// evaluation per iteration, no line search. TAO's own monitors (-tao_monitor, -tao_view) and
// convergence tests (-tao_max_it, -tao_gatol, -tao_grtol, -tao_max_funcs) apply; the gradient norm
// reported with bounds is that of the projected gradient, as for BLMVM.
//
// Options: -tao_adam_lr (default 1e-3), -tao_adam_beta1 (0.9), -tao_adam_beta2 (0.999),
// -tao_adam_epsilon (1e-8).
//
//   mpiexec -n 2 ./flexipde -task invert -tao_type adam -tao_adam_lr 1e-3 -tao_monitor ...
#pragma once
#include "flexipde/petsc.hpp"

namespace flexipde {

// TaoRegister("adam", ...), once per process (later calls do nothing).
PetscErrorCode register_tao_adam();

} // namespace flexipde
