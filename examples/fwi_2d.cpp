// Example: 2D full-waveform inversion of a layered model with an anomaly, from receiver traces.
//
// Math. The acoustic wave u_tt = c(x, y)^2 (u_xx + u_yy) + w(t) delta(x - x_s) - sigma u_t on [0,1]^2
// (y is depth), with a sponge layer sigma of width 0.15 along every edge that absorbs outgoing
// waves (model wave2d), is run once per shot s with a Ricker point source at x_s. Receivers on a
// ring around the region of interest record u(x_r, t). From the traces d of the true model we
// minimise over the field c
//     J(c) = sum_s 0.5 int_0^T sum_r (u_s(x_r, t; c) - d_{s,r}(t))^2 dt + beta TV_eps(c)
// with TAO (BLMVM with bounds by default), the gradient being the exact discrete adjoint of the
// integrator (TSAdjoint, one backward sweep per shot, summed over shots).
//
// The scene, made by code below (every value can be overridden by the usual options):
//   true c: layers 1.0 (y < 0.4), 1.15 (0.4 <= y < 0.6), 1.3 (y >= 0.6) and a slow disc c = 0.95
//           of radius 0.08 at (0.5, 0.5) (-anomaly_x, -anomaly_y, -anomaly_radius, -anomaly_c);
//   initial c: the smooth background 1.0 + 0.3 (y - 0.2) / 0.6, clipped to [1.0, 1.3];
//   4 shots at y = 0.2, x = 0.2 ... 0.8 (f0 = 5), 48 receivers on the square ring at 0.2 / 0.8.
//
// Sample runs (as root add --allow-run-as-root to mpiexec):
//   mpiexec -n 2 build/fwi_2d -tao_monitor -output results/fwi_2d.h5
//   mpiexec -n 2 build/fwi_2d -da_grid_x 61 -da_grid_y 61 -tao_max_it 5 -ts_dt 5e-3
//   mpiexec -n 2 build/fwi_2d -tao_type adam -tao_adam_lr 5e-3 -inv_tv 0 -inv_tikhonov 1e-5
#include "fwi_2d_common.hpp"
#include "flexipde/survey.hpp"
#include <cmath>
#include <string>
#include <vector>

using namespace flexipde;

// c(x, y) of the true model (layers and a disc) or of the initial one (a smooth gradient).
struct Model2D {
  PetscReal ax = 0.5, ay = 0.5, ar = 0.08, ac = 0.95;
  PetscReal truth(PetscReal x, PetscReal y) const {
    if ((x - ax) * (x - ax) + (y - ay) * (y - ay) < ar * ar) return ac;
    return y < 0.4 ? 1.0 : (y < 0.6 ? 1.15 : 1.3);
  }
  PetscReal initial(PetscReal, PetscReal y) const { return PetscMin(1.3, PetscMax(1.0, 1.0 + 0.3 * (y - 0.2) / 0.6)); }
};

static PetscErrorCode run() {
  MPI_Comm comm = PETSC_COMM_WORLD;
  Model2D m;
  char output[PETSC_MAX_PATH_LEN] = "";
  PetscFunctionBeginUser;
  // 1. The demo scene as option defaults: wave2d with a c field, sources and a ring of receivers.
  PetscOptionsBegin(comm, nullptr, "2D FWI demo", "fwi_2d");
  PetscCall(PetscOptionsReal("-anomaly_x", "Centre x of the slow disc", "fwi_2d", m.ax, &m.ax, nullptr));
  PetscCall(PetscOptionsReal("-anomaly_y", "Centre y (depth) of the slow disc", "fwi_2d", m.ay, &m.ay, nullptr));
  PetscCall(PetscOptionsReal("-anomaly_radius", "Radius of the disc", "fwi_2d", m.ar, &m.ar, nullptr));
  PetscCall(PetscOptionsReal("-anomaly_c", "Speed in the disc", "fwi_2d", m.ac, &m.ac, nullptr));
  PetscCall(PetscOptionsString("-output", "HDF5 results file", "fwi_2d", output, output, sizeof(output), nullptr));
  PetscOptionsEnd();
  std::vector<double> rx, ry;
  for (int k = 0; k < 13; ++k) { // top and bottom lines, x = 0.2 ... 0.8
    for (double y : {0.2, 0.8}) {
      rx.push_back(0.2 + 0.05 * k);
      ry.push_back(y);
    }
  }
  for (int k = 1; k < 12; ++k) { // left and right sides, y = 0.25 ... 0.75
    for (double x : {0.2, 0.8}) {
      rx.push_back(x);
      ry.push_back(0.2 + 0.05 * k);
    }
  }
  PetscCall(fwi2d::default_options({
      {"-model", "wave2d"},
      {"-da_grid_x", "101"},
      {"-da_grid_y", "101"},
      {"-wave2d_c_field", "1"},
      {"-ts_type", "rk"},
      {"-ts_dt", "4e-3"},
      {"-ts_max_time", "1.4"},
      {"-objective_type", "receivers"},
      {"-survey_sources_x", "0.2,0.4,0.6,0.8"},
      {"-survey_sources_y", "0.2"},
      {"-survey_ricker_f0", "5"},
      {"-survey_receivers_x", fwi2d::join(rx)},
      {"-survey_receivers_y", fwi2d::join(ry)},
      {"-inv_lower", "0.8"},
      {"-inv_upper", "1.6"},
      {"-inv_tv", "2e-5"},
      {"-inv_tv_eps", "0.5"},
      {"-tao_max_it", "40"},
  }));

  // 2. The scene from the options, the true and initial speeds from the model above, the synthetic
  // traces of every shot, and the inversion (fwi_2d_common.hpp).
  fwi2d::Inverted r;
  PetscCall(r.run(comm, [&](PetscReal x, PetscReal y) { return m.truth(x, y); },
                  [&](PetscReal x, PetscReal y) { return m.initial(x, y); }));
  if (r.help) PetscFunctionReturn(0);
  const Scene &scene = r.scene;
  const Inversion &inv = r.inv;
  PetscCall(PetscPrintf(comm,
                        "fwi_2d: %" PetscInt_FMT " x %" PetscInt_FMT " grid, %" PetscInt_FMT " shots, %s after %" PetscInt_FMT
                        " iterations (%" PetscInt_FMT " gradient evaluations); velocity RMSE %.4e -> %.4e\n",
                        scene.grid.n(), scene.grid.ny(), scene.objective.survey()->shots(), TaoConvergedReasons[inv.converged_reason()],
                        inv.iterations(), inv.evaluations(), (double)r.rmse_initial, (double)r.rmse_recovered));

  // 3. Results: the three models on the grid and the history, for run/plot_fwi_2d.py.
  if (output[0]) {
    PetscCall(fwi2d::write_results(output, scene, r.p_true, r.p0, r.p, inv, [&](H5Writer &w) -> PetscErrorCode {
      PetscFunctionBeginUser;
      PetscCall(w.write_series("/survey", "receivers_x", std::vector<PetscReal>(rx.begin(), rx.end())));
      PetscCall(w.write_series("/survey", "receivers_y", std::vector<PetscReal>(ry.begin(), ry.end())));
      PetscFunctionReturn(0);
    }));
    PetscCall(PetscPrintf(comm, "fwi_2d: results written to %s\n", output));
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) { return fwi2d::main_of(argc, argv, run); }
