// Binomial checkpointing for TSAdjoint: the schedule and the TSTrajectory type "binomial".
//
// What a TSTrajectory must do for TSAdjointSolve in PETSc 3.18 (src/ts/interface/sensitivity):
// the forward TSSolve calls Set(step) before the first step and after every step; the adjoint
// then calls Get(k) for k = n, n-1, ..., 1 (and 0 at the end), and the adjoint step that follows
// reverses step k-1 -> k using what the TS holds: ts->vec_sol = U_k, the step's stages (RK: Y_i;
// theta: the stage X, or X0 for the endpoint forms) and ts->ptime = t_k with a negative
// ts->time_step = t_{k-1} - t_k. The cheapest way to put all of that in place is to run the step
// k-1 -> k again from U_{k-1} with TSStep, which fills the stages of whatever integrator is in
// use; TSStep records nothing into the trajectory (only TSSolve calls Set), so re-running steps
// inside Get is safe. Get(n) needs nothing: the forward solve left the last step in the TS.
//
// A restored state restarts the integrator (TSRestartStep): an FSAL Runge-Kutta method (3bs,
// 5dp, 5bs, 6vr) would otherwise reuse the last stage derivative of whatever step ran before, which
// belongs to a different point of the trajectory. A checkpoint keeps the time and the step size
// with which the forward run left that state, so that re-run steps repeat the forward
// arithmetic exactly.
#include "flexipde/checkpoint.hpp"
#include "flexipde/leapfrog.hpp"
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>
#include <petsc/private/tsimpl.h>

namespace flexipde {

// ---------------------------------------------------------------------------------------------
// Binomial arithmetic

static const PetscInt64 beta_cap = std::numeric_limits<PetscInt64>::max() / 4;

PetscInt64 binomial_beta(PetscInt64 s, PetscInt64 r) {
  if (s < 0 || r < 0) return 0;
  // C(s + r, s) = C(s + r, k) with k = min(s, r); b_i = C(s + r - k + i, i) stays an integer.
  const PetscInt64 k = std::min(s, r), top = s + r - k;
  PetscInt64 b = 1;
  for (PetscInt64 i = 1; i <= k; ++i) {
    if (b > beta_cap / (top + i)) return beta_cap;
    b = b * (top + i) / i;
  }
  return b;
}

PetscInt64 binomial_repetitions(PetscInt64 n, PetscInt64 s) {
  if (n <= 1) return 0;
  if (s < 1) return -1;    // no checkpoint: nothing can be reversed
  PetscInt64 r = 0, b = 1; // b = beta(s, r)
  while (b < n) {
    ++r;
    b = (b > beta_cap / (s + r)) ? beta_cap : b * (s + r) / r;
  }
  return r;
}

PetscInt64 binomial_optimal_recomputations(PetscInt64 n, PetscInt64 s) {
  if (n <= 1) return 0;
  const PetscInt64 r = binomial_repetitions(n, s);
  if (r < 0) return -1;
  return r * n - binomial_beta(s + 1, r - 1);
}

// Where to store next when l steps remain to be reversed with c checkpoints, one of them holding
// the start of the range (c >= 2, l >= 2). With r = r(l, c), any split m with
//   beta(c, r-2) <= m <= beta(c, r-1)   and   beta(c-1, r-1) <= l - m <= beta(c-1, r)
// puts the left part (c checkpoints) in repetition bracket r-1 and the right part (c-1
// checkpoints) in bracket r, so their costs add up to m + t(m, c) + t(l-m, c-1) = t(l, c) by
// Pascal's rule. The largest such m is taken.
static PetscInt64 binomial_split(PetscInt64 l, PetscInt64 c) {
  const PetscInt64 r = binomial_repetitions(l, c);
  PetscInt64 m = std::min(binomial_beta(c, r - 1), l - binomial_beta(c - 1, r - 1));
  return std::max<PetscInt64>(1, std::min(m, l - 1));
}

// ---------------------------------------------------------------------------------------------
// The schedule

void BinomialSchedule::reset(PetscInt steps, PetscInt budget) {
  n_ = steps;
  s_ = budget;
  peak_ = 0;
  stack_.clear();
  next_forward_ = (n_ >= 2 && s_ >= 1) ? 0 : -1; // one step needs no stored state at all
}

bool BinomialSchedule::store_in_forward(PetscInt step) {
  if (step != next_forward_) return false;
  stack_.push_back(step);
  peak_ = std::max(peak_, held());
  next_forward_ = -1;
  const PetscInt64 l = n_ - step, c = s_ - held() + 1;
  if (l >= 2 && c >= 2) {
    const PetscInt64 next = step + binomial_split(l, c);
    // State n-1 is never stored: the forward solve itself runs the last step.
    if (next < n_ - 1) next_forward_ = (PetscInt)next;
  }
  return true;
}

PetscErrorCode BinomialSchedule::reverse(PetscInt k, std::vector<Action> &plan) {
  PetscFunctionBegin;
  plan.clear();
  PetscCheck(k >= 1 && k < n_, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
             "Binomial schedule: step %" PetscInt_FMT " is outside 1..%" PetscInt_FMT, k, n_ - 1);
  PetscCheck(!stack_.empty() && stack_.back() <= k - 1, PETSC_COMM_SELF, PETSC_ERR_PLIB,
             "Binomial schedule: no stored state before step %" PetscInt_FMT " (steps must be reversed in order)", k);
  PetscInt a = stack_.back();
  plan.push_back({Op::Restore, a});
  PetscInt64 c = s_ - held() + 1; // checkpoints for the range (a, k], counting the one at a
  while (k - a > 1 && c > 1) {
    const PetscInt64 m = binomial_split(k - a, c);
    if (a + m >= k - 1) break; // storing k-1 would be released straight after this step
    a += (PetscInt)m;
    plan.push_back({Op::Advance, a});
    plan.push_back({Op::Store, a});
    stack_.push_back(a);
    peak_ = std::max(peak_, held());
    --c;
  }
  if (a < k - 1) plan.push_back({Op::Advance, k - 1});
  plan.push_back({Op::Tape, k});
  if (stack_.back() == k - 1) { // every later step lies before k-1
    plan.push_back({Op::Release, k - 1});
    stack_.pop_back();
  }
  PetscFunctionReturn(0);
}

PetscInt64 BinomialSchedule::steps_in(const std::vector<Action> &plan, PetscInt from) {
  PetscInt64 steps = 0;
  PetscInt at = from;
  for (const Action &a : plan) {
    switch (a.op) {
    case Op::Restore:
      at = a.step;
      break;
    case Op::Advance:
      steps += a.step - at;
      at = a.step;
      break;
    case Op::Tape:
      steps += 1;
      at = a.step;
      break;
    default:
      break;
    }
  }
  return steps;
}

// ---------------------------------------------------------------------------------------------
// The TSTrajectory type

namespace {

struct Checkpoint {
  PetscInt step = -1;
  PetscReal time = 0, dt = 0; // time of the state, step size the forward run continued with
};

struct BinomialTrajectory {
  PetscInt budget = 0;
  BinomialSchedule schedule;
  // The pool is allocated once per setup (at most min(budget, n-1) vectors), so the memory held
  // is fixed before the first step; free_ lists the unused pool entries, held_ the used ones in
  // the order of the schedule's stack.
  Vec *pool = nullptr;
  PetscInt pool_size = 0;
  std::vector<Checkpoint> meta;
  std::vector<PetscInt> free_, held_;
  std::vector<BinomialSchedule::Action> plan;
  PetscInt64 stores = 0, recomputed = 0;
};

BinomialTrajectory *context(TSTrajectory tj) { return static_cast<BinomialTrajectory *>(tj->data); }

PetscErrorCode store_state(TSTrajectory tj, BinomialTrajectory *bt, PetscInt step, PetscReal time, PetscReal dt,
                           Vec X) {
  PetscFunctionBegin;
  PetscCheck(!bt->free_.empty(), PetscObjectComm((PetscObject)tj), PETSC_ERR_PLIB,
             "Binomial trajectory: more stored states than the budget %" PetscInt_FMT, bt->budget);
  const PetscInt slot = bt->free_.back();
  bt->free_.pop_back();
  PetscCall(VecCopy(X, bt->pool[slot]));
  bt->meta[slot] = {step, time, dt};
  bt->held_.push_back(slot);
  ++bt->stores;
  if (tj->monitor)
    PetscCall(
        PetscViewerASCIIPrintf(tj->monitor, "binomial: store state %" PetscInt_FMT " (t = %g)\n", step, (double)time));
  PetscFunctionReturn(0);
}

// One forward step again. Monitors and pre-/post-step hooks are not called: monitors would see
// the step twice, and TSSolve stores a state before its post-step hook runs, so a hook that
// changes the state could not be replayed faithfully anyway (the Simulation sets none).
PetscErrorCode run_step(TS ts, BinomialTrajectory *bt) {
  PetscFunctionBegin;
  PetscCall(TSStep(ts));
  PetscCheck(ts->reason >= 0, PetscObjectComm((PetscObject)ts), PETSC_ERR_NOT_CONVERGED,
             "Binomial trajectory: re-running step %" PetscInt_FMT " for the adjoint failed (%s)", ts->steps,
             TSConvergedReasons[ts->reason]);
  ++bt->recomputed;
  PetscFunctionReturn(0);
}

PetscErrorCode binomial_set(TSTrajectory tj, TS ts, PetscInt stepnum, PetscReal time, Vec X) {
  BinomialTrajectory *bt = context(tj);
  const PetscInt n = bt->schedule.steps();
  PetscFunctionBegin;
  PetscCheck(stepnum <= n, PetscObjectComm((PetscObject)tj), PETSC_ERR_ARG_OUTOFRANGE,
             "Binomial trajectory: the forward solve takes more than the %" PetscInt_FMT " steps it was planned for",
             n);
  PetscCheck(!ts->reason || stepnum == n, PetscObjectComm((PetscObject)tj), PETSC_ERR_ARG_OUTOFRANGE,
             "Binomial trajectory: the forward solve stopped after %" PetscInt_FMT " of %" PetscInt_FMT
             " planned steps; the step count (-ts_max_steps) must be the one reached at -ts_max_time",
             stepnum, n);
  if (bt->schedule.store_in_forward(stepnum)) PetscCall(store_state(tj, bt, stepnum, time, ts->time_step, X));
  PetscFunctionReturn(0);
}

PetscErrorCode binomial_get(TSTrajectory tj, TS ts, PetscInt stepnum, PetscReal *t) {
  BinomialTrajectory *bt = context(tj);
  const PetscInt n = bt->schedule.steps();
  PetscFunctionBegin;
  if (stepnum == 0) { // the adjoint has finished: a next TSSolve sets the schedule up again (pool kept)
    PetscCall(TSTrajectoryReset(tj));
    PetscFunctionReturn(0);
  }
  PetscCheck(stepnum <= n, PetscObjectComm((PetscObject)tj), PETSC_ERR_ARG_OUTOFRANGE,
             "Binomial trajectory: step %" PetscInt_FMT " was never computed (%" PetscInt_FMT " steps)", stepnum, n);
  if (stepnum < n) {
    const TSConvergedReason reason = ts->reason;
    PetscCall(bt->schedule.reverse(stepnum, bt->plan));
    for (const BinomialSchedule::Action &a : bt->plan) {
      switch (a.op) {
      case BinomialSchedule::Op::Restore: {
        const Checkpoint &cp = bt->meta[bt->held_.back()];
        PetscCall(VecCopy(bt->pool[bt->held_.back()], ts->vec_sol));
        ts->ptime = cp.time;
        ts->time_step = cp.dt;
        PetscCall(TSSetStepNumber(ts, cp.step));
        PetscCall(TSRestartStep(ts));
        if (tj->monitor)
          PetscCall(PetscViewerASCIIPrintf(tj->monitor, "binomial: restore state %" PetscInt_FMT "\n", cp.step));
        break;
      }
      case BinomialSchedule::Op::Advance:
        if (tj->monitor)
          PetscCall(PetscViewerASCIIPrintf(tj->monitor, "binomial: advance %" PetscInt_FMT " -> %" PetscInt_FMT "\n",
                                           ts->steps, a.step));
        while (ts->steps < a.step) PetscCall(run_step(ts, bt));
        break;
      case BinomialSchedule::Op::Store:
        PetscCall(store_state(tj, bt, ts->steps, ts->ptime, ts->time_step, ts->vec_sol));
        break;
      case BinomialSchedule::Op::Tape:
        PetscCheck(ts->steps == a.step - 1, PetscObjectComm((PetscObject)tj), PETSC_ERR_PLIB,
                   "Binomial trajectory: at step %" PetscInt_FMT " instead of %" PetscInt_FMT, ts->steps, a.step - 1);
        if (tj->monitor)
          PetscCall(PetscViewerASCIIPrintf(tj->monitor,
                                           "binomial: step %" PetscInt_FMT " -> %" PetscInt_FMT " for its stages\n",
                                           a.step - 1, a.step));
        PetscCall(run_step(ts, bt));
        break;
      case BinomialSchedule::Op::Release:
        bt->free_.push_back(bt->held_.back());
        bt->held_.pop_back();
        break;
      }
    }
    ts->reason = reason;
    tj->recomps = (PetscInt)std::min<PetscInt64>(bt->recomputed, PETSC_MAX_INT);
  }
  // The adjoint step runs backwards from t_k over the step the forward run took to get there.
  ts->time_step = ts->ptime_prev - ts->ptime;
  *t = ts->ptime;
  PetscFunctionReturn(0);
}

PetscErrorCode binomial_setup(TSTrajectory tj, TS ts) {
  BinomialTrajectory *bt = context(tj);
  MPI_Comm comm = PetscObjectComm((PetscObject)tj);
  TSAdapt adapt;
  PetscBool fixed;
  PetscFunctionBegin;
  PetscCheck(bt->budget >= 1, comm, PETSC_ERR_ARG_WRONGSTATE,
             "TSTrajectory binomial needs a budget of stored states: -checkpoint_budget N with N >= 1");
  PetscCall(TSGetAdapt(ts, &adapt));
  PetscCall(PetscObjectTypeCompare((PetscObject)adapt, TSADAPTNONE, &fixed));
  PetscCheck(fixed, comm, PETSC_ERR_SUP,
             "-checkpoint_budget plans the schedule for a known number of steps and cannot be combined with adaptive "
             "time steps (-ts_adapt_type %s); leave -checkpoint_budget unset to store every state",
             ((PetscObject)adapt)->type_name);
  PetscCheck(ts->max_steps >= 1 && ts->max_steps < PETSC_MAX_INT, comm, PETSC_ERR_ARG_WRONGSTATE,
             "TSTrajectory binomial needs the number of steps in advance (TSSetMaxSteps)");
  PetscCheck(ts->vec_sol, comm, PETSC_ERR_ORDER, "TSTrajectory binomial: set the TS solution before the solve");
  const PetscInt n = ts->max_steps;
  bt->schedule.reset(n, bt->budget);
  const PetscInt need = std::max<PetscInt>(1, std::min<PetscInt>(bt->budget, n - 1));
  if (bt->pool_size != need) {
    if (bt->pool) PetscCall(VecDestroyVecs(bt->pool_size, &bt->pool));
    PetscCall(VecDuplicateVecs(ts->vec_sol, need, &bt->pool));
    bt->pool_size = need;
  }
  bt->meta.assign(need, Checkpoint());
  bt->free_.clear();
  for (PetscInt i = need - 1; i >= 0; --i) bt->free_.push_back(i);
  bt->held_.clear();
  bt->stores = bt->recomputed = 0;
  PetscFunctionReturn(0);
}

PetscErrorCode binomial_setfromoptions(TSTrajectory tj, PetscOptionItems *) {
  PetscBool set;
  PetscInt budget;
  PetscFunctionBegin;
  // Usually set by setup_adjoint_trajectory; read here too so -ts_trajectory_type binomial works alone.
  PetscCall(PetscOptionsGetInt(((PetscObject)tj)->options, nullptr, "-checkpoint_budget", &budget, &set));
  if (set) PetscCall(binomial_trajectory_set_budget(tj, budget));
  PetscFunctionReturn(0);
}

PetscErrorCode binomial_view(TSTrajectory tj, PetscViewer viewer) {
  BinomialTrajectory *bt = context(tj);
  PetscFunctionBegin;
  PetscCall(PetscViewerASCIIPrintf(viewer,
                                   "binomial checkpointing: budget %" PetscInt_FMT " states for %" PetscInt_FMT
                                   " steps, at most %" PetscInt_FMT " held, %" PetscInt64_FMT " stores\n",
                                   bt->budget, bt->schedule.steps(), bt->schedule.peak(), bt->stores));
  PetscCall(PetscViewerASCIIPrintf(viewer,
                                   "  recomputed steps %" PetscInt64_FMT ", binomial optimum %" PetscInt64_FMT "\n",
                                   bt->recomputed, binomial_optimal_recomputations(bt->schedule.steps(), bt->budget)));
  PetscFunctionReturn(0);
}

PetscErrorCode binomial_destroy(TSTrajectory tj) {
  BinomialTrajectory *bt = context(tj);
  PetscFunctionBegin;
  if (bt->pool) PetscCall(VecDestroyVecs(bt->pool_size, &bt->pool));
  delete bt;
  tj->data = nullptr;
  PetscFunctionReturn(0);
}

PetscErrorCode binomial_create(TSTrajectory tj, TS) {
  PetscFunctionBegin;
  tj->data = new BinomialTrajectory();
  tj->ops->set = binomial_set;
  tj->ops->get = binomial_get;
  tj->ops->setup = binomial_setup;
  tj->ops->setfromoptions = binomial_setfromoptions;
  tj->ops->view = binomial_view;
  tj->ops->destroy = binomial_destroy;
  // The time history grows with the number of steps and nothing here reads it.
  tj->usehistory = PETSC_FALSE;
  tj->solution_only = PETSC_TRUE; // stages are always rebuilt by re-running a step
  PetscFunctionReturn(0);
}

// ---------------------------------------------------------------------------------------------
// Simulation glue: options and statistics

// -checkpoint_memory: the states that fit in it on every rank. All of them (n + 1 for n steps): full
// storage, which keeps stages too only within the same memory; fewer: the binomial schedule with as
// many as fit.
PetscErrorCode budget_from_memory(TS ts, const char *text, bool single, CheckpointStats *stats, PetscInt *budget) {
  MPI_Comm comm = PetscObjectComm((PetscObject)ts);
  PetscFunctionBegin;
  const PetscReal bytes = parse_memory_size(text);
  PetscCheck(bytes > 0, comm, PETSC_ERR_ARG_WRONG,
             "-checkpoint_memory %s: give a size per rank such as 4GB, 512MB or 64kB", text);
  PetscCheck(ts->max_time < PETSC_MAX_REAL && ts->time_step > 0, comm, PETSC_ERR_ARG_WRONG,
             "-checkpoint_memory plans for a known number of fixed steps: give -ts_max_time and -ts_dt");
  PetscInt n, steps = (PetscInt)std::ceil((ts->max_time - ts->ptime) / ts->time_step - 1e-9);
  steps = std::min(steps, ts->max_steps - ts->steps);
  if (ts->vec_sol) PetscCall(VecGetLocalSize(ts->vec_sol, &n));
  else { // (the solution is set later: a state of the TS's DM)
    DM dm;
    Vec v;
    PetscCall(TSGetDM(ts, &dm));
    PetscCall(DMGetGlobalVector(dm, &v));
    PetscCall(VecGetLocalSize(v, &n));
    PetscCall(DMRestoreGlobalVector(dm, &v));
  }
  PetscReal state = (PetscReal)n * (single ? sizeof(float) : sizeof(PetscScalar));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &state, 1, MPIU_REAL, MPI_MAX, comm));
  const PetscReal fit = std::floor(bytes / state);
  stats->memory_mb = bytes / 1048576.0, stats->state_mb = state / 1048576.0;
  PetscCheck(fit >= 1, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "-checkpoint_memory %s holds no state of this scene (%.3g MB per rank): give more", text, (double)stats->state_mb);
  // full storage keeps every state; an FSAL Runge-Kutta method (PETSc's memory trajectory) its stages too
  PetscInt per_step = 1;
  PetscBool rk, fsal = PETSC_FALSE;
  PetscCall(PetscObjectTypeCompare((PetscObject)ts, TSRK, &rk));
  if (rk) {
    PetscInt s;
    PetscCall(TSRKGetTableau(ts, &s, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, &fsal));
    if (fsal) per_step += s;
  }
  *budget = fit >= (PetscReal)(steps + 1) * per_step ? 0 : (PetscInt)std::min<PetscReal>(fit, PETSC_MAX_INT);
  PetscFunctionReturn(0);
}

PetscErrorCode checkpoint_options(PetscObject obj, PetscOptionItems *PetscOptionsObject, void *ctx) {
  TS ts = (TS)obj;
  auto *stats = static_cast<CheckpointStats *>(ctx);
  TSTrajectory tj;
  PetscInt budget = 0;
  PetscBool set = PETSC_FALSE, memory_set = PETSC_FALSE;
  char memory[64] = "";
  const char *precisions[] = {"double", "single"};
  PetscInt precision = 0;
  PetscFunctionBegin;
  PetscCall(TSGetTrajectory(ts, &tj));
  PetscOptionsHeadBegin(PetscOptionsObject, "Adjoint checkpointing (flexipde)");
  PetscCall(PetscOptionsInt("-checkpoint_budget",
                            "Most forward states kept for the adjoint, binomial (revolve) schedule; unset: every state",
                            "setup_adjoint_trajectory", budget, &budget, &set));
  PetscCall(PetscOptionsString("-checkpoint_memory",
                               "Memory per rank for the states the adjoint keeps (e.g. 4GB, 512MB): every state when they "
                               "fit, else the binomial schedule with as many as fit",
                               "setup_adjoint_trajectory", memory, memory, sizeof memory, &memory_set));
  PetscCall(PetscOptionsEList("-checkpoint_precision", "Full storage's states as doubles, or as floats: half the memory, "
                              "the gradient exact to their rounding", "setup_adjoint_trajectory", precisions, 2,
                              precisions[precision], &precision, nullptr));
  const bool single = precision == 1;
  PetscCheck(!(set && memory_set), PetscObjectComm(obj), PETSC_ERR_ARG_INCOMP,
             "-checkpoint_budget (states) and -checkpoint_memory (bytes) both bound the trajectory: give one of them");
  if (memory_set) {
    PetscCall(budget_from_memory(ts, memory, single, stats, &budget));
    set = budget > 0 ? PETSC_TRUE : PETSC_FALSE;
  }
  if (set) {
    PetscCheck(budget >= 1, PetscObjectComm(obj), PETSC_ERR_ARG_OUTOFRANGE,
               "-checkpoint_budget %" PetscInt_FMT ": the budget is a number of stored states and must be at least 1 "
               "(leave it unset to store every state)",
               budget);
    PetscCheck(!single, PetscObjectComm(obj), PETSC_ERR_ARG_INCOMP,
               "-checkpoint_precision single keeps every state: not with the binomial schedule of %s",
               memory_set ? "-checkpoint_memory (the states in single precision do not all fit)" : "-checkpoint_budget");
    PetscCall(TSTrajectorySetType(tj, ts, FLEXIPDE_TSTRAJECTORY_BINOMIAL));
    PetscCall(binomial_trajectory_set_budget(tj, budget));
    stats->budget = budget;
    PetscFunctionReturn(0);
  }
  // Full storage. PETSc 3.18's memory trajectory in solution-only mode re-runs each step in the
  // adjoint without restarting the integrator, so an FSAL Runge-Kutta method (3bs, 5dp, ...) picks
  // up a stage derivative from another step and the gradient is wrong (3bs: 3e-5 relative,
  // docs/checkpointing.md). Such methods keep their stages instead (no step is re-run).
  TSType type;
  PetscBool is_rk, fsal = PETSC_FALSE;
  PetscCall(TSGetType(ts, &type));
  PetscCall(PetscStrcmp(type, TSRK, &is_rk));
  if (is_rk) PetscCall(TSRKGetTableau(ts, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, &fsal));
  PetscCheck(!(single && fsal), PetscObjectComm(obj), PETSC_ERR_ARG_INCOMP,
             "-checkpoint_precision single: not with -ts_rk_type %s, whose stages are kept in double", type);
  if (fsal) PetscCall(TSTrajectorySetSolutionOnly(tj, PETSC_FALSE));
  else {
    PetscCall(TSTrajectorySetType(tj, ts, FLEXIPDE_TSTRAJECTORY_STORE)); // one buffer, one memcpy per step
    if (memory_set) PetscCall(store_trajectory_cap_stages(tj, stats->memory_mb));
    PetscCall(store_trajectory_set_single(tj, single));
  }
  PetscFunctionReturn(0);
}

// Copies what the trajectory did into the statistics; called by TSAdjointSolve after every Get.
PetscErrorCode checkpoint_statistics(TS ts, PetscInt step, PetscReal, Vec, PetscInt, Vec *, Vec *, void *ctx) {
  auto *stats = static_cast<CheckpointStats *>(ctx);
  TSTrajectory tj;
  PetscBool binomial;
  PetscFunctionBegin;
  PetscCall(TSGetTrajectory(ts, &tj));
  PetscBool store;
  PetscCall(PetscObjectTypeCompare((PetscObject)tj, FLEXIPDE_TSTRAJECTORY_BINOMIAL, &binomial));
  PetscCall(PetscObjectTypeCompare((PetscObject)tj, FLEXIPDE_TSTRAJECTORY_STORE, &store));
  if (store) { // every state stored; the leapfrog re-runs nothing, other integrators each step once
    if (!stats->steps) stats->steps = step;
    stats->budget = 0;
    stats->stored_peak = store_trajectory_states(tj);
    stats->stores = stats->stored_peak;
    stats->recomputed_steps = store_trajectory_recomputed(tj);
    stats->stored_mb = store_trajectory_mb(tj);
    stats->optimal_recomputations = is_leapfrog(ts) || store_trajectory_keeps_stages(tj) ? 0 : stats->steps - 1;
  } else if (binomial) {
    const BinomialTrajectory *bt = context(tj);
    stats->budget = bt->budget;
    stats->steps = bt->schedule.steps();
    stats->stored_peak = bt->schedule.peak();
    stats->stores = bt->stores;
    stats->recomputed_steps = bt->recomputed;
    stats->optimal_recomputations = binomial_optimal_recomputations(stats->steps, bt->budget);
  } else {                                  // PETSc's memory trajectory keeps every state (or every step's stages)
    if (!stats->steps) stats->steps = step; // the first call comes at the final step
    const PetscInt n = stats->steps;
    stats->budget = 0;
    stats->stored_peak = tj->solution_only ? n : n - 1;
    stats->stores = stats->stored_peak;
    stats->recomputed_steps = tj->recomps;
    stats->optimal_recomputations = tj->solution_only ? n - 1 : 0;
  }
  PetscFunctionReturn(0);
}

} // namespace

PetscReal parse_memory_size(const char *text) {
  if (!text || !*text) return -1;
  char *end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || !(v > 0) || !std::isfinite(v)) return -1;
  std::string unit(end);
  while (!unit.empty() && unit[0] == ' ') unit.erase(0, 1);
  for (auto &c : unit) c = (char)std::toupper((unsigned char)c);
  if (!unit.empty() && unit.back() == 'B') unit.pop_back();
  const char *units[] = {"", "K", "M", "G", "T"};
  for (int k = 0; k < 5; ++k)
    if (unit == units[k]) return v * std::pow(1024.0, k);
  return -1;
}

PetscErrorCode register_binomial_trajectory() {
  PetscFunctionBegin;
  PetscCall(TSTrajectoryRegister(FLEXIPDE_TSTRAJECTORY_BINOMIAL, binomial_create)); // replaces itself when repeated
  PetscFunctionReturn(0);
}

PetscErrorCode binomial_trajectory_set_budget(TSTrajectory tj, PetscInt budget) {
  PetscBool match;
  PetscFunctionBegin;
  PetscCall(PetscObjectTypeCompare((PetscObject)tj, FLEXIPDE_TSTRAJECTORY_BINOMIAL, &match));
  PetscCheck(match, PetscObjectComm((PetscObject)tj), PETSC_ERR_ARG_WRONG, "The trajectory is not of type binomial");
  PetscCheck(budget >= 1, PetscObjectComm((PetscObject)tj), PETSC_ERR_ARG_OUTOFRANGE,
             "-checkpoint_budget %" PetscInt_FMT ": the budget is a number of stored states and must be at least 1",
             budget);
  context(tj)->budget = budget;
  PetscFunctionReturn(0);
}

bool adjoint_monitors_read_state(TS ts) {
  for (PetscInt i = 0; i < ts->numberadjointmonitors; ++i)
    if (ts->adjointmonitor[i] != checkpoint_statistics) return true;
  return false;
}

PetscErrorCode setup_adjoint_trajectory(TS ts, CheckpointStats *stats) {
  TSTrajectory tj;
  PetscFunctionBegin;
  *stats = CheckpointStats();
  PetscCall(register_binomial_trajectory());
  PetscCall(register_store_trajectory());
  PetscCall(TSSetSaveTrajectory(ts));
  PetscCall(TSGetTrajectory(ts, &tj));
  PetscCall(TSTrajectorySetType(tj, ts, TSTRAJECTORYMEMORY));
  // Store U only and recompute a step's stages in the adjoint: 1/(stages+1) of the memory and, on
  // the seed scene, less time than copying every stage.
  PetscCall(TSTrajectorySetSolutionOnly(tj, PETSC_TRUE));
  // -checkpoint_budget is read once the integrator is known (inside TSSetFromOptions, before the
  // trajectory's own options, so -ts_trajectory_* still override).
  PetscCall(PetscObjectAddOptionsHandler((PetscObject)ts, checkpoint_options, nullptr, stats));
  PetscCall(TSAdjointMonitorSet(ts, checkpoint_statistics, stats, nullptr));
  leapfrog_adjoint_monitor_reads_no_lambda(checkpoint_statistics);
  PetscFunctionReturn(0);
}

} // namespace flexipde
