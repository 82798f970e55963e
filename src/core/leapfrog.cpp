// The leapfrog TS type and its adjoint; the scheme and its transpose are derived in leapfrog.hpp.
#include "flexipde/leapfrog.hpp"
#include "flexipde/checkpoint.hpp" // FLEXIPDE_TSTRAJECTORY_STORE
#include <petsc/private/petscimpl.h> // PetscObjectStateGet
#include <petsc/private/tsimpl.h>
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <string>
#include <vector>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace flexipde {
namespace {

struct Leapfrog {
  PetscInt pairs = 0; // m
  PetscInt dof = 0;   // 2m
  Vec F = nullptr;    // G(t, U) at the state the TS holds: its p rows are a(t, q), the next kick
  // With the model's fused step (step below): a(t, q) alone, m per point, instead of F.
  std::vector<PetscScalar> accel;
  Vec Y0 = nullptr;   // the state at the start of the last step (the step's one "stage")
  Vec W = nullptr;    // adjoint work: (dG/dU)^T lambda
  Vec dmu = nullptr;  // adjoint work: (dG/dtheta)^T lambda
  // F (or accel) is valid for the vector state and time recorded here (first same as last).
  PetscObjectState F_state = -1;
  PetscReal F_time = 0;
  bool F_valid = false;
  // r(t_{k+1}, U_{k+1}) of the last forward-integral call, reused by the next step as its start.
  Vec r_end = nullptr;
  PetscInt r_end_step = -1;
  // The damping sigma in the velocity rows (null: none), and the factors of the step dt_scaled, with
  // s = sigma dt/2: (1 - s)/(1 + s) in the velocity rows (the first kick after a second kick, first
  // same as last; the adjoint drift's lambda_p), 1/(1 + s) in the position rows (the first kick after a
  // fresh G; the adjoint drift's lambda_q), so that the adjoint reads them in lambda's layout.
  Vec sigma = nullptr, factors = nullptr;
  // The runs [first, second) of points where sigma is not 0 (in any velocity row), in order: elsewhere
  // both factors are 1 and the undamped loops give the same numbers without reading them.
  std::vector<std::pair<PetscInt, PetscInt>> damped;
  // The same factors m per point, for the split step's kick: 1/(1 + s) and (1 - s)/(1 + s).
  std::vector<PetscScalar> inv_factor, keep_factor;
  // what the integrand of a time-integrated objective reads (leapfrog_set_integrand_reads)
  bool integrand_reads_velocities = true, integrand_reads_parameters = true;
  // adds w dr/dU to lambda in place, when the objective can (leapfrog_set_integrand_adjoint)
  LeapfrogIntegrandAdjoint integrand_adjoint = nullptr;
  void *integrand_adjoint_ctx = nullptr;
  PetscReal dt_scaled = 0;
  // the model's fused adjoint kick, when it has one
  LeapfrogAdjointKick adjoint_kick = nullptr;
  void *adjoint_kick_ctx = nullptr;
  // the model's fused forward step, when it has one
  LeapfrogStep step = nullptr;
  void *step_ctx = nullptr;
  // It reads the positions alone: a full-storage trajectory points Q (a Vec of the positions, no array
  // of its own) at the stored ones of level k-1 before the adjoint of step k-1 -> k, which reads them
  // there instead of from Y0 (leapfrog_place_positions).
  Vec Q = nullptr;
  bool Q_placed = false;
  const PetscScalar *Q_next = nullptr; // the positions the step after that reads, for the kick to prefetch
  // Where the next step also writes the positions it produces (a full-storage trajectory's next slot,
  // leapfrog_sink_positions), with non-temporal stores; consumed by that one step. `sunk` = where the
  // last step wrote them (null: nowhere).
  PetscScalar *sink = nullptr;
  const PetscScalar *sunk = nullptr;
  // Whether this solve's steps must leave U_k in Y0: for a trajectory that stores stages or re-runs
  // steps (PETSc's, binomial checkpointing). Plain forward solves and the "store" trajectory (which
  // hands the adjoint U_{k-1} itself) skip the copy, a third of a step's memory traffic.
  bool copy_stage = true;
  // The model's split step (leapfrog_set_split_step), the positions Qs (m per point) and velocities Vs
  // it keeps between steps, and the monitors that form the solution themselves when they read it.
  LeapfrogSplitStep split = nullptr;
  void *split_ctx = nullptr;
  Vec Qs = nullptr;
  std::vector<PetscScalar> Vs;
  std::vector<LeapfrogMonitor> forming_monitors;
  // Qs and Vs hold the state at split_time when split_valid, v at split_time - split_dt/2 (split_dt = 0:
  // v is p at split_time itself, as loaded from U). U was last consistent with them when its object
  // state was split_u_state; u_behind: they have moved on since, and U is stale.
  bool split_valid = false, u_behind = false;
  PetscReal split_time = 0, split_dt = 0;
  Vec split_u = nullptr; // (not a reference: compared only)
  PetscObjectState split_u_state = -1;
  // With the model's adjoint kick: lambda's positions and velocities parts per cost (m per point each),
  // current instead of ts->vecs_sensi while lambda_split.
  std::vector<Vec> Lq, Lp;
  bool lambda_split = false;
};

// Adjoint monitors known to read no lambda (leapfrog_adjoint_monitor_reads_no_lambda).
std::vector<LeapfrogAdjointMonitor> &quiet_adjoint_monitors() {
  static std::vector<LeapfrogAdjointMonitor> list;
  return list;
}

Leapfrog *data(TS ts) { return static_cast<Leapfrog *>(ts->data); }

// The per-point loops below take the number of pairs M as a template argument when it is 1 (the
// wave equations), so that the compiler sees fixed strides; M = 0 means "m at run time". They read a
// from F's velocity rows (2m entries per point, n entries in all) or, with Accel, from an array of the
// accelerations alone (m per point: the fused step's).
template <bool Accel> inline PetscInt accel_at(PetscInt k, PetscInt m, PetscInt c) { return Accel ? k * m + c : 2 * k * m + m + c; }
template <int M, bool Accel = false>
void kick_loop(PetscScalar *__restrict u, const PetscScalar *__restrict f, PetscInt n, PetscInt m_rt, PetscReal s) {
  const PetscInt m = M ? M : m_rt, d = 2 * m;
  for (PetscInt k = 0; k < n / d; ++k)
    for (PetscInt c = 0; c < m; ++c) u[k * d + m + c] += s * f[accel_at<Accel>(k, m, c)];
}

// p += s * F_p on every grid point (the kick).
PetscErrorCode kick(const Leapfrog &lf, Vec U, Vec F, PetscReal s) {
  PetscScalar *u;
  const PetscScalar *f;
  PetscInt n;
  PetscFunctionBegin;
  PetscCall(VecGetLocalSize(U, &n));
  PetscCall(VecGetArray(U, &u));
  PetscCall(VecGetArrayRead(F, &f));
  if (lf.pairs == 1) kick_loop<1>(u, f, n, 1, s);
  else kick_loop<0>(u, f, n, lf.pairs, s);
  PetscCall(VecRestoreArrayRead(F, &f));
  PetscCall(VecRestoreArray(U, &u));
  PetscFunctionReturn(0);
}

PetscErrorCode update_factors(Leapfrog &lf, PetscReal dt);

// fn(lo, hi, damped) over [begin, end) (points) cut at the edges of the damped runs.
template <class Fn> void for_damping_runs(const std::vector<std::pair<PetscInt, PetscInt>> &damped, PetscInt begin, PetscInt end, Fn &&fn) {
  auto run = std::upper_bound(damped.begin(), damped.end(), std::make_pair(begin, std::numeric_limits<PetscInt>::max()));
  if (run != damped.begin() && std::prev(run)->second > begin) --run;
  PetscInt at = begin;
  for (; at < end && run != damped.end() && run->first < end; ++run) {
    if (run->first > at) fn(at, run->first, false);
    const PetscInt lo = std::max(at, run->first), hi = std::min(end, run->second);
    if (hi > lo) fn(lo, hi, true);
    at = std::max(at, hi);
  }
  if (at < end) fn(at, end, false);
}

// lambda_p += s lambda_q on the points [lo, hi) of an interleaved lambda (2m entries per point).
void interleaved_drift_transpose(PetscScalar *lambda, PetscInt lo, PetscInt hi, PetscInt m, PetscReal s) {
  if (m == 1)
    for (PetscInt i = lo; i < hi; ++i) lambda[2 * i + 1] += s * lambda[2 * i];
  else
    for (PetscInt i = lo; i < hi; ++i)
      for (PetscInt c = 0; c < m; ++c) lambda[2 * m * i + m + c] += s * lambda[2 * m * i + c];
}

// The drift's transpose on the adjoint: lambda_p += dt * lambda_q, and with damping (the two kicks'
// factors on either side of it) lambda_p = ((1 - s) lambda_p + dt lambda_q) / (1 + s), s = sigma dt/2
// (the forward drift is fused into start_kick_drift).
PetscErrorCode drift_transpose(Leapfrog &lf, Vec lambda, PetscReal dt) {
  PetscScalar *l;
  PetscInt n;
  PetscFunctionBegin;
  PetscCall(VecGetLocalSize(lambda, &n));
  PetscCall(VecGetArray(lambda, &l));
  if (lf.sigma) {
    const PetscScalar *g;
    const PetscInt m = lf.pairs, d = lf.dof;
    PetscCall(update_factors(lf, dt));
    PetscCall(VecGetArrayRead(lf.factors, &g));
    for_damping_runs(lf.damped, 0, n / d, [&](PetscInt lo, PetscInt hi, bool damped) {
      if (!damped) return interleaved_drift_transpose(l, lo, hi, m, dt);
      for (PetscInt i = lo * d; i < hi * d; i += d)
        for (PetscInt c = 0; c < m; ++c) l[i + m + c] = g[i + m + c] * l[i + m + c] + dt * g[i + c] * l[i + c];
    });
    PetscCall(VecRestoreArrayRead(lf.factors, &g));
  } else interleaved_drift_transpose(l, 0, n / lf.dof, lf.pairs, dt);
  PetscCall(VecRestoreArray(lambda, &l));
  PetscFunctionReturn(0);
}

// The same on the split lambda: lambda_p = keep lambda_p + dt inv lambda_q with the damping's factors.
PetscErrorCode split_drift_transpose(Leapfrog &lf, Vec lambda_q, Vec lambda_p, PetscReal dt) {
  PetscScalar *lp;
  const PetscScalar *lq;
  PetscInt n;
  PetscFunctionBegin;
  PetscCall(VecGetLocalSize(lambda_p, &n));
  PetscCall(VecGetArray(lambda_p, &lp));
  PetscCall(VecGetArrayRead(lambda_q, &lq));
  if (lf.sigma) {
    const PetscInt m = lf.pairs;
    PetscCall(update_factors(lf, dt));
    const PetscScalar *keep = lf.keep_factor.data(), *inv = lf.inv_factor.data();
    for_damping_runs(lf.damped, 0, n / m, [&](PetscInt lo, PetscInt hi, bool damped) {
      if (!damped) return leapfrog_drift_transpose(lp, lq, lo * m, hi * m, dt);
      for (PetscInt i = lo * m; i < hi * m; ++i) lp[i] = keep[i] * lp[i] + dt * inv[i] * lq[i];
    });
  } else leapfrog_drift_transpose(lp, lq, 0, n, dt);
  PetscCall(VecRestoreArrayRead(lambda_q, &lq));
  PetscCall(VecRestoreArray(lambda_p, &lp));
  PetscFunctionReturn(0);
}

// A state (q, p) with m positions and m momenta per point, interleaved as the Vec holds it, and the
// split arrays holding each alone (m per point): split_pairs copies u into q and p, join_pairs back.
void split_pairs(const PetscScalar *__restrict u, PetscScalar *__restrict q, PetscScalar *__restrict p, PetscInt npt, PetscInt m) {
  for (PetscInt k = 0; k < npt; ++k)
    for (PetscInt c = 0; c < m; ++c) q[k * m + c] = u[2 * k * m + c], p[k * m + c] = u[2 * k * m + m + c];
}
void join_pairs(const PetscScalar *__restrict q, const PetscScalar *__restrict p, PetscScalar *__restrict u, PetscInt npt, PetscInt m) {
  for (PetscInt k = 0; k < npt; ++k)
    for (PetscInt c = 0; c < m; ++c) u[2 * k * m + c] = q[k * m + c], u[2 * k * m + m + c] = p[k * m + c];
}

// lambda split (lf.Lq, lf.Lp, made when first needed) from ts->vecs_sensi, or (form) vecs_sensi from them.
PetscErrorCode lambda_split_load(TS ts, Leapfrog &lf, bool form) {
  PetscFunctionBegin;
  const PetscInt m = lf.pairs, d = 2 * m;
  for (PetscInt k = (PetscInt)lf.Lq.size(); k < ts->numcost; ++k) {
    Vec q, p;
    PetscInt n;
    PetscCall(VecGetLocalSize(ts->vecs_sensi[k], &n));
    PetscCall(VecCreate(PetscObjectComm((PetscObject)ts), &q));
    PetscCall(VecSetSizes(q, n / 2, PETSC_DETERMINE));
    PetscCall(VecSetBlockSize(q, m));
    PetscCall(VecSetType(q, VECSTANDARD));
    PetscCall(VecDuplicate(q, &p));
    lf.Lq.push_back(q), lf.Lp.push_back(p);
  }
  for (PetscInt k = 0; k < ts->numcost; ++k) {
    PetscScalar *l, *q, *p;
    PetscInt n;
    PetscCall(VecGetLocalSize(ts->vecs_sensi[k], &n));
    PetscCall(VecGetArray(ts->vecs_sensi[k], &l));
    PetscCall(VecGetArray(lf.Lq[k], &q));
    PetscCall(VecGetArray(lf.Lp[k], &p));
    if (form) join_pairs(q, p, l, n / d, m);
    else split_pairs(l, q, p, n / d, m);
    PetscCall(VecRestoreArray(lf.Lp[k], &p));
    PetscCall(VecRestoreArray(lf.Lq[k], &q));
    PetscCall(VecRestoreArray(ts->vecs_sensi[k], &l));
  }
  lf.lambda_split = !form;
  PetscFunctionReturn(0);
}

// Whether an adjoint monitor may read lambda (all but those registered as reading none).
bool lambda_watched(TS ts) {
  const auto &quiet = quiet_adjoint_monitors();
  for (PetscInt i = 0; i < ts->numberadjointmonitors; ++i)
    if (std::find(quiet.begin(), quiet.end(), ts->adjointmonitor[i]) == quiet.end()) return true;
  return false;
}

// lambda_q += s * W_q (the q rows of (dG/dU)^T lambda = A^T lambda_p).
PetscErrorCode add_q_rows(const Leapfrog &lf, Vec lambda, Vec W, PetscReal s) {
  PetscScalar *l;
  const PetscScalar *w;
  PetscInt n;
  PetscFunctionBegin;
  PetscCall(VecGetLocalSize(lambda, &n));
  PetscCall(VecGetArray(lambda, &l));
  PetscCall(VecGetArrayRead(W, &w));
  const PetscInt m = lf.pairs, d = lf.dof;
  for (PetscInt i = 0; i < n; i += d)
    for (PetscInt c = 0; c < m; ++c) l[i + c] += s * w[i + c];
  PetscCall(VecRestoreArrayRead(W, &w));
  PetscCall(VecRestoreArray(lambda, &l));
  PetscFunctionReturn(0);
}

#if defined(__SSE2__) && !defined(PETSC_USE_COMPLEX) && defined(PETSC_USE_REAL_DOUBLE)
// start_kick_drift_loop<1> that also writes the new positions to q (16-byte aligned), two points per
// non-temporal store: the state and the stored copy in one pass.
void start_kick_drift_sink(PetscScalar *__restrict u, const PetscScalar *__restrict f, PetscScalar *__restrict q,
                           PetscInt n, PetscReal dt) {
  const PetscInt npt = n / 2;
  PetscInt k = 0;
  for (; k + 1 < npt; k += 2) {
    PetscScalar *a = u + 2 * k;
    const PetscScalar *g = f + 2 * k;
    const PetscScalar ph0 = a[1] + 0.5 * dt * g[1], ph1 = a[3] + 0.5 * dt * g[3];
    const PetscScalar q0 = a[0] + dt * ph0, q1 = a[2] + dt * ph1;
    a[0] = q0, a[1] = ph0, a[2] = q1, a[3] = ph1;
    _mm_stream_pd(q + k, _mm_set_pd(q1, q0));
  }
  for (; k < npt; ++k) {
    const PetscScalar ph = u[2 * k + 1] + 0.5 * dt * f[2 * k + 1];
    u[2 * k + 1] = ph;
    u[2 * k] += dt * ph;
    q[k] = u[2 * k];
  }
  _mm_sfence();
}
#define FLEXIPDE_LEAPFROG_SINK 1
#endif

template <int M, bool Accel = false>
void start_kick_drift_loop(PetscScalar *__restrict u, const PetscScalar *__restrict f, PetscScalar *__restrict y,
                           PetscInt n, PetscInt m_rt, PetscReal dt) {
  const PetscInt m = M ? M : m_rt, d = 2 * m;
  if (y)
    for (PetscInt i = 0; i < n; ++i) y[i] = u[i];
  for (PetscInt k = 0; k < n / d; ++k)
    for (PetscInt c = 0; c < m; ++c) {
      const PetscScalar ph = u[k * d + m + c] + 0.5 * dt * f[accel_at<Accel>(k, m, c)];
      u[k * d + m + c] = ph;
      u[k * d + c] += dt * ph;
    }
}

// The damped first kick and the drift: p += dt/2 g F_p with g from the factors (those of the velocity
// rows after a second kick, of the position rows when F is fresh), then q += dt p; Y0 = U first and the
// new positions to `sink` when given.
template <int M, bool Accel = false>
void damped_start_kick_drift_loop(PetscScalar *__restrict u, const PetscScalar *__restrict f, PetscScalar *__restrict y,
                                  PetscScalar *__restrict sink, const PetscScalar *__restrict factors, bool fresh,
                                  PetscInt n, PetscInt m_rt, PetscReal dt) {
  const PetscInt m = M ? M : m_rt, d = 2 * m, row = fresh ? 0 : m;
  if (y)
    for (PetscInt i = 0; i < n; ++i) y[i] = u[i];
  for (PetscInt k = 0; k < n / d; ++k)
    for (PetscInt c = 0; c < m; ++c) {
      const PetscScalar g = factors[k * d + row + c];
      const PetscScalar ph = u[k * d + m + c] + 0.5 * dt * g * f[accel_at<Accel>(k, m, c)];
      u[k * d + m + c] = ph;
      u[k * d + c] += dt * ph;
      if (sink) sink[k * m + c] = u[k * d + c];
    }
}

// lf.factors for the step dt.
PetscErrorCode update_factors(Leapfrog &lf, PetscReal dt) {
  PetscScalar *g;
  const PetscScalar *sg;
  PetscInt n;
  PetscFunctionBegin;
  if (lf.factors && lf.dt_scaled == dt) PetscFunctionReturn(0);
  if (!lf.factors) PetscCall(VecDuplicate(lf.sigma, &lf.factors));
  PetscCall(VecGetLocalSize(lf.sigma, &n));
  PetscCall(VecGetArrayRead(lf.sigma, &sg));
  PetscCall(VecGetArrayWrite(lf.factors, &g));
  const PetscInt m = lf.pairs, d = 2 * m;
  lf.damped.clear();
  lf.inv_factor.resize((size_t)(n / 2));
  lf.keep_factor.resize((size_t)(n / 2));
  for (PetscInt i = 0; i < n; i += d) {
    bool damped = false;
    for (PetscInt c = 0; c < m; ++c) {
      const PetscScalar s = 0.5 * dt * sg[i + m + c];
      g[i + c] = lf.inv_factor[i / 2 + c] = 1.0 / (1.0 + s);
      g[i + m + c] = lf.keep_factor[i / 2 + c] = (1.0 - s) / (1.0 + s);
      damped = damped || sg[i + m + c] != 0;
    }
    const PetscInt k = i / d;
    if (!damped) continue;
    if (!lf.damped.empty() && lf.damped.back().second == k) ++lf.damped.back().second;
    else lf.damped.emplace_back(k, k + 1);
  }
  PetscCall(VecRestoreArrayWrite(lf.factors, &g));
  PetscCall(VecRestoreArrayRead(lf.sigma, &sg));
  lf.dt_scaled = dt;
  PetscFunctionReturn(0);
}

// The point-local parts of a step for a model's fused sweep (leapfrog_set_step) on ranges of points.
class StepParts final : public LeapfrogStepParts {
public:
  // factors, damped: the damping's (null: none) and its runs.
  StepParts(PetscInt pairs, const PetscScalar *factors, const std::vector<std::pair<PetscInt, PetscInt>> *damped,
            PetscScalar *sink, bool fresh, PetscReal dt)
      : m_(pairs), factors_(factors), damped_(damped), sink_(sink), fresh_(fresh), dt_(dt) {}
  void kick_drift(PetscScalar *u, const PetscScalar *a, PetscInt begin, PetscInt end) const override {
    if (factors_)
      for_damping_runs(*damped_, begin, end, [&](PetscInt lo, PetscInt hi, bool damped) {
        if (!damped) return plain_kick_drift(u, a, lo, hi);
        const PetscInt d = 2 * m_, o = lo * d, n = (hi - lo) * d;
        PetscScalar *q = sink_ ? sink_ + lo * m_ : nullptr;
        if (m_ == 1) damped_start_kick_drift_loop<1, true>(u + o, a + lo * m_, nullptr, q, factors_ + o, fresh_, n, 1, dt_);
        else damped_start_kick_drift_loop<0, true>(u + o, a + lo * m_, nullptr, q, factors_ + o, fresh_, n, m_, dt_);
      });
    else plain_kick_drift(u, a, begin, end);
  }
  void kick(PetscScalar *u, const PetscScalar *a, PetscInt begin, PetscInt end) const override {
    const PetscInt o = begin * 2 * m_, n = (end - begin) * 2 * m_;
    if (m_ == 1) kick_loop<1, true>(u + o, a + begin * m_, n, 1, 0.5 * dt_);
    else kick_loop<0, true>(u + o, a + begin * m_, n, m_, 0.5 * dt_);
  }

private:
  // The undamped first kick and drift (and the positions to the sink).
  void plain_kick_drift(PetscScalar *u, const PetscScalar *a, PetscInt begin, PetscInt end) const {
    const PetscInt d = 2 * m_, o = begin * d, n = (end - begin) * d;
    const PetscScalar *ar = a + begin * m_;
    PetscScalar *q = sink_ ? sink_ + begin * m_ : nullptr;
    if (m_ == 1) start_kick_drift_loop<1, true>(u + o, ar, nullptr, n, 1, dt_);
    else start_kick_drift_loop<0, true>(u + o, ar, nullptr, n, m_, dt_);
    if (q) copy_positions(u + o, q, end - begin);
  }
  // The positions of npt points of u (2m entries each) to q (m each): the cache lines of q that the
  // range covers whole with non-temporal stores (the trajectory is not read again until the adjoint),
  // the partial ones at its ends with plain stores, which other ranges of the step complete.
  void copy_positions(const PetscScalar *u, PetscScalar *q, PetscInt npt) const {
    const PetscInt m = m_, d = 2 * m, nq = npt * m;
    PetscInt k = 0;
#if defined(FLEXIPDE_LEAPFROG_SINK)
    for (; k < nq && reinterpret_cast<uintptr_t>(q + k) % 64 != 0; ++k) q[k] = u[(k / m) * d + k % m];
    if (m == 1)
      for (; k + 8 <= nq; k += 8)
        for (PetscInt e = 0; e < 8; e += 2) _mm_stream_pd(q + k + e, _mm_set_pd(u[2 * (k + e + 1)], u[2 * (k + e)]));
#endif
    for (; k < nq; ++k) q[k] = u[(k / m) * d + k % m];
  }
  PetscInt m_;
  const PetscScalar *factors_;
  const std::vector<std::pair<PetscInt, PetscInt>> *damped_;
  PetscScalar *sink_;
  bool fresh_;
  PetscReal dt_;
};

// The point-local parts of a split step (leapfrog_set_split_step) on ranges of points.
class SplitParts final : public LeapfrogSplitParts {
public:
  // inv, keep: the damping's factors 1/(1 + s) and (1 - s)/(1 + s), m per point (null: none); fresh: v
  // is p at the step's start (a half kick), else at the half step before it; sink: where the n new
  // positions also go (null: nowhere), on a cache line.
  SplitParts(PetscInt pairs, const PetscScalar *inv, const PetscScalar *keep, PetscScalar *sink, PetscInt n, bool fresh,
             PetscReal dt)
      : m_(pairs), inv_(inv), keep_(fresh ? inv : keep), sink_(sink), n_(n), dt_(dt), w_(fresh ? 0.5 * dt : dt) {}
  // v += w a, or with damping (1 + s) v_{k+1/2} = (1 - s) v_{k-1/2} + dt a (fresh: (1 + s) v = p_k + dt/2 a):
  // v = keep v + w inv a, where nothing is damped 1 * v + w * 1 * a = v + w a exactly.
  PointKick point_kick() const override { return {w_, inv_, inv_ ? keep_ : nullptr}; }
  void drift(PetscScalar *q, const PetscScalar *v, PetscInt begin, PetscInt end) const override {
    PetscScalar *__restrict qq = q + begin * m_;
    const PetscScalar *__restrict vv = v + begin * m_;
    const PetscReal dt = dt_;
    for (PetscInt i = 0; i < (end - begin) * m_; ++i) qq[i] += dt * vv[i];
    if (sink_) sink_positions(q, end * m_);
  }

private:
  // sink[copied, upto) = q[copied, upto) as far as whole cache lines of the sink go (the last range:
  // all of it), with non-temporal stores: the trajectory is not read again until the adjoint, and no line
  // gets both kinds of store. Ranges that come out of order are copied with plain stores.
  void sink_positions(const PetscScalar *q, PetscInt upto) const {
    PetscInt k = copied_, end = upto;
#if defined(FLEXIPDE_LEAPFROG_SINK)
    if (upto < n_) end = (PetscInt)(((reinterpret_cast<uintptr_t>(sink_ + upto) & ~(uintptr_t)63) - reinterpret_cast<uintptr_t>(sink_)) / sizeof(PetscScalar));
    if (reinterpret_cast<uintptr_t>(sink_ + k) % 16 == 0)
      for (; k + 2 <= end; k += 2) _mm_stream_pd(sink_ + k, _mm_loadu_pd(q + k));
#endif
    for (; k < end; ++k) sink_[k] = q[k];
    copied_ = std::max(copied_, end);
  }
  PetscInt m_;
  const PetscScalar *inv_, *keep_;
  const std::vector<std::pair<PetscInt, PetscInt>> *damped_;
  PetscScalar *sink_;
  PetscInt n_;
  mutable PetscInt copied_ = 0;
  PetscReal dt_, w_;
};

// Y0 = U (when asked for), then the first kick and the drift; the new positions also go to lf.sink
// when there is one (and no Y0), recorded in lf.sunk. fresh: F was evaluated at U itself (not kept
// from the last step's second kick), which matters with damping only.
PetscErrorCode start_kick_drift(Leapfrog &lf, Vec U, Vec F, Vec Y0, PetscReal dt, bool fresh) {
  PetscScalar *u, *y = nullptr;
  const PetscScalar *f;
  PetscInt n;
  PetscFunctionBegin;
  if (lf.sigma) PetscCall(update_factors(lf, dt));
  PetscCall(VecGetLocalSize(U, &n));
  PetscCall(VecGetArray(U, &u));
  if (Y0) PetscCall(VecGetArrayWrite(Y0, &y));
  PetscCall(VecGetArrayRead(F, &f));
  lf.sunk = nullptr;
  if (lf.sigma) {
    const PetscScalar *g;
    PetscScalar *sink = y ? nullptr : lf.sink;
    PetscCall(VecGetArrayRead(lf.factors, &g));
    if (lf.pairs == 1) damped_start_kick_drift_loop<1>(u, f, y, sink, g, fresh, n, 1, dt);
    else damped_start_kick_drift_loop<0>(u, f, y, sink, g, fresh, n, lf.pairs, dt);
    PetscCall(VecRestoreArrayRead(lf.factors, &g));
    lf.sunk = sink;
  } else
#if defined(FLEXIPDE_LEAPFROG_SINK)
  if (lf.pairs == 1 && lf.sink && !y && reinterpret_cast<uintptr_t>(lf.sink) % 16 == 0) {
    start_kick_drift_sink(u, f, lf.sink, n, dt);
    lf.sunk = lf.sink;
  } else
#endif
  if (lf.pairs == 1) start_kick_drift_loop<1>(u, f, y, n, 1, dt);
  else start_kick_drift_loop<0>(u, f, y, n, lf.pairs, dt);
  PetscCall(VecRestoreArrayRead(F, &f));
  if (Y0) PetscCall(VecRestoreArrayWrite(Y0, &y));
  PetscCall(VecRestoreArray(U, &u));
  PetscFunctionReturn(0);
}

// The fused step keeps a alone: the velocity rows of F.
PetscErrorCode keep_accelerations(Leapfrog &lf) {
  const PetscScalar *f;
  PetscInt n;
  PetscFunctionBegin;
  PetscCall(VecGetLocalSize(lf.F, &n));
  lf.accel.resize((size_t)(n / 2));
  PetscCall(VecGetArrayRead(lf.F, &f));
  const PetscInt m = lf.pairs, d = 2 * m;
  for (PetscInt k = 0; k < n / d; ++k)
    for (PetscInt c = 0; c < m; ++c) lf.accel[k * m + c] = f[k * d + m + c];
  PetscCall(VecRestoreArrayRead(lf.F, &f));
  PetscFunctionReturn(0);
}

// The split arrays from U = (q, p) at the TS's time: v = p, at the time itself.
PetscErrorCode split_load(TS ts, Leapfrog &lf) {
  Vec U = ts->vec_sol;
  const PetscScalar *u;
  PetscScalar *q;
  PetscInt n;
  PetscFunctionBegin;
  PetscCall(VecGetLocalSize(U, &n));
  const PetscInt m = lf.pairs, d = 2 * m, npt = n / d;
  if (!lf.Qs) {
    PetscCall(VecCreate(PetscObjectComm((PetscObject)ts), &lf.Qs));
    PetscCall(VecSetSizes(lf.Qs, npt * m, PETSC_DETERMINE));
    PetscCall(VecSetBlockSize(lf.Qs, m));
    PetscCall(VecSetType(lf.Qs, VECSTANDARD));
  }
  lf.Vs.resize((size_t)(npt * m));
  PetscCall(VecGetArrayRead(U, &u));
  PetscCall(VecGetArrayWrite(lf.Qs, &q));
  split_pairs(u, q, lf.Vs.data(), npt, m);
  PetscCall(VecRestoreArrayWrite(lf.Qs, &q));
  PetscCall(VecRestoreArrayRead(U, &u));
  PetscCall(PetscObjectStateGet((PetscObject)U, &lf.split_u_state));
  lf.split_u = U;
  lf.split_valid = true;
  lf.u_behind = false;
  lf.split_time = ts->ptime;
  lf.split_dt = 0;
  PetscFunctionReturn(0);
}

// U = (q_k, p_k) from the split arrays, when they are ahead of it: U = (q_k, v_{k-1/2}), then the
// kick p_k = v + dt/2 G_p(q_k, v), whose F is the one the next kick-drift-kick step would keep.
PetscErrorCode split_form(TS ts, Leapfrog &lf) {
  Vec U = ts->vec_sol;
  PetscScalar *u;
  const PetscScalar *q;
  PetscInt n;
  PetscObjectState st;
  PetscFunctionBegin;
  if (!lf.split_valid || !lf.u_behind) PetscFunctionReturn(0);
  PetscCall(PetscObjectStateGet((PetscObject)U, &st));
  if (U != lf.split_u || st != lf.split_u_state) { // U was set since: it holds the state, not the arrays
    lf.split_valid = lf.u_behind = false;
    PetscFunctionReturn(0);
  }
  PetscCall(VecGetLocalSize(U, &n));
  const PetscInt m = lf.pairs, d = 2 * m, npt = n / d;
  PetscCall(VecGetArrayWrite(U, &u));
  PetscCall(VecGetArrayRead(lf.Qs, &q));
  join_pairs(q, lf.Vs.data(), u, npt, m);
  PetscCall(VecRestoreArrayRead(lf.Qs, &q));
  PetscCall(VecRestoreArrayWrite(U, &u));
  PetscCall(TSComputeRHSFunction(ts, lf.split_time, U, lf.F));
  PetscCall(kick(lf, U, lf.F, 0.5 * lf.split_dt));
  PetscCall(PetscObjectStateGet((PetscObject)U, &lf.F_state));
  lf.F_time = lf.split_time;
  lf.F_valid = true;
  if (lf.step) PetscCall(keep_accelerations(lf));
  lf.split_u_state = lf.F_state;
  lf.u_behind = false;
  PetscFunctionReturn(0);
}

// Whether anything but the split step's own readers may look at U between steps: monitors other than
// TSMonitorDefault and those that form the solution themselves, step hooks, events, forward
// sensitivities, Jacobian tests, a trajectory other than "store", or an integrand that reads velocities.
bool solution_watched(TS ts, const Leapfrog &lf) {
  for (PetscInt i = 0; i < ts->numbermonitors; ++i) {
    const LeapfrogMonitor fn = ts->monitor[i];
    if (fn == reinterpret_cast<LeapfrogMonitor>(TSMonitorDefault)) continue;
    if (std::find(lf.forming_monitors.begin(), lf.forming_monitors.end(), fn) == lf.forming_monitors.end()) return true;
  }
  if (ts->prestep || ts->poststep || ts->postevaluate || ts->event || ts->forward_solve || ts->testjacobian ||
      ts->testjacobiantranspose)
    return true;
  if (ts->quadraturets && ts->costintegralfwd && lf.integrand_reads_velocities) return true;
  return lf.copy_stage;
}

// A split step (leapfrog_set_split_step): from the split arrays, loaded from U when U was set since
// they were last consistent (or the step size changed: the next step starts from U_k). need_stage: Y0 =
// U_k first (the forward cost integral's r(t_k, U_k)).
PetscErrorCode split_step(TS ts, Leapfrog &lf, bool need_stage) {
  Vec U = ts->vec_sol;
  const PetscReal dt = ts->time_step, t = ts->ptime;
  PetscObjectState st;
  PetscFunctionBegin;
  PetscCall(PetscObjectStateGet((PetscObject)U, &st));
  if (lf.split_valid && (U != lf.split_u || st != lf.split_u_state || t != lf.split_time)) lf.split_valid = false;
  if (lf.split_valid && lf.split_dt != 0 && lf.split_dt != dt) {
    PetscCall(split_form(ts, lf));
    lf.split_valid = false;
  }
  if (!lf.split_valid) PetscCall(split_load(ts, lf));
  if (need_stage) {
    PetscCall(split_form(ts, lf));
    PetscCall(VecCopy(U, lf.Y0));
  }
  PetscScalar *sink = need_stage ? nullptr : lf.sink;
  if (lf.sigma) PetscCall(update_factors(lf, dt));
  lf.sunk = nullptr;
  const PetscScalar *inv = lf.sigma ? lf.inv_factor.data() : nullptr, *keep = lf.sigma ? lf.keep_factor.data() : nullptr;
  PetscCall(lf.split(lf.split_ctx, t, lf.Qs, lf.Vs.data(),
                     SplitParts(lf.pairs, inv, keep, sink, (PetscInt)lf.Vs.size(), lf.split_dt == 0, dt)));
#if defined(FLEXIPDE_LEAPFROG_SINK)
  if (sink) _mm_sfence(); // the non-temporal stores of the positions, before anyone reads them
#endif
  lf.sunk = sink;
  lf.sink = nullptr; // one step only
  lf.split_time = t + dt;
  lf.split_dt = dt;
  lf.u_behind = true;
  lf.F_valid = false;
  ts->ptime += dt;
  // U at the end of the solve (TSStep's test, with room for the rounding of the times)
  if (ts->steps + 1 >= ts->max_steps || ts->ptime >= ts->max_time - 1e-10 * PetscMax((PetscReal)1, PetscAbsReal(ts->max_time)))
    PetscCall(split_form(ts, lf));
  PetscFunctionReturn(0);
}

PetscErrorCode TSStep_Leapfrog(TS ts) {
  Leapfrog *lf = data(ts);
  Vec U = ts->vec_sol;
  const PetscReal dt = ts->time_step, t = ts->ptime;
  PetscObjectState st;
  PetscFunctionBegin;
  if (ts->steps == 0) { // once per solve: does anything read this solve's stages?
    PetscBool store = PETSC_FALSE;
    if (ts->trajectory) PetscCall(PetscObjectTypeCompare((PetscObject)ts->trajectory, FLEXIPDE_TSTRAJECTORY_STORE, &store));
    lf->copy_stage = ts->trajectory && !store;
  }
  // the forward cost integral reads r(t_k, U_k) from Y0 when it does not have it from the last step
  const bool need_stage = lf->copy_stage || (ts->quadraturets && ts->costintegralfwd && lf->r_end_step != ts->steps);
  // A split step unless someone reads U after it: a watcher, or a trajectory that gave the step no slot
  // for its positions (such as single-precision storage, or when it keeps U_k for an integrand).
  if (lf->split && !solution_watched(ts, *lf) && (!ts->trajectory || (lf->sink && !need_stage))) {
    PetscCall(split_step(ts, *lf, need_stage));
    PetscFunctionReturn(0);
  }
  PetscCall(split_form(ts, *lf)); // (the split arrays go stale with this step)
  lf->split_valid = false;
  PetscCall(PetscObjectStateGet((PetscObject)U, &st));
  const bool fresh = !lf->F_valid || st != lf->F_state || t != lf->F_time;
  if (fresh) PetscCall(TSComputeRHSFunction(ts, t, U, lf->F));
  if (fresh && lf->step) PetscCall(keep_accelerations(*lf));
  if (lf->step) { // the model's one sweep: the parts below on every point, in its order
    if (need_stage) PetscCall(VecCopy(U, lf->Y0));
    PetscScalar *sink = need_stage ? nullptr : lf->sink;
    const PetscScalar *g = nullptr;
    if (lf->sigma) {
      PetscCall(update_factors(*lf, dt));
      PetscCall(VecGetArrayRead(lf->factors, &g));
    }
    lf->sunk = nullptr;
    PetscCall(lf->step(lf->step_ctx, t + dt, U, lf->accel.data(), StepParts(lf->pairs, g, &lf->damped, sink, fresh, dt)));
    lf->sunk = sink;
#if defined(FLEXIPDE_LEAPFROG_SINK)
    if (sink) _mm_sfence(); // the non-temporal stores of the positions, before anyone reads them
#endif
    if (g) PetscCall(VecRestoreArrayRead(lf->factors, &g));
  } else {
    PetscCall(start_kick_drift(*lf, U, lf->F, need_stage ? lf->Y0 : nullptr, dt, fresh));
    // the second kick p_{k+1} = p_h + dt/2 G_p(q_{k+1}, p_h), also with damping (leapfrog.hpp)
    PetscCall(TSComputeRHSFunction(ts, t + dt, U, lf->F));
    PetscCall(kick(*lf, U, lf->F, 0.5 * dt));
  }
  lf->sink = nullptr; // one step only
  PetscCall(PetscObjectStateGet((PetscObject)U, &lf->F_state));
  lf->F_time = t + dt;
  lf->F_valid = true;
  ts->ptime += dt;
  PetscFunctionReturn(0);
}

PetscErrorCode TSSetUp_Leapfrog(TS ts) {
  Leapfrog *lf = data(ts);
  PetscInt bs;
  PetscFunctionBegin;
  PetscCall(TSCheckImplicitTerm(ts));
  PetscCheck(lf->pairs > 0, PetscObjectComm((PetscObject)ts), PETSC_ERR_ORDER,
             "-ts_type leapfrog needs a model in second-order form (q_t = p, p_t = a(t, q)): this one has none");
  PetscCall(VecGetBlockSize(ts->vec_sol, &bs));
  PetscCheck(bs == 2 * lf->pairs, PetscObjectComm((PetscObject)ts), PETSC_ERR_ARG_WRONG,
             "-ts_type leapfrog: %" PetscInt_FMT " position/velocity pairs need %" PetscInt_FMT
             " components per grid point, the state has %" PetscInt_FMT,
             lf->pairs, 2 * lf->pairs, bs);
  lf->dof = bs;
  PetscCall(VecDuplicate(ts->vec_sol, &lf->F));
  PetscCall(VecDuplicate(ts->vec_sol, &lf->Y0));
  PetscCall(TSGetAdapt(ts, &ts->adapt));
  PetscCall(TSAdaptCandidatesClear(ts->adapt));
  lf->F_valid = false;
  lf->r_end_step = -1;
  PetscFunctionReturn(0);
}

PetscErrorCode TSReset_Leapfrog(TS ts) {
  Leapfrog *lf = data(ts);
  PetscFunctionBegin;
  PetscCall(VecDestroy(&lf->F));
  PetscCall(VecDestroy(&lf->Y0));
  PetscCall(VecDestroy(&lf->W));
  PetscCall(VecDestroy(&lf->dmu));
  PetscCall(VecDestroy(&lf->r_end));
  PetscCall(VecDestroy(&lf->factors));
  lf->accel.clear();
  lf->accel.shrink_to_fit();
  PetscCall(VecDestroy(&lf->Qs));
  for (Vec &v : lf->Lq) PetscCall(VecDestroy(&v));
  for (Vec &v : lf->Lp) PetscCall(VecDestroy(&v));
  lf->Lq.clear(), lf->Lp.clear();
  lf->lambda_split = false;
  lf->Vs.clear();
  lf->Vs.shrink_to_fit();
  lf->split_valid = lf->u_behind = false;
  if (lf->Q_placed) PetscCall(VecResetArray(lf->Q));
  lf->Q_placed = false;
  PetscCall(VecDestroy(&lf->Q));
  lf->F_valid = false;
  lf->r_end_step = -1;
  PetscFunctionReturn(0);
}

PetscErrorCode TSDestroy_Leapfrog(TS ts) {
  PetscFunctionBegin;
  PetscCall(TSReset_Leapfrog(ts));
  PetscCall(VecDestroy(&data(ts)->sigma));
  delete data(ts);
  ts->data = nullptr;
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetPairs_C", nullptr));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetAdjointKick_C", nullptr));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetStep_C", nullptr));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetSplitStep_C", nullptr));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogFormSolution_C", nullptr));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogMonitorFormsSolution_C", nullptr));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetDamping_C", nullptr));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetIntegrandReads_C", nullptr));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetIntegrandAdjoint_C", nullptr));
  PetscFunctionReturn(0);
}

PetscErrorCode TSGetStages_Leapfrog(TS ts, PetscInt *ns, Vec **Y) {
  Leapfrog *lf = data(ts);
  PetscFunctionBegin;
  if (ns) *ns = 1;
  if (Y) *Y = &lf->Y0;
  PetscFunctionReturn(0);
}

// Trapezoidal rule over the step: called by TSSolve after each step with ts->steps = k (the step's
// start index), Y0 = U_k and the TS holding U_{k+1}.
PetscErrorCode TSForwardCostIntegral_Leapfrog(TS ts) {
  Leapfrog *lf = data(ts);
  TS quadts = ts->quadraturets;
  const PetscReal dt = ts->ptime - ts->ptime_prev;
  PetscFunctionBegin;
  if (!lf->r_end) PetscCall(VecDuplicate(ts->vec_costintegrand, &lf->r_end));
  if (lf->r_end_step != ts->steps)
    PetscCall(TSComputeRHSFunction(quadts, ts->ptime_prev, lf->Y0, lf->r_end)); // r(t_k, U_k)
  PetscCall(VecAXPY(quadts->vec_sol, 0.5 * dt, lf->r_end));
  // r(t_{k+1}, U_{k+1}), from the split step's positions when U is behind them (r reads no velocity then)
  PetscCall(TSComputeRHSFunction(quadts, ts->ptime, lf->split_valid && lf->u_behind ? lf->Qs : ts->vec_sol, lf->r_end));
  PetscCall(VecAXPY(quadts->vec_sol, 0.5 * dt, lf->r_end));
  lf->r_end_step = ts->steps + 1;
  PetscFunctionReturn(0);
}

PetscErrorCode TSAdjointSetUp_Leapfrog(TS ts) {
  Leapfrog *lf = data(ts);
  PetscFunctionBegin;
  PetscCheck(!ts->vecs_sensi2, PetscObjectComm((PetscObject)ts), PETSC_ERR_SUP,
             "-ts_type leapfrog has no second-order adjoint");
  PetscCheck(!ts->quadraturets || ts->costintegralfwd, PetscObjectComm((PetscObject)ts), PETSC_ERR_SUP,
             "-ts_type leapfrog accumulates cost integrals in the forward sweep only");
  lf->lambda_split = false;
  if (lf->adjoint_kick) PetscFunctionReturn(0); // the model's fused kick needs no work vectors (lambda_split_load)
  if (!lf->W) PetscCall(VecDuplicate(ts->vecs_sensi[0], &lf->W));
  if (ts->vecs_sensip && !lf->dmu) PetscCall(VecDuplicate(ts->vecs_sensip[0], &lf->dmu));
  PetscFunctionReturn(0);
}

// lambda_q += w g_q and lambda_p += w g_p, g interleaved (2m entries per point).
PetscErrorCode add_split(const Leapfrog &lf, const PetscScalar *g, PetscReal w, Vec lambda_q, Vec lambda_p) {
  PetscScalar *q, *p;
  PetscInt n;
  PetscFunctionBegin;
  PetscCall(VecGetLocalSize(lambda_q, &n));
  PetscCall(VecGetArray(lambda_q, &q));
  PetscCall(VecGetArray(lambda_p, &p));
  const PetscInt m = lf.pairs;
  for (PetscInt i = 0; i < n / m; ++i)
    for (PetscInt c = 0; c < m; ++c) q[i * m + c] += w * g[2 * m * i + c], p[i * m + c] += w * g[2 * m * i + m + c];
  PetscCall(VecRestoreArray(lambda_p, &p));
  PetscCall(VecRestoreArray(lambda_q, &q));
  PetscFunctionReturn(0);
}

// All contributions of time level (t, X): the half-kick of the step to its right (weight
// w_right, reversed first, so it sees lambda without this level's integrand term), the integrand
// with quadrature weight w_quad, then the half-kick of the step to its left (w_left), which sees the
// complete dJ/dU at this level. Without an integrand, or with one that reads no velocity, both
// half-kicks see the same lambda_p and take one product with weight w_right + w_left.
// drift: the model's fused kick first applies the drift's transpose lambda_p += drift lambda_q (0 without one).
PetscErrorCode half_kicks(TS ts, Mat J, PetscReal t, Vec X, PetscReal w, PetscReal drift = 0,
                          const PetscScalar *prefetch = nullptr) {
  Leapfrog *lf = data(ts);
  PetscFunctionBegin;
  if (w == 0 && drift == 0) PetscFunctionReturn(0);
  if (lf->adjoint_kick) {
    for (PetscInt k = 0; k < ts->numcost; ++k)
      PetscCall(lf->adjoint_kick(lf->adjoint_kick_ctx, t, X, lf->Lq[k], lf->Lp[k], w,
                                 ts->vecs_sensip ? ts->vecs_sensip[k] : nullptr, drift, k == 0 ? prefetch : nullptr));
    PetscFunctionReturn(0);
  }
  PetscCheck(drift == 0, PetscObjectComm((PetscObject)ts), PETSC_ERR_PLIB, "leapfrog: a drift for a kick without the model's sweep");
  for (PetscInt k = 0; k < ts->numcost; ++k) {
    Vec lambda = ts->vecs_sensi[k];
    PetscCall(MatMultTranspose(J, lambda, lf->W)); // q rows: A^T lambda_p (G_q = p has no q)
    if (ts->vecs_sensip) {
      PetscCall(MatMultTranspose(ts->Jacprhs, lambda, lf->dmu)); // uses lambda_p only: G_q has no theta
      PetscCall(VecAXPY(ts->vecs_sensip[k], w, lf->dmu));
    }
    PetscCall(add_q_rows(*lf, lambda, lf->W, w));
  }
  PetscFunctionReturn(0);
}

// drift: the transpose of the drift that ends at this level, applied by the model's fused kick with the
// first half-kick (0: already applied, or none); prefetch: what the next level's kick reads (null: none).
PetscErrorCode adjoint_level(TS ts, PetscReal t, Vec X, PetscReal w_right, PetscReal w_quad, PetscReal w_left, PetscReal drift = 0,
                             const PetscScalar *prefetch = nullptr) {
  TS quadts = ts->quadraturets;
  Mat J = nullptr, Jpre, Jquad = nullptr;
  PetscScalar *col;
  PetscFunctionBegin;
  if (!data(ts)->adjoint_kick) {
    PetscCall(TSGetRHSJacobian(ts, &J, &Jpre, nullptr, nullptr));
    PetscCall(TSComputeRHSJacobian(ts, t, X, J, Jpre));
    if (ts->vecs_sensip) PetscCall(TSComputeRHSJacobianP(ts, t, X, ts->Jacprhs));
  }
  // an integrand that reads no velocity adds nothing to lambda_p, which is all the kicks read
  const bool one_sweep = !quadts || !data(ts)->integrand_reads_velocities;
  PetscCall(half_kicks(ts, J, t, X, one_sweep ? w_right + w_left : w_right, drift, prefetch));
  if (!quadts) PetscFunctionReturn(0);
  Leapfrog *lf = data(ts);
  const bool with_p = ts->vecs_sensip && lf->integrand_reads_parameters;
  if (lf->integrand_adjoint) { // lambda += w dr/dU in place (a sparse dr/dU)
    // split: into lambda_q when dr/dU has no velocity rows, else into lambda formed for the call
    const bool into_q = lf->lambda_split && !lf->integrand_reads_velocities, around = lf->lambda_split && !into_q;
    if (around) PetscCall(lambda_split_load(ts, *lf, true));
    for (PetscInt k = 0; k < ts->numcost; ++k)
      PetscCall(lf->integrand_adjoint(lf->integrand_adjoint_ctx, t, X, w_quad, into_q ? lf->Lq[k] : ts->vecs_sensi[k]));
    if (around) PetscCall(lambda_split_load(ts, *lf, false));
  } else {
    PetscCall(TSGetRHSJacobian(quadts, &Jquad, nullptr, nullptr, nullptr));
    PetscCall(TSComputeRHSJacobian(quadts, t, X, Jquad, nullptr));
    for (PetscInt k = 0; k < ts->numcost; ++k) {
      PetscCall(MatDenseGetColumn(Jquad, k, &col));
      if (lf->lambda_split) PetscCall(add_split(*lf, col, w_quad, lf->Lq[k], lf->Lp[k]));
      else {
        PetscCall(VecPlaceArray(ts->vec_drdu_col, col));
        PetscCall(VecAXPY(ts->vecs_sensi[k], w_quad, ts->vec_drdu_col));
        PetscCall(VecResetArray(ts->vec_drdu_col));
      }
      PetscCall(MatDenseRestoreColumn(Jquad, &col));
    }
  }
  if (with_p) PetscCall(TSComputeRHSJacobianP(quadts, t, X, quadts->Jacprhs));
  for (PetscInt k = 0; k < ts->numcost && with_p; ++k) {
    PetscCall(MatDenseGetColumn(quadts->Jacprhs, k, &col));
    PetscCall(VecPlaceArray(ts->vec_drdp_col, col));
    PetscCall(VecAXPY(ts->vecs_sensip[k], w_quad, ts->vec_drdp_col));
    PetscCall(VecResetArray(ts->vec_drdp_col));
    PetscCall(MatDenseRestoreColumn(quadts->Jacprhs, &col));
  }
  if (!one_sweep) PetscCall(half_kicks(ts, J, t, X, w_left));
  PetscFunctionReturn(0);
}

// The last-level cache (the indices go outwards: the last one listed) and the number of cores that
// share it, from /sys (32 MB and 2 if unknown).
struct LastLevelCache {
  size_t bytes = (size_t)32 << 20, sharing = 2;
};
const LastLevelCache &last_level_cache() {
  static const LastLevelCache llc = [] {
    LastLevelCache c;
    for (int index = 0; index < 8; ++index) {
      const std::string dir = "/sys/devices/system/cpu/cpu0/cache/index" + std::to_string(index) + "/";
      std::ifstream size_file(dir + "size"), cpus_file(dir + "shared_cpu_list");
      std::string size, cpus;
      if (!(size_file >> size) || !(cpus_file >> cpus)) continue;
      size_t value = std::strtoul(size.c_str(), nullptr, 10);
      if (size.back() == 'K') value <<= 10;
      else if (size.back() == 'M') value <<= 20;
      size_t sharing = 0; // "0-1,4" -> 3
      for (size_t at = 0; at < cpus.size();) {
        const size_t comma = std::min(cpus.find(',', at), cpus.size());
        const std::string range = cpus.substr(at, comma - at);
        const size_t dash = range.find('-');
        sharing += dash == std::string::npos ? 1 : std::stoul(range.substr(dash + 1)) - std::stoul(range) + 1;
        at = comma + 1;
      }
      if (sharing > 0 && value > 0) c.bytes = value, c.sharing = sharing;
    }
    return c;
  }();
  return llc;
}

// Reverses step k-1 -> k. On entry ts->ptime = t_k, ts->time_step = -(t_k - t_{k-1}),
// ts->steps = k-1, Y0 = U_{k-1}, and lambda = dJ/dU_k with all of level k's contributions (the
// first adjoint step, k = n, adds level n's itself: the TS still holds U_n).
PetscErrorCode TSAdjointStep_Leapfrog(TS ts) {
  Leapfrog *lf = data(ts);
  const PetscReal dt = -ts->time_step, tk = ts->ptime;
  PetscFunctionBegin;
  // With the model's kick lambda is split from the first step on and formed after the last one (and
  // after each step an adjoint monitor may read).
  if (lf->adjoint_kick && (ts->adjoint_steps == 0 || !lf->lambda_split)) PetscCall(lambda_split_load(ts, *lf, false));
  if (ts->adjoint_steps == 0) PetscCall(adjoint_level(ts, tk, ts->vec_sol, 0, 0.5 * dt, 0.5 * dt));
  // The drift's transpose: handed to the model's kick at level k-1 when it has one and a rank's lambda
  // and positions exceed the whole last-level cache (the kick may fold it into its sweep: one pass over
  // memory fewer), else a pass of its own here: a pass over data the cache holds costs less than the
  // kick's sweep broken into rows (docs/performance.md).
  PetscInt n;
  PetscCall(VecGetLocalSize(ts->vec_sol, &n));
  const bool fuse_drift =
      lf->adjoint_kick != nullptr && !lf->sigma && sizeof(PetscScalar) * (size_t)(n + n / 2) > last_level_cache().bytes;
  if (!fuse_drift)
    for (PetscInt k = 0; k < ts->numcost; ++k) {
      if (lf->lambda_split) PetscCall(split_drift_transpose(*lf, lf->Lq[k], lf->Lp[k], dt));
      else PetscCall(drift_transpose(*lf, ts->vecs_sensi[k], dt));
    }
  // level k-1: the right half-kick of this step, then (except at t_0) the left one of the step before
  PetscCall(adjoint_level(ts, tk - dt, lf->Q_placed ? lf->Q : lf->Y0, 0.5 * dt, ts->steps == 0 ? 0.5 * dt : dt,
                          ts->steps == 0 ? 0 : 0.5 * dt, fuse_drift ? dt : 0, lf->Q_placed ? lf->Q_next : nullptr));
  if (lf->Q_placed) {
    PetscCall(VecResetArray(lf->Q));
    lf->Q_placed = false;
  }
  lf->Q_next = nullptr;
  const bool last = ts->steps == 0 || (ts->adjoint_max_steps > 0 && ts->adjoint_steps + 1 >= ts->adjoint_max_steps);
  if (lf->lambda_split && (last || lambda_watched(ts))) {
    PetscCall(lambda_split_load(ts, *lf, true));
    lf->lambda_split = !last;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode TSView_Leapfrog(TS ts, PetscViewer viewer) {
  PetscBool ascii;
  PetscFunctionBegin;
  PetscCall(PetscObjectTypeCompare((PetscObject)viewer, PETSCVIEWERASCII, &ascii));
  if (ascii)
    PetscCall(PetscViewerASCIIPrintf(viewer, "  Stormer-Verlet (kick-drift-kick), %" PetscInt_FMT " position/velocity pairs\n",
                                     data(ts)->pairs));
  PetscFunctionReturn(0);
}

PetscErrorCode TSLinearStability_Leapfrog(TS, PetscReal xr, PetscReal xi, PetscReal *yr, PetscReal *yi) {
  // Not a one-step map of dU/dt = lambda U; the Simulation checks dt * omega_max < 2 instead.
  PetscFunctionBegin;
  *yr = 1.0 + xr;
  *yi = xi;
  PetscFunctionReturn(0);
}

PetscErrorCode set_pairs(TS ts, PetscInt m) {
  PetscFunctionBegin;
  data(ts)->pairs = m;
  PetscFunctionReturn(0);
}

PetscErrorCode set_damping(TS ts, Vec sigma) {
  Leapfrog *lf = data(ts);
  PetscFunctionBegin;
  if (sigma) PetscCall(PetscObjectReference((PetscObject)sigma));
  PetscCall(VecDestroy(&lf->sigma));
  PetscCall(VecDestroy(&lf->factors));
  lf->sigma = sigma;
  PetscFunctionReturn(0);
}

PetscErrorCode set_integrand_reads(TS ts, PetscBool velocities, PetscBool parameters) {
  PetscFunctionBegin;
  data(ts)->integrand_reads_velocities = velocities;
  data(ts)->integrand_reads_parameters = parameters;
  PetscFunctionReturn(0);
}

PetscErrorCode set_integrand_adjoint(TS ts, LeapfrogIntegrandAdjoint fn, void *ctx) {
  PetscFunctionBegin;
  data(ts)->integrand_adjoint = fn;
  data(ts)->integrand_adjoint_ctx = ctx;
  PetscFunctionReturn(0);
}

PetscErrorCode set_adjoint_kick(TS ts, LeapfrogAdjointKick kick, void *ctx) {
  PetscFunctionBegin;
  data(ts)->adjoint_kick = kick;
  data(ts)->adjoint_kick_ctx = ctx;
  PetscFunctionReturn(0);
}

PetscErrorCode set_step(TS ts, LeapfrogStep step, void *ctx) {
  PetscFunctionBegin;
  data(ts)->step = step;
  data(ts)->step_ctx = ctx;
  PetscFunctionReturn(0);
}

PetscErrorCode set_split_step(TS ts, LeapfrogSplitStep step, void *ctx) {
  PetscFunctionBegin;
  data(ts)->split = step;
  data(ts)->split_ctx = ctx;
  PetscFunctionReturn(0);
}

PetscErrorCode form_solution(TS ts) {
  PetscFunctionBegin;
  PetscCall(split_form(ts, *data(ts)));
  PetscFunctionReturn(0);
}

PetscErrorCode monitor_forms_solution(TS ts, LeapfrogMonitor monitor) {
  PetscFunctionBegin;
  data(ts)->forming_monitors.push_back(monitor);
  PetscFunctionReturn(0);
}

PetscErrorCode TSCreate_Leapfrog(TS ts) {
  PetscFunctionBegin;
  ts->data = new Leapfrog();
  ts->ops->setup = TSSetUp_Leapfrog;
  ts->ops->step = TSStep_Leapfrog;
  ts->ops->reset = TSReset_Leapfrog;
  ts->ops->destroy = TSDestroy_Leapfrog;
  ts->ops->view = TSView_Leapfrog;
  ts->ops->getstages = TSGetStages_Leapfrog;
  ts->ops->forwardintegral = TSForwardCostIntegral_Leapfrog;
  ts->ops->adjointsetup = TSAdjointSetUp_Leapfrog;
  ts->ops->adjointstep = TSAdjointStep_Leapfrog;
  ts->ops->linearstability = TSLinearStability_Leapfrog;
  ts->default_adapt_type = TSADAPTNONE;
  ts->usessnes = PETSC_FALSE;
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetPairs_C", set_pairs));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetAdjointKick_C", set_adjoint_kick));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetStep_C", set_step));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetSplitStep_C", set_split_step));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogFormSolution_C", form_solution));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogMonitorFormsSolution_C", monitor_forms_solution));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetDamping_C", set_damping));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetIntegrandReads_C", set_integrand_reads));
  PetscCall(PetscObjectComposeFunction((PetscObject)ts, "FlexipdeLeapfrogSetIntegrandAdjoint_C", set_integrand_adjoint));
  PetscFunctionReturn(0);
}

} // namespace

PetscErrorCode register_leapfrog_ts() {
  PetscFunctionBegin;
  PetscCall(TSRegister(FLEXIPDE_TSLEAPFROG, TSCreate_Leapfrog)); // replaces itself when repeated
  PetscFunctionReturn(0);
}

PetscErrorCode leapfrog_set_pairs(TS ts, PetscInt m) {
  PetscFunctionBegin;
  PetscTryMethod(ts, "FlexipdeLeapfrogSetPairs_C", (TS, PetscInt), (ts, m));
  PetscFunctionReturn(0);
}

PetscErrorCode leapfrog_set_damping(TS ts, Vec sigma) {
  PetscFunctionBegin;
  PetscTryMethod(ts, "FlexipdeLeapfrogSetDamping_C", (TS, Vec), (ts, sigma));
  PetscFunctionReturn(0);
}

PetscErrorCode leapfrog_set_integrand_reads(TS ts, bool velocities, bool parameters) {
  PetscFunctionBegin;
  PetscTryMethod(ts, "FlexipdeLeapfrogSetIntegrandReads_C", (TS, PetscBool, PetscBool),
                 (ts, velocities ? PETSC_TRUE : PETSC_FALSE, parameters ? PETSC_TRUE : PETSC_FALSE));
  PetscFunctionReturn(0);
}

PetscErrorCode leapfrog_set_integrand_adjoint(TS ts, LeapfrogIntegrandAdjoint fn, void *ctx) {
  PetscFunctionBegin;
  PetscTryMethod(ts, "FlexipdeLeapfrogSetIntegrandAdjoint_C", (TS, LeapfrogIntegrandAdjoint, void *), (ts, fn, ctx));
  PetscFunctionReturn(0);
}

bool leapfrog_positions_suffice(TS ts) {
  return is_leapfrog(ts) && (!ts->quadraturets || !data(ts)->integrand_reads_velocities);
}

PetscInt leapfrog_pairs(TS ts) { return is_leapfrog(ts) ? data(ts)->pairs : 0; }

PetscErrorCode leapfrog_set_adjoint_kick(TS ts, LeapfrogAdjointKick kick, void *ctx) {
  PetscFunctionBegin;
  PetscTryMethod(ts, "FlexipdeLeapfrogSetAdjointKick_C", (TS, LeapfrogAdjointKick, void *), (ts, kick, ctx));
  PetscFunctionReturn(0);
}

bool leapfrog_one_sweep_pays(size_t bytes) {
  const LastLevelCache &llc = last_level_cache();
  return bytes > llc.bytes / llc.sharing;
}

PetscErrorCode leapfrog_set_step(TS ts, LeapfrogStep step, void *ctx) {
  PetscFunctionBegin;
  PetscTryMethod(ts, "FlexipdeLeapfrogSetStep_C", (TS, LeapfrogStep, void *), (ts, step, ctx));
  PetscFunctionReturn(0);
}

PetscErrorCode leapfrog_set_split_step(TS ts, LeapfrogSplitStep step, void *ctx) {
  PetscFunctionBegin;
  PetscTryMethod(ts, "FlexipdeLeapfrogSetSplitStep_C", (TS, LeapfrogSplitStep, void *), (ts, step, ctx));
  PetscFunctionReturn(0);
}

PetscErrorCode leapfrog_form_solution(TS ts) {
  PetscFunctionBegin;
  PetscTryMethod(ts, "FlexipdeLeapfrogFormSolution_C", (TS), (ts));
  PetscFunctionReturn(0);
}

void leapfrog_adjoint_monitor_reads_no_lambda(LeapfrogAdjointMonitor monitor) {
  auto &quiet = quiet_adjoint_monitors();
  if (std::find(quiet.begin(), quiet.end(), monitor) == quiet.end()) quiet.push_back(monitor);
}

PetscErrorCode leapfrog_monitor_forms_solution(TS ts, LeapfrogMonitor monitor) {
  PetscFunctionBegin;
  PetscTryMethod(ts, "FlexipdeLeapfrogMonitorFormsSolution_C", (TS, LeapfrogMonitor), (ts, monitor));
  PetscFunctionReturn(0);
}

PetscErrorCode leapfrog_sink_positions(TS ts, PetscScalar *q) {
  PetscFunctionBegin;
  if (is_leapfrog(ts)) data(ts)->sink = q;
  PetscFunctionReturn(0);
}

const PetscScalar *leapfrog_sunk_positions(TS ts) { return is_leapfrog(ts) ? data(ts)->sunk : nullptr; }

PetscErrorCode leapfrog_place_positions(TS ts, const PetscScalar *q, const PetscScalar *next, bool *placed) {
  PetscFunctionBegin;
  *placed = false;
  if (!is_leapfrog(ts)) PetscFunctionReturn(0);
  Leapfrog *lf = data(ts);
  if (!lf->adjoint_kick || !leapfrog_positions_suffice(ts)) PetscFunctionReturn(0);
  if (!lf->Q) {
    PetscInt n;
    PetscCall(VecGetLocalSize(ts->vec_sol, &n));
    PetscCall(VecCreateMPIWithArray(PetscObjectComm((PetscObject)ts), lf->pairs, n / 2, PETSC_DECIDE, nullptr, &lf->Q));
  }
  if (lf->Q_placed) PetscCall(VecResetArray(lf->Q));
  PetscCall(VecPlaceArray(lf->Q, q));
  lf->Q_placed = true;
  lf->Q_next = next;
  *placed = true;
  PetscFunctionReturn(0);
}

bool is_leapfrog(TS ts) {
  PetscBool match = PETSC_FALSE;
  if (PetscObjectTypeCompare((PetscObject)ts, FLEXIPDE_TSLEAPFROG, &match)) return false;
  return match;
}

} // namespace flexipde
