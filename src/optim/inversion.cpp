#include "flexipde/inversion.hpp"
#include "flexipde/io.hpp"
#include <cstdio>
#include "flexipde/tao_adam.hpp"
#include <algorithm>
#include <cmath>

namespace flexipde {

PetscErrorCode Inversion::setup(Scene &scene, Vec p_true) {
  MPI_Comm comm = scene.comm();
  PetscBool has_lower = PETSC_FALSE, has_upper = PETSC_FALSE;
  PetscFunctionBeginUser;
  scene_ = &scene;
  PetscOptionsBegin(comm, nullptr, "Inversion", "Inversion");
  PetscCall(PetscOptionsReal("-inv_tikhonov", "Weight alpha of the smoothness term 0.5 alpha sum (dp)^2/h on fields",
                             "Inversion", alpha_, &alpha_, nullptr));
  PetscCall(PetscOptionsReal("-inv_tv", "Weight beta of the smoothed total variation beta sum sqrt(|Dp|^2 + eps^2) "
                             "(times the cell volume) on fields", "Inversion", tv_, &tv_, nullptr));
  PetscCall(PetscOptionsReal("-inv_tv_eps", "Smoothing eps of the total variation (units of the parameter's gradient)",
                             "Inversion", tv_eps_, &tv_eps_, nullptr));
  PetscCall(PetscOptionsReal("-inv_lower", "Lower bound on every parameter", "Inversion", lower_value_, &lower_value_,
                             &has_lower));
  PetscCall(PetscOptionsReal("-inv_upper", "Upper bound on every parameter", "Inversion", upper_value_, &upper_value_,
                             &has_upper));
  PetscCall(PetscOptionsInt("-inv_scan", "Scalar problems: evaluate J at N values evenly spaced between the bounds "
                            "and start from its best local minima (guards against cycle skipping; 0 = off)",
                            "Inversion", scan_, &scan_, nullptr));
  PetscCall(PetscOptionsInt("-inv_scan_starts", "With -inv_scan: number of scan minima polished by TAO; the lowest "
                            "objective wins", "Inversion", scan_starts_, &scan_starts_, nullptr));
  PetscCall(PetscOptionsInt("-inv_checkpoint_every", "With a results file (the driver's -output): rewrite its restart "
                            "snapshot every N iterations instead of every one (each snapshot writes an HDF5 file, which "
                            "can cost more than a fast scene's gradient)",
                            "Inversion", checkpoint_every_, &checkpoint_every_, nullptr));
  PetscCall(PetscOptionsReal("-inv_frtol", "Also stop (CONVERGED_USER) when an iteration lowers the objective by at most "
                             "this times max(|f_k|, |f_k+1|, 1), scipy L-BFGS-B's ftol (0: off)", "Inversion", frtol_,
                             &frtol_, nullptr));
  {
    PetscReal bands[64];
    PetscInt nb = 64;
    PetscBool set;
    PetscCall(PetscOptionsRealArray("-inv_frequency_bands", "Frequency continuation: one inversion per low-pass cutoff "
                                    "f1,f2,... of data and sources, increasing (0: the whole band, last)", "Inversion",
                                    bands, &nb, &set));
    if (set) bands_.assign(bands, bands + nb);
  }
  {
    char file[PETSC_MAX_PATH_LEN] = "";
    PetscBool set;
    PetscCall(PetscOptionsString("-inv_restart", "Resume from the last iterate and history in this HDF5 results file",
                                 "Inversion", file, file, sizeof(file), &set));
    restart_file_ = set ? file : "";
  }
  PetscOptionsEnd();
  PetscCheck(restart_file_.empty() || scan_ == 0, comm, PETSC_ERR_ARG_WRONG, "-inv_restart cannot be combined with -inv_scan");
  PetscCheck(scan_ >= 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-inv_scan must be non-negative");
  PetscCheck(bands_.empty() || (scan_ == 0 && restart_file_.empty()), comm, PETSC_ERR_ARG_WRONG,
             "-inv_frequency_bands cannot be combined with -inv_scan or -inv_restart");
  PetscCheck(bands_.empty() || scene.objective.survey(), comm, PETSC_ERR_ARG_WRONG,
             "-inv_frequency_bands needs a survey's data: -objective_type receivers");
  for (size_t k = 0; k < bands_.size(); ++k) {
    const bool whole = bands_[k] == 0, last = k + 1 == bands_.size();
    PetscCheck(bands_[k] >= 0 && (!whole || last) && (whole || k == 0 || bands_[k] > bands_[k - 1]), comm,
               PETSC_ERR_ARG_OUTOFRANGE,
               "-inv_frequency_bands: give increasing positive cutoffs, optionally ending with 0 (the whole band); entry %zu is %g",
               k + 1, (double)bands_[k]);
  }
  PetscCheck(scan_ == 0 || (scene.params.global_size() == 1 && has_lower && has_upper), comm, PETSC_ERR_ARG_WRONG,
             "-inv_scan needs a single scalar parameter and both -inv_lower and -inv_upper");
  PetscCheck(tv_ >= 0 && tv_eps_ > 0, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "-inv_tv must be non-negative and -inv_tv_eps positive, got %g and %g", (double)tv_, (double)tv_eps_);
  PetscCheck(alpha_ >= 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-inv_tikhonov must be non-negative, got %g", (double)alpha_);
  PetscCheck(checkpoint_every_ >= 1, comm, PETSC_ERR_ARG_OUTOFRANGE, "-inv_checkpoint_every must be positive, got %" PetscInt_FMT,
             checkpoint_every_);
  PetscCheck(frtol_ >= 0, comm, PETSC_ERR_ARG_OUTOFRANGE, "-inv_frtol must be non-negative, got %g", (double)frtol_);
  PetscCheck(lower_value_ < upper_value_, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "Inverted bounds: -inv_lower %g is not below -inv_upper %g", (double)lower_value_, (double)upper_value_);
  if (p_true) {
    PetscCall(VecDuplicate(p_true, p_true_.out()));
    PetscCall(VecCopy(p_true, p_true_));
  }
  PetscCall(DMCreateGlobalVector(scene.grid.dm(), field_.out()));
  PetscCall(DMCreateGlobalVector(scene.grid.dm(), gfield_.out()));
  PetscCall(DMCreateLocalVector(scene.grid.dm(), field_local_.out()));
  PetscCall(DMCreateLocalVector(scene.grid.dm(), gfield_local_.out()));

  PetscCall(register_tao_adam()); // -tao_type adam
  PetscCall(TaoCreate(comm, tao_.out()));
  PetscCall(TaoSetType(tao_, TAOBLMVM));
  PetscCall(TaoSetObjectiveAndGradient(tao_, nullptr, form_function_gradient, this));
  PetscCall(scene.params.create_vec(lower_.out()));
  PetscCall(VecDuplicate(lower_, upper_.out()));
  PetscCall(VecSet(upper_, upper_value_));
  { // the user's bound, raised to the physical bound each model declares for its parameters
    Array lo(lower_);
    PetscCall(lo.error());
    for (PetscInt k = 0; k < scene.params.count(); ++k) {
      const ParamInfo &pi = scene.params.info(k);
      for (PetscInt i = 0; i < pi.local_size; ++i) lo[pi.local_offset + i] = PetscMax(lower_value_, pi.lower);
    }
  }
  PetscCall(TaoSetVariableBounds(tao_, lower_, upper_));
  PetscCall(TaoSetMonitor(tao_, monitor, this, nullptr));
  PetscCall(TaoSetConvergenceTest(tao_, convergence_test, this));
  PetscCall(TaoSetFromOptions(tao_));
  PetscFunctionReturn(0);
}

PetscErrorCode Inversion::rmse(Vec p, PetscReal *value) const {
  OwnedVec d;
  PetscReal nrm;
  PetscInt n;
  PetscFunctionBeginUser;
  *value = -1;
  if (!p_true_) PetscFunctionReturn(0);
  PetscCall(VecDuplicate(p, d.out()));
  PetscCall(VecWAXPY(d, -1.0, p_true_, p));
  PetscCall(VecNorm(d, NORM_2, &nrm));
  PetscCall(VecGetSize(d, &n));
  *value = nrm / std::sqrt((PetscReal)n);
  PetscFunctionReturn(0);
}

// Tikhonov and smoothed total variation of every field, with forward differences on the grid
// (1D, 2D or 3D; a periodic direction wraps, a Dirichlet one has no difference past its last point):
//   R = sum_points [ 0.5 alpha |D p|^2 + beta sqrt(|D p|^2 + eps^2) ] * cell volume,
//   |D p|^2 = ((p_{i+1,j,k} - p_{ijk}) / hx)^2 + ((p_{i,j+1,k} - p_{ijk}) / hy)^2 + ((p_{i,j,k+1} - p_{ijk}) / hz)^2
//   (no y term in 1D, no z term below 3D).
// In 1D the Tikhonov part is the seed's 0.5 alpha sum (p_{i+1} - p_i)^2 / h.
PetscErrorCode Inversion::tikhonov(Vec p, PetscReal *R, Vec g) {
  const Grid &grid = scene_->grid;
  const Parameters &params = scene_->params;
  PetscReal local = 0;
  PetscFunctionBeginUser;
  *R = 0;
  if (alpha_ == 0 && tv_ == 0) PetscFunctionReturn(0);
  const bool has_dy = grid.dim() >= 2, has_dz = grid.dim() == 3;
  const PetscReal hx = grid.h(), hy = grid.hy(), hz = grid.hz(), vol = grid.cell_volume();
  for (PetscInt k = 0; k < params.count(); ++k) {
    if (params.info(k).kind != ParamKind::Field) continue;
    PetscCall(params.get_field(p, k, field_));
    PetscCall(DMGlobalToLocal(grid.dm(), field_, INSERT_VALUES, field_local_));
    PetscCall(VecSet(gfield_local_, 0.0));
    // local (ghosted) arrays indexed by (i, j, k) in the DMDA's ghost box (gzs = 0, gzm = 1 below 3D,
    // gys = 0, gym = 1 in 1D)
    PetscInt gxs, gys, gzs, gxm, gym, gzm;
    PetscCall(DMDAGetGhostCorners(grid.dm(), &gxs, &gys, &gzs, &gxm, &gym, &gzm));
    {
      ConstArray f(field_local_);
      Array gf(gfield_local_);
      PetscCall(f.error());
      PetscCall(gf.error());
      auto at = [&](PetscInt i, PetscInt j, PetscInt k) { return ((k - gzs) * gym + (j - gys)) * gxm + (i - gxs); };
      for (PetscInt k = grid.zs(); k < grid.zs() + grid.zm(); ++k)
        for (PetscInt j = grid.ys(); j < grid.ys() + grid.ym(); ++j)
          for (PetscInt i = grid.xs(); i < grid.xs() + grid.xm(); ++i) {
            const bool has_x = grid.periodic() || i < grid.n() - 1;
            const bool has_y = has_dy && (grid.periodic_y() || j < grid.ny() - 1);
            const bool has_z = has_dz && (grid.periodic_z() || k < grid.nz() - 1);
            if (!has_x && !has_y && !has_z) continue; // the last corner: no difference at all
            const PetscInt c = at(i, j, k), cx = at(i + 1, j, k), cy = has_dy ? at(i, j + 1, k) : 0,
                           cz = has_dz ? at(i, j, k + 1) : 0;
            const PetscReal dx = has_x ? PetscRealPart(f[cx] - f[c]) / hx : 0.0;
            const PetscReal dy = has_y ? PetscRealPart(f[cy] - f[c]) / hy : 0.0;
            const PetscReal dz = has_z ? PetscRealPart(f[cz] - f[c]) / hz : 0.0;
            // below 3D no z term at all, so that the sum is the 1D and 2D one to the bit
            const PetscReal s2 = has_dz ? dx * dx + dy * dy + dz * dz : dx * dx + dy * dy;
            PetscReal w = alpha_; // dR/d(dx) = w dx vol, the same for dy and dz
            local += 0.5 * alpha_ * s2 * vol;
            if (tv_ > 0) {
              const PetscReal root = std::sqrt(s2 + tv_eps_ * tv_eps_);
              local += tv_ * root * vol;
              w += tv_ / root;
            }
            if (has_x) {
              gf[c] -= w * dx * vol / hx;
              gf[cx] += w * dx * vol / hx;
            }
            if (has_y) {
              gf[c] -= w * dy * vol / hy;
              gf[cy] += w * dy * vol / hy;
            }
            if (has_z) {
              gf[c] -= w * dz * vol / hz;
              gf[cz] += w * dz * vol / hz;
            }
          }
    }
    PetscCall(VecSet(gfield_, 0.0));
    PetscCall(DMLocalToGlobal(grid.dm(), gfield_local_, ADD_VALUES, gfield_));
    // g += gfield on field k
    PetscCall(params.get_field(g, k, field_));
    PetscCall(VecAXPY(field_, 1.0, gfield_));
    PetscCall(params.set_field(g, k, field_));
  }
  PetscCallMPI(MPI_Allreduce(&local, R, 1, MPIU_REAL, MPI_SUM, grid.comm()));
  PetscFunctionReturn(0);
}

PetscErrorCode Inversion::evaluate(Vec p, PetscReal *f, Vec g) {
  PetscReal J, R;
  PetscFunctionBeginUser;
  PetscCall(scene_->gradient(p, &J, g));
  PetscCall(tikhonov(p, &R, g));
  last_misfit_ = J;
  *f = J + R;
  ++evaluations_;
  PetscFunctionReturn(0);
}

PetscErrorCode Inversion::form_function_gradient(Tao, Vec p, PetscReal *f, Vec g, void *ctx) {
  PetscFunctionBeginUser;
  PetscCall(static_cast<Inversion *>(ctx)->evaluate(p, f, g));
  PetscFunctionReturn(0);
}

PetscErrorCode Inversion::monitor(Tao tao, void *ctx) {
  auto *inv = static_cast<Inversion *>(ctx);
  PetscInt it;
  PetscReal f, gnorm, cnorm, xdiff, e;
  TaoConvergedReason reason;
  Vec x;
  PetscFunctionBeginUser;
  PetscCall(TaoGetSolutionStatus(tao, &it, &f, &gnorm, &cnorm, &xdiff, &reason));
  PetscCall(TaoGetSolution(tao, &x));
  PetscCall(inv->rmse(x, &e));
  if (inv->skip_first_ && it == 0) { // the resumed iterate is already recorded
    inv->skip_first_ = false;
    PetscFunctionReturn(0);
  }
  inv->history_.push_back({it + inv->iteration_offset_, f, inv->last_misfit_, gnorm, e});
  if (!inv->checkpoint_file_.empty() && (it + inv->iteration_offset_) % inv->checkpoint_every_ == 0)
    PetscCall(inv->write_checkpoint(x));
  PetscFunctionReturn(0);
}

// TAO's own tests, then (-inv_frtol) scipy L-BFGS-B's relative reduction of the objective between two
// iterations, (f_k - f_{k+1}) / max(|f_k|, |f_{k+1}|, 1) <= frtol.
PetscErrorCode Inversion::convergence_test(Tao tao, void *ctx) {
  auto *inv = static_cast<Inversion *>(ctx);
  PetscInt it;
  PetscReal f;
  TaoConvergedReason reason;
  PetscFunctionBeginUser;
  PetscCall(TaoDefaultConvergenceTest(tao, nullptr));
  PetscCall(TaoGetSolutionStatus(tao, &it, &f, nullptr, nullptr, nullptr, &reason));
  if (it == 0) inv->previous_f_ = PETSC_MAX_REAL;
  if (reason == TAO_CONTINUE_ITERATING && inv->frtol_ > 0 && it > 0 &&
      inv->previous_f_ - f <= inv->frtol_ * PetscMax(PetscMax(PetscAbsReal(inv->previous_f_), PetscAbsReal(f)), 1.0))
    PetscCall(TaoSetConvergedReason(tao, TAO_CONVERGED_USER));
  inv->previous_f_ = f;
  PetscFunctionReturn(0);
}

// J at scan_ evenly spaced values of the single scalar parameter; returns the values at the local
// minima of the scan, best first.
PetscErrorCode Inversion::scan(Vec p, std::vector<PetscReal> &starts) {
  const Parameters &params = scene_->params;
  std::vector<PetscReal> v(scan_), J(scan_);
  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < scan_; ++k) {
    v[k] = lower_value_ + (upper_value_ - lower_value_) * (k + 0.5) / scan_;
    PetscCall(params.set_scalar(p, 0, v[k]));
    PetscCall(scene_->value(p, &J[k])); // no adjoint; includes a time integral, if any
  }
  std::vector<PetscInt> minima;
  for (PetscInt k = 0; k < scan_; ++k)
    if ((k == 0 || J[k] <= J[k - 1]) && (k == scan_ - 1 || J[k] <= J[k + 1])) minima.push_back(k);
  std::sort(minima.begin(), minima.end(), [&](PetscInt a, PetscInt b) { return J[a] < J[b]; });
  starts.clear();
  for (PetscInt k : minima) starts.push_back(v[k]);
  PetscFunctionReturn(0);
}

PetscErrorCode Inversion::write_restart(H5Writer &w, Vec p) const {
  std::vector<PetscReal> it, f, mis, gn, rm;
  PetscFunctionBeginUser;
  for (const HistoryEntry &h : history_) {
    it.push_back(h.iteration);
    f.push_back(h.objective);
    mis.push_back(h.misfit);
    gn.push_back(h.gradient_norm);
    rm.push_back(h.rmse);
  }
  PetscCall(w.write_vec("/restart", "p", p));
  PetscCall(w.write_series("/restart", "iteration", std::vector<PetscReal>{it.empty() ? 0.0 : it.back()}));
  PetscCall(w.write_series("/history", "iteration", it));
  PetscCall(w.write_series("/history", "objective", f));
  PetscCall(w.write_series("/history", "misfit", mis));
  PetscCall(w.write_series("/history", "gradient_norm", gn));
  PetscCall(w.write_series("/history", "rmse", rm));
  PetscFunctionReturn(0);
}

// The snapshot goes to <file>.part first and is renamed once complete: a run killed while writing
// keeps the previous snapshot.
PetscErrorCode Inversion::write_checkpoint(Vec p) const {
  MPI_Comm comm = scene_->comm();
  PetscMPIInt rank;
  H5Writer w;
  PetscFunctionBeginUser;
  const std::string part = checkpoint_file_ + ".part";
  PetscCall(w.open(comm, part));
  PetscCall(write_restart(w, p));
  PetscCall(w.close());
  PetscCallMPI(MPI_Barrier(comm));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  int err = 0;
  if (rank == 0) err = std::rename(part.c_str(), checkpoint_file_.c_str());
  PetscCallMPI(MPI_Bcast(&err, 1, MPI_INT, 0, comm));
  PetscCheck(!err, comm, PETSC_ERR_FILE_WRITE, "Cannot rename %s to %s", part.c_str(), checkpoint_file_.c_str());
  PetscFunctionReturn(0);
}

PetscErrorCode Inversion::resume(Vec p) {
  MPI_Comm comm = scene_->comm();
  H5Reader r;
  std::vector<PetscReal> it, f, mis, gn, rm, last;
  PetscInt n;
  PetscFunctionBeginUser;
  PetscCall(r.open(comm, restart_file_));
  PetscCall(VecGetSize(p, &n));
  PetscCall(r.read_series("/restart", "iteration", last));
  PetscCall(r.read_vec("/restart", "p", p)); // checks the number of parameters
  PetscCall(r.read_series("/history", "iteration", it));
  PetscCall(r.read_series("/history", "objective", f));
  PetscCall(r.read_series("/history", "misfit", mis));
  PetscCall(r.read_series("/history", "gradient_norm", gn));
  PetscCall(r.read_series("/history", "rmse", rm));
  PetscCall(r.close());
  PetscCheck(it.size() == f.size() && f.size() == mis.size() && mis.size() == gn.size() && gn.size() == rm.size(), comm,
             PETSC_ERR_FILE_UNEXPECTED, "%s: the /history series have different lengths", restart_file_.c_str());
  PetscReal pmin, pmax;
  PetscCall(VecMin(p, nullptr, &pmin));
  PetscCall(VecMax(p, nullptr, &pmax));
  PetscCheck(std::isfinite((double)pmin) && std::isfinite((double)pmax), comm, PETSC_ERR_FILE_UNEXPECTED,
             "%s: /restart/p holds NaN/Inf", restart_file_.c_str());
  for (size_t k = 0; k < it.size(); ++k) history_.push_back({(PetscInt)it[k], f[k], mis[k], gn[k], rm[k]});
  iteration_offset_ = last.empty() ? 0 : (PetscInt)last[0];
  skip_first_ = iteration_offset_ > 0;
  PetscCall(PetscPrintf(comm, "invert: resuming from iteration %" PetscInt_FMT " of %s (%" PetscInt_FMT " parameters)\n",
                        iteration_offset_, restart_file_.c_str(), n));
  PetscFunctionReturn(0);
}

PetscErrorCode Inversion::solve(Vec p) {
  PetscFunctionBeginUser;
  history_.clear();
  iteration_offset_ = 0;
  if (!restart_file_.empty()) PetscCall(resume(p));
  if (!bands_.empty()) {
    MPI_Comm comm = scene_->comm();
    iterations_ = 0;
    for (size_t k = 0; k < bands_.size(); ++k) {
      PetscInt its;
      PetscReal f;
      PetscCall(scene_->set_frequency_band(bands_[k]));
      iteration_offset_ = history_.empty() ? 0 : history_.back().iteration + 1;
      PetscCall(TaoSetSolution(tao_, p));
      PetscCall(TaoSolve(tao_));
      PetscCall(TaoGetConvergedReason(tao_, &reason_));
      PetscCall(TaoGetSolutionStatus(tao_, &its, &f, nullptr, nullptr, nullptr, nullptr));
      iterations_ += its;
      PetscReal e = 0;
      PetscCall(rmse(p, &e));
      if (bands_[k] > 0)
        PetscCall(PetscPrintf(comm, "invert: band %zu, frequencies up to %g: %s after %" PetscInt_FMT " iterations, objective %.6e, parameter RMSE %.6e\n",
                              k + 1, (double)bands_[k], TaoConvergedReasons[reason_], its, (double)f, (double)e));
      else
        PetscCall(PetscPrintf(comm, "invert: band %zu, the whole band: %s after %" PetscInt_FMT " iterations, objective %.6e, parameter RMSE %.6e\n",
                              k + 1, TaoConvergedReasons[reason_], its, (double)f, (double)e));
    }
    PetscCall(scene_->set_frequency_band(0));
    PetscFunctionReturn(0);
  }
  if (scan_ == 0) {
    PetscCall(TaoSetSolution(tao_, p));
    PetscCall(TaoSolve(tao_));
    PetscCall(TaoGetConvergedReason(tao_, &reason_));
    PetscCall(TaoGetIterationNumber(tao_, &iterations_));
    iterations_ += iteration_offset_;
    PetscFunctionReturn(0);
  }
  // Polish the best few minima of the scan and keep the lowest objective: snapshot misfits of waves
  // have several nearly equal minima (cycle skipping), which a single start cannot tell apart.
  std::vector<PetscReal> starts;
  PetscCall(scan(p, starts));
  OwnedVec best;
  PetscReal fbest = PETSC_MAX_REAL;
  std::vector<HistoryEntry> best_history;
  const size_t n = std::min<size_t>(starts.size(), (size_t)scan_starts_);
  for (size_t k = 0; k < n; ++k) {
    PetscReal f;
    history_.clear();
    PetscCall(scene_->params.set_scalar(p, 0, starts[k]));
    PetscCall(TaoSetSolution(tao_, p));
    PetscCall(TaoSolve(tao_));
    PetscCall(TaoGetSolutionStatus(tao_, nullptr, &f, nullptr, nullptr, nullptr, nullptr));
    PetscCall(PetscInfo(tao_.get(), "scan start %g -> objective %g\n", (double)starts[k], (double)f));
    if (f < fbest) {
      fbest = f;
      best_history = history_;
      if (!best) PetscCall(VecDuplicate(p, best.out()));
      PetscCall(VecCopy(p, best));
      scan_start_ = starts[k];
      PetscCall(TaoGetConvergedReason(tao_, &reason_));
      PetscCall(TaoGetIterationNumber(tao_, &iterations_));
    }
  }
  PetscCall(VecCopy(best, p));
  history_ = best_history;
  PetscFunctionReturn(0);
}

} // namespace flexipde
