// Dual numbers (flexipde/dual.hpp): first derivatives of generic functions against their closed
// forms, second derivatives from nested Duals (the Hessian-vector products of a pointwise function),
// and the non-smooth helpers taking the branch's derivative.
#include "flexipde/dual.hpp"
#include <cmath>
#include <gtest/gtest.h>

using namespace flexipde;

namespace {

// f(x, y) = exp(x) sin(y) / (1 + x^2) + sqrt(x y) tanh(y) - log(x) cos(x y)
template <class T> T f(const T &x, const T &y) {
  return exp(x) * sin(y) / (1.0 + sqr(x)) + sqrt(x * y) * tanh(y) - log(x) * cos(x * y);
}

double f_num(double x, double y) { return f(x, y); }

} // namespace

TEST(Dual, GradientMatchesCentralDifferences) {
  const double x = 0.7, y = 1.3, h = 1e-6;
  const auto r = f(Dual<double, 2>::seeded(x, 0), Dual<double, 2>::seeded(y, 1));
  EXPECT_DOUBLE_EQ(r.v, f_num(x, y));
  EXPECT_NEAR(r.d[0], (f_num(x + h, y) - f_num(x - h, y)) / (2 * h), 1e-8);
  EXPECT_NEAR(r.d[1], (f_num(x, y + h) - f_num(x, y - h)) / (2 * h), 1e-8);
}

TEST(Dual, NestedDualsGiveHessianVectorProducts) {
  // H v for v = (0.3, -0.8): seed the inner lane with the direction, the outer lanes with the unit vectors
  using In = Dual<double, 1>;
  using Out = Dual<In, 2>;
  const double x = 0.7, y = 1.3, v[2] = {0.3, -0.8}, h = 1e-4;
  In xi(x), yi(y);
  xi.d[0] = v[0], yi.d[0] = v[1];
  const Out r = f(Out::seeded(xi, 0), Out::seeded(yi, 1));
  // d/dx_k of (grad f . v) by central differences of the first derivatives
  auto grad = [](double a, double b, int k) { return f(Dual<double, 2>::seeded(a, 0), Dual<double, 2>::seeded(b, 1)).d[k]; };
  for (int k = 0; k < 2; ++k) {
    const double hv = (grad(x + h * v[0], y + h * v[1], k) - grad(x - h * v[0], y - h * v[1], k)) / (2 * h);
    EXPECT_NEAR(r.d[k].d[0], hv, 1e-6) << "component " << k;
    EXPECT_DOUBLE_EQ(r.d[k].v, grad(x, y, k)); // the outer lanes' values are the gradient
  }
}

TEST(Dual, NonSmoothHelpersFollowTheBranch) {
  using D = Dual<double, 1>;
  const D a = D::seeded(-2.0, 0), b = D::seeded(3.0, 0);
  EXPECT_EQ(max(a, D(0.0)).d[0], 0.0);
  EXPECT_EQ(min(a, D(0.0)).d[0], 1.0);
  EXPECT_EQ(abs(a).d[0], -1.0);
  EXPECT_EQ(abs(b).d[0], 1.0);
  EXPECT_EQ(sqr(b).d[0], 6.0);
  // the Engquist-Osher flux F(a, b) = max(a,0)^2/2 + min(b,0)^2/2 and its derivatives max(a,0), min(b,0)
  auto F = [](const Dual<double, 2> &p, const Dual<double, 2> &q) {
    return 0.5 * sqr(max(p, Dual<double, 2>(0.0))) + 0.5 * sqr(min(q, Dual<double, 2>(0.0)));
  };
  for (double p : {-1.5, 0.25})
    for (double q : {-0.75, 2.0}) {
      const auto r = F(Dual<double, 2>::seeded(p, 0), Dual<double, 2>::seeded(q, 1));
      EXPECT_DOUBLE_EQ(r.d[0], std::max(p, 0.0));
      EXPECT_DOUBLE_EQ(r.d[1], std::min(q, 0.0));
    }
}
