// The leapfrog TS type (src/core/leapfrog.cpp): it is the seed's leapfrog recurrence, it converges
// at second order in time, and its gradient does not depend on how the trajectory is kept.
// (Taylor tests, dJ/dU0 and 1 vs 2 ranks for leapfrog run with the other integrators in
// test_gradient.cpp.)
#include "flexipde/leapfrog.hpp"
#include "flexipde/scene.hpp"
#include "test_support.hpp"
#include <cmath>

using namespace flexipde;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

// u(T) of the scene in the options, gathered on every rank (the u component only).
PetscErrorCode final_u(std::vector<PetscReal> &u, SimulationStats *stats = nullptr) {
  Scene scene;
  OwnedVec p, U;
  std::vector<PetscReal> all;
  PetscFunctionBeginUser;
  PetscCall(scene.setup(PETSC_COMM_WORLD));
  PetscCall(scene.params.create_vec(p.out()));
  PetscCall(scene.parameters_from_options("", p));
  PetscCall(scene.sim.create_state(U.out()));
  PetscCall(scene.sim.forward(p, U));
  PetscCall(flexipde_test::gather_all(U, all));
  u.resize(all.size() / 2);
  for (size_t i = 0; i < u.size(); ++i) u[i] = all[2 * i];
  if (stats) *stats = scene.sim.stats();
  PetscFunctionReturn(0);
}

} // namespace

// The seed scheme written out: u_{k+1} = 2 u_k - u_{k-1} + dt^2 c^2 D2 u_k with the Verlet start
// u_1 = u_0 + dt v_0 + dt^2/2 c^2 D2 u_0 (D2 the second-order stencil, u = 0 on the walls).
TEST(Leapfrog, IsTheSeedRecurrence) {
  const PetscInt n = 201;
  const PetscReal c = 0.9, T = 0.4, dt = 1e-3, xc = 0.5, w = 0.2;
  ScopedOptions opts{{"-da_grid_x", "201"}, {"-ts_max_time", "0.4"}, {"-ts_dt", "1e-3"},
                     {"-ts_type", "leapfrog"},  {"-wave_c", "0.9"},      {"-wave_ic_center", "0.5"},
                     {"-wave_ic_width", "0.2"}};
  std::vector<PetscReal> u;
  SimulationStats st;
  PETSC_ASSERT_OK(final_u(u, &st));
  ASSERT_EQ((PetscInt)u.size(), n);
  EXPECT_EQ(st.steps, 400);
  EXPECT_STREQ(st.ts_type, "leapfrog");

  const PetscReal h = 1.0 / (n - 1);
  std::vector<PetscReal> u0(n), v0(n), um(n), uk(n), up(n);
  for (PetscInt i = 0; i < n; ++i) {
    const PetscReal s = (i * h - xc) / w, g = std::exp(-s * s);
    const bool wall = i == 0 || i == n - 1;
    u0[i] = wall ? 0 : g;
    v0[i] = wall ? 0 : -c * (-2.0 * s / w * g); // travelling pulse: v0 = -c u0'
  }
  auto accel = [&](const std::vector<PetscReal> &q, PetscInt i) {
    return (i == 0 || i == n - 1) ? 0.0 : c * c * (q[i - 1] - 2 * q[i] + q[i + 1]) / (h * h);
  };
  for (PetscInt i = 0; i < n; ++i) uk[i] = u0[i] + dt * v0[i] + 0.5 * dt * dt * accel(u0, i);
  um = u0;
  const PetscInt steps = (PetscInt)std::llround(T / dt);
  for (PetscInt k = 1; k < steps; ++k) {
    for (PetscInt i = 0; i < n; ++i) up[i] = 2 * uk[i] - um[i] + dt * dt * accel(uk, i);
    um.swap(uk);
    uk.swap(up);
  }
  PetscReal diff = 0, scale = 0;
  for (PetscInt i = 0; i < n; ++i) {
    diff = std::max(diff, std::fabs(u[i] - uk[i]));
    scale = std::max(scale, std::fabs(uk[i]));
  }
  PetscPrintf(PETSC_COMM_WORLD, "  leapfrog vs seed recurrence: max |diff| / max |u| = %.3e\n", (double)(diff / scale));
  EXPECT_GT(scale, 0.1);
  EXPECT_LE(diff / scale, 1e-11);
}

// With a sponge sigma(x) the kicks take the damping half implicitly, half explicitly, which is the
// centred damped recurrence (1 + s) u_{k+1} = 2 u_k - (1 - s) u_{k-1} + dt^2 c^2 D2 u_k, s = sigma dt/2,
// started by u_1 = u_0 + dt (v_0 + dt/2 c^2 D2 u_0) / (1 + s).
TEST(Leapfrog, DampedIsTheCentredDampedRecurrence) {
  const PetscInt n = 201;
  const PetscReal c = 0.9, T = 0.6, dt = 1e-3, xc = 0.4, w = 0.1, W = 0.25, sigma_max = 40;
  ScopedOptions opts{{"-da_grid_x", "201"},        {"-ts_max_time", "0.6"},          {"-ts_dt", "1e-3"},
                     {"-ts_type", "leapfrog"},     {"-wave_c", "0.9"},               {"-wave_ic_center", "0.4"},
                     {"-wave_ic_width", "0.1"},    {"-wave_sponge_width", "0.25"},   {"-wave_sponge_strength", "40"}};
  std::vector<PetscReal> u;
  PETSC_ASSERT_OK(final_u(u));
  ASSERT_EQ((PetscInt)u.size(), n);

  const PetscReal h = 1.0 / (n - 1);
  std::vector<PetscReal> u0(n), v0(n), s(n);
  for (PetscInt i = 0; i < n; ++i) {
    const PetscReal x = i * h, z = (x - xc) / w, g = std::exp(-z * z), r = std::max(0.0, W - std::min(x, 1 - x)) / W;
    const bool wall = i == 0 || i == n - 1;
    u0[i] = wall ? 0 : g;
    v0[i] = wall ? 0 : -c * (-2.0 * z / w * g);
    s[i] = 0.5 * dt * sigma_max * r * r;
  }
  auto accel = [&](const std::vector<PetscReal> &q, PetscInt i) {
    return (i == 0 || i == n - 1) ? 0.0 : c * c * (q[i - 1] - 2 * q[i] + q[i + 1]) / (h * h);
  };
  const PetscInt steps = (PetscInt)std::llround(T / dt);
  auto recurrence = [&](bool damped) {
    std::vector<PetscReal> um = u0, uk(n), up(n);
    auto sk = [&](PetscInt i) { return damped ? s[i] : 0.0; };
    for (PetscInt i = 0; i < n; ++i) uk[i] = u0[i] + dt * (v0[i] + 0.5 * dt * accel(u0, i)) / (1 + sk(i));
    for (PetscInt k = 1; k < steps; ++k) {
      for (PetscInt i = 0; i < n; ++i) up[i] = (2 * uk[i] - (1 - sk(i)) * um[i] + dt * dt * accel(uk, i)) / (1 + sk(i));
      um.swap(uk);
      uk.swap(up);
    }
    return uk;
  };
  const std::vector<PetscReal> damped = recurrence(true), undamped = recurrence(false);
  PetscReal diff = 0, scale = 0, effect = 0;
  for (PetscInt i = 0; i < n; ++i) {
    diff = std::max(diff, std::fabs(u[i] - damped[i]));
    scale = std::max(scale, std::fabs(damped[i]));
    effect = std::max(effect, std::fabs(undamped[i] - damped[i]));
  }
  PetscPrintf(PETSC_COMM_WORLD, "  damped leapfrog vs centred damped recurrence: %.3e (the damping moves u(T) by %.3e)\n",
              (double)(diff / scale), (double)(effect / scale));
  EXPECT_GT(scale, 0.05);
  EXPECT_GT(effect / scale, 0.1); // the pulse has reached the sponge
  EXPECT_LE(diff / scale, 1e-11);
}

// Second order in time: with the grid fixed, successive differences of u(T) fall 4x per halving; with
// and without a sponge that the pulse reaches.
TEST(Leapfrog, SecondOrderInTime) {
  for (const char *sponge : {"0", "0.25"}) {
    std::vector<std::vector<PetscReal>> u(4);
    const char *dts[] = {"4e-3", "2e-3", "1e-3", "5e-4"};
    for (int k = 0; k < 4; ++k) {
      ScopedOptions opts{{"-da_grid_x", "101"}, {"-ts_max_time", "0.4"}, {"-ts_dt", dts[k]}, {"-ts_type", "leapfrog"},
                         {"-wave_c", "1.0"},    {"-wave_sponge_width", sponge}};
      PETSC_ASSERT_OK(final_u(u[k]));
    }
    auto dist = [](const std::vector<PetscReal> &a, const std::vector<PetscReal> &b) {
      PetscReal d = 0;
      for (size_t i = 0; i < a.size(); ++i) d = std::max(d, std::fabs(a[i] - b[i]));
      return d;
    };
    const PetscReal e1 = dist(u[0], u[1]), e2 = dist(u[1], u[2]), e3 = dist(u[2], u[3]);
    PetscPrintf(PETSC_COMM_WORLD, "  leapfrog (sponge %s) time differences %.3e %.3e %.3e, ratios %.3f %.3f\n", sponge,
                (double)e1, (double)e2, (double)e3, (double)(e1 / e2), (double)(e2 / e3));
    EXPECT_NEAR(e1 / e2, 4.0, 0.3); // 3.77 without a sponge: the coarsest step is not yet asymptotic
    EXPECT_NEAR(e2 / e3, 4.0, 0.2);
  }
}

// The gradient is the same with full storage (no step re-run) and with binomial checkpointing
// (steps re-run from a few stored states), also for a time-integrated objective, and with a sponge
// (whose first kick after a restart differs from the one after a step: G is evaluated afresh).
TEST(Leapfrog, CheckpointedGradientEqualsFullStorage) {
  for (const char *objective : {"l2sq", "time_variation"})
  for (const char *sponge : {"0", "0.3"}) {
    ScopedOptions opts{{"-da_grid_x", "101"}, {"-ts_max_time", "0.3"}, {"-ts_dt", "2e-3"},  {"-ts_type", "leapfrog"},
                       {"-wave_c_field", "1"}, {"-wave_c", "0.9"},     {"-true_wave_c", "1"}, {"-objective_type", objective},
                       {"-wave_sponge_width", sponge}};
    PetscReal J[2];
    OwnedVec g[2];
    for (int k = 0; k < 2; ++k) {
      ScopedOptions budget;
      if (k == 1) budget.set("-checkpoint_budget", "4");
      flexipde_test::SceneProblem pb;
      PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
      PETSC_ASSERT_OK(VecDuplicate(pb.p, g[k].out()));
      PETSC_ASSERT_OK(pb.scene.sim.gradient(pb.p, &J[k], g[k], nullptr));
      const CheckpointStats &cs = pb.scene.sim.checkpoint_stats();
      if (k == 0) EXPECT_EQ(cs.recomputed_steps, 0) << "full storage re-runs no leapfrog step";
      else EXPECT_EQ(cs.recomputed_steps, cs.optimal_recomputations);
    }
    const PetscReal dg = rel_diff(g[1], g[0]);
    PetscPrintf(PETSC_COMM_WORLD, "  leapfrog %s, sponge %s: checkpointed vs full storage: J %.2e, gradient %.2e\n",
                objective, sponge, (double)rel_diff(J[1], J[0]), (double)dg);
    EXPECT_LE(rel_diff(J[1], J[0]), 1e-14);
    EXPECT_LE(dg, 1e-13);
    EXPECT_GT(flexipde_test::norm(g[0]), 0.0);
  }
}

namespace {

PetscErrorCode model_rhs(TS, PetscReal t, Vec U, Vec G, void *ctx) { return static_cast<Model *>(ctx)->rhs(t, U, G); }

PetscErrorCode model_step(void *ctx, PetscReal t, Vec U, PetscScalar *accel, const LeapfrogStepParts &parts) {
  return static_cast<Model *>(ctx)->second_order_step(t, U, accel, parts);
}

PetscErrorCode model_split_step(void *ctx, PetscReal t, Vec Q, PetscScalar *v, const LeapfrogSplitParts &parts) {
  return static_cast<Model *>(ctx)->second_order_split_step(t, Q, v, parts);
}

// Monitors of the split steps: one that forms the solution before it reads it (at every step), and one
// that reads it without saying so. Both check that U holds numbers.
PetscErrorCode forming_monitor(TS ts, PetscInt, PetscReal, Vec U, void *) {
  PetscReal nrm;
  PetscFunctionBeginUser;
  PetscCall(leapfrog_form_solution(ts));
  PetscCall(VecNorm(U, NORM_2, &nrm));
  PetscCheck(std::isfinite(nrm), PETSC_COMM_SELF, PETSC_ERR_FP, "not finite");
  PetscFunctionReturn(0);
}
PetscErrorCode reading_monitor(TS, PetscInt, PetscReal, Vec U, void *) {
  PetscReal nrm;
  PetscFunctionBeginUser;
  PetscCall(VecNorm(U, NORM_2, &nrm));
  PetscCheck(std::isfinite(nrm), PETSC_COMM_SELF, PETSC_ERR_FP, "not finite");
  PetscFunctionReturn(0);
}

// How leapfrog_solve steps: three passes driven by rhs() alone, the model's one sweep on the interleaved
// state, its split step (alone, with a monitor that forms the solution at every step, or with one that
// reads it unannounced, which makes every step a kick-drift-kick step).
enum class Stepping { Passes, OneSweep, Split, SplitFormed, SplitWatched };

// U(T) by the leapfrog TS, from the Simulation's U0; sigma: the damping in the velocity rows (null: none).
PetscErrorCode leapfrog_solve(Scene &scene, Vec p, Vec sigma, PetscReal dt, PetscInt steps, Stepping how, Vec U) {
  OwnedTS ts;
  PetscFunctionBeginUser;
  PetscCall(scene.sim.initial_condition(p, U));
  PetscCall(TSCreate(scene.grid.comm(), ts.out()));
  PetscCall(TSSetProblemType(ts, TS_NONLINEAR));
  PetscCall(TSSetType(ts, FLEXIPDE_TSLEAPFROG));
  PetscCall(TSSetRHSFunction(ts, nullptr, model_rhs, scene.model.get()));
  PetscCall(leapfrog_set_pairs(ts, 1));
  PetscCall(leapfrog_set_damping(ts, sigma));
  if (how == Stepping::OneSweep) PetscCall(leapfrog_set_step(ts, model_step, scene.model.get()));
  if (how >= Stepping::Split) PetscCall(leapfrog_set_split_step(ts, model_split_step, scene.model.get()));
  if (how == Stepping::SplitFormed) {
    PetscCall(TSMonitorSet(ts, forming_monitor, nullptr, nullptr));
    PetscCall(leapfrog_monitor_forms_solution(ts, forming_monitor));
  }
  if (how == Stepping::SplitWatched) PetscCall(TSMonitorSet(ts, reading_monitor, nullptr, nullptr));
  PetscCall(TSSetTimeStep(ts, dt));
  PetscCall(TSSetMaxSteps(ts, steps));
  PetscCall(TSSetMaxTime(ts, dt * (steps + 1)));
  PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
  PetscCall(TSSolve(ts, U));
  PetscFunctionReturn(0);
}

} // namespace

// A 2D or 3D second-order model's leapfrog step as one sweep over the grid, with the sponge's damped
// kicks and with a point source inside the grid (its forcing added row by row), on a grid that is not
// square, on 1 and 2 ranks:
//  * on the interleaved state (Model::second_order_step, taken for states beyond the caches when the
//    solution is watched): the three passes' numbers exactly;
//  * the split step (Model::second_order_split_step): the three passes' to round-off, exactly the same
//    numbers when a monitor forms the solution at every step, and the three passes' exactly when a
//    monitor reads the solution unannounced (every step is then a kick-drift-kick step);
//  * the Simulation's solve (split steps) is the split step's.
TEST(Leapfrog, OneSweepStepIsTheThreePasses) {
  const PetscReal dt = 2e-3;
  const PetscInt steps = 150;
  for (const std::string m : {"wave2d", "wave3d"})
  for (int source = 0; source < 2; ++source) {
    const bool three = m == "wave3d";
    ScopedOptions opts{{"-da_grid_x", three ? "31" : "37"}, {"-da_grid_y", three ? "27" : "29"}, {"-da_grid_z", "29"},
                       {"-ts_dt", "2e-3"}, {"-ts_max_time", "0.3"}, {"-ts_type", "leapfrog"}};
    opts.set("-model", m);
    opts.set("-" + m + "_c_field", "1");
    opts.set("-" + m + "_c", "0.9");
    if (source) {
      opts.set("-objective_type", "receivers");
      opts.set("-survey_sources_x", "0.31");
      opts.set("-survey_sources_y", "0.58");
      opts.set("-survey_sources_z", "0.44");
      opts.set("-survey_receivers_spread", "0.1,0.9,5");
      opts.set("-survey_receivers_y", "0.2");
      opts.set("-survey_receivers_z", "0.6");
      opts.set("-" + m + "_ic", "zero");
      opts.set("-" + m + "_sponge_width", "0");
    } else {
      opts.set("-" + m + "_ic", "pulse");
      opts.set("-" + m + "_ic_x", "0.3");
      opts.set("-" + m + "_sponge_width", "0.2");
    }
    Scene scene;
    OwnedVec p, simulation, passes, sweep, sigma;
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    ASSERT_TRUE(scene.model->has_second_order_step());
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
    { // a speed that varies from point to point
      PetscScalar *a;
      PetscInt lo, hi;
      PETSC_ASSERT_OK(VecGetOwnershipRange(p, &lo, &hi));
      PETSC_ASSERT_OK(VecGetArray(p, &a));
      for (PetscInt i = lo; i < hi; ++i) a[i - lo] = 0.9 + 0.1 * std::sin(0.37 * (PetscReal)i);
      PETSC_ASSERT_OK(VecRestoreArray(p, &a));
    }
    PETSC_ASSERT_OK(scene.sim.create_state(simulation.out()));
    PETSC_ASSERT_OK(VecDuplicate(simulation, passes.out()));
    PETSC_ASSERT_OK(VecDuplicate(simulation, sweep.out()));
    PETSC_ASSERT_OK(scene.sim.forward(p, simulation));
    ASSERT_EQ(scene.sim.stats().steps, steps);
    Vec damping = nullptr;
    if (!source) { // sigma = -G_p at U = (0, 1): G_p = a(q) - sigma p, and a(0) = 0
      OwnedVec u;
      PETSC_ASSERT_OK(VecDuplicate(simulation, u.out()));
      PETSC_ASSERT_OK(VecDuplicate(simulation, sigma.out()));
      PETSC_ASSERT_OK(VecStrideSet(u, 0, 0.0));
      PETSC_ASSERT_OK(VecStrideSet(u, 1, 1.0));
      PETSC_ASSERT_OK(scene.model->rhs(0.0, u, sigma));
      PETSC_ASSERT_OK(VecScale(sigma, -1.0));
      PETSC_ASSERT_OK(VecStrideSet(sigma, 0, 0.0));
      PetscReal smax;
      PETSC_ASSERT_OK(VecMax(sigma, nullptr, &smax));
      EXPECT_GT(smax, 0.0) << "the sponge damps";
      damping = sigma;
    }
    OwnedVec split, formed, watched;
    PETSC_ASSERT_OK(VecDuplicate(simulation, split.out()));
    PETSC_ASSERT_OK(VecDuplicate(simulation, formed.out()));
    PETSC_ASSERT_OK(VecDuplicate(simulation, watched.out()));
    PETSC_ASSERT_OK(leapfrog_solve(scene, p, damping, dt, steps, Stepping::Passes, passes));
    PETSC_ASSERT_OK(leapfrog_solve(scene, p, damping, dt, steps, Stepping::OneSweep, sweep));
    PETSC_ASSERT_OK(leapfrog_solve(scene, p, damping, dt, steps, Stepping::Split, split));
    PETSC_ASSERT_OK(leapfrog_solve(scene, p, damping, dt, steps, Stepping::SplitFormed, formed));
    PETSC_ASSERT_OK(leapfrog_solve(scene, p, damping, dt, steps, Stepping::SplitWatched, watched));
    const auto max_diff = [](Vec a, Vec b) {
      OwnedVec d;
      PetscReal r = -1;
      if (VecDuplicate(a, d.out()) || VecWAXPY(d, -1.0, b, a) || VecNorm(d, NORM_INFINITY, &r)) return -1.0;
      return (double)r;
    };
    PetscReal scale;
    PETSC_ASSERT_OK(VecNorm(passes, NORM_INFINITY, &scale));
    const double d_sweep = max_diff(sweep, passes), d_split = max_diff(split, passes), d_formed = max_diff(formed, split),
                 d_watched = max_diff(watched, passes), d_sim = max_diff(simulation, split);
    PetscPrintf(PETSC_COMM_WORLD,
                "  %s, %s: max |U| %.3e; max |diff| against three passes: one sweep %.3e, split %.3e, split watched %.3e; "
                "against split: formed every step %.3e, Simulation %.3e\n",
                m.c_str(), source ? "point source" : "sponge", (double)scale, d_sweep, d_split, d_watched, d_formed, d_sim);
    EXPECT_GT(scale, 1e-3);
    EXPECT_EQ(d_sweep, 0.0);
    EXPECT_GE(d_split, 0.0);
    EXPECT_LE(d_split, 1e-13 * scale);
    EXPECT_EQ(d_formed, 0.0);
    EXPECT_EQ(d_watched, 0.0);
    EXPECT_EQ(d_sim, 0.0);
  }
}
