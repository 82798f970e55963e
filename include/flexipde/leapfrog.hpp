// The leapfrog (Stormer-Verlet, kick-drift-kick) integrator as a PETSc TS type with its own
// discrete adjoint, for models in second-order form (Model::second_order_pairs() = m > 0):
//
//   U = (q, p) per grid point, q_t = p, p_t = a(t, q; theta) - sigma(x) p
//   (G_q = p, G_p = a - sigma p, with sigma >= 0 a fixed damping, e.g. an absorbing sponge)
//
//   step t_k -> t_{k+1} = t_k + dt, with s = sigma dt / 2:
//     (1 + s) p_h = p_k + dt/2 a(t_k, q_k)            kick (the damping implicit)
//     q_{k+1}     = q_k + dt p_h                      drift
//     p_{k+1}     = (1 - s) p_h + dt/2 a(t_{k+1}, q_{k+1})  kick (the damping explicit)
//
// Eliminating p gives (1 + s) q_{k+1} = 2 q_k - (1 - s) q_{k-1} + dt^2 a(q_k): the seed's leapfrog
// when sigma = 0 (second order, symplectic), and the centred damped scheme of FWI codes otherwise; stable
// for dt * omega_max < 2 (omega_max^2 the largest eigenvalue of -da/dq, i.e. the imaginary radius of
// the first-order system's spectrum). In terms of G: the second kick is p_{k+1} = p_h + dt/2 G_p(q_{k+1}, p_h),
// and G there is kept for the next step's first kick (first same as last), which is then
// p_h = p_k + dt/2 (1 - s)/(1 + s) G_p (p_k + dt/2 G_p/(1 + s) after a fresh evaluation of G at U_k),
// so a step costs ONE evaluation of G. The Simulation finds sigma as -dG_p/dp (leapfrog_set_damping).
//
// Adjoint (lambda = dJ/dU, mu = dJ/dtheta), exact for the scheme above: a step's transpose is
//   lambda_q += dt/2 A_{k+1}^T lambda_p,  lambda_p += dt lambda_q,  lambda_q += dt/2 A_k^T lambda_p
// with A_k = da/dq(q_k) (and mu += dt/2 (da/dtheta)_k^T lambda_p likewise); with damping the drift's
// transpose is lambda_p = ((1 - s) lambda_p + dt lambda_q) / (1 + s), the rest unchanged. The two half-kicks
// that meet at a time level k use the same lambda_p, so they are applied together, once per level,
// with weight dt (dt/2 at t_0 and T): an adjoint step costs one product with (dG/dU)^T and one
// with (dG/dtheta)^T, and needs only the state at the step's start (kept as the step's one
// "stage", so PETSc's memory trajectory stores it and nothing is recomputed). With the model's fused kick
// (Model::second_order_adjoint) lambda_q and lambda_p live in arrays of their own between steps, and the
// undamped drift's transpose is handed to the kick beyond the caches, which may fold it into its own
// sweep over lambda. Since G_q = p, (dG/dU)^T lambda has A^T lambda_p in its q rows and
// (dG/dtheta)^T lambda = (da/dtheta)^T lambda_p (sigma depends on no parameter), so the full Jacobians
// serve without masking.
//
// Time-integrated objectives int_0^T r(t, U) dt use the trapezoidal rule on the time levels
// (weights dt, dt/2 at both ends), accumulated in the forward sweep; the adjoint adds the same
// weights times dr/dU and dr/dtheta at each level.
//
// Fixed steps only (the scheme is symplectic for a constant dt and no damping); the Simulation refuses
// adaptivity and models without the second-order form for -ts_type leapfrog.
#pragma once
#include "flexipde/petsc.hpp"
#include <petscts.h>

namespace flexipde {

#define FLEXIPDE_TSLEAPFROG "leapfrog"
PetscErrorCode register_leapfrog_ts();
// Number m of position/velocity pairs per grid point (components 0..m-1 and m..2m-1).
PetscErrorCode leapfrog_set_pairs(TS ts, PetscInt m);
// The damping sigma >= 0 in the velocity rows of a state-shaped Vec (the position rows unread), or null
// for none; the TS keeps a reference.
PetscErrorCode leapfrog_set_damping(TS ts, Vec sigma);
// What a time-integrated objective's integrand r reads (Objective::integrand_reads_*): with no
// velocity, the two half-kicks of a level are one sweep; with no parameter, dr/dp is not formed.
PetscErrorCode leapfrog_set_integrand_reads(TS ts, bool velocities, bool parameters);
// Whether the adjoint of this leapfrog TS reads the positions of the stored states alone: no cost
// integrand, or one that reads no velocity (then its dr/dU is evaluated at positions alone, handed to
// the quadrature TS's Jacobian as a Vec of m components per point).
bool leapfrog_positions_suffice(TS ts);
// Optional: lambda += w dr/dU(t, X) in place, X a state or (leapfrog_positions_suffice) the positions
// alone, for integrands with a sparse dr/dU (Objective::integrand_dU_add); else the adjoint adds the
// quadrature TS's dense dr/dU. With the model's kick (leapfrog_set_adjoint_kick) and positions alone,
// lambda is the adjoint's positions part lambda_q (m per point).
using LeapfrogIntegrandAdjoint = PetscErrorCode (*)(void *ctx, PetscReal t, Vec X, PetscReal w, Vec lambda);
PetscErrorCode leapfrog_set_integrand_adjoint(TS ts, LeapfrogIntegrandAdjoint fn, void *ctx);
bool is_leapfrog(TS ts);
PetscInt leapfrog_pairs(TS ts); // m, or 0 for another TS type
// Optional fused adjoint kick at one time level (Model::second_order_adjoint), on the adjoint's positions
// and velocities held in arrays of their own (lambda_q, lambda_p: m per owned point each, the model's
// positions layout): first
//   lambda_p += drift lambda_q  (the transpose of the drift that ends at this level; drift = 0: none),
// then
//   lambda_q += w (da/dq)^T lambda_p,  mu += w (da/dtheta)^T lambda_p  (mu null: no parameters).
// When set, the adjoint keeps lambda so between steps (the stencils' transposes read whole vectors of
// lambda_p) and forms the TS's interleaved lambda at the end of the solve and for adjoint monitors; it
// calls the kick instead of computing and applying the RHS Jacobians, and, beyond the caches, hands it
// each undamped step's drift instead of making a pass of its own (the model may fold it into its sweep).
// `prefetch`: the stored positions the next adjoint step will read (leapfrog_place_positions), for the
// kick to prefetch while it sweeps (null: none).
using LeapfrogAdjointKick = PetscErrorCode (*)(void *ctx, PetscReal t, Vec U, Vec lambda_q, Vec lambda_p, PetscReal w, Vec mu,
                                               PetscReal drift, const PetscScalar *prefetch);
// One prefetch per cache line of the n entries at q (null: nothing), for kicks that do not spread them.
inline void leapfrog_prefetch(const PetscScalar *q, PetscInt n) {
  if (!q) return;
  const char *b = reinterpret_cast<const char *>(q);
  for (size_t o = 0; o < sizeof(PetscScalar) * (size_t)n; o += 64) __builtin_prefetch(b + o, 0, 3);
}
// The drift's transpose lambda_p += s lambda_q on the entries [lo, hi) of the split arrays, for kicks
// that apply it in a pass of their own.
inline void leapfrog_drift_transpose(PetscScalar *__restrict lambda_p, const PetscScalar *__restrict lambda_q, PetscInt lo,
                                     PetscInt hi, PetscReal s) {
  for (PetscInt i = lo; i < hi; ++i) lambda_p[i] += s * lambda_q[i];
}
// Optional fused forward step (Model::second_order_step): the model sweeps a whole step in one pass
// over the grid, applying the integrator's point-local parts below to ranges of owned points in an
// order its stencil allows, so that the state passes through the cache once instead of three times.
// The same operations on every point as the three passes (kick and drift, G, kick): the same numbers.
// Between fused steps the integrator keeps the accelerations a = G_p alone (m per point), not all of
// G: its position rows are p, which the step has in U.
class LeapfrogStepParts {
public:
  // u: the local array of U (2m entries per point); a: the accelerations (m per point); points [begin, end).
  // The first kick and the drift, p += dt/2 g a and q += dt p (and q to the trajectory's slot):
  // before G reads the point's positions anywhere.
  virtual void kick_drift(PetscScalar *u, const PetscScalar *a, PetscInt begin, PetscInt end) const = 0;
  // The second kick p += dt/2 a: once the point's a is final.
  virtual void kick(PetscScalar *u, const PetscScalar *a, PetscInt begin, PetscInt end) const = 0;

protected:
  ~LeapfrogStepParts() = default;
};
// accel = G_p(t, U) (m per owned point) at the state after kick_drift, and U after kick (t: the step's end).
using LeapfrogStep = PetscErrorCode (*)(void *ctx, PetscReal t, Vec U, PetscScalar *accel, const LeapfrogStepParts &parts);
PetscErrorCode leapfrog_set_step(TS ts, LeapfrogStep step, void *ctx);
// Optional split step (Model::second_order_split_step): the integrator keeps the positions q and the
// velocities v in arrays of their own between steps, v at the half steps, and makes a step
//   v_{k+1/2} = v_{k-1/2} + dt a(t_k, q_k),   q_{k+1} = q_k + dt v_{k+1/2}
// (the two half-kicks that meet at t_k as one; with damping (1 + s) v_{k+1/2} = (1 - s) v_{k-1/2} + dt a_k)
// in one sweep over q and v: the stencils read whole vectors of positions, and a is never stored. It is
// the same scheme as the kick-drift-kick above, in another order of rounding. U = (q, p) is formed
// (p_k = v_{k-1/2} + dt/2 G_p(q_k, v_{k-1/2})) only when someone reads it: at the end of a solve, before
// a step of the other kind, for monitors that ask (leapfrog_form_solution); a solve whose steps are
// watched by anything else (monitors, step hooks, events, other trajectories, an integrand that reads
// velocities) takes the kick-drift-kick steps.
class LeapfrogSplitParts {
public:
  // The kick as one formula at every point, for the sweep that applies it as it forms the point's
  // accelerations a: v = keep v + w inv a (inv and keep m per point, both null when nothing is damped: 1).
  struct PointKick {
    PetscReal w = 0;
    const PetscScalar *inv = nullptr, *keep = nullptr;
  };
  virtual PointKick point_kick() const = 0;
  // q += dt v on the points [begin, end) (and q to the trajectory's slot): once no G reads their q_k.
  virtual void drift(PetscScalar *q, const PetscScalar *v, PetscInt begin, PetscInt end) const = 0;

protected:
  ~LeapfrogSplitParts() = default;
};
// Q: the positions (m per owned point, the model's positions layout), changed in place; v: the velocities
// (m per owned point); t: the step's start, where a is evaluated.
using LeapfrogSplitStep = PetscErrorCode (*)(void *ctx, PetscReal t, Vec Q, PetscScalar *v, const LeapfrogSplitParts &parts);
PetscErrorCode leapfrog_set_split_step(TS ts, LeapfrogSplitStep step, void *ctx);
// The TS's solution made current (collective; nothing when it is): for a monitor that reads it, which
// says so with leapfrog_monitor_forms_solution (a monitor that does not say so makes every step a
// kick-drift-kick step). TSMonitorDefault reads no state.
PetscErrorCode leapfrog_form_solution(TS ts);
using LeapfrogMonitor = PetscErrorCode (*)(TS, PetscInt, PetscReal, Vec, void *);
PetscErrorCode leapfrog_monitor_forms_solution(TS ts, LeapfrogMonitor monitor);
// Whether one sweep beats three passes for a rank whose U and accelerations take `bytes`: when they exceed the
// last-level cache's share per core. Within the caches the three passes stream faster; beyond them one
// sweep saves two passes over memory (docs/performance.md).
bool leapfrog_one_sweep_pays(size_t bytes);
// The kick takes U as a whole state or as the positions alone.
PetscErrorCode leapfrog_set_adjoint_kick(TS ts, LeapfrogAdjointKick kick, void *ctx);
// An adjoint monitor that reads no lambda (statistics), for every TS: the adjoint forms the interleaved
// lambda after every step only for the other monitors.
using LeapfrogAdjointMonitor = PetscErrorCode (*)(TS, PetscInt, PetscReal, Vec, PetscInt, Vec *, Vec *, void *);
void leapfrog_adjoint_monitor_reads_no_lambda(LeapfrogAdjointMonitor monitor);
// For a trajectory that stores the positions alone (m of every 2m components, contiguous): the next
// adjoint step's level k-1 reads them from q in place when the kick takes positions (*placed), else
// the trajectory must fill the stage with U_{k-1} itself. q must stay valid until that step is done.
// `next`: the positions the step after it will read (null: none), handed to the kick to prefetch.
PetscErrorCode leapfrog_place_positions(TS ts, const PetscScalar *q, const PetscScalar *next, bool *placed);
// For a trajectory that stores the positions alone: the next step also writes the positions it
// produces to q (one pass with the drift, non-temporal stores), when it can (m = 1, q 16-byte
// aligned, no stage copy); leapfrog_sunk_positions then returns q, else null.
PetscErrorCode leapfrog_sink_positions(TS ts, PetscScalar *q);
const PetscScalar *leapfrog_sunk_positions(TS ts);

} // namespace flexipde
