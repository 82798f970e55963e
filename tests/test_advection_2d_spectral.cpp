// Advection-diffusion model, the parts added after the 1D finite-difference slice:
// -advection_scheme spectral (FFTW-MPI), -advection_dim 2, and the sampled-eigenvalue stability check.
//   - operator convergence: 2D fd2/fd4/upwind/diffusion orders, spectral to round-off by N = 64,
//   - dot-product identities of dG/dU (AIJ or MatShell) and dG/dp, and consistency with rhs(),
//   - Taylor tests for spectral x {rk4, rk3, cn, beuler} and 2D x schemes, for every parameter kind
//     (amplitude, a, b, scalar D, field D),
//   - 1 rank vs 2 ranks (same J and gradient) for spectral and 2D scenes,
//   - the stability check: the largest accepted dt is the true limit (from eigenvalues computed
//     independently from the explicit operator) for scalar D, and stable for a field D,
//   - what a 2D scene declares, and that 2D upwinding is monotone on a square pulse.
#include "flexipde/scene.hpp"
#include "flexipde/spectral.hpp"
#include "flexipde/taylor.hpp"
#include "test_support.hpp"
#include <cmath>
#include <complex>
#include <functional>
#include <string>

using namespace flexipde;
using flexipde_test::dot;
using flexipde_test::fill_random;
using flexipde_test::QuietErrors;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

using Options = std::vector<std::pair<const char *, const char *>>;
const char *const two_pi = "6.283185307179586";

// [0, 2 pi) in 1D, or [0, 2 pi)^2 with -advection_dim 2 when ny > 0.
void base_options(ScopedOptions &o, PetscInt n, PetscInt ny = 0) {
  o.set("-model", "advection");
  o.set("-grid_periodic", "1");
  o.set("-grid_x0", "0");
  o.set("-grid_x1", two_pi);
  o.set("-da_grid_x", std::to_string(n));
  if (ny > 0) {
    o.set("-advection_dim", "2");
    o.set("-grid_y1", two_pi);
    o.set("-da_grid_y", std::to_string(ny));
  }
}

PetscErrorCode fill_grid(const Grid &g, Vec v, const std::function<PetscReal(PetscReal, PetscReal)> &f) {
  PetscFunctionBeginUser;
  Array a(v);
  PetscCall(a.error());
  PetscInt il = 0;
  for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j)
    for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) a[il++] = f(g.x(i), g.dim() == 2 ? g.y(j) : 0.0);
  PetscFunctionReturn(0);
}

// ---------------------------------------------------------------------------------------------
// Convergence: max |G - (-a u_x - b u_y + div(D grad u))| / max |exact| for the smooth, not
// band-limited u = exp(sin x + cos(y)/2) (1D: y = 0), D scalar 0.1 or the field
// D = 0.1 + 0.05 sin x cos y.

struct OrderCase {
  const char *name;
  Options options;
  bool two_d;
  PetscReal D; // < 0: no diffusion
  bool D_field;
  PetscReal expected; // order, or 0: round-off (< 1e-12) at N = 64
};
std::ostream &operator<<(std::ostream &os, const OrderCase &c) { return os << c.name; }

PetscErrorCode operator_error(const OrderCase &c, PetscInt n, PetscReal *err) {
  ScopedOptions o;
  base_options(o, n, c.two_d ? n : 0);
  for (auto &kv : c.options) o.set(kv.first, kv.second);
  Scene s;
  OwnedVec p, U, G, E, field;
  const PetscReal a = 1.3, b = c.two_d ? -0.7 : 0.0;
  PetscFunctionBeginUser;
  PetscCall(s.setup(PETSC_COMM_WORLD));
  PetscCall(s.params.create_vec(p.out()));
  PetscCall(s.params.set_scalar(p, s.params.find("advection_a"), a));
  if (c.two_d) PetscCall(s.params.set_scalar(p, s.params.find("advection_b"), b));
  auto Dfun = [&](PetscReal x, PetscReal y) { return c.D_field ? 0.1 + 0.05 * std::sin(x) * std::cos(y) : c.D; };
  if (c.D >= 0) {
    const PetscInt kD = s.params.find("advection_D");
    if (c.D_field) {
      PetscCall(DMCreateGlobalVector(s.grid.dm(), field.out()));
      PetscCall(fill_grid(s.grid, field, Dfun));
      PetscCall(s.params.set_field(p, kD, field));
    } else PetscCall(s.params.set_scalar(p, kD, c.D));
  }
  PetscCall(s.model->set_parameters(p));
  PetscCall(s.sim.create_state(U.out()));
  PetscCall(VecDuplicate(U, G.out()));
  PetscCall(VecDuplicate(U, E.out()));
  const bool two_d = c.two_d, diffusion = c.D >= 0, field_D = c.D_field;
  auto u = [=](PetscReal x, PetscReal y) { return std::exp(std::sin(x) + (two_d ? 0.5 * std::cos(y) : 0.0)); };
  PetscCall(fill_grid(s.grid, U, u));
  PetscCall(fill_grid(s.grid, E, [&](PetscReal x, PetscReal y) {
    const PetscReal v = u(x, y), ux = std::cos(x) * v, uxx = (std::cos(x) * std::cos(x) - std::sin(x)) * v;
    const PetscReal uy = two_d ? -0.5 * std::sin(y) * v : 0, uyy = two_d ? (0.25 * std::sin(y) * std::sin(y) - 0.5 * std::cos(y)) * v : 0;
    PetscReal g = -a * ux - b * uy;
    if (diffusion) {
      const PetscReal D = Dfun(x, y);
      const PetscReal Dx = field_D ? 0.05 * std::cos(x) * std::cos(y) : 0, Dy = field_D ? -0.05 * std::sin(x) * std::sin(y) : 0;
      g += Dx * ux + D * uxx + (two_d ? Dy * uy + D * uyy : 0.0);
    }
    return g;
  }));
  PetscCall(s.model->rhs(0.0, U, G));
  PetscReal scale;
  PetscCall(VecNorm(E, NORM_INFINITY, &scale));
  PetscCall(VecAXPY(G, -1.0, E));
  PetscCall(VecNorm(G, NORM_INFINITY, err));
  *err /= scale;
  PetscFunctionReturn(0);
}

class Operator2DSpectralConvergence : public ::testing::TestWithParam<OrderCase> {};

TEST_P(Operator2DSpectralConvergence, Order) {
  const OrderCase &c = GetParam();
  const PetscInt ns[3] = {16, 32, 64};
  PetscReal e[3];
  for (int k = 0; k < 3; ++k) PETSC_ASSERT_OK(operator_error(c, ns[k], &e[k]));
  const PetscReal o2 = std::log2(e[1] / e[2]);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] relative max error N=16 %.3e, 32 %.3e, 64 %.3e; order %.3f, %.3f\n", c.name,
              (double)e[0], (double)e[1], (double)e[2], (double)std::log2(e[0] / e[1]), (double)o2);
  if (c.expected > 0) EXPECT_NEAR(o2, c.expected, 0.15);
  else {
    EXPECT_GT(e[0], 1e-8); // not exact at N = 16
    EXPECT_LT(e[2], 1e-12);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Advection, Operator2DSpectralConvergence,
    ::testing::Values(
        OrderCase{"spectral_1d", {{"-advection_scheme", "spectral"}}, false, -1, false, 0},
        OrderCase{"spectral_1d_scalar_D", {{"-advection_scheme", "spectral"}, {"-advection_diffusion", "1"}}, false, 0.1, false, 0},
        OrderCase{"spectral_1d_field_D",
                  {{"-advection_scheme", "spectral"}, {"-advection_diffusion", "1"}, {"-advection_D_field", "1"}}, false, 0.1, true, 0},
        OrderCase{"spectral_2d_field_D",
                  {{"-advection_scheme", "spectral"}, {"-advection_diffusion", "1"}, {"-advection_D_field", "1"}}, true, 0.1, true, 0},
        OrderCase{"fd2_2d", {{"-advection_scheme", "fd2"}}, true, -1, false, 2},
        OrderCase{"fd4_2d", {{"-advection_scheme", "fd4"}}, true, -1, false, 4},
        OrderCase{"upwind_2d", {{"-advection_scheme", "upwind"}}, true, -1, false, 1},
        OrderCase{"fd2_2d_field_D", {{"-advection_diffusion", "1"}, {"-advection_D_field", "1"}}, true, 0.1, true, 2},
        OrderCase{"fd4_2d_field_D",
                  {{"-advection_scheme", "fd4"}, {"-advection_diffusion", "1"}, {"-advection_D_field", "1"}}, true, 0.1, true, 4}),
    [](const ::testing::TestParamInfo<OrderCase> &i) { return std::string(i.param.name); });

// ---------------------------------------------------------------------------------------------
// dG/dU and dG/dp: dot-product identities, J U = G(U), and G(U; p + d) - G(U; p) = (dG/dp) d.

struct DerivativeCase {
  const char *name;
  Options options;
  bool two_d;
};
std::ostream &operator<<(std::ostream &os, const DerivativeCase &c) { return os << c.name; }

class AdvectionNewDerivatives : public ::testing::TestWithParam<DerivativeCase> {};

TEST_P(AdvectionNewDerivatives, TransposesAndConsistency) {
  const DerivativeCase &c = GetParam();
  ScopedOptions o;
  base_options(o, 24, c.two_d ? 20 : 0);
  for (auto &kv : c.options) o.set(kv.first, kv.second);
  Scene scene;
  OwnedVec p, U, x, y, Ax, Aty, G, px, Jty, q, G1;
  OwnedMat J, Jp;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  const PetscInt kD = scene.params.find("advection_D");
  if (kD >= 0 && scene.params.info(kD).kind == ParamKind::Field) { // smooth and positive (spectral truncation)
    OwnedVec f;
    PETSC_ASSERT_OK(DMCreateGlobalVector(scene.grid.dm(), f.out()));
    PETSC_ASSERT_OK(fill_grid(scene.grid, f, [](PetscReal x, PetscReal y) { return 0.1 + 0.03 * std::sin(x + 2 * y); }));
    PETSC_ASSERT_OK(scene.params.set_field(p, kD, f));
  }
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 52));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
  PETSC_ASSERT_OK(scene.model->create_jacobian_p(Jp.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U, J));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U, Jp));
  for (auto *v : {&x, &y, &Ax, &Aty, &G, &G1}) PETSC_ASSERT_OK(VecDuplicate(U, v->out()));
  for (auto *v : {&px, &Jty, &q}) PETSC_ASSERT_OK(VecDuplicate(p, v->out()));
  PETSC_ASSERT_OK(fill_random(x, -1, 1, 53));
  PETSC_ASSERT_OK(fill_random(y, -1, 1, 54));
  PETSC_ASSERT_OK(MatMult(J, x, Ax));
  PETSC_ASSERT_OK(MatMultTranspose(J, y, Aty));
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] <Jx,y> = %.15e, <x,J^T y> = %.15e\n", c.name, (double)dot(Ax, y), (double)dot(x, Aty));
  EXPECT_LE(rel_diff(dot(Ax, y), dot(x, Aty)), 1e-12);
  PETSC_ASSERT_OK(MatMult(J, U, Ax));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G));
  EXPECT_LE(rel_diff(Ax, G), 1e-14);
  // dG/dp
  PETSC_ASSERT_OK(fill_random(px, -0.01, 0.01, 55));
  PETSC_ASSERT_OK(MatMult(Jp, px, Ax));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, Jty));
  const PetscReal l = dot(Ax, y), r = dot(px, Jty);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] <dG/dp x, y> = %.15e, <x, (dG/dp)^T y> = %.15e\n", c.name, (double)l, (double)r);
  EXPECT_GT(std::fabs(l), 0.0);
  EXPECT_LE(rel_diff(l, r), 1e-12);
  PETSC_ASSERT_OK(VecWAXPY(q, 1.0, px, p));
  PETSC_ASSERT_OK(scene.model->set_parameters(q));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G1));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(VecAXPY(G1, -1.0, G));
  EXPECT_LE(rel_diff(Ax, G1), 1e-10);
}

INSTANTIATE_TEST_SUITE_P(
    Advection, AdvectionNewDerivatives,
    ::testing::Values(
        DerivativeCase{"spectral_no_D", {{"-advection_scheme", "spectral"}, {"-advection_a", "0.7"}}, false},
        DerivativeCase{"spectral_scalar_D_amplitude",
                       {{"-advection_scheme", "spectral"}, {"-advection_D", "0.1"}, {"-advection_ic_amplitude_param", "1"}}, false},
        DerivativeCase{"spectral_field_D", {{"-advection_scheme", "spectral"}, {"-advection_D_field", "1"}, {"-advection_a", "-0.6"}}, false},
        DerivativeCase{"spectral_2d_field_D",
                       {{"-advection_scheme", "spectral"}, {"-advection_D_field", "1"}, {"-advection_b", "0.4"}}, true},
        DerivativeCase{"spectral_2d_scalar_D", {{"-advection_scheme", "spectral"}, {"-advection_D", "0.05"}, {"-advection_b", "-0.4"}}, true},
        DerivativeCase{"fd2_2d_field_D", {{"-advection_D_field", "1"}, {"-advection_b", "0.4"}}, true},
        DerivativeCase{"upwind_2d_negative_b_scalar_D_fd4",
                       {{"-advection_scheme", "upwind"}, {"-advection_D", "0.1"}, {"-fd_order", "4"}, {"-advection_b", "-0.5"}}, true},
        DerivativeCase{"fd4_2d_field_D_fd4", {{"-advection_scheme", "fd4"}, {"-advection_D_field", "1"}, {"-advection_b", "0.9"}}, true}),
    [](const ::testing::TestParamInfo<DerivativeCase> &i) { return std::string(i.param.name); });

// ---------------------------------------------------------------------------------------------
// A spectral field D enters the operator through its 2/3-rule truncation P D, so its exact gradient
// is P g: truncated. The layer accumulates the pointwise sums over an adjoint and applies P once at its
// end (Model::end_adjoint); the gradient must still be truncated, for each integrator family (RK stage
// hook, PETSc's RK step through the Jacobians, theta), not only match Taylor tests whose smooth scenes
// barely reach the truncated modes.

using TruncationCase = flexipde_test::NamedOptions;

class SpectralFieldD : public ::testing::TestWithParam<TruncationCase> {};

TEST_P(SpectralFieldD, GradientIsTruncated) {
  ScopedOptions opts;
  base_options(opts, 24);
  opts.set("-advection_scheme", "spectral");
  opts.set("-advection_D_field", "1");
  opts.set("-advection_D", "0.1");
  opts.set("-true_advection_D", "0.15");
  opts.set("-advection_ic", "square"); // every mode, so products of E u and E x reach the truncated ones
  opts.set("-ts_max_time", "0.2");
  opts.set("-ts_dt", "0.01");
  for (auto &kv : GetParam().options) opts.set(kv.first, kv.second);
  flexipde_test::SceneProblem pb;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  OwnedVec g, gD, PgD;
  PetscReal J;
  PETSC_ASSERT_OK(VecDuplicate(pb.p, g.out()));
  PETSC_ASSERT_OK(pb.scene.sim.gradient(pb.p, &J, g, nullptr));
  const PetscInt kD = pb.scene.params.find("advection_D");
  ASSERT_GE(kD, 0);
  PETSC_ASSERT_OK(DMCreateGlobalVector(pb.scene.grid.dm(), gD.out()));
  PETSC_ASSERT_OK(VecDuplicate(gD, PgD.out()));
  PETSC_ASSERT_OK(pb.scene.params.get_field(g, kD, gD));
  SpectralDifferentiator s;
  PETSC_ASSERT_OK(s.setup(pb.scene.grid));
  PETSC_ASSERT_OK(s.dealias(gD, PgD));
  const PetscReal norm = flexipde_test::norm(gD, NORM_2);
  PETSC_ASSERT_OK(VecAXPY(PgD, -1.0, gD));
  const PetscReal off = flexipde_test::norm(PgD, NORM_2);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] |g_D| = %.3e, |P g_D - g_D| = %.3e\n", GetParam().name, (double)norm, (double)off);
  EXPECT_GT(J, 0);
  EXPECT_GT(norm, 1e-8);
  EXPECT_LE(off, 1e-12 * norm);
}

INSTANTIATE_TEST_SUITE_P(Advection, SpectralFieldD,
                         ::testing::Values(TruncationCase{"rk4_stage", {{"-ts_type", "rk"}, {"-ts_rk_type", "4"}}},
                                           TruncationCase{"rk4_petsc_step", {{"-ts_type", "rk"}, {"-ts_rk_type", "4"}, {"-adjoint_petsc_step", "1"}}},
                                           TruncationCase{"cn", {{"-ts_type", "cn"}}}),
                         flexipde_test::CaseName());

// ---------------------------------------------------------------------------------------------
// Taylor tests of Simulation::gradient: r1 ~ eps (ratio 2), r2 ~ eps^2 (ratio 4).

struct TaylorCase {
  const char *name;
  Options options;
  bool two_d;
  PetscReal eps0 = 1e-2; // smaller where the second-order term dominates at 1e-2 (many field entries)
};
std::ostream &operator<<(std::ostream &os, const TaylorCase &c) { return os << c.name; }

class AdvectionNewTaylor : public ::testing::TestWithParam<TaylorCase> {};

TEST_P(AdvectionNewTaylor, Converges) {
  const TaylorCase &tc = GetParam();
  ScopedOptions opts;
  base_options(opts, tc.two_d ? 16 : 32, tc.two_d ? 16 : 0);
  opts.set("-ts_max_time", "0.5");
  opts.set("-ts_dt", "0.025");
  opts.set("-advection_ic", "gaussian");
  opts.set("-advection_ic_width", "0.9");
  for (auto &kv : tc.options) opts.set(kv.first, kv.second);
  flexipde_test::SceneProblem pb;
  OwnedVec d;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(VecDuplicate(pb.p, d.out()));
  PETSC_ASSERT_OK(fill_random(d, 0.2, 1.0, 61));
  auto f = [&](Vec q, PetscReal *J, Vec g) { return pb.scene.sim.gradient(q, J, g, nullptr); };
  TaylorResult tr;
  PETSC_ASSERT_OK(taylor_test(f, pb.p, d, tc.eps0, 5, tr));
  PetscPrintf(PETSC_COMM_WORLD, "  Taylor [%s, %" PetscInt_FMT " parameters, %s]: g.d = %.6e\n", tc.name,
              pb.scene.params.global_size(), pb.scene.sim.stats().ts_type, (double)tr.gd);
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
    Advection, AdvectionNewTaylor,
    ::testing::Values(
        TaylorCase{"spectral_amplitude_a_mean_square_rk4",
                   {{"-advection_scheme", "spectral"}, {"-objective_type", "mean_square"}, {"-advection_ic_amplitude_param", "1"},
                    {"-advection_ic_amplitude", "1.5"}, {"-ts_dt", "0.01"}}},
        TaylorCase{"spectral_a_misfit_cn", {{"-advection_scheme", "spectral"}, {"-ts_type", "cn"}, {"-advection_a", "0.8"}, {"-true_advection_a", "1.0"}}},
        TaylorCase{"spectral_D_scalar_misfit_rk3",
                   {{"-advection_scheme", "spectral"}, {"-ts_rk_type", "3"}, {"-advection_D", "0.1"}, {"-true_advection_D", "0.15"}, {"-ts_dt", "0.01"}}},
        TaylorCase{"spectral_D_field_misfit_beuler",
                   {{"-advection_scheme", "spectral"}, {"-ts_type", "beuler"}, {"-advection_D_field", "1"}, {"-advection_D", "0.1"},
                    {"-true_advection_D_profile", "gaussian"}, {"-true_advection_D", "0.1"}, {"-true_advection_D_bump", "0.05"},
                    {"-true_advection_D_width", "1.0"}}},
        TaylorCase{"spectral_D_field_amplitude_mean_square_rk4",
                   {{"-advection_scheme", "spectral"}, {"-objective_type", "mean_square"}, {"-advection_ic_amplitude_param", "1"},
                    {"-advection_D_field", "1"}, {"-advection_D", "0.1"}, {"-ts_dt", "0.01"}}},
        TaylorCase{"2d_fd2_b_misfit_rk4", {{"-advection_b", "0.5"}, {"-true_advection_b", "0.7"}, {"-ts_dt", "0.05"}}, true},
        TaylorCase{"2d_upwind_D_field_misfit_cn",
                   {{"-advection_scheme", "upwind"}, {"-ts_type", "cn"}, {"-advection_D_field", "1"}, {"-advection_D", "0.05"},
                    {"-advection_b", "-0.6"}, {"-true_advection_D", "0.08"}, {"-ts_dt", "0.05"}}, true},
        TaylorCase{"2d_fd4_D_scalar_amplitude_mean_square_beuler",
                   {{"-advection_scheme", "fd4"}, {"-ts_type", "beuler"}, {"-objective_type", "mean_square"},
                    {"-advection_ic_amplitude_param", "1"}, {"-advection_D", "0.1"}, {"-ts_dt", "0.05"}}, true},
        TaylorCase{"2d_spectral_D_field_b_misfit_rk4",
                   {{"-advection_scheme", "spectral"}, {"-advection_D_field", "1"}, {"-advection_D", "0.05"}, {"-advection_b", "0.5"},
                    {"-true_advection_b", "0.4"}, {"-true_advection_D", "0.07"}, {"-ts_dt", "0.02"}}, true, 1e-3}),
    [](const ::testing::TestParamInfo<TaylorCase> &i) { return std::string(i.param.name); });

// ---------------------------------------------------------------------------------------------
// The same scene on PETSC_COMM_WORLD and on PETSC_COMM_SELF: the same J and gradient. Field
// gradients are compared in natural (x fastest) order, which a 2D DMDA on 2 ranks need not keep.

struct RankCase {
  const char *name;
  Options options;
  bool two_d;
};
std::ostream &operator<<(std::ostream &os, const RankCase &c) { return os << c.name; }
class AdvectionNewRanks : public ::testing::TestWithParam<RankCase> {};

TEST_P(AdvectionNewRanks, ParallelMatchesSerial) {
  const RankCase &c = GetParam();
  ScopedOptions opts;
  base_options(opts, c.two_d ? 24 : 32, c.two_d ? 16 : 0);
  opts.set("-ts_max_time", "0.4");
  opts.set("-ts_dt", "0.02");
  opts.set("-advection_ic", "gaussian");
  opts.set("-advection_ic_width", "0.9");
  for (auto &kv : c.options) opts.set(kv.first, kv.second);
  flexipde_test::expect_parallel_matches_serial(c.name);
}

INSTANTIATE_TEST_SUITE_P(
    Advection, AdvectionNewRanks,
    ::testing::Values(
        RankCase{"spectral_field_D_cn",
                 {{"-advection_scheme", "spectral"}, {"-ts_type", "cn"}, {"-advection_D_field", "1"}, {"-advection_D", "0.05"},
                  {"-true_advection_D", "0.08"}, {"-advection_ic_amplitude_param", "1"}}, false},
        RankCase{"spectral_2d_field_D_rk4",
                 {{"-advection_scheme", "spectral"}, {"-advection_D_field", "1"}, {"-advection_D", "0.05"}, {"-advection_b", "0.5"},
                  {"-true_advection_b", "0.6"}, {"-true_advection_D", "0.08"}, {"-ts_dt", "0.01"}}, true},
        RankCase{"fd4_2d_field_D_beuler",
                 {{"-advection_scheme", "fd4"}, {"-ts_type", "beuler"}, {"-advection_D_field", "1"}, {"-advection_D", "0.05"},
                  {"-advection_b", "0.5"}, {"-true_advection_b", "0.6"}, {"-true_advection_D", "0.08"}, {"-ts_dt", "0.05"}}, true}),
    [](const ::testing::TestParamInfo<RankCase> &i) { return std::string(i.param.name); });

// ---------------------------------------------------------------------------------------------
// Stability with sampled eigenvalues.

// Outcome of the stability check for dt (0: accepted).
PetscErrorCode check_dt(PetscReal dt, PetscErrorCode *outcome) {
  ScopedOptions o;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", (double)dt);
  o.set("-ts_dt", buf);
  o.set("-ts_max_time", buf);
  Scene s;
  OwnedVec p;
  PetscFunctionBeginUser;
  PetscCall(s.setup(PETSC_COMM_WORLD));
  PetscCall(s.params.create_vec(p.out()));
  PetscCall(s.parameters_from_options("", p));
  PetscCall(s.model->set_parameters(p)); // the check reads the model's current parameters
  {
    QuietErrors q;
    *outcome = s.sim.check_options();
  }
  PetscFunctionReturn(0);
}

// All eigenvalues of dG/dU of the scene from the current options, from the explicit operator
// (KSPComputeEigenvaluesExplicitly with no preconditioner): independent of the model's symbols.
PetscErrorCode explicit_eigenvalues(std::vector<std::complex<double>> &ev) {
  flexipde_test::SceneProblem pb;
  OwnedMat J;
  OwnedVec U;
  KSP ksp;
  PC pc;
  PetscFunctionBeginUser;
  PetscCall(pb.setup(PETSC_COMM_WORLD));
  PetscCall(pb.scene.model->set_parameters(pb.p));
  PetscCall(pb.scene.model->create_jacobian(J.out()));
  PetscCall(pb.scene.sim.create_state(U.out())); // dG/dU of the linear model is the same at every state
  PetscCall(pb.scene.model->rhs_jacobian(0.0, U, J));
  PetscInt n;
  PetscCall(MatGetSize(J, &n, nullptr));
  std::vector<PetscReal> re(n), im(n);
  PetscCall(KSPCreate(PETSC_COMM_WORLD, &ksp));
  PetscCall(KSPSetOperators(ksp, J, J));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PCSetType(pc, PCNONE));
  PetscCall(KSPSetUp(ksp));
  PetscCall(KSPComputeEigenvaluesExplicitly(ksp, n, re.data(), im.data()));
  PetscCall(KSPDestroy(&ksp));
  PetscCallMPI(MPI_Bcast(re.data(), (int)n, MPIU_REAL, 0, PETSC_COMM_WORLD)); // computed on rank 0 only
  PetscCallMPI(MPI_Bcast(im.data(), (int)n, MPIU_REAL, 0, PETSC_COMM_WORLD));
  ev.resize(n);
  for (PetscInt k = 0; k < n; ++k) ev[k] = {re[k], im[k]};
  PetscFunctionReturn(0);
}

// RK4's stability function, and the largest dt with |R(dt lambda)| <= 1 for every eigenvalue.
std::complex<double> R4(std::complex<double> z) { return 1.0 + z + z * z / 2.0 + z * z * z / 6.0 + z * z * z * z / 24.0; }
double max_amplification(const std::vector<std::complex<double>> &ev, double dt) {
  double m = 0;
  for (auto &l : ev) m = std::max(m, std::abs(R4(dt * l)));
  return m;
}

} // namespace

TEST(AdvectionSampledStability, AcceptsJustBelowTheTrueLimitAndRefusesJustAbove) {
  struct Case {
    const char *name;
    Options options;
    bool exact; // scalar D: samples are the eigenvalues; field D: a bound (accepted steps stable)
  } cases[] = {
      {"fd2 1D, D = 0.0245", {{"-advection_D", "0.0245"}}, true},
      {"fd4 2D, D = 0.02, b = -0.6", {{"-advection_dim", "2"}, {"-da_grid_y", "16"}, {"-advection_scheme", "fd4"}, {"-advection_D", "0.02"}, {"-advection_b", "-0.6"}}, true},
      {"upwind 2D, b = 0.3", {{"-advection_dim", "2"}, {"-da_grid_y", "12"}, {"-advection_scheme", "upwind"}, {"-advection_b", "0.3"}}, true},
      {"spectral 1D, D = 0.05", {{"-advection_scheme", "spectral"}, {"-advection_D", "0.05"}}, true},
      {"spectral 1D, field D", {{"-advection_scheme", "spectral"}, {"-advection_D_field", "1"}, {"-advection_D", "0.05"}}, false},
      {"fd2 2D, field D", {{"-advection_dim", "2"}, {"-da_grid_y", "12"}, {"-advection_D_field", "1"}, {"-advection_D", "0.03"}}, false},
  };
  for (auto &c : cases) {
    ScopedOptions o;
    base_options(o, 16);
    o.set("-grid_y1", two_pi);
    for (auto &kv : c.options) o.set(kv.first, kv.second);
    std::vector<std::complex<double>> ev;
    PETSC_ASSERT_OK(explicit_eigenvalues(ev));
    double lo = 1e-4, hi = 10; // true limit by bisection on the explicit eigenvalues
    for (int k = 0; k < 60; ++k) (max_amplification(ev, 0.5 * (lo + hi)) <= 1 + 1e-10 ? lo : hi) = 0.5 * (lo + hi);
    const double true_dt = lo;
    // largest accepted by the Simulation, by bisection
    double alo = 0.2 * true_dt, ahi = 2 * true_dt;
    for (int k = 0; k < 24; ++k) {
      PetscErrorCode outcome;
      PETSC_ASSERT_OK(check_dt(0.5 * (alo + ahi), &outcome));
      ASSERT_TRUE(outcome == 0 || outcome == PETSC_ERR_ARG_OUTOFRANGE) << outcome;
      (outcome == 0 ? alo : ahi) = 0.5 * (alo + ahi);
    }
    PetscPrintf(PETSC_COMM_WORLD,
                "  [%s] true limit (explicit eigenvalues) %.6e, largest accepted %.6e (ratio %.6f), max|R| there %.8f\n",
                c.name, true_dt, alo, alo / true_dt, max_amplification(ev, alo));
    EXPECT_LE(max_amplification(ev, alo), 1 + 1e-9) << c.name; // accepted steps are stable
    if (c.exact) {
      PetscErrorCode below, above;
      PETSC_ASSERT_OK(check_dt(0.999 * true_dt, &below));
      PETSC_ASSERT_OK(check_dt(1.001 * true_dt, &above));
      EXPECT_EQ(below, 0) << c.name;
      EXPECT_EQ(above, PETSC_ERR_ARG_OUTOFRANGE) << c.name;
    } else {
      EXPECT_GT(alo / true_dt, 0.3) << c.name; // a bound, but not a useless one
    }
  }
}

TEST(AdvectionScene2D, DeclaresOnlyWhatItUses) {
  struct Expect {
    Options options;
    PetscInt dim, count, global_size, width;
    bool has_b;
  } cases[] = {
      // width: the ghost width 2R of the pointwise layer (R the stencil radius; spectral: 0)
      {{}, 1, 1, 1, 2, false},
      {{{"-advection_scheme", "spectral"}, {"-advection_D", "0.1"}}, 1, 2, 2, 0, false},
      {{{"-advection_dim", "2"}}, 2, 2, 2, 2, true},
      {{{"-advection_dim", "2"}, {"-advection_D_field", "1"}}, 2, 3, 2 + 16 * 16, 2, true},
      {{{"-advection_dim", "2"}, {"-advection_scheme", "fd4"}, {"-advection_diffusion", "1"}}, 2, 3, 3, 6, true},
      {{{"-advection_dim", "2"}, {"-advection_scheme", "spectral"}}, 2, 2, 2, 0, true},
  };
  for (auto &c : cases) {
    ScopedOptions o;
    base_options(o, 16);
    o.set("-da_grid_y", "16");
    for (auto &kv : c.options) o.set(kv.first, kv.second);
    Scene s;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    EXPECT_EQ(s.grid.dim(), c.dim);
    EXPECT_EQ(s.grid.points(), c.dim == 2 ? 16 * 16 : 16);
    EXPECT_EQ(s.params.count(), c.count);
    EXPECT_EQ(s.params.global_size(), c.global_size);
    EXPECT_EQ(s.grid.stencil_width(), c.width);
    EXPECT_EQ(s.params.find("advection_b") >= 0, c.has_b);
  }
}

TEST(AdvectionScene2D, RefusesBadSetups) {
  auto setup_error = [](const Options &extra) {
    ScopedOptions o;
    base_options(o, 16);
    for (auto &kv : extra) o.set(kv.first, kv.second);
    Scene s;
    QuietErrors q;
    return s.setup(PETSC_COMM_WORLD);
  };
  EXPECT_EQ(setup_error({{"-advection_scheme", "spectral"}, {"-da_grid_x", "15"}}), PETSC_ERR_ARG_OUTOFRANGE);
  EXPECT_EQ(setup_error({{"-advection_dim", "2"}, {"-grid_periodic_y", "0"}}), PETSC_ERR_ARG_WRONG);
  EXPECT_NE(setup_error({{"-advection_dim", "3"}}), 0);
  EXPECT_NE(setup_error({{"-advection_scheme", "chebyshev"}}), 0);
}

// 2D square pulse: upwinding creates no new extrema (RK4 at a dt/hx + |b| dt/hy = 0.8, backward
// Euler at 4); centred fd2 and spectral do, by a measurable amount (the check can fail).
TEST(AdvectionUpwind2D, MonotoneOnSquarePulse) {
  struct Run {
    const char *scheme, *ts, *dt;
    bool monotone;
  } runs[] = {{"upwind", "rk", "0.098", true}, {"upwind", "beuler", "0.49", true}, {"fd2", "rk", "0.098", false},
              {"spectral", "rk", "0.05", false}};
  for (auto &r : runs) {
    ScopedOptions o;
    base_options(o, 32, 32);
    o.set("-advection_scheme", r.scheme);
    o.set("-advection_a", "1");
    o.set("-advection_b", "-0.6");
    o.set("-advection_ic", "square");
    o.set("-advection_ic_width", "2.0");
    o.set("-ts_type", r.ts);
    o.set("-ts_dt", r.dt);
    o.set("-ts_max_time", "1.96");
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
    PetscPrintf(PETSC_COMM_WORLD, "  [2D %s, %s] square pulse in [0, 1] -> [%.3e, %.6f]\n", r.scheme, r.ts, (double)lo,
                (double)hi);
    if (r.monotone) {
      EXPECT_GE(lo, -1e-14) << r.scheme << " " << r.ts;
      EXPECT_LE(hi, 1 + 1e-14) << r.scheme << " " << r.ts;
    } else {
      EXPECT_GT(std::max(-lo, hi - 1), 0.01) << r.scheme << " should oscillate";
    }
  }
}
