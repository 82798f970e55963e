// Full storage for TSAdjoint in one contiguous block: the TSTrajectory type "store".
//
// PETSc's memory trajectory creates a new Vec for every step it stores (object, allocation and
// fresh pages each time), which on the seed scene cost as much as the leapfrog's whole forward
// sweep. Here every state U_k is a slice of one buffer, reserved once for the planned number of
// steps and kept by the Simulation between gradients, so a Set is one memcpy.
//
// Get(k) leaves the TS ready for the adjoint of step k-1 -> k (see checkpoint.cpp for what that
// means): the leapfrog's one stage is the step's start U_{k-1}. By default only its positions q are
// stored (its adjoint reads nothing else: G_p depends on q alone), half the memory: the step writes
// them into the next slot itself (leapfrog_sink_positions, streaming stores), and the model's fused
// kick reads them there (leapfrog_place_positions; without one they are copied into the stage). The
// slot the next adjoint step reads is prefetched, and buffers of 2 MB and more sit on huge pages
// (StateBuffer). With a cost integrand (which may read p) whole states are stored and the stage Vec
// is pointed at them (VecPlaceArray), nothing copied; any other
// integrator re-runs the step from U_{k-1} (TSStep) to rebuild its stages, like PETSc's memory
// trajectory in solution-only mode, unless it keeps them: an explicit RK's stages are placed in the
// buffer and written there by the step itself, with the records its fused adjoint stage reads beside
// them (Model::stage_record_size) or, when those replace the stage (the wave models), the records
// alone. Fixed steps only (the Simulation uses PETSc's memory trajectory for adaptive runs).
#include "flexipde/checkpoint.hpp"
#include "flexipde/leapfrog.hpp"
#include "flexipde/rk_adjoint.hpp"
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <emmintrin.h>
#include <sys/mman.h>
#include <petsc/private/tsimpl.h>
#include <vector>

namespace flexipde {
namespace {

// b[0, n) = x[0, n) with non-temporal stores (8 or 16 bytes at a time past the caches: the adjoint
// reads the slot much later); stream_fence() after the last of them.
void stream_copy(PetscScalar *b, const PetscScalar *x, PetscInt n) {
#if defined(__SSE2__) && !defined(PETSC_USE_COMPLEX) && defined(PETSC_USE_REAL_DOUBLE)
  auto store8 = [](PetscScalar *p, PetscReal v) {
    long long bits;
    std::memcpy(&bits, &v, sizeof bits);
    _mm_stream_si64(reinterpret_cast<long long *>(p), bits);
  };
  PetscInt i = 0;
  if (n > 0 && reinterpret_cast<uintptr_t>(b) % 16) store8(b, x[0]), i = 1;
  for (; i + 1 < n; i += 2) _mm_stream_pd(b + i, _mm_loadu_pd(x + i));
  for (; i < n; ++i) store8(b + i, x[i]);
#else
  std::copy(x, x + n, b);
#endif
}
void stream_fence() {
#if defined(__SSE2__)
  _mm_sfence();
#endif
}

struct StoreTrajectory {
  StateBuffer own;
  StateBuffer *buffer = &own;
  std::vector<PetscReal> times;
  // h of the step k -> k+1 as the forward took it (ts->time_step when U_k is stored): the adjoint steps
  // and any re-run use exactly it, not the difference of two stored times, which can differ from it
  // in the last bits (and an implicit method's shift with it: a refactorisation at such steps).
  std::vector<PetscReal> steps;
  PetscInt nlocal = 0, last = -1;
  PetscInt64 recomputed = 0;
  // Keep each step's stages too (slot = U_k and the stages of step k-1 -> k), so that nothing is
  // re-run in the adjoint, when the buffer stays within -checkpoint_keep_stages_max_mb per rank (a
  // memory cap: beyond it the adjoint re-runs the steps). The leapfrog never needs it (its stage is
  // U_{k-1}).
  PetscReal keep_stages_max_mb = 2048;
  bool keep_stages = false;
  PetscInt nstages = 0, slot = 0; // entries per step: (1 + nstages) * nlocal when keeping stages
  // Leapfrog without a cost integrand, or with one that reads no velocity: only the first `pairs` of
  // every `dof` components are kept.
  PetscInt pairs = 0, dof = 0;
  // Explicit RK keeping its stages: the stage Vecs write straight into the buffer (VecPlaceArray on
  // the next step's slot before it runs; in the adjoint, on the slot being reversed), so no stage is
  // ever copied in or out. `placed` = the slot the stage Vecs currently point into (-1: their own).
  // A solve that stops early leaves them placed; their own arrays are still what VecDestroy frees,
  // and the buffer (kept by the Simulation) outlives the TS.
  bool place_stages = false;
  PetscInt placed = -1;
  // With placed stages the slot of step k holds the stages of step k -> k+1 and nothing else: an
  // explicit RK's first stage is a copy of U_k, so U_k is stored by the step's own stage copy, not by
  // Set (one copy and one vector of memory per step fewer). Slot k = [Y_0 = U_k, Y_1, ..., Y_{s-1}].
  bool compact = false;
  bool lf_placed = false; // the leapfrog's stage Vec points into the buffer
  // Explicit RK whose adjoint stage reads a record of each stage (rk_adjoint_stage_needs:
  // Model::stage_record_size): rec_n entries per stage, those of step k -> k+1 at rec_offset in the slot
  // where that step's stages are (compact: k, placed: k + 1). The RHS evaluations at the stages write
  // them there (rk_adjoint_arm_records) and the adjoint reads them in place (rk_adjoint_place_records).
  // rec_only: they replace the stages (Model::stage_record_replaces_state), slot k = the records of
  // step k -> k+1 and nothing else.
  PetscInt rec_n = 0, rec_offset = 0;
  bool rec_only = false;
  // An endpoint theta method (cn, beuler, -ts_theta_endpoint): its two stages are U_{k-1} and U_k, both
  // stored as solutions, so only the solutions are kept and Get hands it both (no stage copies, no
  // re-run, a third of the memory).
  bool theta_endpoint = false;
  bool use_prefetch = false; // prefetch the slot after next (slots of at most kPrefetchMaxBytes)
  bool use_stream = false;   // non-temporal stores: the leapfrog's states (not RK's)
  // -checkpoint_precision single: the states (or positions) are kept as floats, two to a slot entry, and
  // copied in and out converting; nothing is read in place (no placed or kept stages, no records), so
  // every integrator but the leapfrog re-runs each step in the adjoint.
  bool single = false;
};

// Prefetching the slot after next pays where slots are short (a few KB to a few hundred: the hardware
// prefetchers do not get going within one, and the adjoint walks the slots backwards); on slots of
// megabytes they do, and the prefetches only compete with them. Per rank.
constexpr size_t kPrefetchMaxBytes = 1024 * 1024;

StoreTrajectory *context(TSTrajectory tj) { return static_cast<StoreTrajectory *>(tj->data); }

PetscScalar *at(const StoreTrajectory &st, PetscInt k, PetscInt part) {
  return st.buffer->data.get() + (size_t)k * st.slot + (size_t)part * st.nlocal;
}

float *at_single(const StoreTrajectory &st, PetscInt k) { return reinterpret_cast<float *>(at(st, k, 0)); }

// x = the positions b (m per point) as the first m of every d components at npt points; the other
// components are left as they are. T: double, or float for single-precision states.
template <class T> void unpack_positions(PetscScalar *x, const T *b, PetscInt m, PetscInt d, PetscInt npt) {
  if (m == 1)
    for (PetscInt i = 0; i < npt; ++i) x[i * d] = b[i];
  else
    for (PetscInt i = 0; i < npt; ++i)
      for (PetscInt c = 0; c < m; ++c) x[i * d + c] = b[i * m + c];
}

// b = the first m of every d components of x (npt points).
template <class T> void pack_positions(T *b, const PetscScalar *x, PetscInt m, PetscInt d, PetscInt npt) {
  if (m == 1)
    for (PetscInt i = 0; i < npt; ++i) b[i] = (T)x[i * d];
  else
    for (PetscInt i = 0; i < npt; ++i)
      for (PetscInt c = 0; c < m; ++c) b[i * m + c] = (T)x[i * d + c];
}

PetscErrorCode copy_out(const StoreTrajectory &st, PetscInt k, PetscInt part, Vec X) {
  PetscScalar *x;
  PetscFunctionBegin;
  if (st.single || st.pairs) { // floats (part 0: nothing else is stored), or positions only
    PetscCall(VecGetArray(X, &x));
    const PetscInt m = st.pairs, d = st.dof;
    if (!st.single) unpack_positions(x, at(st, k, part), m, d, st.nlocal / d);
    else if (m) unpack_positions(x, at_single(st, k), m, d, st.nlocal / d);
    else std::copy(at_single(st, k), at_single(st, k) + st.nlocal, x);
    PetscCall(VecRestoreArray(X, &x));
    PetscFunctionReturn(0);
  }
  PetscCall(VecGetArrayWrite(X, &x));
  std::memcpy(x, at(st, k, part), sizeof(PetscScalar) * st.nlocal);
  PetscCall(VecRestoreArrayWrite(X, &x));
  PetscFunctionReturn(0);
}

// b = the first m of every d components of x (npt points); streaming stores when asked.
void copy_positions(PetscScalar *b, const PetscScalar *x, PetscInt m, PetscInt d, PetscInt npt, bool stream) {
  if (m == 1 && stream && reinterpret_cast<uintptr_t>(b) % 16 == 0) {
    PetscInt i = 0;
    for (; i + 1 < npt; i += 2) _mm_stream_pd(b + i, _mm_set_pd(x[(i + 1) * d], x[i * d]));
    for (; i < npt; ++i) b[i] = x[i * d];
    _mm_sfence();
  } else pack_positions(b, x, m, d, npt);
}

PetscErrorCode copy_in(const StoreTrajectory &st, PetscInt k, PetscInt part, Vec X) {
  const PetscScalar *x;
  PetscFunctionBegin;
  PetscCall(VecGetArrayRead(X, &x));
  if (st.single) {
    if (st.pairs) pack_positions(at_single(st, k), x, st.pairs, st.dof, st.nlocal / st.dof);
    else std::copy(x, x + st.nlocal, at_single(st, k));
  } else if (st.pairs) copy_positions(at(st, k, part), x, st.pairs, st.dof, st.nlocal / st.dof, st.use_stream);
  else if (st.use_stream) {
    stream_copy(at(st, k, part), x, st.nlocal); // (past the caches: the adjoint reads it much later)
    stream_fence();
  }
  else std::memcpy(at(st, k, part), x, sizeof(PetscScalar) * st.nlocal);
  PetscCall(VecRestoreArrayRead(X, &x));
  PetscFunctionReturn(0);
}

// Ask the memory system for slot k ahead of its use (the adjoint reads the slots in reverse order,
// which the hardware prefetchers follow poorly): one prefetch per cache line.
void prefetch_slot(const StoreTrajectory &st, PetscInt k) {
  if (k >= 0) leapfrog_prefetch(at(st, k, 0), st.slot);
}

// The records of the step about to run are written to slot k (k < 0, or no records: none).
PetscErrorCode arm_records(StoreTrajectory &st, TS ts, PetscInt k) {
  PetscFunctionBegin;
  if (!st.rec_n) PetscFunctionReturn(0);
  const bool fits = k >= 0 && (size_t)(k + 1) * st.slot <= st.buffer->size;
  PetscCall(rk_adjoint_arm_records(ts, fits ? at(st, k, 0) + st.rec_offset : nullptr, st.rec_n));
  PetscFunctionReturn(0);
}

// Point the stage Vecs into slot k (k < 0: back to their own arrays).
PetscErrorCode place_stages(StoreTrajectory &st, TS ts, PetscInt k) {
  Vec *Y;
  PetscFunctionBegin;
  if (st.placed == k) PetscFunctionReturn(0);
  PetscCall(TSGetStages(ts, nullptr, &Y));
  if (st.placed >= 0)
    for (PetscInt i = 0; i < st.nstages; ++i) PetscCall(VecResetArray(Y[i]));
  st.placed = -1;
  if (k >= 0 && (size_t)(k + 1) * st.slot <= st.buffer->size) {
    for (PetscInt i = 0; i < st.nstages; ++i) PetscCall(VecPlaceArray(Y[i], at(st, k, st.compact ? i : 1 + i)));
    st.placed = k;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode store_setup(TSTrajectory tj, TS ts) {
  StoreTrajectory *st = context(tj);
  PetscFunctionBegin;
  PetscCheck(ts->vec_sol, PetscObjectComm((PetscObject)tj), PETSC_ERR_ORDER,
             "TSTrajectory store: set the TS solution before the solve");
  PetscCall(VecGetLocalSize(ts->vec_sol, &st->nlocal));
  PetscCall(TSGetStages(ts, &st->nstages, nullptr));
  st->keep_stages = false;
  st->theta_endpoint = false;
  {
    PetscBool theta;
    PetscCall(PetscObjectTypeCompareAny((PetscObject)ts, &theta, TSTHETA, TSCN, TSBEULER, ""));
    if (theta && ts->max_steps < PETSC_MAX_INT) {
      Vec *Y;
      PetscInt ns;
      PetscCall(TSGetStages(ts, &ns, &Y));
      st->theta_endpoint = ns == 2 && Y[1] == ts->vec_sol; // {U_{k-1}, U_k}: PETSc's endpoint forms
    }
  }
  st->pairs = 0;
  if (leapfrog_positions_suffice(ts)) {
    PetscCall(VecGetBlockSize(ts->vec_sol, &st->dof));
    st->pairs = leapfrog_pairs(ts);
  }
  st->times.clear();
  st->steps.clear();
  st->last = -1;
  st->recomputed = 0;
  st->placed = -1;
  st->place_stages = false;
  st->compact = false;
  st->lf_placed = false;
  st->use_stream = is_leapfrog(ts);
  st->rec_n = st->rec_offset = 0;
  st->rec_only = false;
  // Stages: how they would be kept (explicit RK: records alone, or compact or placed with the records
  // after the stages; otherwise copied next to the state), then whether that fits the memory cap.
  PetscInt stage_slot = 0;
  if (!is_leapfrog(ts) && !st->theta_endpoint && st->nstages > 0) {
    PetscBool rk;
    Vec *Y;
    bool stage_is_solution = false;
    PetscCall(PetscObjectTypeCompare((PetscObject)ts, TSRK, &rk));
    PetscCall(TSGetStages(ts, nullptr, &Y));
    for (PetscInt i = 0; i < st->nstages; ++i) stage_is_solution = stage_is_solution || Y[i] == ts->vec_sol;
    const bool fixed = ts->max_steps < PETSC_MAX_INT;
    RkStageNeeds needs;
    if (fixed && !stage_is_solution) PetscCall(rk_adjoint_stage_needs(ts, &needs));
    const bool partial = !adjoint_monitors_read_state(ts); // keep less than whole stages
    if (needs.record_size > 0 && (!needs.record_replaces || partial)) {
      st->rec_n = needs.record_size;
      st->rec_only = needs.record_replaces;
    }
    if (st->rec_only) stage_slot = st->nstages * st->rec_n;
    else {
      st->place_stages = rk && fixed && !stage_is_solution;
      if (st->place_stages) { // Y_0 = U_k exactly: c_0 = 0 and A's first row zero
        PetscInt s;
        const PetscReal *A, *c;
        PetscCall(TSRKGetTableau(ts, &s, &A, nullptr, &c, nullptr, nullptr, nullptr, nullptr));
        st->compact = c[0] == 0;
        for (PetscInt j = 0; j < s; ++j) st->compact = st->compact && A[j] == 0;
      }
      stage_slot = (st->compact ? st->nstages : 1 + st->nstages) * st->nlocal;
      if (!st->place_stages) st->rec_n = 0;
      st->rec_offset = stage_slot;
      stage_slot += st->nstages * st->rec_n;
    }
    if (fixed) { // only within the memory cap, decided alike on every rank
      PetscReal mb = (PetscReal)(ts->max_steps + 1) * stage_slot * sizeof(PetscScalar) / 1048576.0;
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &mb, 1, MPIU_REAL, MPI_MAX, PetscObjectComm((PetscObject)tj)));
      st->keep_stages = mb <= st->keep_stages_max_mb;
    }
    if (!st->keep_stages) st->rec_n = 0, st->place_stages = st->compact = st->rec_only = false;
  }
  if (st->single) st->keep_stages = st->place_stages = st->compact = st->rec_only = st->use_stream = false, st->rec_n = 0;
  st->slot = st->pairs ? st->nlocal / st->dof * st->pairs : st->keep_stages ? stage_slot : st->nlocal;
  if (st->single) st->slot = (st->slot + 1) / 2; // floats, two per entry
  // The leapfrog's position slots start on a cache line (padded to 8 entries): the step's streaming
  // stores need 16-byte alignment, and with 101^2 points an odd slot lost it (every other state was
  // then copied by Set, with plain stores).
  if (st->pairs && !st->single) st->slot = (st->slot + 7) / 8 * 8;
  st->use_prefetch = (size_t)st->slot * sizeof(PetscScalar) <= kPrefetchMaxBytes;
  if (ts->max_steps < PETSC_MAX_INT) { // reserve the planned trajectory once
    st->buffer->grow((size_t)(ts->max_steps + 1) * st->slot, false);
    st->times.reserve(ts->max_steps + 1);
    st->steps.reserve(ts->max_steps + 1);
  }
  PetscFunctionReturn(0);
}


PetscErrorCode store_set(TSTrajectory tj, TS ts, PetscInt stepnum, PetscReal time, Vec X) {
  StoreTrajectory *st = context(tj);
  PetscFunctionBegin;
  PetscCheck(stepnum == (PetscInt)st->times.size(), PetscObjectComm((PetscObject)tj), PETSC_ERR_PLIB,
             "TSTrajectory store: step %" PetscInt_FMT " stored out of order", stepnum);
  st->times.push_back(time);
  st->steps.push_back(ts->time_step);
  st->last = stepnum;
  if (st->rec_n && ts->reason) PetscCall(rk_adjoint_arm_records(ts, nullptr, 0)); // the solve is over
  if (st->rec_only) { // the next step's stages write their records to slot stepnum
    if (ts->reason) PetscFunctionReturn(0);
    const size_t need = (size_t)(stepnum + 1) * st->slot;
    if (st->buffer->size < need) st->buffer->grow(std::max(need, 2 * st->buffer->size), true);
    PetscCall(arm_records(*st, ts, stepnum));
    PetscFunctionReturn(0);
  }
  if (ts->reason) PetscFunctionReturn(0); // the final state stays in the TS for the first adjoint step
  const size_t need = (size_t)(stepnum + 1) * st->slot;
  if (st->buffer->size < need) {
    PetscCall(place_stages(*st, ts, -1)); // the buffer moves
    st->buffer->grow(std::max(need, 2 * st->buffer->size), true);
  }
  if (st->compact) { // U_stepnum goes to this slot as the next step's first stage
    PetscCall(place_stages(*st, ts, stepnum));
    PetscCall(arm_records(*st, ts, st->placed));
    PetscFunctionReturn(0);
  }
  if (!st->pairs || st->single || leapfrog_sunk_positions(ts) != at(*st, stepnum, 0)) PetscCall(copy_in(*st, stepnum, 0, X));
  if (st->pairs && st->use_stream && !st->single && (size_t)(stepnum + 2) * st->slot <= st->buffer->size)
    PetscCall(leapfrog_sink_positions(ts, at(*st, stepnum + 1, 0))); // the next step writes its positions there itself
  if (st->keep_stages && stepnum > 0 && st->placed != stepnum) { // placed: the step wrote them here
    Vec *Y;
    PetscCall(TSGetStages(ts, nullptr, &Y));
    for (PetscInt i = 0; i < st->nstages; ++i) PetscCall(copy_in(*st, stepnum, 1 + i, Y[i]));
  }
  if (st->place_stages) { // where the next step writes its stages (and records)
    PetscCall(place_stages(*st, ts, stepnum + 1));
    PetscCall(arm_records(*st, ts, st->placed));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode store_get(TSTrajectory tj, TS ts, PetscInt k, PetscReal *t) {
  StoreTrajectory *st = context(tj);
  PetscFunctionBegin;
  if (k == 0) { // the adjoint has finished
    PetscCall(place_stages(*st, ts, -1));
    if (st->rec_n) {
      PetscCall(rk_adjoint_place_records(ts, nullptr, 0));
      PetscCall(rk_adjoint_arm_records(ts, nullptr, 0));
    }
    if (st->lf_placed) {
      Vec *Y;
      PetscCall(TSGetStages(ts, nullptr, &Y));
      PetscCall(VecResetArray(Y[0]));
      st->lf_placed = false;
    }
    PetscCall(TSTrajectoryReset(tj));
    PetscFunctionReturn(0);
  }
  PetscCheck(k <= st->last, PetscObjectComm((PetscObject)tj), PETSC_ERR_ARG_OUTOFRANGE,
             "TSTrajectory store: step %" PetscInt_FMT " was never computed (%" PetscInt_FMT " steps)", k, st->last);
  if (is_leapfrog(ts)) { // its one stage is U_{k-1}, also for the last step (whose forward step did not keep it)
    Vec *Y;
    PetscCall(TSGetStages(ts, nullptr, &Y));
    if (st->single) PetscCall(copy_out(*st, k - 1, 0, Y[0])); // (whole states or positions, converted)
    else if (st->pairs) { // the model's kick reads the stored positions in place when it can
      bool placed;
      // the kick reading them in place also prefetches the next slot while it sweeps (a burst of
      // prefetches here, before it, holds up its own loads)
      PetscCall(leapfrog_place_positions(ts, at(*st, k - 1, 0), st->use_prefetch && k >= 2 ? at(*st, k - 2, 0) : nullptr, &placed));
      if (!placed) PetscCall(copy_out(*st, k - 1, 0, Y[0]));
      if (!placed && st->use_prefetch) prefetch_slot(*st, k - 2);
    } else { // the whole state is stored: the stage Vec reads it in place
      if (st->lf_placed) PetscCall(VecResetArray(Y[0]));
      PetscCall(VecPlaceArray(Y[0], at(*st, k - 1, 0)));
      st->lf_placed = true;
    }
  }
  if (st->theta_endpoint) { // the stages U_{k-1} and U_k (U_last is still in the TS)
    Vec *Y;
    PetscCall(TSGetStages(ts, nullptr, &Y));
    PetscCall(copy_out(*st, k - 1, 0, Y[0]));
    if (k < st->last) PetscCall(copy_out(*st, k, 0, ts->vec_sol));
    if (st->use_prefetch) prefetch_slot(*st, k - 2);
    ts->ptime = st->times[k];
    ts->ptime_prev = st->times[k - 1];
  } else if (st->rec_only) { // the records of the stages of step k-1 -> k, read in place
    PetscCall(rk_adjoint_place_records(ts, at(*st, k - 1, 0), st->rec_n));
    if (st->use_prefetch) prefetch_slot(*st, k - 2);
    ts->ptime = st->times[k];
    ts->ptime_prev = st->times[k - 1];
  } else if (st->compact) { // the stages of step k-1 -> k, in place; U_k only for adjoint monitors
    PetscCall(place_stages(*st, ts, k - 1));
    if (st->rec_n) PetscCall(rk_adjoint_place_records(ts, at(*st, k - 1, 0) + st->rec_offset, st->rec_n));
    if (st->use_prefetch) prefetch_slot(*st, k - 2);
    if (k < st->last && adjoint_monitors_read_state(ts)) PetscCall(copy_out(*st, k, 0, ts->vec_sol));
    ts->ptime = st->times[k];
    ts->ptime_prev = st->times[k - 1];
  } else if (k < st->last) { // the last step's stages are still in the TS
    if (is_leapfrog(ts) || st->keep_stages) {
      Vec *Y;
      PetscCall(TSGetStages(ts, nullptr, &Y));
      if (!is_leapfrog(ts)) {
        if (st->place_stages) PetscCall(place_stages(*st, ts, k));
        if (st->placed != k)
          for (PetscInt i = 0; i < st->nstages; ++i)
            if (Y[i] != ts->vec_sol) PetscCall(copy_out(*st, k, 1 + i, Y[i]));
        PetscCall(copy_out(*st, k, 0, ts->vec_sol));
      } // the leapfrog's adjoint reads only its stage (and U_n, still in the TS, at the first step)
      ts->ptime = st->times[k];
      ts->ptime_prev = st->times[k - 1];
    } else {
      const TSConvergedReason reason = ts->reason;
      PetscCall(copy_out(*st, k - 1, 0, ts->vec_sol));
      ts->ptime = st->times[k - 1];
      ts->time_step = st->steps[k - 1];
      PetscCall(TSSetStepNumber(ts, k - 1));
      PetscCall(TSRestartStep(ts));
      PetscCall(TSStep(ts));
      PetscCheck(ts->reason >= 0, PetscObjectComm((PetscObject)ts), PETSC_ERR_NOT_CONVERGED,
                 "TSTrajectory store: re-running step %" PetscInt_FMT " for the adjoint failed (%s)", k - 1,
                 TSConvergedReasons[ts->reason]);
      ts->reason = reason;
      ++st->recomputed;
      tj->recomps = (PetscInt)std::min<PetscInt64>(st->recomputed, PETSC_MAX_INT);
    }
  }
  if (st->rec_n && !st->compact && !st->rec_only) // placed stages: step k-1 -> k's are in slot k
    PetscCall(rk_adjoint_place_records(ts, at(*st, k, 0) + st->rec_offset, st->rec_n));
  ts->time_step = -st->steps[k - 1];
  *t = ts->ptime;
  PetscFunctionReturn(0);
}

PetscErrorCode store_setfromoptions(TSTrajectory tj, PetscOptionItems *PetscOptionsObject) {
  StoreTrajectory *st = context(tj);
  PetscFunctionBegin;
  PetscOptionsHeadBegin(PetscOptionsObject, "Full-storage trajectory (flexipde)");
  PetscCall(PetscOptionsReal("-checkpoint_keep_stages_max_mb",
                             "Full storage also keeps every step's stages, so that the adjoint re-runs no step, while "
                             "that buffer takes at most this many MB per rank (beyond it, or 0: the steps are re-run)",
                             "store", st->keep_stages_max_mb, &st->keep_stages_max_mb, nullptr));
  PetscOptionsHeadEnd();
  PetscFunctionReturn(0);
}

PetscErrorCode store_destroy(TSTrajectory tj) {
  PetscFunctionBegin;
  delete context(tj);
  tj->data = nullptr;
  PetscFunctionReturn(0);
}

PetscErrorCode store_create(TSTrajectory tj, TS) {
  PetscFunctionBegin;
  tj->data = new StoreTrajectory();
  tj->ops->set = store_set;
  tj->ops->get = store_get;
  tj->ops->setup = store_setup;
  tj->ops->setfromoptions = store_setfromoptions;
  tj->ops->destroy = store_destroy;
  tj->usehistory = PETSC_FALSE;
  tj->solution_only = PETSC_TRUE;
  PetscFunctionReturn(0);
}

} // namespace

PetscScalar *StateBuffer::allocate(size_t n) {
  const size_t huge = (size_t)2 << 20, bytes = n * sizeof(PetscScalar);
  if (bytes < huge) return static_cast<PetscScalar *>(std::malloc(bytes));
  void *p = std::aligned_alloc(huge, (bytes + huge - 1) / huge * huge);
#ifdef MADV_HUGEPAGE
  if (p) (void)madvise(p, (bytes + huge - 1) / huge * huge, MADV_HUGEPAGE); // advice only: ignored where unsupported
#endif
  return static_cast<PetscScalar *>(p);
}

PetscErrorCode register_store_trajectory() {
  PetscFunctionBegin;
  PetscCall(TSTrajectoryRegister(FLEXIPDE_TSTRAJECTORY_STORE, store_create)); // replaces itself when repeated
  PetscFunctionReturn(0);
}

PetscErrorCode store_trajectory_use_buffer(TSTrajectory tj, StateBuffer *buffer) {
  PetscBool match;
  PetscFunctionBegin;
  PetscCall(PetscObjectTypeCompare((PetscObject)tj, FLEXIPDE_TSTRAJECTORY_STORE, &match));
  if (match) context(tj)->buffer = buffer ? buffer : &context(tj)->own;
  PetscFunctionReturn(0);
}

PetscErrorCode store_trajectory_cap_stages(TSTrajectory tj, PetscReal mb) {
  PetscBool match;
  PetscFunctionBegin;
  PetscCall(PetscObjectTypeCompare((PetscObject)tj, FLEXIPDE_TSTRAJECTORY_STORE, &match));
  if (match) context(tj)->keep_stages_max_mb = mb;
  PetscFunctionReturn(0);
}

PetscErrorCode store_trajectory_set_single(TSTrajectory tj, bool single) {
  PetscBool match;
  PetscFunctionBegin;
  PetscCall(PetscObjectTypeCompare((PetscObject)tj, FLEXIPDE_TSTRAJECTORY_STORE, &match));
  if (match) context(tj)->single = single;
  PetscFunctionReturn(0);
}

PetscInt64 store_trajectory_recomputed(TSTrajectory tj) { return context(tj)->recomputed; }
PetscInt store_trajectory_states(TSTrajectory tj) { return context(tj)->last; } // U_0 .. U_{n-1}
bool store_trajectory_keeps_stages(TSTrajectory tj) { return context(tj)->keep_stages || context(tj)->theta_endpoint; }
PetscReal store_trajectory_mb(TSTrajectory tj) {
  const StoreTrajectory *st = context(tj);
  return (PetscReal)(st->last + 1) * st->slot * sizeof(PetscScalar) / 1048576.0;
}

} // namespace flexipde
