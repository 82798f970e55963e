// Wave model derivatives: adjoint (dot-product) identities of dG/dU, dG/dp and dU0/dp, their
// consistency with finite differences of rhs() and initial_condition(), and rhs() against an
// independent evaluation of [v ; c^2 D2 u] on the gathered state (SecondDerivative::row with walls, a
// stencil cut at the ends with -wave_boundary zero_outside). The two-level start (-wave_ic two_level)
// against the plain recurrence it stands for.
//
// Scenes live on PETSC_COMM_WORLD; every check reduces to global numbers before asserting.
#include "flexipde/differentiator.hpp"
#include "flexipde/scene.hpp"
#include "test_support.hpp"
#include <tuple>

using namespace flexipde;
using flexipde_test::dot;
using flexipde_test::fill_random;
using flexipde_test::norm;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

struct Case {
  bool field;
  PetscInt order;
  bool periodic;
  bool zero_outside = false; // -wave_boundary zero_outside (else walls)
};

std::string case_name(const ::testing::TestParamInfo<Case> &i) {
  return std::string(i.param.field ? "field" : "scalar") + "_fd" + std::to_string(i.param.order) +
         (i.param.periodic ? "_periodic" : i.param.zero_outside ? "_zero_outside" : "_dirichlet");
}

// (D2 u)_i with the stencil cut at the ends (zeros outside the grid), from the weights themselves.
PetscReal d2_zero_outside(const std::vector<PetscReal> &u, PetscInt stride, PetscInt n, PetscInt i, PetscInt order,
                          PetscReal h) {
  static const PetscReal w2[3] = {1, -2, 1}, w4[5] = {-1.0 / 12, 16.0 / 12, -30.0 / 12, 16.0 / 12, -1.0 / 12};
  const PetscInt r = order / 2;
  const PetscReal *w = order == 2 ? w2 : w4;
  PetscReal s = 0;
  for (PetscInt k = -r; k <= r; ++k)
    if (i + k >= 0 && i + k < n) s += w[k + r] * u[stride * (i + k)];
  return s / (h * h);
}

class WaveDerivatives : public ::testing::TestWithParam<Case> {
protected:
  void SetUp() override {
    const Case c = GetParam();
    opts_.set("-da_grid_x", "61");
    opts_.set("-wave_c_field", c.field ? "1" : "0");
    opts_.set("-fd_order", std::to_string(c.order));
    opts_.set("-grid_periodic", c.periodic ? "1" : "0");
    opts_.set("-wave_boundary", c.zero_outside ? "zero_outside" : "walls");
    opts_.set("-wave_c", "1.1");
    opts_.set("-wave_ic_width", "0.1");
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
    if (c.field) PETSC_ASSERT_OK(fill_random(p, 0.8, 1.2, 11)); // a rough field: every entry matters
    PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
    PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 12));
    PETSC_ASSERT_OK(scene.model->set_parameters(p));
  }

  ScopedOptions opts_;
  Scene scene;
  OwnedVec p, U;
};

} // namespace

TEST_P(WaveDerivatives, SetupMatchesOptions) {
  const Case c = GetParam();
  EXPECT_EQ(scene.model->dof(), 2);
  EXPECT_STREQ(scene.model->component_name(0), "u");
  EXPECT_STREQ(scene.model->component_name(1), "v");
  EXPECT_EQ(scene.grid.stencil_width(), c.order); // 2R ghosts for the radius R = order / 2 (pointwise layer)
  EXPECT_EQ(scene.grid.periodic(), c.periodic);
  EXPECT_EQ(scene.params.count(), 1);
  EXPECT_EQ(scene.params.find("wave_c"), 0);
  EXPECT_EQ(scene.params.global_size(), c.field ? 61 : 1);
  PetscInt n;
  PETSC_ASSERT_OK(VecGetSize(U, &n));
  EXPECT_EQ(n, 2 * 61);
}

// rhs() equals [v ; c^2 D2 u] computed independently from the gathered state and parameter.
TEST_P(WaveDerivatives, RhsMatchesStencil) {
  const Case c = GetParam();
  OwnedVec G;
  PETSC_ASSERT_OK(VecDuplicate(U, G.out()));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G));
  std::vector<PetscReal> u_all, p_all, g_all;
  PETSC_ASSERT_OK(flexipde_test::gather_all(U, u_all));
  PETSC_ASSERT_OK(flexipde_test::gather_all(p, p_all));
  PETSC_ASSERT_OK(flexipde_test::gather_all(G, g_all));
  SecondDerivative d;
  PETSC_ASSERT_OK(d.set_order(c.order));
  const Grid &g = scene.grid;
  SecondDerivative::Row st;
  PetscReal maxerr = 0, maxg = 0;
  for (PetscInt i = 0; i < g.n(); ++i) {
    PetscReal eu = 0, ev = 0;
    const PetscReal ci = c.field ? p_all[i] : p_all[0];
    if (c.zero_outside) { // every point has an equation
      eu = u_all[2 * i + 1];
      ev = ci * ci * d2_zero_outside(u_all, 2, g.n(), i, c.order, g.h());
    } else if (!g.is_boundary(i)) {
      PetscInt m = d.row(g, i, st);
      PetscReal s = 0;
      for (PetscInt q = 0; q < m; ++q) s += st[q].weight * u_all[2 * st[q].j];
      eu = u_all[2 * i + 1];
      ev = ci * ci * s;
    }
    maxerr = std::max({maxerr, std::fabs(g_all[2 * i] - eu), std::fabs(g_all[2 * i + 1] - ev)});
    maxg = std::max({maxg, std::fabs(eu), std::fabs(ev)});
  }
  EXPECT_LE(maxerr, 1e-12 * maxg) << "rhs differs from [v; c^2 D2 u]";
}

TEST_P(WaveDerivatives, JacobianStateAdjointAndConsistency) {
  OwnedMat J;
  PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U, J));
  OwnedVec x, y, Jx, JTy;
  PETSC_ASSERT_OK(VecDuplicate(U, x.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, y.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Jx.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, JTy.out()));
  PETSC_ASSERT_OK(fill_random(x, -1, 1, 21));
  PETSC_ASSERT_OK(fill_random(y, -1, 1, 22));
  PETSC_ASSERT_OK(MatMult(J, x, Jx));
  PETSC_ASSERT_OK(MatMultTranspose(J, y, JTy));
  const PetscReal lhs = dot(Jx, y), rhs = dot(x, JTy);
  EXPECT_LE(rel_diff(lhs, rhs), 1e-12) << "<Jx,y> = " << lhs << ", <x,J^T y> = " << rhs;
  EXPECT_GT(norm(Jx), 0.0);

  // G is linear in U: G(U + dU) - G(U) = J dU up to round-off.
  OwnedVec G0, G1, U1, diff;
  PETSC_ASSERT_OK(VecDuplicate(U, G0.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, G1.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, U1.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, diff.out()));
  PETSC_ASSERT_OK(VecWAXPY(U1, 1.0, x, U));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G0));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U1, G1));
  PETSC_ASSERT_OK(VecWAXPY(diff, -1.0, G0, G1));
  EXPECT_LE(rel_diff(diff, Jx), 1e-12) << "rhs and rhs_jacobian disagree";
  // dG/dU does not depend on the state (jacobian_constant()).
  EXPECT_TRUE(scene.model->linear());
  EXPECT_TRUE(scene.model->jacobian_constant());
  OwnedMat J2;
  PETSC_ASSERT_OK(scene.model->create_jacobian(J2.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.7, U1, J2));
  PETSC_ASSERT_OK(MatAXPY(J2, -1.0, J, SAME_NONZERO_PATTERN));
  PetscReal nJ, nd;
  PETSC_ASSERT_OK(MatNorm(J, NORM_FROBENIUS, &nJ));
  PETSC_ASSERT_OK(MatNorm(J2, NORM_FROBENIUS, &nd));
  EXPECT_LE(nd, 1e-14 * nJ);
}

TEST_P(WaveDerivatives, JacobianParameterAdjointAndFiniteDifference) {
  OwnedMat Jp;
  PETSC_ASSERT_OK(scene.model->create_jacobian_p(Jp.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U, Jp));
  OwnedVec dp, lam, Jpdp, JpTlam;
  PETSC_ASSERT_OK(VecDuplicate(p, dp.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, JpTlam.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, lam.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Jpdp.out()));
  PETSC_ASSERT_OK(fill_random(dp, -1, 1, 31));
  PETSC_ASSERT_OK(fill_random(lam, -1, 1, 32));
  PETSC_ASSERT_OK(MatMult(Jp, dp, Jpdp));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, lam, JpTlam));
  const PetscReal lhs = dot(Jpdp, lam), rhs = dot(dp, JpTlam);
  EXPECT_GT(std::fabs(lhs), 0.0);
  EXPECT_LE(rel_diff(lhs, rhs), 1e-12) << "<Jp dp, lam> = " << lhs << ", <dp, Jp^T lam> = " << rhs;

  // Central difference of rhs in p (G is quadratic in c, so this is exact up to round-off).
  const PetscReal h = 1e-3;
  OwnedVec q, Gp, Gm, fd;
  PETSC_ASSERT_OK(VecDuplicate(p, q.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Gp.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Gm.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, fd.out()));
  PETSC_ASSERT_OK(VecWAXPY(q, h, dp, p));
  PETSC_ASSERT_OK(scene.model->set_parameters(q));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, Gp));
  PETSC_ASSERT_OK(VecWAXPY(q, -h, dp, p));
  PETSC_ASSERT_OK(scene.model->set_parameters(q));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, Gm));
  PETSC_ASSERT_OK(VecWAXPY(fd, -1.0, Gm, Gp));
  PETSC_ASSERT_OK(VecScale(fd, 1.0 / (2 * h)));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(MatMult(Jp, dp, Jpdp)); // the shell uses the model's current c
  const PetscReal e = rel_diff(Jpdp, fd);
  EXPECT_LE(e, 1e-6) << "dG/dp disagrees with the central difference of rhs";
  EXPECT_GT(norm(fd, NORM_INFINITY), 0.0);

  // The shell records D2 u at the state it was given: a new state changes Jp dp accordingly
  // (Jp is linear in U, so Jp(2U) dp = 2 Jp(U) dp).
  OwnedVec U2, Jpdp2;
  PETSC_ASSERT_OK(VecDuplicate(U, U2.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Jpdp2.out()));
  PETSC_ASSERT_OK(VecCopy(U, U2));
  PETSC_ASSERT_OK(VecScale(U2, 2.0));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U2, Jp));
  PETSC_ASSERT_OK(MatMult(Jp, dp, Jpdp2));
  PETSC_ASSERT_OK(VecScale(Jpdp, 2.0));
  EXPECT_LE(rel_diff(Jpdp2, Jpdp), 1e-13);
}

TEST_P(WaveDerivatives, InitialConditionTranspose) {
  OwnedVec dp, lam, grad, q, Up, Um, dU0;
  PETSC_ASSERT_OK(VecDuplicate(p, dp.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, grad.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, q.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, lam.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Up.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Um.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, dU0.out()));
  PETSC_ASSERT_OK(fill_random(dp, -1, 1, 41));
  PETSC_ASSERT_OK(fill_random(lam, -1, 1, 42));
  const PetscReal h = 1e-3;
  PETSC_ASSERT_OK(VecWAXPY(q, h, dp, p));
  PETSC_ASSERT_OK(scene.sim.initial_condition(q, Up));
  PETSC_ASSERT_OK(VecWAXPY(q, -h, dp, p));
  PETSC_ASSERT_OK(scene.sim.initial_condition(q, Um));
  PETSC_ASSERT_OK(VecWAXPY(dU0, -1.0, Um, Up));
  PETSC_ASSERT_OK(VecScale(dU0, 1.0 / (2 * h)));
  EXPECT_GT(norm(dU0), 0.0) << "travelling IC should depend on c";

  // initial_condition_transpose adds to grad: start from a non-zero vector.
  OwnedVec g0;
  PETSC_ASSERT_OK(VecDuplicate(p, g0.out()));
  PETSC_ASSERT_OK(fill_random(g0, -1, 1, 43));
  PETSC_ASSERT_OK(VecCopy(g0, grad));
  PETSC_ASSERT_OK(scene.model->initial_condition_transpose(p, lam, grad));
  PETSC_ASSERT_OK(VecAXPY(grad, -1.0, g0));
  const PetscReal lhs = dot(dU0, lam), rhs = dot(dp, grad);
  EXPECT_LE(rel_diff(lhs, rhs), 1e-7) << "<dU0/dp dp, lam> = " << lhs << ", <dp, (dU0/dp)^T lam> = " << rhs;

  // U0 satisfies the boundary conditions and v0 = -c u0' for the travelling pulse.
  OwnedVec U0;
  PETSC_ASSERT_OK(VecDuplicate(U, U0.out()));
  PETSC_ASSERT_OK(scene.sim.initial_condition(p, U0));
  std::vector<PetscReal> u0, pa;
  PETSC_ASSERT_OK(flexipde_test::gather_all(U0, u0));
  PETSC_ASSERT_OK(flexipde_test::gather_all(p, pa));
  const Grid &g = scene.grid;
  PetscReal err = 0;
  for (PetscInt i = 0; i < g.n(); ++i) {
    const PetscReal s = (g.x(i) - 0.5) / 0.1, e = std::exp(-s * s), de = -2 * s / 0.1 * e;
    const PetscReal c = GetParam().field ? pa[i] : pa[0];
    const bool wall = g.is_boundary(i) && !GetParam().zero_outside;
    const PetscReal eu = wall ? 0.0 : e, ev = wall ? 0.0 : -c * de;
    err = std::max({err, std::fabs(u0[2 * i] - eu), std::fabs(u0[2 * i + 1] - ev)});
  }
  EXPECT_LE(err, 1e-13);
}

INSTANTIATE_TEST_SUITE_P(Wave, WaveDerivatives,
                         ::testing::Values(Case{false, 2, false}, Case{false, 4, false}, Case{true, 2, false},
                                           Case{true, 4, false}, Case{false, 4, true}, Case{true, 2, true},
                                           Case{true, 4, true}, Case{true, 2, false, true}, Case{false, 4, false, true},
                                           Case{true, 4, false, true}),
                         case_name);

// -wave_ic rest: U0 does not depend on c, and the transpose adds nothing.
TEST(WaveInitialCondition, RestIsIndependentOfSpeed) {
  ScopedOptions opts{{"-da_grid_x", "41"}, {"-wave_c_field", "1"}, {"-wave_ic", "rest"}};
  Scene scene;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  OwnedVec p, q, U0, U1, lam, grad;
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.params.create_vec(q.out()));
  PETSC_ASSERT_OK(scene.params.create_vec(grad.out()));
  PETSC_ASSERT_OK(fill_random(p, 0.8, 1.2, 51));
  PETSC_ASSERT_OK(fill_random(q, 0.8, 1.2, 52));
  PETSC_ASSERT_OK(scene.sim.create_state(U0.out()));
  PETSC_ASSERT_OK(scene.sim.create_state(U1.out()));
  PETSC_ASSERT_OK(scene.sim.create_state(lam.out()));
  PETSC_ASSERT_OK(scene.sim.initial_condition(p, U0));
  PETSC_ASSERT_OK(scene.sim.initial_condition(q, U1));
  EXPECT_EQ(rel_diff(U0, U1), 0.0);
  PetscReal vmax = -1, umax = -1;
  PETSC_ASSERT_OK(VecStrideNorm(U0, 1, NORM_INFINITY, &vmax));
  PETSC_ASSERT_OK(VecStrideNorm(U0, 0, NORM_INFINITY, &umax));
  EXPECT_EQ(vmax, 0.0) << "rest IC must have v0 = 0";
  EXPECT_NEAR(umax, 1.0, 1e-2);
  PETSC_ASSERT_OK(fill_random(lam, -1, 1, 53));
  PETSC_ASSERT_OK(scene.model->initial_condition_transpose(p, lam, grad));
  EXPECT_EQ(norm(grad), 0.0);
}

// -wave_ic two_level: u^0 = P(x), u^1 = P(x - c dt) (P the pulse, pointwise in c), and the leapfrog from
// the velocity it sets reproduces the recurrence u^{k+1} = 2 u^k - u^{k-1} + dt^2 c^2 D2 u^k: its first
// step lands on u^1, and 40 steps on u^40 of that loop run here on the gathered arrays (zeros outside
// the grid, or walls held at 0). dU0/dc's transpose passes the dot-product test against central
// differences of the start, which depends on the integrator's step (told by Simulation::initial_condition;
// the model refuses to make it without).
namespace {
struct TwoLevelCase {
  bool field, zero_outside;
  PetscInt order;
};
std::string two_level_name(const ::testing::TestParamInfo<TwoLevelCase> &i) {
  return std::string(i.param.field ? "field" : "scalar") + (i.param.zero_outside ? "_zero_outside" : "_walls") + "_fd" +
         std::to_string(i.param.order);
}
class WaveTwoLevel : public ::testing::TestWithParam<TwoLevelCase> {
protected:
  void SetUp() override {
    const TwoLevelCase c = GetParam();
    opts_.set("-da_grid_x", "61");
    opts_.set("-wave_c_field", c.field ? "1" : "0");
    opts_.set("-wave_c", "1.1");
    opts_.set("-fd_order", std::to_string(c.order));
    opts_.set("-wave_boundary", c.zero_outside ? "zero_outside" : "walls");
    opts_.set("-wave_ic", "two_level");
    opts_.set("-wave_ic_width", "0.1");
    opts_.set("-ts_type", "leapfrog");
    opts_.set("-ts_dt", "2e-3");
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
    if (c.field) PETSC_ASSERT_OK(fill_random(p, 0.8, 1.2, 61));
    PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  }
  ScopedOptions opts_;
  Scene scene;
  OwnedVec p, U;
};
} // namespace

TEST_P(WaveTwoLevel, LeapfrogIsTheRecurrence) {
  const TwoLevelCase c = GetParam();
  const Grid &g = scene.grid;
  const PetscInt n = g.n();
  const PetscReal dt = 2e-3, h = g.h();
  std::vector<PetscReal> pa;
  PETSC_ASSERT_OK(flexipde_test::gather_all(p, pa));
  auto speed = [&](PetscInt i) { return c.field ? pa[i] : pa[0]; };
  auto wall = [&](PetscInt i) { return !c.zero_outside && (i == 0 || i == n - 1); };
  std::vector<PetscReal> um(n), u(n), un(n);
  for (PetscInt i = 0; i < n; ++i) {
    const PetscReal s0 = (g.x(i) - 0.5) / 0.1, s1 = (g.x(i) - speed(i) * dt - 0.5) / 0.1;
    um[i] = wall(i) ? 0.0 : std::exp(-s0 * s0);
    u[i] = wall(i) ? 0.0 : std::exp(-s1 * s1);
  }
  PetscInt level = 1; // u holds u^level
  for (PetscInt steps : {1, 40}) {
    for (; level < steps; ++level) {
      for (PetscInt i = 0; i < n; ++i) {
        const PetscReal ci = speed(i);
        un[i] = wall(i) ? 0.0 : 2 * u[i] - um[i] + dt * dt * ci * ci * d2_zero_outside(u, 1, n, i, c.order, h);
      }
      um.swap(u);
      u.swap(un);
    }
    ScopedOptions t{{"-ts_max_time", std::to_string(steps * dt).c_str()}};
    PETSC_ASSERT_OK(scene.sim.forward(p, U));
    EXPECT_EQ(scene.sim.stats().steps, steps);
    std::vector<PetscReal> Ua;
    PETSC_ASSERT_OK(flexipde_test::gather_all(U, Ua));
    PetscReal err = 0, umax = 0;
    for (PetscInt i = 0; i < n; ++i) {
      err = std::max(err, std::fabs(Ua[2 * i] - u[i]));
      umax = std::max(umax, std::fabs(u[i]));
    }
    EXPECT_LE(err, 1e-12 * umax) << "after " << steps << " steps";
  }
}

TEST_P(WaveTwoLevel, InitialConditionTranspose) {
  OwnedVec dp, lam, grad, g0, q, Up, Um, dU0;
  for (auto *v : {&dp, &grad, &g0, &q}) PETSC_ASSERT_OK(VecDuplicate(p, v->out()));
  for (auto *v : {&lam, &Up, &Um, &dU0}) PETSC_ASSERT_OK(VecDuplicate(U, v->out()));
  PETSC_ASSERT_OK(fill_random(dp, -1, 1, 62));
  PETSC_ASSERT_OK(fill_random(lam, -1, 1, 63));
  const PetscReal h = 1e-3;
  PETSC_ASSERT_OK(VecWAXPY(q, h, dp, p));
  PETSC_ASSERT_OK(scene.sim.initial_condition(q, Up));
  PETSC_ASSERT_OK(VecWAXPY(q, -h, dp, p));
  PETSC_ASSERT_OK(scene.sim.initial_condition(q, Um));
  PETSC_ASSERT_OK(VecWAXPY(dU0, -1.0, Um, Up));
  PETSC_ASSERT_OK(VecScale(dU0, 1.0 / (2 * h)));
  EXPECT_GT(norm(dU0), 0.0) << "the two-level start depends on c";
  PETSC_ASSERT_OK(scene.sim.initial_condition(p, U));
  PETSC_ASSERT_OK(fill_random(g0, -1, 1, 64)); // the transpose adds to grad
  PETSC_ASSERT_OK(VecCopy(g0, grad));
  PETSC_ASSERT_OK(scene.model->initial_condition_transpose(p, lam, grad));
  PETSC_ASSERT_OK(VecAXPY(grad, -1.0, g0));
  const PetscReal lhs = dot(dU0, lam), rhs = dot(dp, grad);
  EXPECT_LE(rel_diff(lhs, rhs), 1e-8) << "<dU0/dp dp, lam> = " << lhs << ", <dp, (dU0/dp)^T lam> = " << rhs;
}

TEST_P(WaveTwoLevel, NeedsTheStep) {
  Scene fresh; // never told the integrator's step
  OwnedVec q, V;
  PETSC_ASSERT_OK(fresh.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(fresh.params.create_vec(q.out()));
  PETSC_ASSERT_OK(fresh.parameters_from_options("", q));
  PETSC_ASSERT_OK(fresh.sim.create_state(V.out()));
  flexipde_test::QuietErrors quiet;
  EXPECT_EQ(fresh.model->initial_condition(q, V), PETSC_ERR_ORDER);
}

INSTANTIATE_TEST_SUITE_P(Wave, WaveTwoLevel,
                         ::testing::Values(TwoLevelCase{true, true, 2}, TwoLevelCase{false, true, 2},
                                           TwoLevelCase{true, true, 4}, TwoLevelCase{true, false, 2},
                                           TwoLevelCase{false, false, 2}),
                         two_level_name);
