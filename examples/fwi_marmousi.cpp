// Example: full-waveform inversion of a Marmousi-like section, made by code, with the tools FWI users
// expect: shots in parallel on groups of ranks, frequency continuation, an absorbing layer and a
// memory budget for the stored trajectory.
//
// Math. The acoustic wave u_tt = c(x, y)^2 (u_xx + u_yy) - sigma u_t + w(t) delta(x - x_s) on
// [0, 3] x [0, 1.2] (km; y is depth), with an absorbing sponge sigma along every edge (model wave2d),
// is run once per shot with a Ricker point source, by the leapfrog (the sponge's damping in its kicks).
// (-wave2d_sponge_width 0 -wave2d_pml_width 0.15 -wave2d_pml_strength 150 -ts_type rk -ts_dt 3e-3 puts
// a perfectly matched layer there instead, with RK4: its gradient costs about 20 times the sponge's with
// RK4, which itself takes about 4 times the leapfrog's here.) From the traces d of the true model at a line of receivers near the surface we
// minimise over the field c (km/s)
//     J(c) = sum_s 0.5 int_0^T sum_r (u_s(x_r, t; c) - d_{s,r}(t))^2 dt + beta TV_eps(c)
// with TAO (BLMVM with bounds), band after band of low-pass filtered data and sources
// (-inv_frequency_bands), the gradient being the exact discrete adjoint of the integrator.
//
// The section (every value can be overridden by the usual options):
//   true c: a water layer (1.5) over sediments whose interfaces dip at 8 degrees (1.7 ... 3.4, with
//           two slower layers among them), cut by a normal fault at x = 1.7 (dipping 60 degrees,
//           throw 0.15: the right block lowered), and a high-velocity body (4.0) at depth, an
//           ellipse centred at (2.1, 0.8);
//   initial c: the smooth trend 1.5 + 1.9 max(0, y - 0.1) / 1.1, nothing of the layers, fault or body;
//   12 shots at depth 0.04, x = 0.3 ... 2.7 (Ricker f0 = 5 Hz), 121 receivers at depth 0.04;
//   three frequency bands: up to 2.5 Hz, up to 4 Hz, all; at most 50 BLMVM iterations each;
//   151 x 61 points (h = 0.02, fourth-order stencil), leapfrog with dt = 2.5e-3 to T = 1.6.
//
// Sample runs (as root add --allow-run-as-root to mpiexec):
//   mpiexec -n 2 build/fwi_marmousi -shot_groups 2 -tao_monitor -output results/fwi_marmousi.h5
//   mpiexec -n 2 build/fwi_marmousi -da_grid_x 301 -da_grid_y 121 -ts_dt 1.25e-3 -shot_groups 2
//   mpiexec -n 2 build/fwi_marmousi -da_grid_x 101 -da_grid_y 41 -ts_max_time 1.2 -tao_max_it 2
//     -survey_sources_x 1,2 -inv_frequency_bands 3,0
#include "fwi_2d_common.hpp"
#include "flexipde/survey.hpp"
#include <cmath>
#include <string>
#include <vector>

using namespace flexipde;

static std::string spread(double a, double b, int n) {
  std::string s;
  for (int k = 0; k < n; ++k) s += (k ? "," : "") + std::to_string(n > 1 ? a + (b - a) * k / (n - 1) : a);
  return s;
}

// c(x, y) of the section (true) and of the smooth trend the inversion starts from.
struct Section {
  PetscReal water = 0.1, dip = 8.0 * M_PI / 180, fault_x = 1.7, fault_dip = 60.0 * M_PI / 180, throw_ = 0.15;
  PetscReal body_x = 2.1, body_y = 0.8, body_a = 0.35, body_b = 0.12, body_c = 4.0;
  PetscReal truth(PetscReal x, PetscReal y) const {
    if (y < water) return 1.5;
    const PetscReal dx = (x - body_x) / body_a, dy = (y - body_y) / body_b;
    if (dx * dx + dy * dy < 1) return body_c;
    // right of the fault plane the layers sit lower by the throw
    const bool right = x > fault_x + (y - water) / std::tan(fault_dip);
    const PetscReal depth = y - water - std::tan(dip) * x + (right ? -throw_ : 0.0);
    const PetscReal layers[] = {1.7, 1.9, 2.1, 2.0, 2.3, 2.6, 2.5, 2.8, 3.1, 3.4};
    const int k = (int)std::floor(depth / 0.1) + 3; // interfaces every 0.1 of depth along the dip
    return layers[std::max(0, std::min(9, k))];
  }
  PetscReal initial(PetscReal, PetscReal y) const { return 1.5 + 1.9 * std::max<PetscReal>(0, y - water) / 1.1; }
};

static PetscErrorCode run() {
  MPI_Comm comm = PETSC_COMM_WORLD;
  Section m;
  char output[PETSC_MAX_PATH_LEN] = "";
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, nullptr, "FWI of a Marmousi-like section", "fwi_marmousi");
  PetscCall(PetscOptionsReal("-section_fault_x", "Where the fault meets the sea floor", "fwi_marmousi", m.fault_x, &m.fault_x,
                             nullptr));
  PetscCall(PetscOptionsReal("-section_throw", "The fault's throw (the right block lowered)", "fwi_marmousi", m.throw_,
                             &m.throw_, nullptr));
  PetscCall(PetscOptionsReal("-section_body_c", "Speed in the high-velocity body", "fwi_marmousi", m.body_c, &m.body_c,
                             nullptr));
  PetscCall(PetscOptionsString("-output", "HDF5 results file", "fwi_marmousi", output, output, sizeof(output), nullptr));
  PetscOptionsEnd();
  // 1. The scene as option defaults.
  PetscCall(fwi2d::default_options({
      {"-model", "wave2d"},
      {"-grid_x1", "3"},
      {"-grid_y1", "1.2"},
      {"-da_grid_x", "151"},
      {"-da_grid_y", "61"},
      {"-fd_order", "4"},
      {"-wave2d_c_field", "1"},
      {"-wave2d_c_min", "1"},
      {"-wave2d_sponge_width", "0.15"},
      {"-wave2d_sponge_strength", "120"}, // sigma_max, for speeds twice the unit ones
      {"-ts_type", "leapfrog"},
      {"-ts_dt", "2.5e-3"}, // stable up to c = 4.5 (the upper bound): dt omega_max = 1.84 < 2
      {"-ts_max_time", "1.6"},
      {"-checkpoint_memory", "2GB"},
      {"-objective_type", "receivers"},
      {"-survey_sources_x", spread(0.3, 2.7, 12)},
      {"-survey_sources_y", "0.04"},
      {"-survey_ricker_f0", "5"},
      {"-survey_ricker_amplitude", "100"}, // misfits of order 0.1: TAO's default tolerances apply
      {"-survey_receivers_spread", "0.2,2.8,121"},
      {"-survey_receivers_y", "0.04"},
      {"-inv_frequency_bands", "2.5,4,0"},
      {"-inv_lower", "1.4"},
      {"-inv_upper", "4.5"},
      {"-inv_tv", "1e-3"},
      {"-inv_tv_eps", "0.5"},
      {"-tao_max_it", "50"},
  }));

  // 2. The scene from the options, the true and initial speeds from the model above, the synthetic
  // traces of every shot, and the inversion (fwi_2d_common.hpp).
  fwi2d::Inverted r;
  double t0 = MPI_Wtime();
  PetscCall(r.run(comm, [&](PetscReal x, PetscReal y) { return m.truth(x, y); },
                  [&](PetscReal x, PetscReal y) { return m.initial(x, y); }));
  if (r.help) PetscFunctionReturn(0);
  const Scene &scene = r.scene;
  const Inversion &inv = r.inv;
  PetscCall(PetscPrintf(comm,
                        "fwi_marmousi: %" PetscInt_FMT " x %" PetscInt_FMT " grid, %" PetscInt_FMT " shots in %" PetscInt_FMT
                        " groups, %s after %" PetscInt_FMT " iterations (%" PetscInt_FMT
                        " gradient evaluations, %.0f s); velocity RMSE %.4e -> %.4e\n",
                        scene.grid.n(), scene.grid.ny(), scene.objective.survey()->shots(), scene.shot_groups(),
                        TaoConvergedReasons[inv.converged_reason()], inv.iterations(), inv.evaluations(), MPI_Wtime() - t0,
                        (double)r.rmse_initial, (double)r.rmse_recovered));

  // 3. Results: the three models and the history, for run/plot_fwi_marmousi.py.
  if (output[0]) {
    PetscCall(fwi2d::write_results(output, scene, r.p_true, r.p0, r.p, inv));
    PetscCall(PetscPrintf(comm, "fwi_marmousi: results written to %s\n", output));
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv) { return fwi2d::main_of(argc, argv, run); }
