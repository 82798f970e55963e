// Advection-diffusion model (src/models/advection.cpp) and the mean-square objective:
//   - convergence order of the operator against exact derivatives on a periodic grid,
//   - dot-product identities of dG/dU and dG/dp and their consistency with rhs(),
//   - Taylor tests of Simulation::gradient for the amplitude, a, scalar D and field D,
//   - refusal of explicit steps beyond the advection and diffusion limits, and stability of the
//     largest accepted step when the spectrum lies off both axes,
//   - the mean-square gradient against central differences, monotone upwinding, what a scene declares.
//
// Scenes live on PETSC_COMM_WORLD; every check reduces to global numbers before asserting.
#include "flexipde/scene.hpp"
#include "flexipde/taylor.hpp"
#include "test_support.hpp"
#include <cmath>
#include <complex>
#include <functional>
#include <string>

using namespace flexipde;
using flexipde_test::dot;
using flexipde_test::fill_random;
using flexipde_test::norm;
using flexipde_test::QuietErrors;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

using Options = std::vector<std::pair<const char *, const char *>>;
const char *const two_pi = "6.283185307179586";

// The periodic scene every test starts from: [0, 2 pi), the advection model.
void base_options(ScopedOptions &o, PetscInt n) {
  o.set("-model", "advection");
  o.set("-grid_periodic", "1");
  o.set("-grid_x0", "0");
  o.set("-grid_x1", two_pi);
  o.set("-da_grid_x", std::to_string(n));
}

// Grid-shaped Vec with f(x_i).
PetscErrorCode fill_grid(const Grid &g, Vec v, const std::function<PetscReal(PetscReal)> &f) {
  PetscFunctionBeginUser;
  Array a(v);
  PetscCall(a.error());
  for (PetscInt il = 0; il < g.xm(); ++il) a[il] = f(g.x(g.xs() + il));
  PetscFunctionReturn(0);
}

// ---------------------------------------------------------------------------------------------
// Convergence: max_i |G_i - (-a u' + (D u')')(x_i)| for u = sin x + 0.3 cos 2x, with D a scalar or
// the field D(x) = 0.1 + 0.05 sin x.

struct OrderCase {
  const char *name;
  Options options;
  PetscReal a, D; // D < 0: no diffusion; D_field uses the field above
  bool D_field;
  PetscReal expected;
};
std::ostream &operator<<(std::ostream &os, const OrderCase &c) { return os << c.name; }

PetscErrorCode operator_error(const OrderCase &c, PetscInt n, PetscReal *err) {
  ScopedOptions o;
  base_options(o, n);
  for (auto &kv : c.options) o.set(kv.first, kv.second);
  Scene s;
  OwnedVec p, U, G, E, field;
  PetscFunctionBeginUser;
  PetscCall(s.setup(PETSC_COMM_WORLD));
  PetscCall(s.params.create_vec(p.out()));
  PetscCall(s.params.set_scalar(p, s.params.find("advection_a"), c.a));
  if (c.D >= 0) {
    const PetscInt kD = s.params.find("advection_D");
    PetscCheck(kD >= 0, PETSC_COMM_WORLD, PETSC_ERR_PLIB, "no D declared");
    if (c.D_field) {
      PetscCall(DMCreateGlobalVector(s.grid.dm(), field.out()));
      PetscCall(fill_grid(s.grid, field, [](PetscReal x) { return 0.1 + 0.05 * std::sin(x); }));
      PetscCall(s.params.set_field(p, kD, field));
    } else {
      PetscCall(s.params.set_scalar(p, kD, c.D));
    }
  }
  PetscCall(s.model->set_parameters(p));
  PetscCall(s.sim.create_state(U.out()));
  PetscCall(VecDuplicate(U, G.out()));
  PetscCall(VecDuplicate(U, E.out()));
  PetscCall(fill_grid(s.grid, U, [](PetscReal x) { return std::sin(x) + 0.3 * std::cos(2 * x); }));
  const PetscReal a = c.a, D0 = c.D;
  const bool fieldD = c.D_field, diffusion = c.D >= 0;
  PetscCall(fill_grid(s.grid, E, [=](PetscReal x) {
    const PetscReal du = std::cos(x) - 0.6 * std::sin(2 * x), d2u = -std::sin(x) - 1.2 * std::cos(2 * x);
    PetscReal g = -a * du;
    if (diffusion) {
      const PetscReal D = fieldD ? 0.1 + 0.05 * std::sin(x) : D0, dD = fieldD ? 0.05 * std::cos(x) : 0.0;
      g += dD * du + D * d2u;
    }
    return g;
  }));
  PetscCall(s.model->rhs(0.0, U, G));
  PetscCall(VecAXPY(G, -1.0, E));
  PetscCall(VecNorm(G, NORM_INFINITY, err));
  PetscFunctionReturn(0);
}

class OperatorConvergence : public ::testing::TestWithParam<OrderCase> {};

TEST_P(OperatorConvergence, Order) {
  const OrderCase &c = GetParam();
  const PetscInt ns[3] = {32, 64, 128};
  PetscReal e[3];
  for (int k = 0; k < 3; ++k) PETSC_ASSERT_OK(operator_error(c, ns[k], &e[k]));
  const PetscReal o1 = std::log2(e[0] / e[1]), o2 = std::log2(e[1] / e[2]);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] max error N=32 %.3e, 64 %.3e, 128 %.3e; order %.3f, %.3f\n", c.name, (double)e[0],
              (double)e[1], (double)e[2], (double)o1, (double)o2);
  EXPECT_NEAR(o2, c.expected, 0.15);
}

INSTANTIATE_TEST_SUITE_P(
    Advection, OperatorConvergence,
    ::testing::Values(OrderCase{"fd2", {{"-advection_scheme", "fd2"}}, 1.3, -1, false, 2},
                      OrderCase{"fd4", {{"-advection_scheme", "fd4"}}, 1.3, -1, false, 4},
                      OrderCase{"upwind_a_positive", {{"-advection_scheme", "upwind"}}, 1.3, -1, false, 1},
                      OrderCase{"upwind_a_negative", {{"-advection_scheme", "upwind"}}, -0.7, -1, false, 1},
                      OrderCase{"diffusion_scalar_fd2", {{"-advection_diffusion", "1"}, {"-fd_order", "2"}}, 0, 0.1, false, 2},
                      OrderCase{"diffusion_scalar_fd4", {{"-advection_diffusion", "1"}, {"-fd_order", "4"}}, 0, 0.1, false, 4},
                      OrderCase{"diffusion_field_fd2",
                                {{"-advection_diffusion", "1"}, {"-advection_D_field", "1"}, {"-fd_order", "2"}},
                                0, 0.1, true, 2},
                      OrderCase{"diffusion_field_fd4",
                                {{"-advection_diffusion", "1"}, {"-advection_D_field", "1"}, {"-fd_order", "4"}},
                                0, 0.1, true, 4},
                      OrderCase{"fd4_with_field_diffusion",
                                {{"-advection_scheme", "fd4"}, {"-advection_diffusion", "1"}, {"-advection_D_field", "1"}},
                                1.3, 0.1, true, 4}),
    [](const ::testing::TestParamInfo<OrderCase> &i) { return std::string(i.param.name); });

// ---------------------------------------------------------------------------------------------
// dG/dU and dG/dp: <A x, y> = <x, A^T y>, J U = G(U), and G(U; p + d) - G(U; p) = (dG/dp) d exactly
// (G is linear in a and in D).

struct DerivativeCase {
  const char *name;
  Options options;
  PetscReal a;
};
std::ostream &operator<<(std::ostream &os, const DerivativeCase &c) { return os << c.name; }

class AdvectionDerivatives : public ::testing::TestWithParam<DerivativeCase> {
protected:
  void SetUp() override {
    const DerivativeCase &c = GetParam();
    base_options(opts_, 40);
    for (auto &kv : c.options) opts_.set(kv.first, kv.second);
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
    flexipde_test::rough_diffusion_field(scene, p, 0.08, 0.12); // every entry of a field D matters
    PETSC_ASSERT_OK(scene.params.set_scalar(p, scene.params.find("advection_a"), c.a));
    PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
    PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 22));
    PETSC_ASSERT_OK(scene.model->set_parameters(p));
    PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
    PETSC_ASSERT_OK(scene.model->create_jacobian_p(Jp.out()));
    PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U, J));
    PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U, Jp));
  }
  ScopedOptions opts_;
  Scene scene;
  OwnedVec p, U;
  OwnedMat J, Jp;
};

TEST_P(AdvectionDerivatives, JacobianTransposeAndConsistency) {
  OwnedVec x, y, Ax, Aty, G;
  PETSC_ASSERT_OK(VecDuplicate(U, x.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, y.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Ax.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Aty.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, G.out()));
  PETSC_ASSERT_OK(fill_random(x, -1, 1, 23));
  PETSC_ASSERT_OK(fill_random(y, -1, 1, 24));
  PETSC_ASSERT_OK(MatMult(J, x, Ax));
  PETSC_ASSERT_OK(MatMultTranspose(J, y, Aty));
  EXPECT_LE(rel_diff(dot(Ax, y), dot(x, Aty)), 1e-12);
  PETSC_ASSERT_OK(MatMult(J, U, Ax));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G));
  EXPECT_LE(rel_diff(Ax, G), 1e-14);
}

TEST_P(AdvectionDerivatives, ParameterJacobianTransposeAndConsistency) {
  OwnedVec x, y, Jx, Jty, G0, G1, q;
  PETSC_ASSERT_OK(VecDuplicate(p, x.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, Jty.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, q.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, y.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Jx.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, G0.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, G1.out()));
  PETSC_ASSERT_OK(fill_random(x, -0.01, 0.01, 25)); // small: D stays positive, a keeps its sign
  PETSC_ASSERT_OK(fill_random(y, -1, 1, 26));
  PETSC_ASSERT_OK(MatMult(Jp, x, Jx));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, Jty));
  const PetscReal lhs = dot(Jx, y), rhs = dot(x, Jty);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] <dG/dp x, y> = %.15e, <x, (dG/dp)^T y> = %.15e\n", GetParam().name, (double)lhs,
              (double)rhs);
  EXPECT_GT(std::fabs(lhs), 0.0);
  EXPECT_LE(rel_diff(lhs, rhs), 1e-12);
  // Bilinear in (U, p): the difference of two right-hand sides is exactly dG/dp x.
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G0));
  PETSC_ASSERT_OK(VecWAXPY(q, 1.0, x, p));
  PETSC_ASSERT_OK(scene.model->set_parameters(q));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G1));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(VecAXPY(G1, -1.0, G0));
  EXPECT_LE(rel_diff(Jx, G1), 1e-10);
}

INSTANTIATE_TEST_SUITE_P(
    Advection, AdvectionDerivatives,
    ::testing::Values(DerivativeCase{"fd2_no_diffusion", {}, 1.0},
                      DerivativeCase{"upwind_negative_a_scalar_D_fd4",
                                     {{"-advection_scheme", "upwind"}, {"-advection_D", "0.1"}, {"-fd_order", "4"}},
                                     -0.8},
                      DerivativeCase{"fd4_field_D_fd4",
                                     {{"-advection_scheme", "fd4"}, {"-advection_D_field", "1"}, {"-advection_D", "0.1"}},
                                     1.2},
                      DerivativeCase{"upwind_field_D_fd2",
                                     {{"-advection_scheme", "upwind"},
                                      {"-advection_D_field", "1"},
                                      {"-advection_D", "0.1"},
                                      {"-advection_ic_amplitude_param", "1"}},
                                     0.9}),
    [](const ::testing::TestParamInfo<DerivativeCase> &i) { return std::string(i.param.name); });

// An upwind stencil's assembled matrix holds the side in use only (a linear G's zeros stay out, so
// that a factorisation fills as for that side); when the velocity changes sign, the same matrix must
// take the other side's entries (its coordinate list is set again), and back.
TEST(AdvectionJacobian, FollowsTheUpwindSideIntoTheSameMatrix) {
  ScopedOptions opts;
  base_options(opts, 24);
  opts.set("-advection_scheme", "upwind");
  Scene scene;
  OwnedVec p, U, JU, G;
  OwnedMat J;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, JU.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, G.out()));
  PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 31));
  PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
  const PetscInt a = scene.params.find("advection_a");
  PetscReal nonzeros[3];
  int k = 0;
  for (PetscReal velocity : {0.7, -0.7, 0.7}) {
    PETSC_ASSERT_OK(scene.params.set_scalar(p, a, velocity));
    PETSC_ASSERT_OK(scene.model->set_parameters(p));
    PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U, J));
    PETSC_ASSERT_OK(MatMult(J, U, JU));
    PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G));
    EXPECT_GT(norm(G), 0.0);
    EXPECT_LE(rel_diff(JU, G), 1e-14) << "a = " << velocity;
    MatInfo info;
    PETSC_ASSERT_OK(MatGetInfo(J, MAT_GLOBAL_SUM, &info));
    nonzeros[k++] = info.nz_used;
  }
  EXPECT_EQ(nonzeros[0], 2 * 24.0); // the diagonal and the upwind neighbour
  EXPECT_EQ(nonzeros[1], nonzeros[0]);
  EXPECT_EQ(nonzeros[2], nonzeros[0]);
}

// ---------------------------------------------------------------------------------------------
// Taylor tests of Simulation::gradient: r1 ~ eps (ratio 2), r2 ~ eps^2 (ratio 4).

using TaylorCase = flexipde_test::NamedOptions;

class AdvectionTaylor : public ::testing::TestWithParam<TaylorCase> {};

TEST_P(AdvectionTaylor, Converges) {
  const TaylorCase &tc = GetParam();
  ScopedOptions opts;
  base_options(opts, 32);
  opts.set("-ts_max_time", "0.5");
  opts.set("-ts_dt", "0.025");
  opts.set("-advection_ic", "gaussian");
  opts.set("-advection_ic_width", "0.8");
  for (auto &kv : tc.options) opts.set(kv.first, kv.second);
  Scene scene;
  OwnedVec p, p_true, d;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.params.create_vec(p_true.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.parameters_from_options("true_", p_true));
  PETSC_ASSERT_OK(scene.make_synthetic_data(p_true));
  PETSC_ASSERT_OK(VecDuplicate(p, d.out()));
  // All entries of one sign: a random sign pattern over a 33-entry field can make g.d so small
  // that the eps^2 term hides the first-order one at the sizes tested.
  PETSC_ASSERT_OK(fill_random(d, 0.2, 1.0, 31));
  auto f = [&](Vec q, PetscReal *J, Vec g) { return scene.sim.gradient(q, J, g, nullptr); };
  TaylorResult tr;
  PETSC_ASSERT_OK(taylor_test(f, p, d, 1e-2, 5, tr));
  PetscPrintf(PETSC_COMM_WORLD, "  Taylor [%s, %" PetscInt_FMT " parameters, %s]: g.d = %.6e\n", tc.name,
              scene.params.global_size(), scene.sim.stats().ts_type, (double)tr.gd);
  for (size_t k = 0; k < tr.eps.size(); ++k)
    PetscPrintf(PETSC_COMM_WORLD, "  %10.3e %12.5e %7.3f %12.5e %7.3f\n", (double)tr.eps[k], (double)tr.r1[k],
                k ? (double)tr.ratio1(k) : 0.0, (double)tr.r2[k], k ? (double)tr.ratio2(k) : 0.0);
  const size_t last = tr.eps.size() - 1;
  EXPECT_GT(std::fabs(tr.gd), 0.0);
  EXPECT_NEAR(tr.ratio1(last), 2.0, 0.2);
  EXPECT_NEAR(tr.ratio2(last), 4.0, 0.5) << "gradient is not the derivative of J";
  for (size_t k = 0; k < tr.eps.size(); ++k) EXPECT_LT(tr.r2[k], 0.5 * tr.r1[k]);
}

INSTANTIATE_TEST_SUITE_P(
    Advection, AdvectionTaylor,
    ::testing::Values(
        TaylorCase{"amplitude_and_a_mean_square_rk4",
                   {{"-ts_rk_type", "4"}, {"-objective_type", "mean_square"}, {"-advection_ic_amplitude_param", "1"},
                    {"-advection_ic_amplitude", "1.5"}, {"-advection_scheme", "upwind"}}},
        TaylorCase{"a_misfit_rk4", {{"-ts_rk_type", "4"}, {"-advection_a", "0.8"}, {"-true_advection_a", "1.0"}}},
        TaylorCase{"a_misfit_fd4_cn",
                   {{"-ts_type", "cn"}, {"-advection_scheme", "fd4"}, {"-advection_a", "-0.8"}, {"-true_advection_a", "-1.0"}}},
        TaylorCase{"D_scalar_misfit_fd4_rk3",
                   {{"-ts_rk_type", "3"},
                    {"-advection_scheme", "fd4"},
                    {"-advection_D", "0.1"},
                    {"-true_advection_D", "0.15"},
                    {"-ts_dt", "0.01"}}},
        TaylorCase{"D_scalar_amplitude_mean_square_cn",
                   {{"-ts_type", "cn"}, {"-objective_type", "mean_square"}, {"-advection_ic_amplitude_param", "1"},
                    {"-advection_D", "0.1"}}},
        TaylorCase{"D_field_misfit_beuler",
                   {{"-ts_type", "beuler"},
                    {"-advection_D_field", "1"},
                    {"-advection_D", "0.1"},
                    {"-true_advection_D_profile", "gaussian"},
                    {"-true_advection_D", "0.1"},
                    {"-true_advection_D_bump", "0.05"},
                    {"-true_advection_D_width", "1.0"}}},
        TaylorCase{"D_field_fd4_mean_square_rk4",
                   {{"-ts_rk_type", "4"}, {"-objective_type", "mean_square"}, {"-advection_scheme", "fd4"},
                    {"-advection_D_field", "1"}, {"-advection_D", "0.1"}, {"-ts_dt", "0.01"}}},
        TaylorCase{"upwind_D_field_square_misfit_rk4",
                   {{"-ts_rk_type", "4"},
                    {"-advection_scheme", "upwind"},
                    {"-advection_ic", "square"},
                    {"-advection_ic_width", "1.5"},
                    {"-advection_D_field", "1"},
                    {"-advection_D", "0.05"},
                    {"-advection_a", "1.1"},
                    {"-true_advection_D", "0.08"}}}),
    flexipde_test::CaseName());

// ---------------------------------------------------------------------------------------------
// Explicit stability: refused beyond the limit with PETSC_ERR_ARG_OUTOFRANGE, accepted below.

// Outcome of one forward solve of `steps` steps of dt with extra options (0: ran).
PetscErrorCode try_step(const Options &extra, PetscReal dt, PetscInt steps, PetscErrorCode *outcome) {
  ScopedOptions o;
  base_options(o, 64);
  for (auto &kv : extra) o.set(kv.first, kv.second);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", (double)dt);
  o.set("-ts_dt", buf);
  std::snprintf(buf, sizeof buf, "%.17g", (double)(dt * steps));
  o.set("-ts_max_time", buf);
  Scene s;
  OwnedVec p, U;
  PetscFunctionBeginUser;
  PetscCall(s.setup(PETSC_COMM_WORLD));
  PetscCall(s.params.create_vec(p.out()));
  PetscCall(s.parameters_from_options("", p));
  PetscCall(s.sim.create_state(U.out()));
  {
    QuietErrors q;
    *outcome = s.sim.forward(p, U);
  }
  PetscFunctionReturn(0);
}

// The largest accepted dt by bisection between an accepted lo and a refused hi (one step each).
PetscErrorCode largest_accepted(const Options &extra, PetscReal lo, PetscReal hi, PetscReal *dt) {
  PetscErrorCode outcome;
  PetscFunctionBeginUser;
  for (int k = 0; k < 40 && hi - lo > 1e-6 * hi; ++k) {
    const PetscReal mid = 0.5 * (lo + hi);
    PetscCall(try_step(extra, mid, 1, &outcome));
    if (outcome == 0) lo = mid;
    else {
      PetscCheck(outcome == PETSC_ERR_ARG_OUTOFRANGE, PETSC_COMM_WORLD, PETSC_ERR_PLIB, "unexpected error %d",
                 (int)outcome);
      hi = mid;
    }
  }
  *dt = lo;
  PetscFunctionReturn(0);
}

} // namespace

TEST(AdvectionStability, RefusesBeyondAdvectionAndDiffusionLimits) {
  const PetscReal h = 2 * PETSC_PI / 64;
  struct Limit {
    const char *what;
    Options options;
    PetscReal dt_limit; // analytic largest stable dt
  } limits[] = {
      // RK4 is stable on [-2.8284i, 2.8284i] and [-2.7853, 0]
      {"fd2 advection, a = 1", {{"-advection_a", "1"}}, 2.8284271 * h / 1.0},
      // max (8 sin t - sin 2t) / 6 = 1.372225 at cos t = 1 - sqrt(6)/2; 64 points miss it by 5e-4
      {"fd4 advection, a = -2", {{"-advection_scheme", "fd4"}, {"-advection_a", "-2"}}, 2.8284271 * h / (2.0 * 1.372225)},
      {"diffusion fd2, D = 0.5", {{"-advection_a", "0"}, {"-advection_D", "0.5"}}, 2.7852935 * h * h / (0.5 * 4)},
      {"diffusion fd4, D = 0.5",
       {{"-advection_a", "0"}, {"-advection_D", "0.5"}, {"-fd_order", "4"}},
       2.7852935 * h * h / (0.5 * (56.0 / 24) * (56.0 / 24))},
  };
  for (auto &l : limits) {
    PetscErrorCode above, below, implicit;
    PETSC_ASSERT_OK(try_step(l.options, 1.01 * l.dt_limit, 3, &above));
    PETSC_ASSERT_OK(try_step(l.options, 0.99 * l.dt_limit, 3, &below));
    Options cn = l.options;
    cn.push_back({"-ts_type", "cn"});
    PETSC_ASSERT_OK(try_step(cn, 10 * l.dt_limit, 3, &implicit));
    PetscReal dt;
    PETSC_ASSERT_OK(largest_accepted(l.options, 0.5 * l.dt_limit, 2 * l.dt_limit, &dt));
    PetscPrintf(PETSC_COMM_WORLD, "  [%s] analytic limit %.6e, largest accepted dt %.6e (ratio %.5f)\n", l.what,
                (double)l.dt_limit, (double)dt, (double)(dt / l.dt_limit));
    EXPECT_EQ(above, PETSC_ERR_ARG_OUTOFRANGE) << l.what;
    EXPECT_EQ(below, 0) << l.what;
    EXPECT_EQ(implicit, 0) << l.what;
    EXPECT_NEAR(dt / l.dt_limit, 1.0, 2e-3) << l.what; // the check's own resolution
  }
}

// With advection and diffusion (or upwinding) the spectrum lies off both axes, where checking the
// two axes alone is not enough. A scalar D makes dG/dU circulant, so its eigenvalues are
// lambda_k = sum_j A_0j exp(2 pi i j k / N) from row 0; at the largest accepted dt every
// |R(dt lambda_k)| must be <= 1, R the stability function of the RK tableau the TS uses.
struct MixedCase {
  const char *rk;
  Options options;
};

// For dG/dU of the scene set up from the current options: max_k |R(dt lambda_k)| over the modes
// k > 0 (lambda_0 = 0, |R| = 1), the step a check of the two axes with the plain radii would allow,
// and the true limit (the largest dt, to 0.1%, with every |R(dt lambda_k)| <= 1).
PetscErrorCode max_amplification(const char *rk, PetscReal dt, PetscReal *amp, PetscReal *axis_dt, PetscReal *true_dt) {
  Scene s;
  OwnedVec p, U;
  OwnedMat J;
  OwnedTS ts;
  PetscMPIInt rank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(PETSC_COMM_WORLD, &rank));
  PetscCall(s.setup(PETSC_COMM_WORLD));
  PetscCall(s.params.create_vec(p.out()));
  PetscCall(s.parameters_from_options("", p));
  PetscCall(s.model->set_parameters(p));
  PetscCall(s.model->create_jacobian(J.out()));
  PetscCall(s.sim.create_state(U.out())); // dG/dU of the linear model is the same at every state
  PetscCall(s.model->rhs_jacobian(0.0, U, J));
  const PetscInt n = s.grid.n();
  std::vector<PetscReal> row(n, 0.0);
  if (rank == 0) {
    PetscInt nc;
    const PetscInt *cols;
    const PetscScalar *vals;
    PetscCall(MatGetRow(J, 0, &nc, &cols, &vals));
    for (PetscInt q = 0; q < nc; ++q) row[cols[q]] = PetscRealPart(vals[q]);
    PetscCall(MatRestoreRow(J, 0, &nc, &cols, &vals));
  }
  PetscCallMPI(MPI_Bcast(row.data(), (int)n, MPIU_REAL, 0, PETSC_COMM_WORLD));
  PetscCall(TSCreate(PETSC_COMM_SELF, ts.out()));
  PetscCall(TSSetType(ts, TSRK));
  PetscCall(TSRKSetType(ts, rk));
  PetscInt st;
  const PetscReal *A, *b;
  PetscCall(TSRKGetTableau(ts, &st, &A, &b, nullptr, nullptr, nullptr, nullptr, nullptr));
  auto R = [&](std::complex<double> z) {
    std::vector<std::complex<double>> Y(st);
    std::complex<double> r = 1.0;
    for (PetscInt i = 0; i < st; ++i) {
      Y[i] = 1.0;
      for (PetscInt j = 0; j < i; ++j) Y[i] += z * A[i * st + j] * Y[j];
      r += z * b[i] * Y[i];
    }
    return r;
  };
  auto axis_limit = [&](std::complex<double> dir) { // largest r with |R(r dir)| <= 1 on [0, r]
    double r = 0;
    while (r < 20 && std::abs(R((r + 1e-4) * dir)) <= 1 + 1e-12) r += 1e-4;
    return r;
  };
  std::vector<std::complex<double>> lambda(n);
  PetscReal re = 0, im = 0;
  for (PetscInt k = 1; k < n; ++k) {
    for (PetscInt j = 0; j < n; ++j) lambda[k] += row[j] * std::polar(1.0, 2 * PETSC_PI * j * k / n);
    re = std::max<PetscReal>(re, std::fabs(lambda[k].real()));
    im = std::max<PetscReal>(im, std::fabs(lambda[k].imag()));
  }
  auto max_R = [&](PetscReal t) {
    PetscReal m = 0;
    for (PetscInt k = 1; k < n; ++k) m = std::max<PetscReal>(m, std::abs(R(t * lambda[k])));
    return m;
  };
  *amp = max_R(dt);
  *axis_dt = std::min(axis_limit({0, 1}) / im, axis_limit({-1, 0}) / re);
  *true_dt = 0;
  for (PetscReal t = 1e-3 * dt; max_R(t) <= 1 + 1e-12; t *= 1.001) *true_dt = t;
  PetscFunctionReturn(0);
}

TEST(AdvectionStability, LargestAcceptedStepIsStableOffTheAxes) {
  const MixedCase cases[] = {
      {"4", {{"-advection_D", "0.0245"}}}, // 4D/h^2 ~ a/h: near the worst balance for RK4
      {"3", {{"-advection_D", "0.035"}}},
      {"4", {{"-advection_scheme", "fd4"}, {"-advection_D", "0.03"}, {"-fd_order", "4"}}},
      {"3", {{"-advection_scheme", "fd4"}, {"-advection_D", "0.05"}}},
      {"4", {{"-advection_scheme", "upwind"}}},
      {"3", {{"-advection_scheme", "upwind"}, {"-advection_D", "0.02"}}},
      {"5dp", {{"-advection_D", "0.03"}}},
      {"3bs", {{"-advection_D", "0.03"}}},
  };
  for (auto &c : cases) {
    Options o = c.options;
    o.push_back({"-ts_rk_type", c.rk});
    PetscReal dt, amp, axis_dt, axis_amp, true_dt, unused;
    PETSC_ASSERT_OK(largest_accepted(o, 1e-3, 1.0, &dt));
    ScopedOptions so;
    base_options(so, 64);
    for (auto &kv : o) so.set(kv.first, kv.second);
    PETSC_ASSERT_OK(max_amplification(c.rk, dt, &amp, &axis_dt, &true_dt));
    PETSC_ASSERT_OK(max_amplification(c.rk, axis_dt, &axis_amp, &unused, &unused));
    std::string label = std::string("rk ") + c.rk;
    for (auto &kv : c.options) label += std::string(" ") + kv.first + " " + kv.second;
    PetscPrintf(PETSC_COMM_WORLD,
                "  [%s] largest accepted dt %.4e (a dt/h = %.3f, max|R| = %.6f), true limit %.4e (ratio %.3f); "
                "the axes alone would allow %.4e (max|R| = %.4f)\n",
                label.c_str(), (double)dt, (double)(dt * 64 / (2 * PETSC_PI)), (double)amp, (double)true_dt,
                (double)(dt / true_dt), (double)axis_dt, (double)axis_amp);
    EXPECT_LE(amp, 1.0 + 1e-12) << label;
  }
}

// ---------------------------------------------------------------------------------------------

// Every entry of the mean-square gradient (a, scalar D, amplitude) against central differences.
TEST(AdvectionObjective, MeanSquareGradientMatchesCentralDifferences) {
  ScopedOptions o;
  base_options(o, 48);
  o.set("-objective_type", "mean_square");
  o.set("-advection_ic", "gaussian");
  o.set("-advection_ic_width", "0.7");
  o.set("-advection_ic_amplitude_param", "1");
  o.set("-advection_ic_amplitude", "0.7");
  o.set("-advection_scheme", "upwind");
  o.set("-advection_D", "0.05");
  o.set("-advection_a", "0.9");
  o.set("-ts_dt", "0.02");
  o.set("-ts_max_time", "0.6");
  Scene s;
  OwnedVec p, g, q;
  PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
  EXPECT_EQ(s.objective.data(), nullptr);
  PETSC_ASSERT_OK(s.params.create_vec(p.out()));
  PETSC_ASSERT_OK(s.params.create_vec(g.out()));
  PETSC_ASSERT_OK(s.params.create_vec(q.out()));
  PETSC_ASSERT_OK(s.parameters_from_options("", p));
  PETSC_ASSERT_OK(s.make_synthetic_data(p)); // nothing to make for a data-free objective
  PetscReal J;
  PETSC_ASSERT_OK(s.sim.gradient(p, &J, g, nullptr));
  // J by hand from the same forward solve: mean of u(T)^2.
  OwnedVec U;
  PETSC_ASSERT_OK(s.sim.create_state(U.out()));
  PETSC_ASSERT_OK(s.sim.forward(p, U));
  const PetscReal nU = norm(U);
  EXPECT_LE(rel_diff(J, nU * nU / 48), 1e-14);
  ASSERT_EQ(s.params.global_size(), 3);
  for (const char *name : {"advection_a", "advection_D", "advection_ic_amplitude"}) {
    const PetscInt k = s.params.find(name);
    ASSERT_GE(k, 0) << name;
    PetscReal v, gk, Jp, Jm;
    const PetscReal h = 1e-5;
    PETSC_ASSERT_OK(s.params.scalar(p, k, &v));
    PETSC_ASSERT_OK(s.params.scalar(g, k, &gk));
    PETSC_ASSERT_OK(VecCopy(p, q));
    PETSC_ASSERT_OK(s.params.set_scalar(q, k, v + h));
    PETSC_ASSERT_OK(s.sim.gradient(q, &Jp, nullptr, nullptr));
    PETSC_ASSERT_OK(s.params.set_scalar(q, k, v - h));
    PETSC_ASSERT_OK(s.sim.gradient(q, &Jm, nullptr, nullptr));
    const PetscReal fd = (Jp - Jm) / (2 * h);
    PetscPrintf(PETSC_COMM_WORLD, "  dJ/d%s: adjoint %.12e, central difference %.12e, relative difference %.2e\n", name,
                (double)gk, (double)fd, (double)rel_diff(gk, fd));
    EXPECT_LE(rel_diff(gk, fd), 1e-7) << name;
  }
}

// First-order upwinding creates no new extrema on a square pulse (RK4 at CFL 0.8 and backward
// Euler); centred differences do, which shows the check can fail.
TEST(AdvectionUpwind, MonotoneOnSquarePulse) {
  struct Run {
    const char *scheme, *ts, *dt;
    bool monotone;
  } runs[] = {{"upwind", "rk", "0.0785398", true}, {"upwind", "beuler", "0.2", true}, {"fd2", "rk", "0.0785398", false}};
  for (auto &r : runs) {
    ScopedOptions o;
    base_options(o, 64);
    o.set("-advection_scheme", r.scheme);
    o.set("-advection_ic", "square");
    o.set("-advection_ic_width", "2.0");
    o.set("-ts_type", r.ts);
    o.set("-ts_dt", r.dt);
    o.set("-ts_max_time", "2.0");
    Scene s;
    OwnedVec p, U;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(s.params.create_vec(p.out()));
    PETSC_ASSERT_OK(s.parameters_from_options("", p));
    PETSC_ASSERT_OK(s.sim.create_state(U.out()));
    PETSC_ASSERT_OK(s.sim.forward(p, U));
    PetscReal lo, hi;
    PETSC_ASSERT_OK(VecMin(U, nullptr, &lo));
    PETSC_ASSERT_OK(VecMax(U, nullptr, &hi));
    PetscPrintf(PETSC_COMM_WORLD, "  [%s, %s] square pulse in [0, 1] -> [%.3e, %.6f]\n", r.scheme, r.ts, (double)lo,
                (double)hi);
    if (r.monotone) {
      EXPECT_GE(lo, -1e-14) << r.scheme << " " << r.ts;
      EXPECT_LE(hi, 1 + 1e-14) << r.scheme << " " << r.ts;
    } else {
      EXPECT_GT(std::max(-lo, hi - 1), 0.05) << "centred differences should oscillate";
    }
  }
}

// A scene declares only what it uses, and bad set-ups fail with a clear error.
TEST(AdvectionScene, DeclaresOnlyWhatItUses) {
  struct Expect {
    Options options;
    PetscInt count, global_size, width;
    bool has_D, has_A;
  } cases[] = {
      // width: the ghost width 2R of the pointwise layer, R the stencil radius
      {{}, 1, 1, 2, false, false},
      {{{"-advection_ic_amplitude_param", "1"}}, 2, 2, 2, false, true},
      {{{"-advection_D", "0.1"}}, 2, 2, 2, true, false},
      {{{"-advection_D", "0.1"}, {"-advection_diffusion", "0"}}, 1, 1, 2, false, false},
      {{{"-advection_diffusion", "1"}, {"-advection_scheme", "fd4"}}, 2, 2, 6, true, false}, // fd_order follows: 4
      {{{"-advection_D_field", "1"}}, 2, 1 + 32, 2, true, false},
      {{{"-advection_scheme", "fd4"}}, 1, 1, 4, false, false},
  };
  for (auto &c : cases) {
    ScopedOptions o;
    base_options(o, 32);
    for (auto &kv : c.options) o.set(kv.first, kv.second);
    Scene s;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    EXPECT_EQ(s.params.count(), c.count);
    EXPECT_EQ(s.params.global_size(), c.global_size);
    EXPECT_EQ(s.grid.stencil_width(), c.width);
    EXPECT_EQ(s.params.find("advection_D") >= 0, c.has_D);
    EXPECT_EQ(s.params.find("advection_ic_amplitude") >= 0, c.has_A);
    EXPECT_NE(s.objective.data(), nullptr); // default objective: the l2sq misfit
  }
  { // D defaults to the model's value, not 1
    ScopedOptions o;
    base_options(o, 32);
    o.set("-advection_diffusion", "1");
    Scene s;
    OwnedVec p;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(s.params.create_vec(p.out()));
    PETSC_ASSERT_OK(s.parameters_from_options("", p));
    PetscReal D;
    PETSC_ASSERT_OK(s.params.scalar(p, s.params.find("advection_D"), &D));
    EXPECT_EQ(D, 0.01);
  }
}

TEST(AdvectionScene, RefusesBadSetups) {
  auto setup_error = [](const Options &extra, bool periodic = true) {
    ScopedOptions o;
    base_options(o, 32);
    if (!periodic) o.set("-grid_periodic", "0");
    for (auto &kv : extra) o.set(kv.first, kv.second);
    Scene s;
    QuietErrors q;
    return s.setup(PETSC_COMM_WORLD);
  };
  EXPECT_EQ(setup_error({}, false), PETSC_ERR_ARG_WRONG);
  EXPECT_NE(setup_error({{"-fd_order", "3"}, {"-advection_diffusion", "1"}}), 0);
  // order 8 is the wave's: the diffusion faces are of order 2 or 4
  EXPECT_EQ(setup_error({{"-fd_order", "8"}, {"-advection_diffusion", "1"}}), PETSC_ERR_ARG_OUTOFRANGE);
  EXPECT_NE(setup_error({{"-advection_scheme", "fd3"}}), 0);
  EXPECT_EQ(setup_error({{"-advection_ic_width", "0"}}), PETSC_ERR_ARG_OUTOFRANGE);
  // A negative diffusivity is refused when the parameters are set.
  ScopedOptions o;
  base_options(o, 32);
  o.set("-advection_D", "-0.1");
  Scene s;
  OwnedVec p;
  PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(s.params.create_vec(p.out()));
  PETSC_ASSERT_OK(s.parameters_from_options("", p));
  QuietErrors q;
  EXPECT_EQ(s.model->set_parameters(p), PETSC_ERR_ARG_OUTOFRANGE);
}
