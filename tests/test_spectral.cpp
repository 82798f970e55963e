// SpectralDifferentiator (src/discretisation/spectral.cpp), FFTW-MPI:
//   - dot-product identities <M x, y> = <x, M^T y> of first and second derivatives, the 2/3
//     filter and the derivative MatShell, in 1D, 2D and x-only on a 2D grid with a non-periodic y,
//   - accuracy: round-off by N = 64 for smooth periodic functions (exponential convergence),
//   - odd-derivative skew-symmetry, and refusal of odd N and non-periodic directions,
//   - apply_many (two real outputs per backward transform) and apply_sum (two real fields per
//     forward transform, one backward transform for their sum) against apply, one symbol at a time.
// Grids live on PETSC_COMM_WORLD, so every case runs distributed on 2 ranks too. A 1D grid on several
// ranks is transformed whole on every rank (replicated, up to kReplicateMax points) or by FFTW-MPI's
// distributed transform: the 1D cases run both ways (setup's replicate_max 0 forces the distributed one
// on small grids), and the two agree to round-off.
#include "flexipde/spectral.hpp"
#include "test_support.hpp"
#include <cmath>
#include <complex>
#include <functional>
#include <initializer_list>

using namespace flexipde;
using flexipde_test::dot;
using flexipde_test::fill_random;
using flexipde_test::QuietErrors;
using flexipde_test::rel_diff;

namespace {

const PetscReal two_pi = 2 * PETSC_PI;

PetscErrorCode make_grid(PetscInt dim, PetscInt nx, PetscInt ny, bool periodic_y, Grid &g) {
  GridOptions o;
  o.dim = dim;
  o.n = nx;
  o.ny = ny;
  o.x1 = two_pi;
  o.y1 = two_pi;
  o.periodic = PETSC_TRUE;
  o.periodic_y = periodic_y ? PETSC_TRUE : PETSC_FALSE;
  return Grid::create(PETSC_COMM_WORLD, 1, o, g);
}

PetscErrorCode fill(const Grid &g, Vec v, const std::function<PetscReal(PetscReal, PetscReal)> &f) {
  PetscFunctionBeginUser;
  Array a(v);
  PetscCall(a.error());
  PetscInt il = 0;
  for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j)
    for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i) a[il++] = f(g.x(i), g.dim() == 2 ? g.y(j) : 0.0);
  PetscFunctionReturn(0);
}

struct DotCase {
  const char *name;
  PetscInt dim, nx, ny;
  bool periodic_y, x_only;
  bool distributed = false; // 1D: FFTW-MPI's distributed transform also on small grids (replicate_max 0)
};
std::ostream &operator<<(std::ostream &os, const DotCase &c) { return os << c.name; }

class SpectralTranspose : public ::testing::TestWithParam<DotCase> {};

// The case's grid and differentiator, and global Vecs of its layout.
PetscErrorCode setup_case(const DotCase &c, Grid &g, SpectralDifferentiator &s, std::initializer_list<OwnedVec *> vs) {
  PetscFunctionBeginUser;
  PetscCall(make_grid(c.dim, c.nx, c.ny, c.periodic_y, g));
  PetscCall(s.setup(g, c.x_only, c.distributed ? 0 : SpectralDifferentiator::kReplicateMax));
  for (OwnedVec *v : vs) PetscCall(DMCreateGlobalVector(g.dm(), v->out()));
  PetscFunctionReturn(0);
}

TEST_P(SpectralTranspose, DotProductIdentities) {
  const DotCase &c = GetParam();
  Grid g;
  SpectralDifferentiator s;
  OwnedVec x, y, Mx, Mty;
  PETSC_ASSERT_OK(setup_case(c, g, s, {&x, &y, &Mx, &Mty}));
  PETSC_ASSERT_OK(fill_random(x, -1, 1, 41));
  PETSC_ASSERT_OK(fill_random(y, -1, 1, 42));
  const PetscInt ndir = c.dim == 2 && !c.x_only ? 2 : 1;
  for (PetscInt dir = 0; dir < ndir; ++dir)
    for (PetscInt order = 1; order <= 2; ++order)
      for (bool dealias : {false, true}) {
        PETSC_ASSERT_OK(s.derivative(dir, order, x, Mx, dealias));
        PETSC_ASSERT_OK(s.derivative(dir, order, y, Mty, dealias, true));
        const PetscReal l = dot(Mx, y), r = dot(x, Mty);
        PetscPrintf(PETSC_COMM_WORLD, "  [%s] d^%d/d%s%s: <Mx,y> = %.15e, <x,M^T y> = %.15e\n", c.name, (int)order,
                    dir ? "y" : "x", dealias ? " (2/3)" : "", (double)l, (double)r);
        EXPECT_GT(std::fabs(l), 1e-3);
        EXPECT_LE(rel_diff(l, r), 1e-12) << c.name << " dir " << dir << " order " << order;
        if (order == 1) { // skew-symmetric: M^T = -M
          PETSC_ASSERT_OK(s.derivative(dir, order, y, Mx, dealias));
          PETSC_ASSERT_OK(VecAXPY(Mx, 1.0, Mty));
          EXPECT_LE(flexipde_test::norm(Mx, NORM_INFINITY), 1e-12 * flexipde_test::norm(Mty, NORM_INFINITY));
        }
      }
  // the filter is a symmetric projection
  PETSC_ASSERT_OK(s.dealias(x, Mx));
  PETSC_ASSERT_OK(s.dealias(y, Mty));
  EXPECT_LE(rel_diff(dot(Mx, y), dot(x, Mty)), 1e-12);
  PETSC_ASSERT_OK(s.dealias(Mx, Mty));
  EXPECT_LE(rel_diff(Mx, Mty), 1e-13);
  // the MatShell: MULT and MULT_TRANSPOSE
  OwnedMat D;
  PETSC_ASSERT_OK(s.create_derivative_mat(0, 1, D.out()));
  PETSC_ASSERT_OK(MatMult(D, x, Mx));
  PETSC_ASSERT_OK(MatMultTranspose(D, y, Mty));
  EXPECT_LE(rel_diff(dot(Mx, y), dot(x, Mty)), 1e-12);
}

// apply_many packs two outputs into each backward transform: (S_0 + i S_1) u^ -> S_0 u + i S_1 u,
// which needs symbols with real backward transforms (symbol() symmetrises them). Three symbols (a
// pair and a single), one of them neither even nor odd in k (i k + k^2 + 1/2): each output must
// equal apply() of its symbol alone, and a first derivative must match derivative().
TEST_P(SpectralTranspose, ApplyManyMatchesApply) {
  const DotCase &c = GetParam();
  Grid g;
  SpectralDifferentiator s;
  OwnedVec x, y0, y1, y2, r;
  PETSC_ASSERT_OK(setup_case(c, g, s, {&x, &y0, &y1, &y2, &r}));
  PETSC_ASSERT_OK(fill_random(x, -1, 1, 43));
  using cplx = std::complex<PetscReal>;
  const SpectralDifferentiator::Symbol s0 = s.symbol([](const FourierMode &k) { return cplx(0.5 + k.wx * k.wx, k.wx); }),
                                       s1 = s.symbol([](const FourierMode &k) { return SpectralDifferentiator::derivative_symbol(k, 0, 1); }),
                                       s2 = s.symbol([](const FourierMode &k) { return cplx(-(k.wx * k.wx + k.wy * k.wy)); });
  PETSC_ASSERT_OK(s.apply_many({&s0, &s1, &s2}, x, {y0, y1, y2}));
  const SpectralDifferentiator::Symbol *ss[3] = {&s0, &s1, &s2};
  Vec ys[3] = {y0, y1, y2};
  for (int j = 0; j < 3; ++j) {
    PETSC_ASSERT_OK(s.apply(*ss[j], x, r));
    const PetscReal scale = flexipde_test::norm(r, NORM_INFINITY);
    EXPECT_GT(scale, 0.1);
    PETSC_ASSERT_OK(VecAXPY(r, -1.0, ys[j]));
    EXPECT_LE(flexipde_test::norm(r, NORM_INFINITY), 1e-13 * scale) << c.name << " output " << j;
  }
  PETSC_ASSERT_OK(s.derivative(0, 1, x, r));
  EXPECT_LE(rel_diff(r, y1), 1e-13) << c.name;
}

// apply_sum: y = S0 v0 + S1 v1 + S2 v2 from one forward transform per two fields (v0 + i alpha v1, and
// v2 alone) and one backward transform, against the sum of apply() of each; symbols even, odd and
// neither. A term of the pair dropped or taken with the wrong sign of i / alpha would miss by O(1).
// Then v1 on a scale 1e6 times v0's with S0 1e6 times larger, so that both terms of the pair are the
// same size: without the scaling alpha = ||v0|| / ||v1|| the small field's round-off in the pair
// (eps |S0| |v1|) would be 1e6 eps of the result.
TEST_P(SpectralTranspose, ApplySumMatchesApply) {
  const DotCase &c = GetParam();
  Grid g;
  SpectralDifferentiator s;
  OwnedVec v0, v1, v2, y, r, t;
  PETSC_ASSERT_OK(setup_case(c, g, s, {&v0, &v1, &v2, &y, &r, &t}));
  using cplx = std::complex<PetscReal>;
  const SpectralDifferentiator::Symbol s0 = s.symbol([](const FourierMode &k) { return cplx(0.5 + k.wx * k.wx, k.wx); }),
                                       s1 = s.symbol([](const FourierMode &k) { return SpectralDifferentiator::derivative_symbol(k, 0, 1); }),
                                       s2 = s.symbol([](const FourierMode &k) { return cplx(-(k.wx * k.wx + k.wy * k.wy)); });
  SpectralDifferentiator::Symbol s0_large = s0;
  for (auto &v : s0_large) v *= 1e6;
  for (PetscReal scale1 : {1.0, 1e6}) {
    PETSC_ASSERT_OK(fill_random(v0, -1, 1, 47));
    PETSC_ASSERT_OK(fill_random(v1, -scale1, scale1, 48));
    PETSC_ASSERT_OK(fill_random(v2, -1, 1, 49));
    const SpectralDifferentiator::Symbol *ss[3] = {scale1 == 1 ? &s0 : &s0_large, &s1, &s2};
    Vec vs[3] = {v0, v1, v2};
    for (int n = 1; n <= 3; ++n) { // a single field, a pair, a pair and a single
      PETSC_ASSERT_OK(s.apply_sum({ss, ss + n}, {vs, vs + n}, y));
      PETSC_ASSERT_OK(VecSet(r, 0.0));
      PetscReal size = 0;
      for (int j = 0; j < n; ++j) {
        PETSC_ASSERT_OK(s.apply(*ss[j], vs[j], t));
        size = std::max(size, flexipde_test::norm(t, NORM_INFINITY));
        PETSC_ASSERT_OK(VecAXPY(r, 1.0, t));
      }
      EXPECT_GT(size, 0.1);
      PETSC_ASSERT_OK(VecAXPY(r, -1.0, y));
      EXPECT_LE(flexipde_test::norm(r, NORM_INFINITY), 1e-13 * size) << c.name << " fields " << n << " scale " << scale1;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Spectral, SpectralTranspose,
                         ::testing::Values(DotCase{"1d_64", 1, 64, 1, true, false}, DotCase{"1d_50", 1, 50, 1, true, false},
                                           DotCase{"1d_64_distributed", 1, 64, 1, true, false, true},
                                           DotCase{"1d_50_distributed", 1, 50, 1, true, false, true},
                                           DotCase{"2d_32x24", 2, 32, 24, true, false},
                                           DotCase{"2d_x_only_nonperiodic_y", 2, 32, 15, false, true}),
                         [](const ::testing::TestParamInfo<DotCase> &i) { return std::string(i.param.name); });

// max |d^k u - exact| / max |exact| for u = exp(sin x) (1D) or exp(sin x + cos 2y / 2) (2D).
PetscErrorCode derivative_error(PetscInt dim, PetscInt n, PetscInt dir, PetscInt order, PetscReal *err) {
  Grid g;
  SpectralDifferentiator s;
  OwnedVec u, du, ex;
  PetscFunctionBeginUser;
  PetscCall(make_grid(dim, n, n, true, g));
  PetscCall(s.setup(g));
  PetscCall(DMCreateGlobalVector(g.dm(), u.out()));
  PetscCall(VecDuplicate(u, du.out()));
  PetscCall(VecDuplicate(u, ex.out()));
  auto f = [](PetscReal x, PetscReal y) { return std::exp(std::sin(x) + 0.5 * std::cos(2 * y)); };
  PetscCall(fill(g, u, f));
  PetscCall(fill(g, ex, [&](PetscReal x, PetscReal y) {
    const PetscReal p1 = dir == 0 ? std::cos(x) : -std::sin(2 * y);                    // d(phase)
    const PetscReal p2 = dir == 0 ? -std::sin(x) : -2 * std::cos(2 * y);               // d^2(phase)
    return f(x, y) * (order == 1 ? p1 : p1 * p1 + p2);
  }));
  PetscCall(s.derivative(dir, order, u, du));
  PetscReal scale;
  PetscCall(VecNorm(ex, NORM_INFINITY, &scale));
  PetscCall(VecAXPY(du, -1.0, ex));
  PetscCall(VecNorm(du, NORM_INFINITY, err));
  *err /= scale;
  PetscFunctionReturn(0);
}

} // namespace

// The replicated 1D transform (every rank transforms the whole gathered field) against FFTW-MPI's
// distributed one (replicate_max 0): the same first and second derivatives and the same sum of two
// fields' derivatives (apply_sum) to round-off, on grids that 2 and 3 ranks split evenly or not.
TEST(Spectral, ReplicatedMatchesDistributed1D) {
  for (PetscInt n : {64, 50}) {
    SCOPED_TRACE("N = " + std::to_string(n));
    Grid g;
    SpectralDifferentiator rep, dis;
    OwnedVec x, u, y0, y1;
    PETSC_ASSERT_OK(setup_case(DotCase{"replicated", 1, n, 1, true, false}, g, rep, {&x, &u, &y0, &y1}));
    PETSC_ASSERT_OK(dis.setup(g, false, 0));
    PETSC_ASSERT_OK(fill_random(x, -1, 1, 47));
    PETSC_ASSERT_OK(fill_random(u, -2, 3, 48));
    for (PetscInt order = 1; order <= 2; ++order) {
      PETSC_ASSERT_OK(rep.derivative(0, order, x, y0));
      PETSC_ASSERT_OK(dis.derivative(0, order, x, y1));
      EXPECT_GT(flexipde_test::norm(y1, NORM_INFINITY), 0.1);
      EXPECT_LE(rel_diff(y0, y1), 1e-13) << "order " << order;
    }
    // a sum of two fields (one forward transform of x + i alpha u); each symbol holds the modes of
    // its own transform's layout
    auto d = [](PetscInt order) { return [order](const FourierMode &k) { return SpectralDifferentiator::derivative_symbol(k, 0, order); }; };
    const auto r1 = rep.symbol(d(1)), r2 = rep.symbol(d(2)), d1 = dis.symbol(d(1)), d2 = dis.symbol(d(2));
    PETSC_ASSERT_OK(rep.apply_sum({&r1, &r2}, {x, u}, y0));
    PETSC_ASSERT_OK(dis.apply_sum({&d1, &d2}, {x, u}, y1));
    EXPECT_GT(flexipde_test::norm(y1, NORM_INFINITY), 0.1);
    EXPECT_LE(rel_diff(y0, y1), 1e-13) << "apply_sum";
  }
}

TEST(Spectral, ConvergesToRoundOffByN64) {
  struct Case {
    PetscInt dim, dir, order;
  } cases[] = {{1, 0, 1}, {1, 0, 2}, {2, 0, 1}, {2, 1, 1}, {2, 1, 2}};
  for (auto &c : cases) {
    PetscReal e[3];
    const PetscInt ns[3] = {16, 32, 64};
    for (int k = 0; k < 3; ++k) PETSC_ASSERT_OK(derivative_error(c.dim, ns[k], c.dir, c.order, &e[k]));
    PetscPrintf(PETSC_COMM_WORLD, "  [%dD, d^%d/d%s] relative max error N=16 %.2e, 32 %.2e, 64 %.2e\n", (int)c.dim,
                (int)c.order, c.dir ? "y" : "x", (double)e[0], (double)e[1], (double)e[2]);
    EXPECT_GT(e[0], 1e-8); // not exact on a coarse grid: the test can fail
    EXPECT_LT(e[1], 1e-3 * e[0]);
    EXPECT_LT(e[2], 1e-13);
  }
}

TEST(Spectral, RefusesOddSizesAndNonPeriodicDirections) {
  struct Case {
    PetscInt dim, nx, ny;
    bool periodic_y, x_only;
    PetscErrorCode expected;
  } cases[] = {{1, 63, 1, true, false, PETSC_ERR_ARG_OUTOFRANGE},
               {2, 32, 31, true, false, PETSC_ERR_ARG_OUTOFRANGE},
               {2, 32, 32, false, false, PETSC_ERR_ARG_WRONG},
               {2, 32, 31, false, true, 0}};
  for (auto &c : cases) {
    Grid g;
    SpectralDifferentiator s;
    PETSC_ASSERT_OK(make_grid(c.dim, c.nx, c.ny, c.periodic_y, g));
    PetscErrorCode err;
    {
      QuietErrors q;
      err = s.setup(g, c.x_only);
    }
    EXPECT_EQ(err, c.expected) << c.dim << "D " << c.nx << " x " << c.ny;
  }
}
