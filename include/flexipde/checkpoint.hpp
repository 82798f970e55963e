// Checkpointing of the forward trajectory for TSAdjoint: the adjoint runs in a fixed memory budget.
//
// The adjoint of step k-1 -> k needs the forward state U_{k-1} and the step's stages (RK) or
// stage/start values (theta). With a budget of s stored states and n fixed steps, the forward
// sweep stores a few states, and the adjoint restores the nearest one and re-runs forward steps
// (TSStep) to rebuild what the next adjoint step needs. Where to store follows the binomial
// (revolve) schedule of Griewank & Walther, which minimises the number of recomputed steps:
//
//   beta(s, r) = C(s + r, s)                 most steps s checkpoints reverse when no step is
//                                            advanced more than r times
//   r(n, s)    = min { r : beta(s, r) >= n } repetition number
//   t(n, s)    = r n - beta(s + 1, r - 1)    minimal number of forward steps recomputed
//
// The checkpoints count the initial state (s >= 1); the state held by the TS is not one of them.
// t(n, s) is also exactly the number of TSStep calls this trajectory makes during
// TSAdjointSolve: the revolve count includes the n-1 advances of the first sweep and excludes the
// n "taping" steps, whereas here the first sweep (n steps) is the forward solve and every
// adjoint step but the last needs one re-run step for its stages. With s >= n - 1 the schedule
// stores every state and recomputes n - 1 steps, exactly like PETSc's memory trajectory with
// solution only.
//
// Options (listed by -help with the TS options):
//   -checkpoint_budget s   keep at most s states (s >= 1); unset: full storage (every state)
//   -checkpoint_precision double|single   full storage's states as doubles or as floats (half the memory)
//   -ts_trajectory_monitor prints the schedule (stores, restores, re-run steps)
//
//   mpiexec -n 2 ./flexipde -task gradient -wave_c_field 1 -wave_c 0.9 -da_grid_x 1000
//           -ts_dt 5e-4 -ts_max_time 5 -checkpoint_budget 30      (one command line)
#pragma once
#include "flexipde/petsc.hpp"
#include <petscts.h>
#include <algorithm>
#include <cstdlib>
#include <new>
#include <memory>
#include <vector>

namespace flexipde {

// The binomial arithmetic. beta saturates at a large value instead of overflowing.
PetscInt64 binomial_beta(PetscInt64 s, PetscInt64 r);
PetscInt64 binomial_repetitions(PetscInt64 n, PetscInt64 s);
// t(n, s) above; 0 for n <= 1.
PetscInt64 binomial_optimal_recomputations(PetscInt64 n, PetscInt64 s);

// The schedule alone (no PETSc objects), so that it can be tested and counted without a solve.
// It keeps the positions (step numbers) of the stored states as a stack.
class BinomialSchedule {
public:
  enum class Op {
    Restore, // the TS takes the stored state `step` (the top of the stack)
    Advance, // re-run forward steps until the TS holds state `step`
    Store,   // store the state `step` the TS holds
    Tape,    // re-run one step from `step` - 1 to `step`, leaving its stages in the TS
    Release  // free the stored state `step`
  };
  struct Action {
    Op op;
    PetscInt step;
  };

  void reset(PetscInt steps, PetscInt budget);
  // Forward sweep: called for step = 0, 1, ..., n in order; true when the state is to be stored.
  bool store_in_forward(PetscInt step);
  // Actions that leave the TS ready for the adjoint of step k-1 -> k (1 <= k < n; the adjoint of
  // the last step uses what the forward solve left in the TS). Calls come for k = n-1, ..., 1.
  PetscErrorCode reverse(PetscInt k, std::vector<Action> &plan);
  // Forward steps the plan makes the TS run (Advance and Tape).
  static PetscInt64 steps_in(const std::vector<Action> &plan, PetscInt from);

  PetscInt steps() const { return n_; }
  PetscInt budget() const { return s_; }
  PetscInt held() const { return (PetscInt)stack_.size(); }
  PetscInt peak() const { return peak_; }

private:
  PetscInt n_ = 0, s_ = 0, peak_ = 0;
  std::vector<PetscInt> stack_;
  PetscInt next_forward_ = 0, forward_free_ = 0; // next forward store position, checkpoints left
};

// What the adjoint trajectory cost in the last gradient evaluation.
struct CheckpointStats {
  PetscInt budget = 0;                   // 0: full storage
  PetscInt steps = 0;                    // forward steps n
  PetscInt stored_peak = 0;              // most states held at once by the trajectory
  PetscInt64 stores = 0;                 // checkpoint writes (forward sweep and adjoint)
  PetscInt64 recomputed_steps = 0;       // forward steps run again during TSAdjointSolve
  PetscInt64 optimal_recomputations = 0; // the binomial optimum t(n, s) (full storage: n - 1)
  PetscReal stored_mb = 0;               // full storage: the trajectory's memory on this rank (MB)
  PetscReal memory_mb = 0;               // -checkpoint_memory per rank (MB; 0: not given)
  PetscReal state_mb = 0;                // one stored state on the rank that holds the most (MB)
};
// Bytes in a size like "4GB", "512MB", "64kB", "1.5G" or "1000000" (powers of 1024; B optional), or -1
// when the text is not one.
PetscReal parse_memory_size(const char *text);

// The TSTrajectory type "binomial" (registered on first use).
#define FLEXIPDE_TSTRAJECTORY_BINOMIAL "binomial"
PetscErrorCode register_binomial_trajectory();
PetscErrorCode binomial_trajectory_set_budget(TSTrajectory tj, PetscInt budget);

// The TSTrajectory type "store": every state in one contiguous buffer (trajectory_store.cpp), the
// full storage used when no -checkpoint_budget is given. The buffer may be supplied by the caller
// (the Simulation keeps one across gradients, so it is allocated once).
#define FLEXIPDE_TSTRAJECTORY_STORE "store"
// Uninitialised storage that only grows: zero-filling gigabytes of states that are overwritten
// anyway cost more than the forward sweep of a large grid.
// Large buffers are aligned to 2 MB and offered to the kernel for transparent huge pages
// (madvise): the adjoint reads the buffer backwards, slot by slot, and with 4 KB pages every slot
// costs TLB misses that also stall the prefetches of the next one.
struct StateBuffer {
  struct Free {
    void operator()(PetscScalar *p) const { std::free(p); }
  };
  std::unique_ptr<PetscScalar[], Free> data;
  size_t size = 0;
  // At least n entries; keep = copy the current contents when it moves.
  void grow(size_t n, bool keep) {
    if (n <= size) return;
    std::unique_ptr<PetscScalar[], Free> fresh(allocate(n));
    if (!fresh) throw std::bad_alloc();
    if (keep && size) std::copy(data.get(), data.get() + size, fresh.get());
    data = std::move(fresh);
    size = n;
  }

private:
  static PetscScalar *allocate(size_t n);
};
PetscErrorCode register_store_trajectory();
PetscErrorCode store_trajectory_use_buffer(TSTrajectory tj, StateBuffer *buffer);
// Keep each step's stages only while the whole buffer stays within mb per rank (the default of
// -checkpoint_keep_stages_max_mb, which still overrides it).
PetscErrorCode store_trajectory_cap_stages(TSTrajectory tj, PetscReal mb);
// The states kept in single precision (-checkpoint_precision single): half the memory, gradients exact to
// the states' rounding (about 1e-7 relative), every step but the leapfrog's re-run in the adjoint.
PetscErrorCode store_trajectory_set_single(TSTrajectory tj, bool single);
PetscInt64 store_trajectory_recomputed(TSTrajectory tj);
PetscInt store_trajectory_states(TSTrajectory tj);
bool store_trajectory_keeps_stages(TSTrajectory tj); // every step's stages at hand (stored, or solutions themselves): nothing re-run
PetscReal store_trajectory_mb(TSTrajectory tj);      // memory of the states stored so far on this rank (MB)

// Called on a TS before TSSetFromOptions: saves the trajectory for TSAdjointSolve as full storage
// (PETSc's memory trajectory) or, with -checkpoint_budget, as a binomial checkpointing
// trajectory, and fills *stats during TSAdjointSolve. stats must outlive the TS.
PetscErrorCode setup_adjoint_trajectory(TS ts, CheckpointStats *stats);
// True when an adjoint monitor other than the statistics one above is set (one that may read the
// state U_k the adjoint passes it, which full storage then has to provide).
bool adjoint_monitors_read_state(TS ts);

} // namespace flexipde
