// Simulation::gradient (TSAdjoint): Taylor tests for several integrators, parameterisations and
// objectives, a Taylor test of dJ/dU0 through the pulse centre, and agreement of J and dJ/dp
// between a parallel run (PETSC_COMM_WORLD) and a serial one (PETSC_COMM_SELF on every rank).
//
// A Taylor test passes when r1 = |J(p+eps d) - J(p)| falls like eps (ratio ~2 per halving) and
// r2 = |J(p+eps d) - J(p) - eps g.d| like eps^2 (ratio ~4): true iff g is the derivative of J.
#include "flexipde/scene.hpp"
#include "flexipde/taylor.hpp"
#include "test_support.hpp"
#include <cmath>

using namespace flexipde;
using flexipde_test::fill_random;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

// A small scene with synthetic data from the true parameters (-true_*) and p from (-wave_*).
using Problem = flexipde_test::SceneProblem;

void print_taylor(const char *label, const TaylorResult &tr) {
  PetscPrintf(PETSC_COMM_WORLD, "  Taylor [%s]: g.d = %.6e\n  %10s %12s %7s %12s %7s\n", label, (double)tr.gd, "eps",
              "r1", "ratio", "r2", "ratio");
  for (size_t k = 0; k < tr.eps.size(); ++k)
    PetscPrintf(PETSC_COMM_WORLD, "  %10.3e %12.5e %7.3f %12.5e %7.3f\n", (double)tr.eps[k], (double)tr.r1[k],
                k ? (double)tr.ratio1(k) : 0.0, (double)tr.r2[k], k ? (double)tr.ratio2(k) : 0.0);
}

struct TaylorCase {
  const char *name;
  std::vector<std::pair<const char *, const char *>> options;
  PetscReal eps0;
  PetscInt levels;
};

std::ostream &operator<<(std::ostream &os, const TaylorCase &c) { return os << c.name; }

class GradientTaylor : public ::testing::TestWithParam<TaylorCase> {};

// Common scene: 101 points on [0,1], pulse at 0.5 of width 0.2, T = 0.3.
const std::vector<std::pair<const char *, const char *>> base_options = {
    {"-da_grid_x", "101"}, {"-ts_max_time", "0.3"}, {"-ts_dt", "2e-3"}};

} // namespace

TEST_P(GradientTaylor, Converges) {
  const TaylorCase &tc = GetParam();
  ScopedOptions opts;
  for (auto &o : base_options) opts.set(o.first, o.second);
  for (auto &o : tc.options) opts.set(o.first, o.second);
  Problem pb;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  OwnedVec d;
  PETSC_ASSERT_OK(VecDuplicate(pb.p, d.out()));
  PETSC_ASSERT_OK(fill_random(d, -1.0, 1.0, 7));
  auto f = [&](Vec q, PetscReal *J, Vec g) { return pb.scene.sim.gradient(q, J, g, nullptr); };
  TaylorResult tr;
  PETSC_ASSERT_OK(taylor_test(f, pb.p, d, tc.eps0, tc.levels, tr));
  print_taylor(tc.name, tr);
  ASSERT_EQ(tr.eps.size(), (size_t)tc.levels);
  EXPECT_GT(std::fabs(tr.gd), 0.0);
  const size_t last = tr.eps.size() - 1;
  EXPECT_GE(tr.ratio1(last), 1.8);
  EXPECT_LE(tr.ratio1(last), 2.2);
  EXPECT_GE(tr.ratio2(last), 3.5) << "gradient is not the derivative of J";
  EXPECT_LE(tr.ratio2(last), 4.5) << "gradient is not the derivative of J";
  // r2 must be well below r1 at every level (the gradient captures the first-order change).
  for (size_t k = 0; k < tr.eps.size(); ++k) EXPECT_LT(tr.r2[k], 0.5 * tr.r1[k]);
  // The integrator requested is the one that ran, with a whole number of steps to T.
  const SimulationStats &st = pb.scene.sim.stats();
  EXPECT_NEAR(st.final_time, 0.3, 1e-14);
  EXPECT_NEAR(st.steps * st.dt, 0.3, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(
    Wave, GradientTaylor,
    ::testing::Values(
        TaylorCase{"scalar_rk4",
                   {{"-ts_type", "rk"}, {"-ts_rk_type", "4"}, {"-wave_c", "0.9"}, {"-true_wave_c", "1.0"}},
                   1e-2,
                   4},
        TaylorCase{"scalar_cn",
                   {{"-ts_type", "cn"}, {"-ts_dt", "5e-3"}, {"-wave_c", "0.9"}, {"-true_wave_c", "1.0"}},
                   1e-2,
                   4},
        TaylorCase{"field_rk4",
                   {{"-ts_type", "rk"},
                    {"-ts_rk_type", "4"},
                    {"-wave_c_field", "1"},
                    {"-wave_c_profile", "linear"},
                    {"-wave_c_left", "0.85"},
                    {"-wave_c_right", "0.95"},
                    {"-true_wave_c", "1.0"},
                    {"-true_wave_c_profile", "gaussian"},
                    {"-true_wave_c_bump", "0.1"}},
                   1e-2,
                   4},
        TaylorCase{"field_beuler",
                   {{"-ts_type", "beuler"},
                    {"-ts_dt", "5e-3"},
                    {"-wave_c_field", "1"},
                    {"-wave_c", "0.9"},
                    {"-true_wave_c", "1.0"},
                    {"-true_wave_c_profile", "gaussian"},
                    {"-true_wave_c_bump", "0.1"}},
                   1e-2,
                   4},
        TaylorCase{"scalar_rk4_objective_l2",
                   {{"-ts_type", "rk"},
                    {"-ts_rk_type", "4"},
                    {"-objective_type", "l2"},
                    {"-wave_c", "0.9"},
                    {"-true_wave_c", "1.0"}},
                   1e-2,
                   4},
        TaylorCase{"scalar_rk4_objective_on_v",
                   {{"-ts_rk_type", "4"}, {"-objective_component", "v"}, {"-wave_c", "0.9"}, {"-true_wave_c", "1.0"}},
                   1e-2,
                   4},
        TaylorCase{"field_fd4_periodic_rk3",
                   {{"-ts_rk_type", "3"},
                    {"-fd_order", "4"},
                    {"-grid_periodic", "1"},
                    {"-wave_c_field", "1"},
                    {"-wave_c", "0.9"},
                    {"-true_wave_c", "1.0"},
                    {"-true_wave_c_profile", "gaussian"},
                    {"-true_wave_c_bump", "0.1"}},
                   1e-2,
                   4},
        TaylorCase{"scalar_leapfrog",
                   {{"-ts_type", "leapfrog"}, {"-wave_c", "0.9"}, {"-true_wave_c", "1.0"}},
                   1e-2,
                   4},
        TaylorCase{"field_leapfrog_fd4",
                   {{"-ts_type", "leapfrog"},
                    {"-fd_order", "4"},
                    {"-wave_c_field", "1"},
                    {"-wave_c", "0.9"},
                    {"-true_wave_c", "1.0"},
                    {"-true_wave_c_profile", "gaussian"},
                    {"-true_wave_c_bump", "0.1"}},
                   1e-2,
                   4},
        TaylorCase{"field_leapfrog_time_variation",
                   {{"-ts_type", "leapfrog"},
                    {"-objective_type", "time_variation"},
                    {"-wave_c_field", "1"},
                    {"-wave_c_profile", "linear"},
                    {"-wave_c_left", "0.85"},
                    {"-wave_c_right", "0.95"}},
                   1e-4,
                   4},
        // the sponge's damping in the kicks, receivers (an integrand that reads u alone: one kick sweep per
        // level), and binomial checkpointing re-running damped steps
        TaylorCase{"field_leapfrog_sponge_receivers",
                   {{"-ts_type", "leapfrog"},
                    {"-wave_sponge_width", "0.2"},
                    {"-wave_ic", "zero"},
                    {"-wave_c_field", "1"},
                    {"-wave_c", "0.9"},
                    {"-true_wave_c", "1.0"},
                    {"-true_wave_c_profile", "gaussian"},
                    {"-true_wave_c_bump", "0.1"},
                    {"-objective_type", "receivers"},
                    {"-survey_sources_x", "0.3"},
                    {"-survey_receivers_spread", "0.1,0.9,9"},
                    {"-checkpoint_budget", "9"}},
                   1e-2,
                   4},
        TaylorCase{"field_leapfrog_checkpoint",
                   {{"-ts_type", "leapfrog"},
                    {"-checkpoint_budget", "6"},
                    {"-wave_c_field", "1"},
                    {"-wave_c", "0.9"},
                    {"-true_wave_c", "1.0"},
                    {"-true_wave_c_profile", "gaussian"},
                    {"-true_wave_c_bump", "0.1"}},
                   1e-2,
                   4},
        TaylorCase{"field_theta0.7_rest_ic",
                   {{"-ts_type", "theta"},
                    {"-ts_theta_theta", "0.7"},
                    {"-ts_dt", "5e-3"},
                    {"-wave_ic", "rest"},
                    {"-wave_c_field", "1"},
                    {"-wave_c", "0.9"},
                    {"-true_wave_c", "1.0"},
                    {"-true_wave_c_profile", "linear"},
                    {"-true_wave_c_left", "0.9"}},
                   1e-2,
                   4}),
    [](const ::testing::TestParamInfo<TaylorCase> &i) {
      std::string s = i.param.name;
      for (auto &ch : s)
        if (!isalnum((unsigned char)ch)) ch = '_';
      return s;
    });

// The gradient is a pure function of p: repeated calls give identical J and dJ/dp, and the
// forward-only path gives the same U(T) as the one the objective saw.
TEST(Gradient, RepeatableAndConsistentWithForward) {
  ScopedOptions opts{{"-da_grid_x", "81"}, {"-ts_max_time", "0.2"}, {"-ts_dt", "2e-3"}, {"-wave_c_field", "1"},
                     {"-wave_c", "0.9"},    {"-true_wave_c", "1.0"}};
  Problem pb;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  OwnedVec g1, g2, U;
  PETSC_ASSERT_OK(VecDuplicate(pb.p, g1.out()));
  PETSC_ASSERT_OK(VecDuplicate(pb.p, g2.out()));
  PETSC_ASSERT_OK(pb.scene.sim.create_state(U.out()));
  PetscReal J1, J2, J3;
  PETSC_ASSERT_OK(pb.scene.sim.gradient(pb.p, &J1, g1, nullptr));
  PETSC_ASSERT_OK(pb.scene.sim.forward(pb.p_true, U)); // a different p in between
  PETSC_ASSERT_OK(pb.scene.sim.gradient(pb.p, &J2, g2, nullptr));
  EXPECT_EQ(J1, J2);
  EXPECT_EQ(rel_diff(g1, g2), 0.0);
  PETSC_ASSERT_OK(pb.scene.sim.forward(pb.p, U));
  PETSC_ASSERT_OK(pb.scene.objective.terminal(U, &J3, nullptr));
  EXPECT_LE(rel_diff(J1, J3), 1e-14);
  EXPECT_GT(J1, 0.0);
  // At the true parameters the misfit and its gradient vanish.
  PetscReal J0;
  PETSC_ASSERT_OK(pb.scene.sim.gradient(pb.p_true, &J0, g1, nullptr));
  EXPECT_LE(J0, 1e-28);
  EXPECT_LE(flexipde_test::norm(g1, NORM_INFINITY), 1e-12);
}

// dJ/dU0 (grad_u0) by a Taylor test along the derivative of U0 with respect to the pulse centre:
// J(x_c + eps) against J(x_c) + eps <dJ/dU0, dU0/dx_c>, with the data held fixed.
class InitialStateGradient : public ::testing::TestWithParam<const char *> {};

TEST_P(InitialStateGradient, TaylorInPulseCentre) {
  const std::string ts_type = GetParam();
  const PetscReal xc = 0.45, w = 0.15;
  ScopedOptions opts{{"-da_grid_x", "101"}, {"-ts_max_time", "0.3"}, {"-ts_dt", ts_type == "rk" ? "2e-3" : "5e-3"},
                     {"-ts_type", ts_type.c_str()}, {"-wave_c", "0.9"}, {"-true_wave_c", "1.0"},
                     {"-wave_ic_width", "0.15"}, {"-wave_ic_center", "0.45"}};
  Problem base;
  PETSC_ASSERT_OK(base.setup(PETSC_COMM_WORLD));
  OwnedVec gu0, dU0;
  PETSC_ASSERT_OK(base.scene.sim.create_state(gu0.out()));
  PETSC_ASSERT_OK(base.scene.sim.create_state(dU0.out()));
  PetscReal J0, c;
  PETSC_ASSERT_OK(base.scene.sim.gradient(base.p, &J0, nullptr, gu0));
  PETSC_ASSERT_OK(base.scene.params.scalar(base.p, 0, &c));
  { // dU0/dx_c: u0 = exp(-s^2), s = (x - x_c)/w  ->  du0/dx_c = -u0'(x);  v0 = -c u0'  ->  dv0/dx_c = c u0''
    const Grid &g = base.scene.grid;
    flexipde::Array a(dU0);
    PETSC_ASSERT_OK(a.error());
    for (PetscInt il = 0; il < g.xm(); ++il) {
      const PetscInt i = g.xs() + il;
      const PetscReal s = (g.x(i) - xc) / w, e = std::exp(-s * s);
      const PetscReal du = -2 * s / w * e, d2u = (4 * s * s - 2) / (w * w) * e;
      a[2 * il] = g.is_boundary(i) ? 0.0 : -du;
      a[2 * il + 1] = g.is_boundary(i) ? 0.0 : c * d2u;
    }
  }
  const PetscReal gd = flexipde_test::dot(gu0, dU0);
  std::vector<PetscReal> eps, r1, r2;
  PetscReal e = 1e-2;
  for (int k = 0; k < 4; ++k, e *= 0.5) {
    opts.set("-wave_ic_center", std::to_string(xc + e)); // overrides; cleared with opts
    Problem pb;
    PETSC_ASSERT_OK(pb.scene.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(VecCopy(base.scene.objective.data(), pb.scene.objective.data()));
    PetscReal J;
    PETSC_ASSERT_OK(pb.scene.sim.gradient(base.p, &J, nullptr, nullptr));
    eps.push_back(e);
    r1.push_back(std::fabs(J - J0));
    r2.push_back(std::fabs(J - J0 - e * gd));
  }
  PetscPrintf(PETSC_COMM_WORLD, "  Taylor [dJ/dU0 along dU0/dx_c, %s]: g.d = %.6e\n", ts_type.c_str(), (double)gd);
  for (size_t k = 0; k < eps.size(); ++k)
    PetscPrintf(PETSC_COMM_WORLD, "  %10.3e %12.5e %7.3f %12.5e %7.3f\n", (double)eps[k], (double)r1[k],
                k ? (double)(r1[k - 1] / r1[k]) : 0.0, (double)r2[k], k ? (double)(r2[k - 1] / r2[k]) : 0.0);
  const size_t n = eps.size() - 1;
  EXPECT_GT(std::fabs(gd), 0.0);
  EXPECT_GE(r1[n - 1] / r1[n], 1.8);
  EXPECT_LE(r1[n - 1] / r1[n], 2.2);
  EXPECT_GE(r2[n - 1] / r2[n], 3.5);
  EXPECT_LE(r2[n - 1] / r2[n], 4.5);
}

INSTANTIATE_TEST_SUITE_P(Wave, InitialStateGradient, ::testing::Values("rk", "cn", "leapfrog"));

// J and dJ/dp of the same field-c scene on PETSC_COMM_WORLD and on PETSC_COMM_SELF (each rank runs
// the serial problem): identical up to round-off, whatever the number of ranks.
class RankComparison : public ::testing::TestWithParam<const char *> {};

TEST_P(RankComparison, ParallelMatchesSerial) {
  const std::string ts_type = GetParam();
  ScopedOptions opts{{"-da_grid_x", "101"},
                     {"-ts_max_time", "0.25"},
                     {"-ts_dt", ts_type == "rk" ? "2e-3" : "5e-3"},
                     {"-ts_type", ts_type.c_str()},
                     {"-fd_order", "4"},
                     {"-wave_c_field", "1"},
                     {"-wave_c", "0.95"},
                     {"-wave_c_profile", "gaussian"},
                     {"-wave_c_bump", "-0.1"},
                     {"-wave_c_center", "0.4"},
                     {"-true_wave_c_profile", "linear"},
                     {"-true_wave_c_left", "0.9"},
                     {"-true_wave_c_right", "1.1"}};
  flexipde_test::expect_parallel_matches_serial(ts_type);
}

INSTANTIATE_TEST_SUITE_P(Wave, RankComparison, ::testing::Values("rk", "cn", "leapfrog"));
