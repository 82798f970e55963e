// Evaluating a learned Burgers flux on starts it was not trained on, against classical schemes.
//
// The reference is -model burgers on -eval_reference_cells cells (step scaled with h, RK4), averaged
// onto each coarse grid. On the training grid (-da_grid_x, -ts_dt) the learned scheme (this scene's own
// -learned_burgers_* options, e.g. -learned_burgers_theta_file from learned_burgers_train) and the
// classical face reconstructions of the same flux form run from the held-out starts -eval_seeds to
// -eval_final_time:
//   eo        first-order Engquist-Osher (weights 0, 0, 0: the scheme of -model burgers)
//   centred   second-order centred       (0, 1/2, 0)
//   upwind2   second-order upwind        (-1/2, 0, 0)
//   kappa3    third-order upwind-biased  (-1/6, 1/3, 0: the untrained start of the learned weights)
// The L2 error against the reference (sqrt(h sum (u - ubar)^2)) is sampled every -eval_sample_every, its
// RMS over the seeds written per scheme. The classical schemes also run on the grids -eval_resolutions
// (step scaled with h) for a work-precision diagram: space-time RMS error against the median wall time
// of -eval_repeats solves. Also checked: the learned scheme keeps a constant state (consistency) and
// sum_i u_i (conservation).
//
//   ./learned_burgers_evaluate -learned_burgers_weights network -learned_burgers_theta_file results/lb_net.h5
//           -output results/lb_eval.h5
//   mpiexec -n 2 ./learned_burgers_evaluate -learned_burgers_theta_file results/lb_const.h5 -eval_seeds 201
//           -eval_resolutions 32,64 -output results/lb_eval_const.h5
//   ./learned_burgers_evaluate -help
// Unseen amplitudes: add -learned_burgers_ic_amplitude 1.5 (reference and coarse starts alike).
#include "flexipde/io.hpp"
#include "learned_burgers_common.hpp"
#include <algorithm>
#include <map>

using namespace flexipde;
using namespace learned;

static const char help[] = "Errors of a learned Burgers flux on unseen starts, against classical schemes.\n";

struct Scheme {
  std::string name;
  std::vector<PetscReal> theta; // constant weights; empty: the scene's own options (the learned scheme)
};

// Every rank's copy of a distributed Vec.
static PetscErrorCode replicate(Vec v, std::vector<PetscReal> &out) {
  VecScatter sc;
  OwnedVec all;
  PetscInt n;
  PetscFunctionBeginUser;
  PetscCall(VecScatterCreateToAll(v, &sc, all.out()));
  PetscCall(VecScatterBegin(sc, v, all, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(sc, v, all, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterDestroy(&sc));
  PetscCall(VecGetSize(all, &n));
  const PetscScalar *a;
  PetscCall(VecGetArrayRead(all, &a));
  out.assign(n, 0.0);
  for (PetscInt i = 0; i < n; ++i) out[i] = PetscRealPart(a[i]);
  PetscCall(VecRestoreArrayRead(all, &a));
  PetscFunctionReturn(0);
}

// The learned scheme's consistency (G of a constant state) and conservation (sum u over a run).
static PetscErrorCode check_invariants(Scene &s, Vec p, PetscReal dt, PetscInt steps) {
  OwnedVec U, G;
  PetscReal gmax, m0, m1, umax;
  PetscFunctionBeginUser;
  PetscCall(s.sim.create_state(U.out()));
  PetscCall(VecDuplicate(U, G.out()));
  PetscCall(s.model->set_parameters(p));
  PetscCall(VecSet(U, 0.7));
  PetscCall(s.model->rhs(0, U, G));
  PetscCall(VecNorm(G, NORM_INFINITY, &gmax));
  PetscCall(s.sim.initial_condition(p, U));
  PetscCall(VecSum(U, &m0));
  PetscCall(VecNorm(U, NORM_INFINITY, &umax));
  PetscCall(integrate(s, U, dt, steps, steps + 1, [](PetscInt, PetscReal, Vec) { return PetscErrorCode(0); }));
  PetscCall(VecSum(U, &m1));
  const PetscReal h = 1.0 / s.grid.n();
  PetscCall(PetscPrintf(s.comm(), "consistency: max |G(u = 0.7 everywhere)| = %.3e; conservation: |h sum u(T) - h sum u(0)| = %.3e (max |u0| %.3f)\n",
                        (double)gmax, (double)(h * PetscAbsReal(m1 - m0)), (double)umax));
  PetscFunctionReturn(0);
}

static PetscErrorCode run(MPI_Comm comm) {
  Settings s;
  PetscInt nseeds = 16, seeds[16] = {101, 102, 103}, nres = 16, res[16] = {32, 64, 128, 256}, ref_cells = 1024, repeats = 3;
  PetscReal T = 1.0, sample = 0.05;
  char output[PETSC_MAX_PATH_LEN] = "learned_burgers_eval.h5";
  PetscBool seeds_set = PETSC_FALSE, res_set = PETSC_FALSE;
  PetscFunctionBeginUser;
  // 1. Options
  PetscOptionsBegin(comm, nullptr, "Evaluating a learned Burgers flux", "learned_burgers_evaluate");
  PetscCall(PetscOptionsIntArray("-eval_seeds", "Held-out random starts (seeds)", "", seeds, &nseeds, &seeds_set));
  PetscCall(PetscOptionsReal("-eval_final_time", "Horizon of the evaluation", "", T, &T, nullptr));
  PetscCall(PetscOptionsReal("-eval_sample_every", "Time between error samples", "", sample, &sample, nullptr));
  PetscCall(PetscOptionsInt("-eval_reference_cells", "Cells of the reference grid", "", ref_cells, &ref_cells, nullptr));
  PetscCall(PetscOptionsIntArray("-eval_resolutions", "Grids of the classical schemes' work-precision runs", "", res, &nres, &res_set));
  PetscCall(PetscOptionsInt("-eval_repeats", "Timed solves per scheme and grid (median)", "", repeats, &repeats, nullptr));
  PetscCall(PetscOptionsString("-output", "HDF5 file for the errors and snapshots", "", output, output, sizeof(output), nullptr));
  PetscOptionsEnd();
  if (!seeds_set) nseeds = 3;
  if (!res_set) nres = 4;
  PetscCall(s.from_options(comm));
  PetscCheck(nseeds > 0 && nres > 0, comm, PETSC_ERR_ARG_WRONG, "-eval_seeds and -eval_resolutions need at least one value");
  PetscCheck(T > 0 && sample > 0 && repeats > 0, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "-eval_final_time, -eval_sample_every and -eval_repeats must be positive");
  std::vector<PetscInt> grids(res, res + nres);
  if (std::find(grids.begin(), grids.end(), s.n) == grids.end()) grids.insert(grids.begin(), s.n);
  for (PetscInt N : grids) {
    PetscCheck(ref_cells % N == 0 && ref_cells / N >= 2, comm, PETSC_ERR_ARG_WRONG,
               "-eval_reference_cells %" PetscInt_FMT " must be a multiple of every grid (at least twice it), not of %" PetscInt_FMT,
               ref_cells, N);
    const PetscReal dtN = s.dt * s.n / N, per = sample / dtN;
    PetscCheck(std::fabs(per - std::round(per)) < 1e-9 && std::fabs(T / sample - std::round(T / sample)) < 1e-9, comm,
               PETSC_ERR_ARG_WRONG, "-eval_sample_every %g must be a whole number of steps (%g on %" PetscInt_FMT " cells) and divide -eval_final_time",
               (double)sample, (double)dtN, N);
  }
  PetscBool help = PETSC_FALSE;
  PetscCall(PetscOptionsHasHelp(nullptr, &help));
  if (help) { // the learned scene's options too, then stop
    Scene scene;
    OwnedVec p;
    PetscCall(coarse_scene(comm, scene, s.n, s.dt, T, seeds[0], ref_cells / s.n));
    PetscCall(scene.params.create_vec(p.out()));
    PetscCall(scene.parameters_from_options("", p));
    PetscFunctionReturn(0);
  }
  const std::vector<Scheme> classical = {
      {"eo", {0, 0, 0}}, {"centred", {0, 0.5, 0}}, {"upwind2", {-0.5, 0, 0}}, {"kappa3", {-1.0 / 6, 1.0 / 3, 0}}};
  const PetscInt samples = (PetscInt)std::llround(T / sample) + 1;
  std::map<std::string, std::vector<PetscReal>> err2;       // sum over seeds of error^2 per sample, training grid
  std::map<std::string, std::vector<PetscReal>> wp_err, wp_time, wp_cells; // work-precision
  std::map<std::string, std::vector<PetscReal>> snaps;       // first seed, training grid: samples x n
  std::vector<PetscReal> snapshot_times;

  // 2. For each grid: the reference, then every scheme that runs there, from every held-out start
  for (PetscInt N : grids) {
    const PetscReal dtN = s.dt * s.n / N;
    const PetscInt steps = (PetscInt)std::llround(T / dtN), every = (PetscInt)std::llround(sample / dtN);
    std::vector<Scheme> schemes = classical;
    if (N == s.n) schemes.insert(schemes.begin(), Scheme{"learned", {}});
    std::map<std::string, PetscReal> st_err2, seconds;
    for (PetscInt q = 0; q < nseeds; ++q) {
      std::vector<PetscReal> times;
      std::vector<OwnedVec> ref;
      for (const Scheme &sc : schemes) {
        Scene scene;
        std::vector<std::pair<std::string, std::string>> extra;
        if (!sc.theta.empty()) extra = {{"-learned_burgers_weights", "constant"}};
        PetscCall(coarse_scene(comm, scene, N, dtN, T, seeds[q], ref_cells / N, extra));
        if (ref.empty()) {
          const PetscReal dtf = dtN * N / ref_cells;
          PetscCall(fine_reference(comm, s, ref_cells / N, seeds[q], T, (PetscInt)std::llround(sample / dtf), scene.grid, times, ref));
          PetscCheck((PetscInt)ref.size() == samples, comm, PETSC_ERR_PLIB, "reference has %zu samples, expected %" PetscInt_FMT,
                     ref.size(), samples);
          if (N == s.n && q == 0) {
            std::vector<PetscReal> all, rows;
            for (auto &r : ref) {
              PetscCall(replicate(r, rows));
              all.insert(all.end(), rows.begin(), rows.end());
            }
            snaps["reference"] = all;
            snapshot_times = times;
          }
        }
        OwnedVec p, U;
        PetscCall(scene.params.create_vec(p.out()));
        if (sc.theta.empty()) PetscCall(scene.parameters_from_options("", p));
        else PetscCall(scene.params.set_vector(p, scene.params.find("learned_burgers_theta"), sc.theta));
        PetscCall(scene.sim.create_state(U.out()));
        if (sc.name == "learned" && q == 0) PetscCall(check_invariants(scene, p, dtN, steps));
        PetscCall(scene.sim.initial_condition(p, U));
        auto &e2 = err2[sc.name];
        if (N == s.n && e2.empty()) e2.assign(samples, 0.0);
        std::vector<PetscReal> all, rows;
        PetscCall(integrate(scene, U, dtN, steps, every, [&](PetscInt step, PetscReal, Vec Uc) -> PetscErrorCode {
          PetscReal e;
          const PetscInt k = step / every;
          PetscFunctionBeginUser;
          PetscCall(l2_error(Uc, ref[k], &e));
          st_err2[sc.name] += e * e / (nseeds * samples);
          if (N == s.n) e2[k] += e * e / nseeds;
          if (N == s.n && q == 0) {
            PetscCall(replicate(Uc, rows));
            all.insert(all.end(), rows.begin(), rows.end());
          }
          PetscFunctionReturn(0);
        }));
        if (N == s.n && q == 0) snaps[sc.name] = all;
        if (q == 0) { // the cost: median wall time of whole solves without any sampling
          std::vector<double> t;
          for (PetscInt r = 0; r < repeats; ++r) {
            PetscCall(scene.sim.initial_condition(p, U));
            PetscCallMPI(MPI_Barrier(comm));
            const double t0 = MPI_Wtime();
            PetscCall(integrate(scene, U, dtN, steps, steps + 1, [](PetscInt, PetscReal, Vec) { return PetscErrorCode(0); }));
            PetscCallMPI(MPI_Barrier(comm));
            t.push_back(MPI_Wtime() - t0);
          }
          std::sort(t.begin(), t.end());
          seconds[sc.name] = t[t.size() / 2];
        }
      }
    }
    for (const Scheme &sc : schemes) {
      const PetscReal e = std::sqrt(st_err2[sc.name]);
      wp_err[sc.name].push_back(e), wp_time[sc.name].push_back(seconds[sc.name]), wp_cells[sc.name].push_back(N);
      PetscCall(PetscPrintf(comm, "%4" PetscInt_FMT " cells  %-8s space-time RMS error %.4e  solve %.4f s\n", N, sc.name.c_str(),
                            (double)e, seconds[sc.name]));
    }
  }

  // 3. The verdict on the training grid: the learned weights against their untrained start (kappa3, the
  //    default weights), error over time, and the results file
  {
    const PetscReal el = wp_err["learned"].front(), eu = wp_err["kappa3"].front();
    PetscCall(PetscPrintf(comm, "held-out starts on %" PetscInt_FMT " cells: learned %.4e, untrained start (kappa3) %.4e, ratio %.3f\n", s.n,
                          (double)el, (double)eu, (double)(el / eu)));
  }
  // Error over time on the training grid, and the results file
  PetscCall(PetscPrintf(comm, "error over time on %" PetscInt_FMT " cells (RMS over %" PetscInt_FMT " held-out starts):\n%8s", s.n, nseeds, "t"));
  for (auto &kv : err2) PetscCall(PetscPrintf(comm, " %10s", kv.first.c_str()));
  PetscCall(PetscPrintf(comm, "\n"));
  for (PetscInt k = 0; k < samples; k += std::max<PetscInt>(1, (samples - 1) / 10)) {
    PetscCall(PetscPrintf(comm, "%8.3f", (double)(k * sample)));
    for (auto &kv : err2) PetscCall(PetscPrintf(comm, " %10.3e", (double)std::sqrt(kv.second[k])));
    PetscCall(PetscPrintf(comm, "\n"));
  }
  if (output[0]) { // written at the end: an error on the way leaves no half-written file
    H5Writer w;
    PetscCall(w.open(comm, output));
    PetscCall(w.write_series("/snapshots", "time", snapshot_times));
    std::vector<PetscReal> tk;
    for (PetscInt k = 0; k < samples; ++k) tk.push_back(k * sample);
    PetscCall(w.write_series("/error", "time", tk));
    for (auto &kv : err2) {
      std::vector<PetscReal> e;
      for (PetscReal x : kv.second) e.push_back(std::sqrt(x));
      PetscCall(w.write_series("/error", kv.first.c_str(), e));
    }
    for (auto &kv : wp_err) {
      PetscCall(w.write_series("/work_precision", (kv.first + "_error").c_str(), kv.second));
      PetscCall(w.write_series("/work_precision", (kv.first + "_seconds").c_str(), wp_time[kv.first]));
      PetscCall(w.write_series("/work_precision", (kv.first + "_cells").c_str(), wp_cells[kv.first]));
    }
    for (auto &kv : snaps) PetscCall(w.write_series("/snapshots", kv.first.c_str(), kv.second));
    PetscCall(w.write_series("/settings", "values", {(PetscReal)s.n, s.dt, T, s.nu, s.amplitude, (PetscReal)s.modes, (PetscReal)ref_cells, sample}));
    PetscCall(w.close());
    PetscCall(PetscPrintf(comm, "learned_burgers_evaluate: results written to %s\n", output));
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, help));
  PetscErrorCode ierr = run(PETSC_COMM_WORLD);
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr); // one clear error, every rank stops
  PetscCall(PetscFinalize());
  return 0;
}
