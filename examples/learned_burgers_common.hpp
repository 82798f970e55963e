// What the learned-discretisation examples share (learned_burgers_train.cpp, learned_burgers_evaluate.cpp):
// the scenes' common settings, options set for one scene's set-up, a model integrated with PETSc's RK4
// with a callback at chosen steps, the fine reference averaged onto a coarse grid, and the L2 error.
//
// Grids: every grid covers [0, 1) in cells, point i at the centre (i + 1/2) h of cell [i h, (i + 1) h),
// so a coarse cell holds exactly `refine` fine cells and its value is their mean (-grid_x0 h/2,
// -grid_x1 1 + h/2; the random start is a function of x, the same on every grid).
#pragma once
#include "flexipde/scene.hpp"
#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

namespace learned {
using namespace flexipde;

// The settings every scene shares, read from the options the coarse scenes use.
struct Settings {
  PetscInt n = 32;                    // coarse points (-da_grid_x)
  PetscReal dt = 0.005, T = 0.5;      // coarse step and horizon (-ts_dt, -ts_max_time)
  PetscReal nu = 0.01, amplitude = 1; // -learned_burgers_nu, -learned_burgers_ic_amplitude
  PetscInt modes = 3;                 // -learned_burgers_ic_modes
  PetscInt steps() const { return (PetscInt)std::llround(T / dt); }
  PetscErrorCode from_options(MPI_Comm comm) {
    PetscFunctionBeginUser;
    PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-da_grid_x", &n, nullptr));
    PetscCall(PetscOptionsGetReal(nullptr, nullptr, "-ts_dt", &dt, nullptr));
    PetscCall(PetscOptionsGetReal(nullptr, nullptr, "-ts_max_time", &T, nullptr));
    PetscCall(PetscOptionsGetReal(nullptr, nullptr, "-learned_burgers_nu", &nu, nullptr));
    PetscCall(PetscOptionsGetReal(nullptr, nullptr, "-learned_burgers_ic_amplitude", &amplitude, nullptr));
    PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-learned_burgers_ic_modes", &modes, nullptr));
    PetscCheck(n >= 8, comm, PETSC_ERR_ARG_OUTOFRANGE, "-da_grid_x must be at least 8, got %" PetscInt_FMT, n);
    PetscCheck(dt > 0 && T > 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-ts_dt and -ts_max_time must be positive");
    PetscCheck(std::fabs(steps() * dt - T) < 1e-9 * T, comm, PETSC_ERR_ARG_WRONG,
               "-ts_max_time %g must be a whole number of steps -ts_dt %g", (double)T, (double)dt);
    PetscFunctionReturn(0);
  }
};

// Options in force from set() until the scope ends (the values they replaced are restored).
class OptionScope {
public:
  ~OptionScope() {
    for (auto it = saved_.rbegin(); it != saved_.rend(); ++it) {
      if (it->had) (void)PetscOptionsSetValue(nullptr, it->name.c_str(), it->old.empty() ? nullptr : it->old.c_str());
      else (void)PetscOptionsClearValue(nullptr, it->name.c_str());
    }
  }
  PetscErrorCode set(const std::string &name, const std::string &value) {
    PetscFunctionBeginUser;
    PetscCall(remember(name));
    PetscCall(PetscOptionsSetValue(nullptr, name.c_str(), value.c_str()));
    PetscFunctionReturn(0);
  }
  PetscErrorCode set(const std::string &name, double value) {
    char v[64];
    std::snprintf(v, sizeof v, "%.17g", value);
    return set(name, std::string(v));
  }
  // Removed until the scope ends.
  PetscErrorCode clear(const std::string &name) {
    PetscFunctionBeginUser;
    PetscCall(remember(name));
    PetscCall(PetscOptionsClearValue(nullptr, name.c_str()));
    PetscFunctionReturn(0);
  }
  // The cell-centred grid of n cells on [0, 1) (see the top of this file).
  PetscErrorCode cells(PetscInt n) {
    PetscFunctionBeginUser;
    PetscCall(set("-da_grid_x", std::to_string(n)));
    PetscCall(set("-grid_x0", 0.5 / n));
    PetscCall(set("-grid_x1", 1 + 0.5 / n));
    PetscFunctionReturn(0);
  }

private:
  struct Saved {
    std::string name, old;
    bool had;
  };
  // The option's value before the scope touches it, restored at its end.
  PetscErrorCode remember(const std::string &name) {
    Saved s;
    char old[PETSC_MAX_PATH_LEN] = "";
    PetscBool had;
    PetscFunctionBeginUser;
    PetscCall(PetscOptionsGetString(nullptr, nullptr, name.c_str(), old, sizeof(old), &had));
    s.name = name, s.old = old, s.had = had;
    saved_.push_back(s);
    PetscFunctionReturn(0);
  }
  std::vector<Saved> saved_;
};

// Integrates the scene's model from U (overwritten) with PETSc's classical RK4 at step dt for `steps`
// steps, calling record(step, t, U) at step 0 and every `every` steps.
using Recorder = std::function<PetscErrorCode(PetscInt, PetscReal, Vec)>;
struct IntegrateContext {
  Model *model;
  PetscInt every;
  const Recorder *record;
};
inline PetscErrorCode integrate_rhs(TS, PetscReal t, Vec U, Vec G, void *ctx) {
  return static_cast<IntegrateContext *>(ctx)->model->rhs(t, U, G);
}
inline PetscErrorCode integrate_monitor(TS, PetscInt step, PetscReal t, Vec U, void *ctx) {
  auto *c = static_cast<IntegrateContext *>(ctx);
  PetscFunctionBeginUser;
  if (step % c->every == 0) PetscCall((*c->record)(step, t, U));
  PetscFunctionReturn(0);
}
inline PetscErrorCode integrate(Scene &s, Vec U, PetscReal dt, PetscInt steps, PetscInt every, const Recorder &record) {
  OwnedTS ts;
  IntegrateContext ctx{s.model.get(), every, &record};
  PetscFunctionBeginUser;
  PetscCall(TSCreate(s.comm(), ts.out()));
  PetscCall(TSSetProblemType(ts, TS_NONLINEAR));
  PetscCall(TSSetType(ts, TSRK));
  PetscCall(TSRKSetType(ts, TSRK4));
  PetscCall(TSSetRHSFunction(ts, nullptr, integrate_rhs, &ctx));
  PetscCall(TSSetTimeStep(ts, dt));
  PetscCall(TSSetMaxSteps(ts, steps));
  PetscCall(TSSetMaxTime(ts, (steps + 0.5) * dt));
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_STEPOVER));
  PetscCall(TSMonitorSet(ts, integrate_monitor, &ctx, nullptr));
  PetscCall(TSSolve(ts, U));
  PetscFunctionReturn(0);
}

// Cell averages of a fine grid's state onto a coarse grid `refine` times coarser (every rank gathers
// the fine state: the reference grids here have a few thousand points at most).
class Averager {
public:
  PetscErrorCode setup(Vec fine, const Grid &coarse, PetscInt refine) {
    PetscFunctionBeginUser;
    PetscCall(VecScatterCreateToAll(fine, &scatter_, all_.out()));
    coarse_ = &coarse, refine_ = refine;
    PetscFunctionReturn(0);
  }
  ~Averager() { (void)VecScatterDestroy(&scatter_); }
  PetscErrorCode apply(Vec fine, Vec coarse) {
    PetscFunctionBeginUser;
    PetscCall(VecScatterBegin(scatter_, fine, all_, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterEnd(scatter_, fine, all_, INSERT_VALUES, SCATTER_FORWARD));
    ConstArray f(all_);
    Array c(coarse);
    PetscCall(f.error());
    PetscCall(c.error());
    for (PetscInt i = 0; i < coarse_->xm(); ++i) {
      const PetscInt gi = coarse_->xs() + i;
      PetscReal s = 0;
      for (PetscInt m = 0; m < refine_; ++m) s += PetscRealPart(f[gi * refine_ + m]);
      c[i] = s / refine_;
    }
    PetscFunctionReturn(0);
  }

private:
  VecScatter scatter_ = nullptr;
  OwnedVec all_;
  const Grid *coarse_ = nullptr;
  PetscInt refine_ = 1;
};

// The fine Burgers solution (-model burgers, `refine` times the cells of `coarse`, RK4 with the step
// s.dt scaled from s.n cells to the fine grid's, or a whole fraction of it where the viscous limit
// needs) from the random start `seed`, averaged onto `coarse` every `every_fine` of those scaled steps
// up to T: times and snapshots.
inline PetscErrorCode fine_reference(MPI_Comm comm, const Settings &s, PetscInt refine, PetscInt seed, PetscReal T,
                                     PetscInt every_fine, const Grid &coarse, std::vector<PetscReal> &times,
                                     std::vector<OwnedVec> &snapshots) {
  Scene fine;
  OwnedVec p, U;
  Averager avg;
  // The step of s.n cells scaled to the fine grid, divided further until the viscous term is stable
  // with RK4 (dt < 0.69 h^2 / nu; 0.5 taken).
  const PetscReal hf = 1.0 / (coarse.n() * refine);
  PetscReal dtf = s.dt * s.n * hf;
  const PetscInt split = s.nu > 0 ? std::max<PetscInt>(1, (PetscInt)std::ceil(dtf / (0.5 * hf * hf / s.nu))) : 1;
  dtf /= split;
  every_fine *= split;
  PetscFunctionBeginUser;
  {
    OptionScope o;
    PetscCall(o.cells(coarse.n() * refine));
    PetscCall(o.set("-model", "burgers"));
    PetscCall(o.set("-burgers_ic", "random"));
    PetscCall(o.set("-burgers_ic_seed", std::to_string(seed)));
    PetscCall(o.set("-burgers_ic_modes", std::to_string(s.modes)));
    PetscCall(o.set("-burgers_ic_amplitude", s.amplitude));
    PetscCall(o.set("-burgers_nu", s.nu));
    PetscCall(o.set("-burgers_nu_field", "0"));
    PetscCall(fine.setup(comm));
    PetscCall(fine.params.create_vec(p.out()));
    PetscCall(fine.parameters_from_options("", p)); // the values are read here, not at set-up
  }
  PetscCall(fine.sim.create_state(U.out()));
  PetscCall(fine.sim.initial_condition(p, U));
  PetscCall(avg.setup(U, coarse, refine));
  times.clear(), snapshots.clear();
  const PetscInt steps = (PetscInt)std::llround(T / dtf);
  PetscCall(integrate(fine, U, dtf, steps, every_fine, [&](PetscInt step, PetscReal, Vec Uf) -> PetscErrorCode {
    OwnedVec d;
    PetscFunctionBeginUser;
    PetscCall(DMCreateGlobalVector(coarse.dm(), d.out()));
    PetscCall(avg.apply(Uf, d));
    times.push_back(step * dtf); // exact multiples of the step (the TS's time carries round-off)
    snapshots.push_back(std::move(d));
    PetscFunctionReturn(0);
  }));
  PetscFunctionReturn(0);
}

// sqrt(h sum_i (a_i - b_i)^2): the L2 norm on [0, 1) of the difference.
inline PetscErrorCode l2_error(Vec a, Vec b, PetscReal *e) {
  OwnedVec d;
  PetscInt n;
  PetscReal nrm;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(a, d.out()));
  PetscCall(VecWAXPY(d, -1.0, b, a));
  PetscCall(VecNorm(d, NORM_2, &nrm));
  PetscCall(VecGetSize(a, &n));
  *e = nrm / std::sqrt((PetscReal)n);
  PetscFunctionReturn(0);
}

// A coarse learned_burgers scene on n cells, step dt to T, from the random start `seed`, averaged over `subsamples`
// points per cell (the fine grid's cells), with the options in `extra` in force during its set-up (an
// empty value removes the option).
inline PetscErrorCode coarse_scene(MPI_Comm comm, Scene &scene, PetscInt n, PetscReal dt, PetscReal T, PetscInt seed,
                                   PetscInt subsamples, const std::vector<std::pair<std::string, std::string>> &extra = {}) {
  OptionScope o;
  PetscFunctionBeginUser;
  PetscCall(o.cells(n));
  PetscCall(o.set("-model", "learned_burgers"));
  PetscCall(o.set("-learned_burgers_ic", "random"));
  PetscCall(o.set("-learned_burgers_ic_seed", std::to_string(seed)));
  PetscCall(o.set("-learned_burgers_ic_subsamples", std::to_string(subsamples)));
  for (auto &kv : extra) {
    if (kv.second.empty()) PetscCall(o.clear(kv.first));
    else PetscCall(o.set(kv.first, kv.second));
  }
  SceneDefaults d; // the step and horizon the Simulation takes unless -ts_dt, -ts_max_time say otherwise
  d.dt = dt, d.final_time = T;
  PetscCall(scene.setup(comm, d));
  PetscFunctionReturn(0);
}

} // namespace learned
