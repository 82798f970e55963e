// Implicit theta methods on linear models with constant dG/dU (Simulation::use_shifted_operator): the
// shifted matrix shift*I - A is assembled and factored only when the shift or the parameters
// change, instead of at every step and adjoint stage (one rank, and on several ranks with the
// redundant LU that small operators get there; with MUMPS PETSc's own path runs).
//   - the same J and gradient as PETSc's own path (-adjoint_petsc_step: PETSc forming and factoring
//     every time, and its own adjoint step), for
//     cn, beuler and theta (midpoint), advection (schemes, scalar and field D) and the wave, with
//     the matrix built a handful of times instead of once per step;
//   - never stale: a gradient at p2 after one at p1 (and after a forward and a value at other
//     parameters) equals a fresh Simulation's gradient at p2, and likewise after a change of dt;
//   - binomial checkpointing (steps re-run inside the adjoint) gives the full-storage gradient.
#include "flexipde/scene.hpp"
#include "test_support.hpp"
#include <cmath>
#include <string>

using namespace flexipde;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

using Options = std::vector<std::pair<const char *, const char *>>;
using Problem = flexipde_test::SceneProblem;

struct ReuseCase {
  const char *name;
  Options options;
  bool few_builds = true; // false: checkpointing re-runs forward steps inside the adjoint
};
std::ostream &operator<<(std::ostream &os, const ReuseCase &c) { return os << c.name; }

const Options advection = {{"-model", "advection"},    {"-grid_periodic", "1"}, {"-grid_x0", "0"},
                           {"-grid_x1", "6.283185307179586"}, {"-da_grid_x", "64"}, {"-ts_max_time", "0.5"},
                           {"-ts_dt", "0.01"}};
const Options wave = {{"-da_grid_x", "81"}, {"-ts_max_time", "0.2"}, {"-ts_dt", "4e-3"}, {"-wave_c_field", "1"},
                      {"-wave_c", "0.9"},   {"-true_wave_c", "1.0"}};

Options with(Options base, const Options &more) {
  base.insert(base.end(), more.begin(), more.end());
  return base;
}

struct GradientRun {
  PetscReal J = 0;
  OwnedVec g;
  PetscInt builds = 0, steps = 0;
};

// J and dJ/dp at the scene's p in a fresh Problem, and how often the shifted matrix was built; petsc:
// PETSc's own path (never builds it).
PetscErrorCode gradient_once(bool petsc, GradientRun &r) {
  ScopedOptions o;
  if (petsc) o.set("-adjoint_petsc_step", "1");
  Problem pb;
  PetscFunctionBeginUser;
  PetscCall(pb.setup(PETSC_COMM_WORLD));
  PetscCall(VecDuplicate(pb.p, r.g.out()));
  const PetscInt before = pb.scene.sim.shifted_operator_builds();
  PetscCall(pb.scene.sim.gradient(pb.p, &r.J, r.g, nullptr));
  r.builds = pb.scene.sim.shifted_operator_builds() - before;
  r.steps = pb.scene.sim.stats().steps;
  PetscFunctionReturn(0);
}

class ThetaReuse : public ::testing::TestWithParam<ReuseCase> {};

} // namespace

TEST_P(ThetaReuse, SameGradientAsReformingEveryStep) {
  ScopedOptions opts;
  for (auto &o : GetParam().options) opts.set(o.first, o.second);
  GradientRun reuse, every;
  PETSC_ASSERT_OK(gradient_once(false, reuse));
  PETSC_ASSERT_OK(gradient_once(true, every));
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] J = %.15e, rel diff J %.2e, gradient %.2e; shifted matrix built %d times in %d steps\n",
              GetParam().name, (double)reuse.J, (double)rel_diff(reuse.J, every.J), (double)rel_diff(reuse.g, every.g),
              (int)reuse.builds, (int)reuse.steps);
  EXPECT_GT(reuse.J, 0.0);
  EXPECT_LE(rel_diff(reuse.J, every.J), 1e-12);
  EXPECT_LE(rel_diff(reuse.g, every.g), 1e-12);
  EXPECT_EQ(every.builds, 0);
  // Once for the forward's shift, and again only where the adjoint's dt (a difference of stored
  // times) differs from it in the last bits. With checkpointing, the re-run forward steps and the
  // adjoint steps between them can alternate between two such shifts: still never more often than
  // PETSc itself (at every step and stage).
  // (On 2 ranks too: the redundant LU of these small operators reuses its factors like the serial one.)
  EXPECT_GE(reuse.builds, 1);
  EXPECT_LE(reuse.builds, GetParam().few_builds ? 2 + reuse.steps / 4 : 2 * reuse.steps + 2);
}

INSTANTIATE_TEST_SUITE_P(
    Implicit, ThetaReuse,
    ::testing::Values(
        ReuseCase{"advection_upwind_cn", with(advection, {{"-ts_type", "cn"}, {"-advection_scheme", "upwind"},
                                                           {"-advection_a", "0.8"}, {"-true_advection_a", "1.0"}})},
        ReuseCase{"advection_fd4_D_field_cn",
                  with(advection, {{"-ts_type", "cn"}, {"-advection_scheme", "fd4"}, {"-advection_D_field", "1"},
                                   {"-advection_D", "0.1"}, {"-true_advection_D", "0.15"}})},
        ReuseCase{"advection_fd2_D_beuler", with(advection, {{"-ts_type", "beuler"}, {"-advection_D", "0.1"},
                                                              {"-advection_a", "0.8"}, {"-true_advection_a", "1.0"}})},
        ReuseCase{"advection_fd2_theta_midpoint",
                  with(advection, {{"-ts_type", "theta"}, {"-ts_theta_theta", "0.6"}, {"-advection_a", "0.8"},
                                   {"-true_advection_a", "1.0"}})},
        ReuseCase{"wave_cn", with(wave, {{"-ts_type", "cn"}})},
        ReuseCase{"wave_theta_endpoint",
                  with(wave, {{"-ts_type", "theta"}, {"-ts_theta_theta", "0.7"}, {"-ts_theta_endpoint", "1"}})},
        ReuseCase{"advection_cn_checkpointed", with(advection, {{"-ts_type", "cn"}, {"-checkpoint_budget", "4"},
                                                                 {"-advection_a", "0.8"}, {"-true_advection_a", "1.0"}}), false}),
    [](const ::testing::TestParamInfo<ReuseCase> &i) { return std::string(i.param.name); });

// A stale factorisation must be impossible: after solves at other parameters (gradient, forward,
// value) or another dt, a gradient equals the one a fresh Simulation computes.
TEST(ThetaReuse, NeverStaleAfterParameterOrStepChange) {
  for (const char *ts : {"cn", "beuler"}) {
    ScopedOptions opts;
    for (auto &o : with(advection, {{"-ts_type", ts}, {"-advection_scheme", "fd4"}, {"-advection_D_field", "1"},
                                    {"-advection_D", "0.1"}, {"-true_advection_D", "0.15"}, {"-advection_a", "0.9"}}))
      opts.set(o.first, o.second);
    Problem used, fresh;
    PETSC_ASSERT_OK(used.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(fresh.setup(PETSC_COMM_WORLD));
    OwnedVec p2, g1, g2, gf, U;
    PETSC_ASSERT_OK(VecDuplicate(used.p, p2.out()));
    PETSC_ASSERT_OK(flexipde_test::fill_random(p2, 0.05, 0.2, 11)); // another D field (and a)
    PETSC_ASSERT_OK(VecDuplicate(used.p, g1.out()));
    PETSC_ASSERT_OK(VecDuplicate(used.p, g2.out()));
    PETSC_ASSERT_OK(VecDuplicate(used.p, gf.out()));
    PETSC_ASSERT_OK(used.scene.sim.create_state(U.out()));
    PetscReal J1, J2, J3, Jf, Jv;
    PETSC_ASSERT_OK(used.scene.sim.gradient(used.p, &J1, g1, nullptr)); // p1
    PETSC_ASSERT_OK(used.scene.sim.gradient(p2, &J2, g2, nullptr));     // then p2
    PETSC_ASSERT_OK(fresh.scene.sim.gradient(p2, &Jf, gf, nullptr));    // p2 only
    PetscPrintf(PETSC_COMM_WORLD, "  [%s] after p1: rel diff J %.2e, gradient %.2e (p1 vs p2 gradients differ by %.2e)\n", ts,
                (double)rel_diff(J2, Jf), (double)rel_diff(g2, gf), (double)rel_diff(g1, gf));
    EXPECT_GT(rel_diff(g1, gf), 1e-3); // the parameters matter
    EXPECT_LE(rel_diff(J2, Jf), 1e-12);
    EXPECT_LE(rel_diff(g2, gf), 1e-12);

    // A forward and a value at p1 in between, then p2 again.
    PETSC_ASSERT_OK(used.scene.sim.forward(used.p, U));
    PETSC_ASSERT_OK(used.scene.sim.value(used.p, &Jv));
    EXPECT_LE(rel_diff(Jv, J1), 1e-12);
    PETSC_ASSERT_OK(used.scene.sim.gradient(p2, &J2, g2, nullptr));
    EXPECT_LE(rel_diff(J2, Jf), 1e-12);
    EXPECT_LE(rel_diff(g2, gf), 1e-12);

    // Another dt: the shift changes, so the matrix must be rebuilt. The reference is the same
    // Simulation (same data) with PETSc forming the matrix at every step.
    {
      ScopedOptions dt{{"-ts_dt", "0.02"}};
      PETSC_ASSERT_OK(used.scene.sim.gradient(p2, &J2, g2, nullptr));
      {
        ScopedOptions every{{"-adjoint_petsc_step", "1"}};
        PETSC_ASSERT_OK(used.scene.sim.gradient(p2, &J3, g1, nullptr));
      }
      PetscPrintf(PETSC_COMM_WORLD, "  [%s] after dt change: rel diff J %.2e, gradient %.2e (vs dt 0.01: %.2e)\n", ts,
                  (double)rel_diff(J2, J3), (double)rel_diff(g2, g1), (double)rel_diff(g1, gf));
      EXPECT_GT(rel_diff(g1, gf), 1e-6); // dt matters
      EXPECT_LE(rel_diff(J2, J3), 1e-12);
      EXPECT_LE(rel_diff(g2, g1), 1e-12);
    }
    // And back to dt 0.01 (the option's scope ended): the fresh gradient at p2 again.
    PETSC_ASSERT_OK(used.scene.sim.gradient(p2, &J2, g2, nullptr));
    EXPECT_LE(rel_diff(J2, Jf), 1e-12);
    EXPECT_LE(rel_diff(g2, gf), 1e-12);
  }
}
