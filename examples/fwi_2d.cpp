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
#include "flexipde/inversion.hpp"
#include "flexipde/io.hpp"
#include "flexipde/scene.hpp"
#include "flexipde/survey.hpp"
#include <cmath>
#include <string>
#include <vector>

using namespace flexipde;

// Sets an option unless the user gave it.
static PetscErrorCode default_option(const char *name, const std::string &value) {
  PetscBool set;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsHasName(nullptr, nullptr, name, &set));
  if (!set) PetscCall(PetscOptionsSetValue(nullptr, name, value.c_str()));
  PetscFunctionReturn(0);
}

static std::string join(const std::vector<double> &v) {
  std::string s;
  for (double x : v) s += (s.empty() ? "" : ",") + std::to_string(x);
  return s;
}

// c(x, y) of the true model (layers and a disc) or of the initial one (a smooth gradient).
struct Model2D {
  PetscReal ax = 0.5, ay = 0.5, ar = 0.08, ac = 0.95;
  PetscReal truth(PetscReal x, PetscReal y) const {
    if ((x - ax) * (x - ax) + (y - ay) * (y - ay) < ar * ar) return ac;
    return y < 0.4 ? 1.0 : (y < 0.6 ? 1.15 : 1.3);
  }
  PetscReal initial(PetscReal, PetscReal y) const { return PetscMin(1.3, PetscMax(1.0, 1.0 + 0.3 * (y - 0.2) / 0.6)); }
};

static PetscErrorCode fill_field(const Scene &s, Vec p, bool truth, const Model2D &m) {
  OwnedVec f;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(s.grid.dm(), f.out()));
  {
    Array a(f);
    PetscCall(a.error());
    for (PetscInt k = 0; k < s.grid.local_points(); ++k) {
      const PetscReal x = s.grid.x(s.grid.xs() + k % s.grid.xm()), y = s.grid.y(s.grid.ys() + k / s.grid.xm());
      a[k] = truth ? m.truth(x, y) : m.initial(x, y);
    }
  }
  PetscCall(s.params.set_field(p, s.params.find("wave2d_c"), f));
  PetscFunctionReturn(0);
}

static PetscErrorCode write_field(H5Writer &w, const Scene &s, Vec p, const char *name) {
  OwnedVec f;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(s.grid.dm(), f.out()));
  PetscCall(s.params.get_field(p, s.params.find("wave2d_c"), f));
  PetscCall(w.write_vec("/fields", name, f));
  PetscFunctionReturn(0);
}

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
  const std::pair<const char *, std::string> defaults[] = {
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
      {"-survey_receivers_x", join(rx)},
      {"-survey_receivers_y", join(ry)},
      {"-inv_lower", "0.8"},
      {"-inv_upper", "1.6"},
      {"-inv_tv", "2e-5"},
      {"-inv_tv_eps", "0.5"},
      {"-tao_max_it", "40"},
  };
  for (auto &d : defaults) PetscCall(default_option(d.first, d.second));

  // 2. The scene: grid, model, survey (sources, receivers), integrator, all from the options.
  Scene scene;
  PetscCall(scene.setup(comm));

  // 3. The true and initial models, made by code.
  OwnedVec p, p_true, p0;
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.params.create_vec(p_true.out()));
  PetscCall(scene.params.create_vec(p0.out()));
  PetscCall(fill_field(scene, p_true, true, m));
  PetscCall(fill_field(scene, p, false, m));
  PetscCall(VecCopy(p, p0));

  // 4. Synthetic traces of every shot from the true model (or -survey_data_file).
  PetscCall(scene.make_synthetic_data(p_true));

  // 5. Inversion: TAO with bounds and total variation; history of misfit and RMSE per iteration.
  Inversion inv;
  PetscReal e0, e1;
  PetscCall(inv.setup(scene, p_true));
  PetscCall(inv.rmse(p, &e0));
  PetscCall(inv.solve(p));
  PetscCall(inv.rmse(p, &e1));
  PetscCall(PetscPrintf(comm,
                        "fwi_2d: %" PetscInt_FMT " x %" PetscInt_FMT " grid, %" PetscInt_FMT " shots, %s after %" PetscInt_FMT
                        " iterations (%" PetscInt_FMT " gradient evaluations); velocity RMSE %.4e -> %.4e\n",
                        scene.grid.n(), scene.grid.ny(), scene.objective.survey()->shots(), TaoConvergedReasons[inv.converged_reason()],
                        inv.iterations(), inv.evaluations(), (double)e0, (double)e1));

  // 6. Results: the three models on the grid and the history, for run/plot_fwi_2d.py.
  if (output[0]) {
    H5Writer w;
    std::vector<PetscReal> it, f, mis, rm;
    for (auto &h : inv.history()) {
      it.push_back(h.iteration);
      f.push_back(h.objective);
      mis.push_back(h.misfit);
      rm.push_back(h.rmse);
    }
    PetscCall(w.open(comm, output));
    PetscCall(w.write_coordinates(scene.grid));
    PetscCall(write_field(w, scene, p_true, "wave2d_c_true"));
    PetscCall(write_field(w, scene, p0, "wave2d_c_initial"));
    PetscCall(write_field(w, scene, p, "wave2d_c_recovered"));
    PetscCall(w.write_series("/history", "iteration", it));
    PetscCall(w.write_series("/history", "objective", f));
    PetscCall(w.write_series("/history", "misfit", mis));
    PetscCall(w.write_series("/history", "rmse", rm));
    PetscCall(w.write_series("/survey", "receivers_x", std::vector<PetscReal>(rx.begin(), rx.end())));
    PetscCall(w.write_series("/survey", "receivers_y", std::vector<PetscReal>(ry.begin(), ry.end())));
    PetscCall(w.close());
    PetscCall(PetscPrintf(comm, "fwi_2d: results written to %s\n", output));
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, nullptr));
  PetscErrorCode ierr = run();
  if (ierr) MPI_Abort(MPI_COMM_WORLD, (int)ierr);
  PetscCall(PetscFinalize());
  return 0;
}
