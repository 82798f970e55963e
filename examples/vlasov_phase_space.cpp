// Example: Landau damping and the two-stream instability with the Vlasov-Poisson model, with the
// conservation history and phase-space snapshots for plotting.
//
// Math. Electrons f(x, v, t) on a neutralising background (src/models/vlasov.cpp):
//     f_t + v f_x - E f_v = 0,   E_x = 1 - int f dv,   f0 = (1 + alpha cos(k x)) F(v).
// Every step records the field energy W = 0.5 int E^2 dx and the invariants (mass, momentum,
// total energy = 0.5 int v^2 f + W, L2 norm). W's linear phase gives the rate:
//   -fit landau:  E ~ exp(gamma t) cos(omega t), so the peaks of W fall like exp(2 gamma t) and come
//                 every pi / omega (k = 0.5: gamma = -0.1533, omega = 1.4156);
//   -fit growth:  W ~ exp(2 gamma t) between -fit_t0 and -fit_t1 (two-stream, purely growing mode).
// Output: -history_file (text: t W mass momentum energy l2), -snapshot_times t1,t2,... with
// -snapshot_prefix: f in natural order (x fastest) as PETSc binary files <prefix>_<n>.bin.
//
// Sample runs (as root add --allow-run-as-root --oversubscribe to mpiexec):
//   mpiexec -n 2 build/vlasov_phase_space -fit landau -ts_max_time 30
//   mpiexec -n 2 build/vlasov_phase_space -vlasov_ic two_stream -da_grid_x 64 -da_grid_y 256 -ts_dt 0.05
//           -ts_max_time 60 -fit growth -fit_t0 8 -fit_t1 20 -history_file ts.txt
//           -snapshot_times 0,20,30,60 -snapshot_prefix ts                      (one line)
//   build/vlasov_phase_space -help        lists every option
#include "flexipde/scene.hpp"
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

using namespace flexipde;

struct Recorder {
  Scene *scene;
  std::vector<PetscReal> t;
  std::vector<std::vector<PetscReal>> rows; // W, mass, momentum, energy, l2
  std::vector<PetscReal> snap_times;
  char prefix[PETSC_MAX_PATH_LEN] = "vlasov";
  size_t next_snap = 0;
  PetscReal dt = 0;

  static PetscErrorCode rhs(TS, PetscReal t, Vec U, Vec G, void *ctx) {
    return static_cast<Recorder *>(ctx)->scene->model->rhs(t, U, G);
  }
  // After every step: the diagnostics, and a snapshot when a requested time is reached.
  static PetscErrorCode monitor(TS, PetscInt, PetscReal t, Vec U, void *ctx) {
    auto *r = static_cast<Recorder *>(ctx);
    const char *names[] = {"field_energy", "mass", "momentum", "energy", "l2"};
    std::vector<PetscReal> row(5);
    PetscFunctionBeginUser;
    for (int q = 0; q < 5; ++q) PetscCall(r->scene->model->functional(names[q], U, &row[q], nullptr));
    r->t.push_back(t);
    r->rows.push_back(row);
    while (r->next_snap < r->snap_times.size() && t >= r->snap_times[r->next_snap] - 0.5 * r->dt) {
      PetscCall(r->snapshot(U, r->next_snap));
      ++r->next_snap;
    }
    PetscFunctionReturn(0);
  }
  PetscErrorCode snapshot(Vec U, size_t n) {
    OwnedVec nat;
    OwnedViewer viewer;
    char name[PETSC_MAX_PATH_LEN + 16];
    PetscFunctionBeginUser;
    std::snprintf(name, sizeof(name), "%s_%zu.bin", prefix, n);
    PetscCall(DMDACreateNaturalVector(scene->state_dm, nat.out()));
    PetscCall(DMDAGlobalToNaturalBegin(scene->state_dm, U, INSERT_VALUES, nat));
    PetscCall(DMDAGlobalToNaturalEnd(scene->state_dm, U, INSERT_VALUES, nat));
    PetscCall(PetscViewerBinaryOpen(scene->comm(), name, FILE_MODE_WRITE, viewer.out()));
    PetscCall(PetscViewerBinarySetSkipInfo(viewer, PETSC_TRUE));
    PetscCall(VecView(nat, viewer));
    PetscFunctionReturn(0);
  }
};

static PetscErrorCode run() {
  MPI_Comm comm = PETSC_COMM_WORLD;
  const char *fits[] = {"none", "landau", "growth"};
  PetscInt fit = 0, nsnap = 32;
  PetscReal fit_t0 = 8, fit_t1 = 20, snaps[32];
  char history[PETSC_MAX_PATH_LEN] = "";
  PetscBool snap_set = PETSC_FALSE;
  Recorder rec;
  PetscFunctionBeginUser;
  // 1. The scene: the Vlasov model on its default phase-space grid (64 x 128), RK4, dt = 0.05.
  SceneDefaults defaults;
  defaults.model = "vlasov";
  defaults.dt = 0.05;
  defaults.final_time = 30;
  Scene scene;
  PetscCall(scene.setup(comm, defaults));
  rec.scene = &scene;
  PetscOptionsBegin(comm, nullptr, "Vlasov phase-space example", "Example");
  PetscCall(PetscOptionsEList("-fit", "Rate to fit from W(t): landau (peaks) or growth (log-linear)", "Example", fits, 3,
                              fits[fit], &fit, nullptr));
  PetscCall(PetscOptionsReal("-fit_t0", "growth fit: start of the window", "Example", fit_t0, &fit_t0, nullptr));
  PetscCall(PetscOptionsReal("-fit_t1", "growth fit: end of the window", "Example", fit_t1, &fit_t1, nullptr));
  PetscCall(PetscOptionsString("-history_file", "Text file for t W mass momentum energy l2", "Example", history, history,
                               sizeof(history), nullptr));
  PetscCall(PetscOptionsRealArray("-snapshot_times", "Times of the phase-space snapshots", "Example", snaps, &nsnap,
                                  &snap_set));
  PetscCall(PetscOptionsString("-snapshot_prefix", "Snapshot files <prefix>_<n>.bin", "Example", rec.prefix, rec.prefix,
                               sizeof(rec.prefix), nullptr));
  PetscOptionsEnd();
  if (snap_set) rec.snap_times.assign(snaps, snaps + nsnap);

  // 2. The integrator: PETSc's TS with the model's right-hand side and the recorder as monitor.
  //    -ts_type, -ts_rk_type, -ts_dt and -ts_max_time apply.
  OwnedVec p, U;
  OwnedTS ts;
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.parameters_from_options("", p));
  PetscCall(scene.sim.create_state(U.out()));
  PetscCall(scene.sim.initial_condition(p, U));
  PetscCall(TSCreate(comm, ts.out()));
  PetscCall(TSSetProblemType(ts, TS_NONLINEAR));
  PetscCall(TSSetRHSFunction(ts, nullptr, Recorder::rhs, &rec));
  PetscCall(TSSetType(ts, TSRK));
  PetscCall(TSRKSetType(ts, TSRK4));
  PetscCall(TSSetTimeStep(ts, defaults.dt));
  PetscCall(TSSetMaxTime(ts, defaults.final_time));
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
  PetscCall(TSMonitorSet(ts, Recorder::monitor, &rec, nullptr));
  PetscCall(TSSetFromOptions(ts));
  PetscCall(TSGetTimeStep(ts, &rec.dt));
  PetscReal T;
  PetscCall(TSGetMaxTime(ts, &T));
  PetscCall(TSSetMaxSteps(ts, (PetscInt)std::llround(T / rec.dt)));

  // 3. Run, then report the drift of the invariants and the fitted rate.
  PetscLogDouble t0, t1;
  PetscCall(PetscTime(&t0));
  PetscCall(TSSolve(ts, U));
  PetscCall(PetscTime(&t1));
  const auto &first = rec.rows.front();
  PetscReal drift[5] = {0, 0, 0, 0, 0}, wmax = 0;
  for (auto &row : rec.rows) {
    for (int q = 1; q < 5; ++q)
      drift[q] = std::max(drift[q], std::fabs(row[q] - first[q]) / (q == 2 ? 1.0 : std::fabs(first[q])));
    wmax = std::max(wmax, row[0]);
  }
  PetscCall(PetscPrintf(comm, "vlasov: %" PetscInt_FMT " x %" PetscInt_FMT " phase-space points, %zu steps of %g to T = %g in %.2f s\n",
                        scene.grid.n(), scene.grid.ny(), rec.t.size() - 1, (double)rec.dt, (double)rec.t.back(), t1 - t0));
  PetscCall(PetscPrintf(comm,
                        "invariants: max relative change of mass %.2e, energy %.2e, L2 norm %.2e; max |momentum "
                        "change| %.2e; field energy %.4e -> %.4e (max %.4e)\n",
                        (double)drift[1], (double)drift[3], (double)drift[4], (double)drift[2], (double)first[0],
                        (double)rec.rows.back()[0], (double)wmax));
  PetscReal norm;
  PetscCall(VecNorm(U, NORM_2, &norm));
  PetscCheck(std::isfinite((double)norm), comm, PETSC_ERR_FP, "The solution holds NaN/Inf: reduce -ts_dt");
  if (fit == 1) { // peaks of log W, refined by a parabola through three samples; the first left out
    std::vector<PetscReal> tp, lp;
    for (size_t n = 1; n + 1 < rec.rows.size(); ++n) {
      const PetscReal a = std::log(rec.rows[n - 1][0]), b = std::log(rec.rows[n][0]), c = std::log(rec.rows[n + 1][0]);
      if (!(b > a && b >= c)) continue;
      const PetscReal s = 0.5 * (a - c) / (a - 2 * b + c);
      tp.push_back(rec.t[n] + s * rec.dt);
      lp.push_back(b - 0.25 * (a - c) * s);
    }
    PetscCheck(tp.size() >= 4, comm, PETSC_ERR_ARG_OUTOFRANGE, "-fit landau: only %zu peaks of W; run longer", tp.size());
    PetscReal st = 0, sl = 0, stt = 0, stl = 0, m = 0;
    for (size_t q = 1; q < tp.size(); ++q, ++m) st += tp[q], sl += lp[q], stt += tp[q] * tp[q], stl += tp[q] * lp[q];
    const PetscReal gamma = 0.5 * (m * stl - st * sl) / (m * stt - st * st);
    const PetscReal omega = PETSC_PI * (tp.size() - 2) / (tp.back() - tp[1]);
    PetscCall(PetscPrintf(comm, "landau fit (%zu peaks): gamma = %.5f (rel. error %.2e vs -0.1533), omega = %.5f (rel. error %.2e vs 1.4156)\n",
                          tp.size(), (double)gamma, std::fabs(gamma / -0.1533 - 1), (double)omega,
                          std::fabs(omega / 1.4156 - 1)));
  } else if (fit == 2) {
    PetscReal st = 0, sl = 0, stt = 0, stl = 0, m = 0;
    for (size_t q = 0; q < rec.t.size(); ++q) {
      const PetscReal tt = rec.t[q], l = std::log(rec.rows[q][0]);
      if (tt < fit_t0 - 1e-9 || tt > fit_t1 + 1e-9) continue;
      st += tt, sl += l, stt += tt * tt, stl += tt * l, m += 1;
    }
    PetscCheck(m >= 2, comm, PETSC_ERR_ARG_OUTOFRANGE, "-fit growth: no steps in [%g, %g]", (double)fit_t0, (double)fit_t1);
    PetscCall(PetscPrintf(comm, "growth fit on [%g, %g]: gamma = %.5f\n", (double)fit_t0, (double)fit_t1,
                          (double)(0.5 * (m * stl - st * sl) / (m * stt - st * st))));
  }
  if (history[0]) {
    FILE *fp;
    PetscCall(PetscFOpen(comm, history, "w", &fp));
    PetscCall(PetscFPrintf(comm, fp, "# t field_energy mass momentum energy l2\n"));
    for (size_t n = 0; n < rec.t.size(); ++n)
      PetscCall(PetscFPrintf(comm, fp, "%.6f %.12e %.15e %.12e %.15e %.15e\n", (double)rec.t[n], (double)rec.rows[n][0],
                             (double)rec.rows[n][1], (double)rec.rows[n][2], (double)rec.rows[n][3], (double)rec.rows[n][4]));
    PetscCall(PetscFClose(comm, fp));
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr,
                            "Vlasov-Poisson: Landau damping, two-stream instability, invariants and phase-space snapshots\n"));
  PetscCall(run());
  PetscCall(PetscFinalize());
  return 0;
}
