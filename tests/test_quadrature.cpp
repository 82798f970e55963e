// Time-integrated objectives (quadrature TS in Simulation, TimeVariation objective) on the
// advection-diffusion model, J = int_0^T ||G(t, U; p)||^2 dt (-objective_type time_variation):
//   - value() against the exact integral of a travelling sinusoid,
//   - Taylor tests of the gradient with respect to the amplitude, a, scalar D and field D, for
//     -ts_type rk (rk4) and cn,
//   - the gradient against central differences of value(), and value() against gradient()'s J,
//   - binomial checkpointing (-checkpoint_budget 3) against full storage,
//   - a parallel run against a serial one (PETSC_COMM_SELF on every rank).
// Scenes are small (32-48 points, 20-40 steps) so that the whole file runs in seconds.
#include "flexipde/scene.hpp"
#include "flexipde/taylor.hpp"
#include "test_support.hpp"
#include <cmath>
#include <cstring>
#include <string>

using namespace flexipde;
using flexipde_test::fill_random;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

using Options = std::vector<std::pair<const char *, const char *>>;
const char *const two_pi = "6.283185307179586";

// The scene of every test: a Gaussian pulse advected and diffused on [0, 2 pi), the time variation
// as objective, a, D and the initial amplitude as parameters (options may drop some).
void base_options(ScopedOptions &o, PetscInt n) {
  o.set("-model", "advection");
  o.set("-grid_periodic", "1");
  o.set("-grid_x0", "0");
  o.set("-grid_x1", two_pi);
  o.set("-da_grid_x", std::to_string(n));
  o.set("-objective_type", "time_variation");
  o.set("-advection_ic", "gaussian");
  o.set("-advection_ic_width", "0.8");
  o.set("-advection_a", "0.7");
  o.set("-advection_D", "0.05");
  o.set("-advection_ic_amplitude_param", "1");
  o.set("-ts_max_time", "0.5");
  o.set("-ts_dt", "0.025");
}

// A direction that moves one named parameter only (all entries of a field alike positive).
PetscErrorCode direction_for(const Scene &s, const char *name, Vec d) {
  const PetscInt k = s.params.find(name);
  PetscFunctionBeginUser;
  PetscCheck(k >= 0, PETSC_COMM_WORLD, PETSC_ERR_ARG_WRONG, "no parameter %s", name);
  PetscCall(VecSet(d, 0.0));
  if (s.params.info(k).kind == ParamKind::Field) {
    OwnedVec f;
    PetscCall(DMCreateGlobalVector(s.grid.dm(), f.out()));
    PetscCall(fill_random(f, 0.2, 1.0, 17));
    PetscCall(s.params.set_field(d, k, f));
  } else {
    PetscCall(s.params.set_scalar(d, k, 1.0));
  }
  PetscFunctionReturn(0);
}

// ---------------------------------------------------------------------------------------------
// value() of a pure advection of u0 = A sin x: u(t) = A sin(x - a t) exactly in time for the
// semi-discrete fd2 scheme up to the integrator's error, u_t = -a (D1 u) with |D1 symbol| =
// sin(h)/h, so ||u_t||^2 = a^2 A^2 (sin h / h)^2 N / 2 at every t and J = T times that.

TEST(Quadrature, ValueOfTravellingSinusoid) {
  ScopedOptions o;
  base_options(o, 32);
  o.set("-advection_ic", "sinusoid");
  o.set("-advection_ic_mode", "1");
  o.set("-advection_ic_amplitude", "1.5");
  o.set("-advection_ic_amplitude_param", "0");
  o.set("-advection_diffusion", "0");
  o.set("-advection_a", "0.8");
  o.set("-ts_dt", "0.01");
  Scene s;
  OwnedVec p;
  PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(s.params.create_vec(p.out()));
  PETSC_ASSERT_OK(s.parameters_from_options("", p));
  PetscReal J;
  PETSC_ASSERT_OK(s.sim.value(p, &J));
  const PetscReal N = 32, h = 2 * PETSC_PI / N, k = std::sin(h) / h;
  const PetscReal exact = 0.5 * 0.8 * 0.8 * 1.5 * 1.5 * k * k * N / 2;
  PetscPrintf(PETSC_COMM_WORLD, "  J = %.12e, exact %.12e, rel diff %.2e\n", (double)J, (double)exact,
              (double)rel_diff(J, exact));
  EXPECT_LT(rel_diff(J, exact), 1e-6);
}

// ---------------------------------------------------------------------------------------------
// Taylor tests: r1 ~ eps (ratio 2), r2 ~ eps^2 (ratio 4).

struct TaylorCase {
  const char *name;
  const char *parameter; // the one the direction moves
  const char *ts_type;
  Options options;
};
std::ostream &operator<<(std::ostream &os, const TaylorCase &c) { return os << c.name; }

class QuadratureTaylor : public ::testing::TestWithParam<TaylorCase> {};

TEST_P(QuadratureTaylor, Converges) {
  const TaylorCase &tc = GetParam();
  ScopedOptions opts;
  base_options(opts, 32);
  opts.set("-ts_type", tc.ts_type);
  if (!std::strcmp(tc.ts_type, "rk")) opts.set("-ts_rk_type", "4");
  for (auto &kv : tc.options) opts.set(kv.first, kv.second);
  Scene scene;
  OwnedVec p, d;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(VecDuplicate(p, d.out()));
  PETSC_ASSERT_OK(direction_for(scene, tc.parameter, d));
  auto f = [&](Vec q, PetscReal *J, Vec g) { return scene.sim.gradient(q, J, g, nullptr); };
  TaylorResult tr;
  PETSC_ASSERT_OK(taylor_test(f, p, d, 1e-3, 5, tr));
  PetscPrintf(PETSC_COMM_WORLD, "  Taylor [%s]: g.d = %.6e\n", tc.name, (double)tr.gd);
  for (size_t k = 0; k < tr.eps.size(); ++k)
    PetscPrintf(PETSC_COMM_WORLD, "  %10.3e %12.5e %7.3f %12.5e %7.3f\n", (double)tr.eps[k], (double)tr.r1[k],
                k ? (double)tr.ratio1(k) : 0.0, (double)tr.r2[k], k ? (double)tr.ratio2(k) : 0.0);
  const size_t last = tr.eps.size() - 1;
  EXPECT_GT(std::fabs(tr.gd), 0.0);
  EXPECT_NEAR(tr.ratio1(last), 2.0, 0.2);
  EXPECT_NEAR(tr.ratio2(last), 4.0, 0.5) << "gradient is not the derivative of J";
}

INSTANTIATE_TEST_SUITE_P(
    TimeVariation, QuadratureTaylor,
    ::testing::Values(TaylorCase{"amplitude_rk4", "advection_ic_amplitude", "rk", {}},
                      TaylorCase{"a_rk4", "advection_a", "rk", {}},
                      TaylorCase{"D_rk4", "advection_D", "rk", {}},
                      TaylorCase{"D_field_rk4", "advection_D", "rk", {{"-advection_D_field", "1"}}},
                      TaylorCase{"amplitude_cn", "advection_ic_amplitude", "cn", {}},
                      TaylorCase{"a_cn", "advection_a", "cn", {}},
                      TaylorCase{"D_cn", "advection_D", "cn", {}},
                      TaylorCase{"D_field_cn", "advection_D", "cn", {{"-advection_D_field", "1"}}}),
    [](const ::testing::TestParamInfo<TaylorCase> &i) { return std::string(i.param.name); });

// ---------------------------------------------------------------------------------------------
// The gradient against central differences of value() for every scalar parameter, and value()
// against the J that gradient() returns.

class QuadratureFD : public ::testing::TestWithParam<const char *> {};

TEST_P(QuadratureFD, GradientMatchesCentralDifferences) {
  const std::string ts_type = GetParam();
  ScopedOptions opts;
  base_options(opts, 32);
  opts.set("-ts_type", ts_type);
  if (ts_type == "rk") opts.set("-ts_rk_type", "4");
  Scene s;
  OwnedVec p, g, q;
  PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(s.params.create_vec(p.out()));
  PETSC_ASSERT_OK(s.parameters_from_options("", p));
  PETSC_ASSERT_OK(VecDuplicate(p, g.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, q.out()));
  PetscReal Jg, Jv;
  PETSC_ASSERT_OK(s.sim.gradient(p, &Jg, g, nullptr));
  PETSC_ASSERT_OK(s.sim.value(p, &Jv));
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] J = %.12e (gradient), %.12e (value)\n", ts_type.c_str(), (double)Jg, (double)Jv);
  EXPECT_GT(Jg, 0.0);
  EXPECT_LT(rel_diff(Jg, Jv), 1e-13);
  for (const char *name : {"advection_a", "advection_D", "advection_ic_amplitude"}) {
    const PetscInt k = s.params.find(name);
    ASSERT_GE(k, 0);
    PetscReal pk, gk, Jp, Jm;
    const PetscReal h = 1e-5;
    PETSC_ASSERT_OK(s.params.scalar(p, k, &pk));
    PETSC_ASSERT_OK(s.params.scalar(g, k, &gk));
    PETSC_ASSERT_OK(VecCopy(p, q));
    PETSC_ASSERT_OK(s.params.set_scalar(q, k, pk + h));
    PETSC_ASSERT_OK(s.sim.value(q, &Jp));
    PETSC_ASSERT_OK(s.params.set_scalar(q, k, pk - h));
    PETSC_ASSERT_OK(s.sim.value(q, &Jm));
    const PetscReal fd = (Jp - Jm) / (2 * h);
    PetscPrintf(PETSC_COMM_WORLD, "  [%s] dJ/d%s: adjoint %.12e, central difference %.12e, rel diff %.2e\n",
                ts_type.c_str(), name, (double)gk, (double)fd, (double)rel_diff(gk, fd));
    EXPECT_LT(rel_diff(gk, fd), 1e-7) << name;
  }
}

INSTANTIATE_TEST_SUITE_P(TimeVariation, QuadratureFD, ::testing::Values("rk", "cn"));

// ---------------------------------------------------------------------------------------------
// Binomial checkpointing re-runs forward steps with TSStep during the adjoint; the integral is
// accumulated by TSSolve only, so J and the gradient must equal full storage's.

class QuadratureCheckpoint : public ::testing::TestWithParam<const char *> {};

TEST_P(QuadratureCheckpoint, BudgetMatchesFullStorage) {
  const std::string ts_type = GetParam();
  ScopedOptions opts;
  base_options(opts, 32);
  opts.set("-ts_type", ts_type);
  if (ts_type == "rk") opts.set("-ts_rk_type", "4");
  opts.set("-advection_D_field", "1");
  Scene s;
  OwnedVec p, g_full, g_ckpt, u_full, u_ckpt;
  PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(s.params.create_vec(p.out()));
  PETSC_ASSERT_OK(s.parameters_from_options("", p));
  PETSC_ASSERT_OK(VecDuplicate(p, g_full.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, g_ckpt.out()));
  PETSC_ASSERT_OK(s.sim.create_state(u_full.out()));
  PETSC_ASSERT_OK(s.sim.create_state(u_ckpt.out()));
  PetscReal J_full, J_ckpt;
  PETSC_ASSERT_OK(s.sim.gradient(p, &J_full, g_full, u_full));
  {
    ScopedOptions budget{{"-checkpoint_budget", "3"}};
    PETSC_ASSERT_OK(s.sim.gradient(p, &J_ckpt, g_ckpt, u_ckpt));
    EXPECT_EQ(s.sim.checkpoint_stats().budget, 3);
    EXPECT_GT(s.sim.checkpoint_stats().recomputed_steps, s.sim.stats().steps - 1);
  }
  const PetscReal dg = rel_diff(g_ckpt, g_full), du = rel_diff(u_ckpt, u_full);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] J %.12e vs %.12e, gradient rel diff %.2e, dJ/dU0 rel diff %.2e\n",
              ts_type.c_str(), (double)J_ckpt, (double)J_full, (double)dg, (double)du);
  EXPECT_LT(rel_diff(J_ckpt, J_full), 1e-14);
  EXPECT_LT(dg, 1e-12);
  EXPECT_LT(du, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(TimeVariation, QuadratureCheckpoint, ::testing::Values("rk", "cn"));

// ---------------------------------------------------------------------------------------------
// The same field-D scene on PETSC_COMM_WORLD and on PETSC_COMM_SELF: identical up to round-off.

class QuadratureRanks : public ::testing::TestWithParam<const char *> {};

TEST_P(QuadratureRanks, ParallelMatchesSerial) {
  const std::string ts_type = GetParam();
  ScopedOptions opts;
  base_options(opts, 48);
  opts.set("-ts_type", ts_type);
  if (ts_type == "rk") opts.set("-ts_rk_type", "4");
  opts.set("-advection_D_field", "1");
  Scene par, ser;
  OwnedVec ppar, pser, gpar, gser;
  PETSC_ASSERT_OK(par.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(ser.setup(PETSC_COMM_SELF));
  PETSC_ASSERT_OK(par.params.create_vec(ppar.out()));
  PETSC_ASSERT_OK(ser.params.create_vec(pser.out()));
  PETSC_ASSERT_OK(par.parameters_from_options("", ppar));
  PETSC_ASSERT_OK(ser.parameters_from_options("", pser));
  PETSC_ASSERT_OK(VecDuplicate(ppar, gpar.out()));
  PETSC_ASSERT_OK(VecDuplicate(pser, gser.out()));
  PetscReal Jpar, Jser;
  PETSC_ASSERT_OK(par.sim.gradient(ppar, &Jpar, gpar, nullptr));
  PETSC_ASSERT_OK(ser.sim.gradient(pser, &Jser, gser, nullptr));
  std::vector<PetscReal> a, b;
  PETSC_ASSERT_OK(flexipde_test::gather_all(gpar, a));
  PETSC_ASSERT_OK(flexipde_test::gather_all(gser, b));
  ASSERT_EQ(a.size(), b.size());
  flexipde_test::expect_matches_serial(ts_type, Jpar, Jser, a, b);
}

INSTANTIATE_TEST_SUITE_P(TimeVariation, QuadratureRanks, ::testing::Values("rk", "cn"));

} // namespace
