// SecondDerivative: convergence order against exact second derivatives (Dirichlet with the odd
// reflection closure, and periodic), structure of the operator (symmetry, consistency, spectral
// radius bound used by the stability check) and option handling.
//
// Every grid here lives on PETSC_COMM_SELF: every rank computes the same numbers, so the tests are
// collective-safe on any number of ranks.
#include "flexipde/differentiator.hpp"
#include "test_support.hpp"
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>

using namespace flexipde;
using flexipde_test::QuietErrors;
using flexipde_test::ScopedOptions;

namespace {

struct ErrorNorms {
  PetscReal max_all = 0;  // over every interior point
  PetscReal max_wall = 0; // relative error |err|/|u_xx| over the first and last `width` interior points
                          // (the closure rows; u_xx is O(h) there, so absolute errors superconverge)
};

// Max error of the discrete second derivative of u against u2 on grid g.
PetscErrorCode d2_error(const SecondDerivative &d, const Grid &g, const std::function<PetscReal(PetscReal)> &u,
                        const std::function<PetscReal(PetscReal)> &u2, PetscInt wall_width, ErrorNorms &e) {
  SecondDerivative::Row st;
  PetscFunctionBeginUser;
  e = ErrorNorms();
  for (PetscInt i = 0; i < g.n(); ++i) {
    if (g.is_boundary(i)) continue;
    const PetscInt m = d.row(g, i, st);
    PetscReal s = 0;
    for (PetscInt q = 0; q < m; ++q) s += st[q].weight * u(g.x(st[q].j));
    const PetscReal err = std::fabs(s - u2(g.x(i)));
    e.max_all = std::max(e.max_all, err);
    if (!g.periodic() && (i <= wall_width || i >= g.n() - 1 - wall_width))
      e.max_wall = std::max(e.max_wall, err / std::fabs(u2(g.x(i))));
  }
  PetscFunctionReturn(0);
}

// Dense matrix of the operator on the interior (rows and columns of wall points are left zero).
std::vector<std::vector<PetscReal>> dense(const SecondDerivative &d, const Grid &g) {
  std::vector<std::vector<PetscReal>> D(g.n(), std::vector<PetscReal>(g.n(), 0.0));
  SecondDerivative::Row st;
  for (PetscInt i = 0; i < g.n(); ++i) {
    if (g.is_boundary(i)) continue;
    const PetscInt m = d.row(g, i, st);
    for (PetscInt q = 0; q < m; ++q) D[i][st[q].j] += st[q].weight;
  }
  return D;
}

struct OrderCase {
  PetscInt order;
  PetscReal lo, hi;
};

class Convergence : public ::testing::TestWithParam<OrderCase> {};

const PetscReal pi = M_PI;

} // namespace

TEST_P(Convergence, DirichletSine) {
  const OrderCase oc = GetParam();
  SecondDerivative d;
  PETSC_ASSERT_OK(d.set_order(oc.order));
  auto u = [](PetscReal x) { return std::sin(pi * x); };
  auto u2 = [](PetscReal x) { return -pi * pi * std::sin(pi * x); };
  ErrorNorms e[2];
  // h = 1/40, 1/80 (order 8: 1/10, 1/20, where its error of sin(pi x) is still far above round-off)
  const PetscInt ns[2] = {oc.order == 8 ? 11 : 41, oc.order == 8 ? 21 : 81};
  for (int k = 0; k < 2; ++k) {
    Grid g;
    GridOptions o;
    o.n = ns[k];
    PETSC_ASSERT_OK(Grid::create(PETSC_COMM_SELF, d.half_width(), o, g));
    ASSERT_NEAR(g.h(), 1.0 / (ns[k] - 1), 1e-15);
    PETSC_ASSERT_OK(d2_error(d, g, u, u2, d.half_width(), e[k]));
  }
  const PetscReal rate = std::log2(e[0].max_all / e[1].max_all);
  const PetscReal rate_wall = std::log2(e[0].max_wall / e[1].max_wall);
  if (flexipde_test::is_rank0())
    std::printf("  [order %d Dirichlet] max err %.3e -> %.3e, observed order %.3f (closure rows, relative error: %.3f)\n", (int)oc.order,
                (double)e[0].max_all, (double)e[1].max_all, (double)rate, (double)rate_wall);
  EXPECT_GE(rate, oc.lo);
  EXPECT_LE(rate, oc.hi);
  // The odd reflection keeps the closure rows at the design order for u with u = u_xx = 0 at the walls.
  EXPECT_GE(rate_wall, oc.lo);
  EXPECT_LE(rate_wall, oc.hi);
  EXPECT_LT(e[1].max_all, oc.order == 2 ? 2e-3 : 1e-5);
}

TEST_P(Convergence, PeriodicSmooth) {
  const OrderCase oc = GetParam();
  SecondDerivative d;
  PETSC_ASSERT_OK(d.set_order(oc.order));
  // Period 2 on [-0.5, 1.5).
  auto u = [](PetscReal x) { return std::sin(pi * x) + 0.5 * std::cos(2 * pi * x) + 0.3; };
  auto u2 = [](PetscReal x) { return -pi * pi * std::sin(pi * x) - 2.0 * pi * pi * std::cos(2 * pi * x); };
  ErrorNorms e[2];
  const PetscInt ns[2] = {64, 128};
  for (int k = 0; k < 2; ++k) {
    Grid g;
    GridOptions o;
    o.n = ns[k];
    o.x0 = -0.5;
    o.x1 = 1.5;
    o.periodic = PETSC_TRUE;
    PETSC_ASSERT_OK(Grid::create(PETSC_COMM_SELF, d.half_width(), o, g));
    ASSERT_NEAR(g.h(), 2.0 / ns[k], 1e-15);
    PETSC_ASSERT_OK(d2_error(d, g, u, u2, 0, e[k]));
  }
  const PetscReal rate = std::log2(e[0].max_all / e[1].max_all);
  if (flexipde_test::is_rank0())
    std::printf("  [order %d periodic]  max err %.3e -> %.3e, observed order %.3f\n", (int)oc.order,
                (double)e[0].max_all, (double)e[1].max_all, (double)rate);
  EXPECT_GE(rate, oc.lo);
  EXPECT_LE(rate, oc.hi);
}

// Symmetric (the reflection closure), annihilates constants in the periodic case, and its spectral
// radius is bounded by spectral_radius(h) (Gershgorin) and attained up to a few percent by the
// highest mode: the stability check relies on this bound being both safe and tight.
TEST_P(Convergence, OperatorStructure) {
  const OrderCase oc = GetParam();
  SecondDerivative d;
  PETSC_ASSERT_OK(d.set_order(oc.order));
  for (PetscBool periodic : {PETSC_FALSE, PETSC_TRUE}) {
    Grid g;
    GridOptions o;
    o.n = 24;
    o.periodic = periodic;
    PETSC_ASSERT_OK(Grid::create(PETSC_COMM_SELF, d.half_width(), o, g));
    auto D = dense(d, g);
    PetscReal gersh = 0, asym = 0, rowsum = 0;
    for (PetscInt i = 0; i < g.n(); ++i) {
      PetscReal r = 0, s = 0;
      for (PetscInt j = 0; j < g.n(); ++j) {
        r += std::fabs(D[i][j]);
        s += D[i][j];
        asym = std::max(asym, std::fabs(D[i][j] - D[j][i]));
      }
      gersh = std::max(gersh, r);
      if (periodic) rowsum = std::max(rowsum, std::fabs(s));
    }
    const PetscReal rho = d.spectral_radius(g.h());
    EXPECT_LE(asym, 1e-12 * rho) << "operator not symmetric, periodic=" << periodic;
    EXPECT_LE(gersh, rho * (1 + 1e-12)) << "Gershgorin radius exceeds spectral_radius(h), periodic=" << periodic;
    if (periodic) EXPECT_LE(rowsum, 1e-12 * rho) << "constants not annihilated";
    // Rayleigh quotient of the sawtooth (highest) mode, sin(pi x) modulated on Dirichlet grids.
    std::vector<PetscReal> v(g.n());
    for (PetscInt i = 0; i < g.n(); ++i) v[i] = (i % 2 ? -1.0 : 1.0) * (periodic ? 1.0 : std::sin(pi * g.x(i)));
    PetscReal num = 0, den = 0;
    for (PetscInt i = 0; i < g.n(); ++i) {
      PetscReal Dv = 0;
      for (PetscInt j = 0; j < g.n(); ++j) Dv += D[i][j] * v[j];
      num += v[i] * Dv;
      den += v[i] * v[i];
    }
    const PetscReal rq = -num / den; // D is negative semi-definite
    EXPECT_GT(rq, 0.95 * rho) << "spectral_radius(h) is far from the actual radius, periodic=" << periodic;
    EXPECT_LE(rq, rho * (1 + 1e-12));
  }
}

INSTANTIATE_TEST_SUITE_P(SecondDerivative, Convergence,
                         ::testing::Values(OrderCase{2, 1.8, 2.3}, OrderCase{4, 3.6, 4.5}, OrderCase{8, 7.5, 8.6}),
                         [](const ::testing::TestParamInfo<OrderCase> &i) { return "order" + std::to_string(i.param.order); });

// FirstDerivative's weights: the order of the centred first difference of a smooth periodic function,
// and exactness on polynomials up to that order.
TEST_P(Convergence, FirstDerivativeOrder) {
  const OrderCase oc = GetParam();
  const int R = (int)oc.order / 2;
  auto error = [&](PetscInt n) {
    const PetscReal h = 1.0 / n;
    PetscReal e = 0;
    for (PetscInt i = 0; i < n; ++i) {
      const PetscReal x = i * h;
      PetscReal s = 0;
      for (int k = 1; k <= R; ++k)
        s += FirstDerivative::weight((int)oc.order, k) * (std::exp(std::sin(2 * pi * (x + k * h))) - std::exp(std::sin(2 * pi * (x - k * h))));
      e = std::max(e, std::fabs(s / h - 2 * pi * std::cos(2 * pi * x) * std::exp(std::sin(2 * pi * x))));
    }
    return e;
  };
  const PetscReal rate = std::log2(error(32) / error(64));
  std::printf("  [first derivative, order %d]  observed order %.3f\n", (int)oc.order, (double)rate);
  EXPECT_GE(rate, oc.lo);
  EXPECT_LE(rate, oc.hi);
  for (int m = 1; m <= oc.order; ++m) { // d/dx x^m at 0 is 1 for m = 1, else 0
    PetscReal s = 0;
    for (int k = 1; k <= R; ++k) s += FirstDerivative::weight((int)oc.order, k) * (std::pow(k, m) - std::pow(-k, m));
    EXPECT_NEAR(s, m == 1 ? 1.0 : 0.0, 1e-13) << "x^" << m;
  }
}

TEST(SecondDerivative, StencilWeightsNearWall) {
  // Order 4, Dirichlet: row 1 reflects u_{-1} = -u_1 onto itself (merged), so it has 3 entries:
  // (-30 + 1)/12 at j=1, 16/12 at j=2, -1/12 at j=3 (the wall value at j=0 is zero and omitted).
  SecondDerivative d;
  PETSC_ASSERT_OK(d.set_order(4));
  Grid g;
  GridOptions o;
  o.n = 11;
  PETSC_ASSERT_OK(Grid::create(PETSC_COMM_SELF, 2, o, g));
  SecondDerivative::Row st;
  const PetscReal ih2 = 1.0 / (g.h() * g.h());
  PetscInt m = d.row(g, 1, st);
  ASSERT_EQ(m, 3);
  std::map<PetscInt, PetscReal> w;
  for (PetscInt q = 0; q < m; ++q) w[st[q].j] += st[q].weight / ih2;
  EXPECT_NEAR(w[1], -29.0 / 12, 1e-13);
  EXPECT_NEAR(w[2], 16.0 / 12, 1e-13);
  EXPECT_NEAR(w[3], -1.0 / 12, 1e-13);
  // Mirror row at the right wall.
  m = d.row(g, 9, st);
  ASSERT_EQ(m, 3);
  w.clear();
  for (PetscInt q = 0; q < m; ++q) w[st[q].j] += st[q].weight / ih2;
  EXPECT_NEAR(w[9], -29.0 / 12, 1e-13);
  EXPECT_NEAR(w[8], 16.0 / 12, 1e-13);
  EXPECT_NEAR(w[7], -1.0 / 12, 1e-13);
  // Periodic rows wrap: row 0 reaches n-2 and n-1.
  Grid gp;
  o.periodic = PETSC_TRUE;
  PETSC_ASSERT_OK(Grid::create(PETSC_COMM_SELF, 2, o, gp));
  m = d.row(gp, 0, st);
  ASSERT_EQ(m, 5);
  w.clear();
  for (PetscInt q = 0; q < m; ++q) w[st[q].j] += st[q].weight * gp.h() * gp.h();
  EXPECT_NEAR(w[9], -1.0 / 12, 1e-13);
  EXPECT_NEAR(w[10], 16.0 / 12, 1e-13);
  EXPECT_NEAR(w[0], -30.0 / 12, 1e-13);
}

TEST(SecondDerivative, OrderOptions) {
  {
    ScopedOptions opts{{"-fd_order", "4"}};
    SecondDerivative d;
    PETSC_ASSERT_OK(SecondDerivative::from_options(PETSC_COMM_WORLD, nullptr, 2, d));
    EXPECT_EQ(d.order(), 4);
    EXPECT_EQ(d.half_width(), 2);
  }
  {
    SecondDerivative d;
    PETSC_ASSERT_OK(SecondDerivative::from_options(PETSC_COMM_WORLD, nullptr, 2, d));
    EXPECT_EQ(d.order(), 2) << "default order not used (leaked option?)";
    EXPECT_EQ(d.half_width(), 1);
  }
  EXPECT_EQ(SecondDerivative::half_width_for(4), 2);
  for (const char *bad : {"3", "0", "6", "-2"}) {
    ScopedOptions opts{{"-fd_order", bad}};
    SecondDerivative d;
    PetscErrorCode ierr;
    {
      QuietErrors q;
      ierr = SecondDerivative::from_options(PETSC_COMM_WORLD, nullptr, 2, d);
    }
    EXPECT_NE(ierr, 0) << "-fd_order " << bad << " was accepted";
    EXPECT_EQ(d.order(), 2) << "a refused order must leave the operator unchanged";
  }
  SecondDerivative d;
  PETSC_ASSERT_OK(d.set_order(4));
  {
    QuietErrors q;
    EXPECT_NE(d.set_order(3), 0);
  }
  EXPECT_EQ(d.order(), 4);
}
