// Regression tests for library bugs found while writing the suite (adaptive RK stopping early,
// explicit Euler and theta < 1/2 not refused); each failed before its fix.
// Run them with:   build/tests/unit_tests --gtest_filter='Regressions*'
#include "flexipde/scene.hpp"
#include "test_support.hpp"

using namespace flexipde;
using flexipde_test::QuietErrors;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

// ||U(T)|| from forward() under the current options, or NAN if forward() failed.
PetscReal final_norm() {
  Scene scene;
  if (scene.setup(PETSC_COMM_WORLD)) return NAN;
  OwnedVec p, U;
  if (scene.params.create_vec(p.out()) || scene.parameters_from_options("", p) || scene.sim.create_state(U.out()))
    return NAN;
  QuietErrors q;
  if (scene.sim.forward(p, U)) return NAN;
  return flexipde_test::norm(U);
}

const std::initializer_list<std::pair<const char *, const char *>> scene_opts = {
    {"-da_grid_x", "101"}, {"-ts_max_time", "1"}, {"-ts_dt", "2e-3"}, {"-wave_c", "1"}};

} // namespace

// Simulation::create_ts sets TSSetMaxSteps(round(T/dt)). With an adaptive RK tableau (5dp, 3bs, ...
// get TSADAPTBASIC by default) the controller may shrink the step, and TSSolve then stops at the
// step limit before T, silently: stats() still reports T. Here it stops at t ~ 0.32 instead of 1.
TEST(Regressions, AdaptiveRkStopsBeforeFinalTime) {
  ScopedOptions base(scene_opts);
  PetscReal reference, adaptive;
  {
    ScopedOptions o{{"-ts_rk_type", "4"}, {"-ts_dt", "1e-4"}};
    reference = final_norm();
  }
  {
    ScopedOptions o{{"-ts_rk_type", "5dp"}, {"-ts_rtol", "1e-10"}, {"-ts_atol", "1e-10"}};
    adaptive = final_norm();
  }
  ASSERT_TRUE(std::isfinite(reference));
  EXPECT_LE(rel_diff(adaptive, reference), 1e-6) << "||U(T)|| rk4 fine = " << reference << ", 5dp adaptive = " << adaptive;
}

// The stability check only looks at -ts_type rk. Forward Euler (explicit, unstable for the wave's
// imaginary spectrum at any dt) runs and returns a blown-up but finite state (||U(T)|| ~ 8e13),
// contradicting "Explicit steps beyond the stability limit ... are refused before the run".
TEST(Regressions, ExplicitEulerIsNotRefused) {
  ScopedOptions base(scene_opts);
  ScopedOptions o{{"-ts_type", "euler"}};
  const PetscReal n = final_norm();
  EXPECT_TRUE(std::isnan(n)) << "forward() with -ts_type euler succeeded with ||U(T)|| = " << n;
}

// check_stability assumes every theta method is A-stable ("theta >= 1/2"), but -ts_theta_theta
// below 1/2 is accepted and unstable for the wave: ||U(T)|| ~ 5e4 instead of ~25.
TEST(Regressions, ThetaBelowOneHalfIsNotRefused) {
  ScopedOptions base(scene_opts);
  ScopedOptions o{{"-ts_type", "theta"}, {"-ts_theta_theta", "0.3"}};
  const PetscReal n = final_norm();
  EXPECT_TRUE(std::isnan(n) || n < 100) << "forward() with theta = 0.3 succeeded with ||U(T)|| = " << n;
}
