// Example: 3D full-waveform inversion of a layered earth with a high-velocity body, made by code: a few
// shots fired near the surface, a square array of receivers beside them, the speed c(x, y, z) at every
// grid point recovered from the traces.
//
// Math. The acoustic wave u_tt = c(x, y, z)^2 (u_xx + u_yy + u_zz) - sigma u_t + w(t) delta(x - x_s) in the
// box [0, 1.2] x [0, 1.2] x [0, 0.6] (km; x and y horizontal, z depth), with an absorbing sponge sigma along
// every face (model wave3d, fourth-order stencil), is run once per shot with a Ricker point source, by the
// leapfrog (the sponge's damping in its kicks). From the traces d of the true model at the receivers we
// minimise over the field c (km/s)
//     J(c) = sum_s 0.5 int_0^T sum_r (u_s(x_r, t; c) - d_{s,r}(t))^2 dt + beta TV_eps(c)
// with TAO (BLMVM with bounds), the gradient being the exact discrete adjoint of the leapfrog. The start
// is within half a period of the data here, so the whole band is inverted at once; -inv_frequency_bands
// runs band after band of low-pass filtered data and sources instead.
//
// The scene (every value can be overridden by the usual options):
//   true c: five layers (1.6, 1.9, 2.2, 2.5, 2.9) whose interfaces, at mean depths 0.14, 0.25, 0.36 and 0.47,
//           dip at 8 degrees towards the azimuth 30 degrees from x, and a high-velocity body (3.4), an
//           ellipsoid centred at (0.70, 0.55, 0.32) with semi-axes 0.20, 0.15, 0.08 (-body_*);
//   initial c: the smooth depth trend 1.6 + 1.3 z / 0.6, nothing of the layers' dip or of the body;
//   4 shots on a 2 x 2 pattern at x, y = 0.36, 0.84, depth 0.09 (Ricker f0 = 5 Hz), and 17 x 17 = 289
//   receivers on a square array from 0.12 to 1.08 at depth 0.09 (-array_n, -array_from, -array_to,
//   -array_depth; or any -survey_receivers_x/_y/_z lists or -survey_receivers_file of "x y z" lines);
//   41 x 41 x 21 points (h = 0.03), sponge W = 0.12, leapfrog with dt = 3e-3 to T = 1.1 (367 steps);
//   100 BLMVM iterations, bounds [1.4, 4], total variation beta = 3e-2 (eps = 0.5).
//
// Sample runs (as root add --allow-run-as-root to mpiexec):
//   mpiexec -n 2 build/fwi_3d -shot_groups 2 -tao_monitor -output results/fwi_3d.h5
//   mpiexec -n 2 build/fwi_3d -shot_groups 2 -inv_frequency_bands 3,0 -tao_max_it 50 -inv_tv 0
//   mpiexec -n 2 build/fwi_3d -da_grid_x 21 -da_grid_y 21 -da_grid_z 11 -ts_dt 6e-3 -ts_max_time 0.9
//     -survey_ricker_f0 3 -array_n 9 -inv_frequency_bands 2,0 -tao_max_it 3 -shot_groups 2
#include "fwi_2d_common.hpp"
#include "flexipde/survey.hpp"
#include <cmath>
#include <string>
#include <vector>

using namespace flexipde;

// c(x, y, z) of the layered earth with its body (true) and of the depth trend the inversion starts from.
struct Earth {
  PetscReal dip = 8.0 * M_PI / 180, azimuth = 30.0 * M_PI / 180, centre = 0.6; // the planes turn about x = y = 0.6
  PetscReal interfaces[4] = {0.14, 0.25, 0.36, 0.47};
  PetscReal speeds[5] = {1.6, 1.9, 2.2, 2.5, 2.9};
  PetscReal body_x = 0.70, body_y = 0.55, body_z = 0.32, body_a = 0.20, body_b = 0.15, body_c = 0.08, body_speed = 3.4;
  PetscReal truth(PetscReal x, PetscReal y, PetscReal z) const {
    const PetscReal ex = (x - body_x) / body_a, ey = (y - body_y) / body_b, ez = (z - body_z) / body_c;
    if (ex * ex + ey * ey + ez * ez < 1) return body_speed;
    // depth below the dipping plane through the mean interface depth: the layers deepen along the azimuth
    const PetscReal rise = std::tan(dip) * ((x - centre) * std::cos(azimuth) + (y - centre) * std::sin(azimuth));
    int layer = 0;
    while (layer < 4 && z - rise >= interfaces[layer]) ++layer;
    return speeds[layer];
  }
  PetscReal initial(PetscReal, PetscReal, PetscReal z) const { return speeds[0] + (speeds[4] - speeds[0]) * z / 0.6; }
};

// An option's list of values, one per `n` entries when it holds a single value (for the results file).
static PetscErrorCode option_list(const char *name, size_t n, std::vector<PetscReal> &out) {
  PetscReal buf[1024];
  PetscInt m = 1024;
  PetscBool set;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsGetRealArray(nullptr, nullptr, name, buf, &m, &set));
  out.assign(buf, buf + (set ? m : 0));
  if (out.size() == 1 && n > 1) out.assign(n, out[0]);
  PetscFunctionReturn(0);
}

static PetscErrorCode run() {
  MPI_Comm comm = PETSC_COMM_WORLD;
  Earth m;
  PetscInt array_n = 17;
  PetscReal array_from = 0.12, array_to = 1.08, array_depth = 0.09;
  char output[PETSC_MAX_PATH_LEN] = "";
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, nullptr, "3D FWI of a layered earth with a high-velocity body", "fwi_3d");
  PetscCall(PetscOptionsReal("-body_x", "Centre x of the high-velocity ellipsoid", "fwi_3d", m.body_x, &m.body_x, nullptr));
  PetscCall(PetscOptionsReal("-body_y", "Centre y of the ellipsoid", "fwi_3d", m.body_y, &m.body_y, nullptr));
  PetscCall(PetscOptionsReal("-body_z", "Centre depth z of the ellipsoid", "fwi_3d", m.body_z, &m.body_z, nullptr));
  PetscCall(PetscOptionsReal("-body_speed", "Speed in the ellipsoid", "fwi_3d", m.body_speed, &m.body_speed, nullptr));
  PetscCall(PetscOptionsInt("-array_n", "Receivers per side of the square array", "fwi_3d", array_n, &array_n, nullptr));
  PetscCall(PetscOptionsReal("-array_from", "First receiver line (x and y)", "fwi_3d", array_from, &array_from, nullptr));
  PetscCall(PetscOptionsReal("-array_to", "Last receiver line (x and y)", "fwi_3d", array_to, &array_to, nullptr));
  PetscCall(PetscOptionsReal("-array_depth", "Depth of the receiver array", "fwi_3d", array_depth, &array_depth, nullptr));
  PetscCall(PetscOptionsString("-output", "HDF5 results file", "fwi_3d", output, output, sizeof(output), nullptr));
  PetscOptionsEnd();
  PetscCheck(array_n >= 2, comm, PETSC_ERR_ARG_OUTOFRANGE, "-array_n must be at least 2, got %" PetscInt_FMT, array_n);

  // 1. The scene as option defaults; the receiver array as lists unless the command line gives receivers.
  PetscBool own_receivers = PETSC_FALSE;
  for (const char *o : {"-survey_receivers_x", "-survey_receivers_spread", "-survey_receivers_file"}) {
    PetscBool set;
    PetscCall(PetscOptionsHasName(nullptr, nullptr, o, &set));
    own_receivers = (PetscBool)(own_receivers || set);
  }
  if (!own_receivers) {
    std::vector<PetscReal> rx, ry;
    for (PetscInt j = 0; j < array_n; ++j)
      for (PetscInt i = 0; i < array_n; ++i) {
        rx.push_back(array_from + (array_to - array_from) * i / (array_n - 1));
        ry.push_back(array_from + (array_to - array_from) * j / (array_n - 1));
      }
    PetscCall(fwi2d::default_options({{"-survey_receivers_x", fwi2d::join(rx)},
                                      {"-survey_receivers_y", fwi2d::join(ry)},
                                      {"-survey_receivers_z", std::to_string(array_depth)}}));
  }
  PetscCall(fwi2d::default_options({
      {"-model", "wave3d"},
      {"-grid_x1", "1.2"},
      {"-grid_y1", "1.2"},
      {"-grid_z1", "0.6"},
      {"-da_grid_x", "41"},
      {"-da_grid_y", "41"},
      {"-da_grid_z", "21"},
      {"-fd_order", "4"},
      {"-wave3d_c_field", "1"},
      {"-wave3d_c_min", "1"},
      {"-wave3d_sponge_width", "0.12"},
      {"-wave3d_sponge_strength", "100"}, // sigma_max, for speeds about twice the unit ones
      {"-ts_type", "leapfrog"},
      {"-ts_dt", "3e-3"}, // stable up to c = 5 (above the upper bound): dt c sqrt(16) / h = 2 c dt / h < 2
      {"-ts_max_time", "1.1"},
      {"-checkpoint_memory", "2GB"},
      {"-objective_type", "receivers"},
      {"-survey_sources_x", "0.36,0.36,0.84,0.84"},
      {"-survey_sources_y", "0.36,0.84,0.36,0.84"},
      {"-survey_sources_z", "0.09"},
      {"-survey_ricker_f0", "5"},
      {"-survey_ricker_amplitude", "10"}, // misfits of order 0.1-1: TAO's default tolerances apply
      {"-inv_lower", "1.4"},
      {"-inv_upper", "4"},
      {"-inv_tv", "3e-2"},
      {"-inv_tv_eps", "0.5"},
      {"-tao_max_it", "100"},
  }));

  // 2. The scene from the options, the true and initial speeds from the earth above, the synthetic traces
  // of every shot, and the inversion (fwi_2d_common.hpp).
  fwi2d::Inverted r;
  const double t0 = MPI_Wtime();
  PetscCall(r.run(comm, [&](PetscReal x, PetscReal y, PetscReal z) { return m.truth(x, y, z); },
                  [&](PetscReal x, PetscReal y, PetscReal z) { return m.initial(x, y, z); }));
  if (r.help) PetscFunctionReturn(0);
  const double seconds = MPI_Wtime() - t0;
  Scene &scene = r.scene;
  const Inversion &inv = r.inv;
  // The misfit of the whole band (an inversion through bands ends there) at the start and at the result.
  PetscReal misfit_initial, misfit_recovered;
  PetscCall(scene.value(r.p0, &misfit_initial));
  PetscCall(scene.value(r.p, &misfit_recovered));
  const Survey &survey = *scene.objective.survey();
  PetscCall(PetscPrintf(comm,
                        "fwi_3d: %" PetscInt_FMT " x %" PetscInt_FMT " x %" PetscInt_FMT " grid, %" PetscInt_FMT
                        " shots in %" PetscInt_FMT " groups, %" PetscInt_FMT " receivers, %s after %" PetscInt_FMT
                        " iterations (%" PetscInt_FMT " gradient evaluations, %.0f s)\n",
                        scene.grid.n(), scene.grid.ny(), scene.grid.nz(), survey.shots(), scene.shot_groups(),
                        survey.receivers(), TaoConvergedReasons[inv.converged_reason()], inv.iterations(),
                        inv.evaluations(), seconds));
  PetscCall(PetscPrintf(comm, "fwi_3d: misfit %.4e -> %.4e (x%.4f); velocity RMSE %.4e -> %.4e (x%.4f)\n",
                        (double)misfit_initial, (double)misfit_recovered, (double)(misfit_recovered / misfit_initial),
                        (double)r.rmse_initial, (double)r.rmse_recovered, (double)(r.rmse_recovered / r.rmse_initial)));

  // 3. Results: the three models, the history, the whole-band misfits and where the shots and receivers
  // were, for run/plot_fwi_3d.py (and the .xmf companion for ParaView).
  if (output[0]) {
    std::vector<PetscReal> sx, sy, sz, rx, ry, rz;
    PetscCall(option_list("-survey_sources_x", 1, sx));
    PetscCall(option_list("-survey_sources_y", sx.size(), sy));
    PetscCall(option_list("-survey_sources_z", sx.size(), sz));
    PetscCall(option_list("-survey_receivers_x", 1, rx)); // empty with a receivers file
    PetscCall(option_list("-survey_receivers_y", rx.size(), ry));
    PetscCall(option_list("-survey_receivers_z", rx.size(), rz));
    PetscCall(fwi2d::write_results(output, scene, r.p_true, r.p0, r.p, inv, [&](H5Writer &w) -> PetscErrorCode {
      PetscFunctionBeginUser;
      PetscCall(w.write_series("/summary", "misfit", {misfit_initial, misfit_recovered}));
      PetscCall(w.write_series("/summary", "rmse", {r.rmse_initial, r.rmse_recovered}));
      PetscCall(w.write_series("/summary", "seconds", {(PetscReal)seconds}));
      const std::pair<const char *, const std::vector<PetscReal> *> positions[] = {
          {"sources_x", &sx}, {"sources_y", &sy}, {"sources_z", &sz}, {"receivers_x", &rx}, {"receivers_y", &ry}, {"receivers_z", &rz}};
      for (auto &pos : positions)
        if (!pos.second->empty()) PetscCall(w.write_series("/survey", pos.first, *pos.second));
      PetscFunctionReturn(0);
    }));
    PetscCall(PetscPrintf(comm, "fwi_3d: results written to %s\n", output));
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) { return fwi2d::main_of(argc, argv, run); }
