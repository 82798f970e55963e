// Inversion: TAO minimises J(p) + R(p) with the Simulation's exact discrete gradient.
//
// R is an optional regularisation of every field parameter, in 1D, 2D or 3D (forward differences D p,
// |Dp|^2 = (dp/dx)^2 + (dp/dy)^2 + (dp/dz)^2, the terms the grid has, sums times the cell volume):
//   Tikhonov  0.5 alpha sum |Dp|^2      (-inv_tikhonov alpha; 1D: 0.5 alpha sum_i (p_{i+1} - p_i)^2 / h)
//   smoothed total variation  beta sum sqrt(|Dp|^2 + eps^2)   (-inv_tv beta, -inv_tv_eps eps, default 1e-2)
// (both default 0);
// bounds lower <= p <= upper are given to TAO types that take them (-inv_lower, -inv_upper, the
// lower one never below the physical bound the model declares, e.g. -wave_c_min;
// BLMVM is the default -tao_type, LMVM and the rest of TAO via -tao_type). The history records
// per iteration the objective, the gradient norm and, when the true parameters are known, the
// parameter RMSE sqrt(mean((p - p_true)^2)). -inv_frtol r adds scipy L-BFGS-B's stop on a small relative
// decrease of the objective, (f_k - f_{k+1}) / max(|f_k|, |f_{k+1}|, 1) <= r, to TAO's own tests (which
// look at the gradient only). -inv_scan N (one scalar parameter) first evaluates J at
// N points between the bounds and polishes its best local minima (-inv_scan_starts, default 3),
// keeping the lowest objective: a terminal snapshot of a wave gives an objective with several
// nearly equal minima (cycle skipping), and a scan is the honest cure for one unknown.
//
// Frequency continuation (-inv_frequency_bands f1,f2,...,0; a survey's misfit): one TAO solve per band,
// each from the last one's result, with the data and the sources low-pass filtered at f_k (0: the
// whole band; Scene::set_frequency_band). Low frequencies first widen the basin of the misfit (cycle
// skipping needs a half-period error); each band then adds detail. The history runs on through the
// bands; the whole band is restored at the end.
//
// Restart: with a checkpoint file set (the driver uses its -output file), every iteration (every N with
// -inv_checkpoint_every N) rewrites it with /restart/p (the iterate), /restart/iteration and /history
// (written to <file>.part, then renamed, so an interrupted run leaves the last complete snapshot). -inv_restart <file> starts
// from that iterate and continues the history and the iteration count; the quasi-Newton memory
// starts afresh (TAO keeps no state in the file).
#pragma once
#include "flexipde/scene.hpp"
#include <string>
#include <vector>

namespace flexipde {

struct HistoryEntry {
  PetscInt iteration;
  PetscReal objective, misfit, gradient_norm, rmse;
};

class Inversion {
public:
  PetscErrorCode setup(Scene &scene, Vec p_true /* may be null */);
  PetscErrorCode solve(Vec p);
  const std::vector<HistoryEntry> &history() const { return history_; }
  PetscErrorCode rmse(Vec p, PetscReal *value) const;
  Tao tao() const { return tao_; }
  PetscInt evaluations() const { return evaluations_; }
  PetscReal scan_start() const { return scan_start_; }
  // Of the solve that produced the result (with -inv_scan: the winning start).
  TaoConvergedReason converged_reason() const { return reason_; }
  PetscInt iterations() const { return iterations_; }

  // Objective + regularisation and gradient; public for tests.
  PetscErrorCode evaluate(Vec p, PetscReal *f, Vec g);

private:
  static PetscErrorCode form_function_gradient(Tao, Vec, PetscReal *, Vec, void *);
  static PetscErrorCode monitor(Tao, void *);
  static PetscErrorCode convergence_test(Tao, void *);
  PetscErrorCode tikhonov(Vec p, PetscReal *R, Vec g);
  PetscErrorCode scan(Vec p, std::vector<PetscReal> &starts);
  PetscErrorCode resume(Vec p);

public:
  // Every iteration (every -inv_checkpoint_every) rewrites `file` with the restart snapshot (empty: off).
  void set_checkpoint_file(const std::string &file) { checkpoint_file_ = file; }
  // Writes /restart/p, /restart/iteration and /history into an open writer.
  PetscErrorCode write_restart(class H5Writer &w, Vec p) const;
  PetscInt iteration_offset() const { return iteration_offset_; }

private:
  PetscErrorCode write_checkpoint(Vec p) const;
  std::string checkpoint_file_, restart_file_;
  PetscInt iteration_offset_ = 0;
  PetscInt checkpoint_every_ = 1; // -inv_checkpoint_every

  Scene *scene_ = nullptr;
  OwnedTao tao_;
  OwnedVec p_true_, lower_, upper_, field_, field_local_, gfield_local_, gfield_;
  PetscReal tv_ = 0, tv_eps_ = 1e-2;
  PetscReal alpha_ = 0, lower_value_ = PETSC_NINFINITY, upper_value_ = PETSC_INFINITY, last_misfit_ = 0;
  PetscInt evaluations_ = 0, scan_ = 0, scan_starts_ = 3;
  PetscReal scan_start_ = 0;
  PetscReal frtol_ = 0, previous_f_ = PETSC_MAX_REAL; // -inv_frtol, and the last iteration's objective
  std::vector<PetscReal> bands_;                       // -inv_frequency_bands
  bool skip_first_ = false;                            // the resumed iterate is already in the history
  TaoConvergedReason reason_ = TAO_CONTINUE_ITERATING;
  PetscInt iterations_ = 0;
  std::vector<HistoryEntry> history_;
};

} // namespace flexipde
