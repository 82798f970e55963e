// Vlasov-Poisson 1D1V (src/models/vlasov.cpp): Jacobian and its transpose, functionals and their
// derivatives, conservation of mass, the Landau damping rate and frequency, Taylor tests of the
// gradients with respect to the initial-condition parameters, dJ/dU0 against dU0/dp, and 1 vs 2
// ranks.
#include "flexipde/functional_objective.hpp"
#include "flexipde/scene.hpp"
#include "flexipde/taylor.hpp"
#include "test_support.hpp"
#include <array>
#include <complex>
#include <cmath>
#include <cstdlib>
#include <vector>

using namespace flexipde;
using flexipde_test::dot;
using flexipde_test::fill_random;
using flexipde_test::norm;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

using Options = std::vector<std::pair<std::string, std::string>>;

void small_grid(ScopedOptions &o, const char *ic, const char *nx = "16", const char *nv = "32") {
  o.set("-model", "vlasov");
  o.set("-vlasov_ic", ic);
  o.set("-da_grid_x", nx);
  o.set("-da_grid_y", nv);
}

// Runs the model from U0(p) with classical RK4 steps of dt to T, calling `record(t, U)` after each
// step (and at t = 0). A TS of its own, so that the test sees every step.
struct History {
  Model *model;
  std::function<PetscErrorCode(PetscReal, Vec)> record;
  static PetscErrorCode rhs(TS, PetscReal t, Vec U, Vec G, void *ctx) {
    return static_cast<History *>(ctx)->model->rhs(t, U, G);
  }
  static PetscErrorCode monitor(TS, PetscInt, PetscReal t, Vec U, void *ctx) {
    return static_cast<History *>(ctx)->record(t, U);
  }
  // From U0(p), or from the U given when p is null.
  PetscErrorCode run(Scene &scene, Vec p, PetscReal dt, PetscReal T, Vec U) {
    OwnedTS ts;
    PetscFunctionBeginUser;
    model = scene.model.get();
    if (p) PetscCall(scene.sim.initial_condition(p, U));
    PetscCall(TSCreate(scene.comm(), ts.out()));
    PetscCall(TSSetProblemType(ts, TS_NONLINEAR));
    PetscCall(TSSetRHSFunction(ts, nullptr, rhs, this));
    PetscCall(TSSetType(ts, TSRK));
    PetscCall(TSRKSetType(ts, TSRK4));
    PetscCall(TSSetTimeStep(ts, dt));
    PetscCall(TSSetMaxSteps(ts, (PetscInt)std::llround(T / dt)));
    PetscCall(TSSetMaxTime(ts, T));
    PetscCall(TSSetExactFinalTime(ts, TS_EXACTFINALTIME_MATCHSTEP));
    if (record) PetscCall(TSMonitorSet(ts, monitor, this, nullptr));
    PetscCall(TSSolve(ts, U));
    PetscFunctionReturn(0);
  }
};

// ---------------------------------------------------------------------------------------------
// dG/dU: transpose (dot product) and consistency. G is quadratic in f (E is linear in f), so the
// central difference (G(U + e x) - G(U - e x)) / 2e equals dG/dU x up to round-off for any e.

class VlasovJacobian : public ::testing::TestWithParam<const char *> {};

TEST_P(VlasovJacobian, TransposeAndCentralDifference) {
  const std::string name = GetParam();
  ScopedOptions o;
  small_grid(o, name == "landau" ? "landau" : "two_stream", "20", "24");
  if (name == "two_stream_dissipation") o.set("-vlasov_dissipation", "1");
  Scene scene;
  OwnedVec p, U, x, y, Jx, Jty, Gp, Gm, W;
  OwnedMat J;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  for (Vec *v : {x.out(), y.out(), Jx.out(), Jty.out(), Gp.out(), Gm.out(), W.out()}) PETSC_ASSERT_OK(VecDuplicate(U, v));
  // A rough, non-negative state: every stencil entry matters, including next to the v bounds.
  PETSC_ASSERT_OK(fill_random(U, 0.0, 1.0, 41));
  PETSC_ASSERT_OK(fill_random(x, -1, 1, 42));
  PETSC_ASSERT_OK(fill_random(y, -1, 1, 43));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U, J));
  PETSC_ASSERT_OK(MatMult(J, x, Jx));
  PETSC_ASSERT_OK(MatMultTranspose(J, y, Jty));
  const PetscReal lhs = dot(Jx, y), rhs = dot(x, Jty);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] <J x, y> = %.15e, <x, J^T y> = %.15e\n", GetParam(), (double)lhs, (double)rhs);
  EXPECT_GT(std::fabs(lhs), 1.0);
  EXPECT_LE(rel_diff(lhs, rhs), 1e-12);
  const PetscReal e = 1e-3;
  PETSC_ASSERT_OK(VecWAXPY(W, e, x, U));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, W, Gp));
  PETSC_ASSERT_OK(VecWAXPY(W, -e, x, U));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, W, Gm));
  PETSC_ASSERT_OK(VecAXPY(Gp, -1.0, Gm));
  PETSC_ASSERT_OK(VecScale(Gp, 0.5 / e));
  EXPECT_LE(rel_diff(Gp, Jx), 1e-9);
  // Mass: the rows of G sum to zero (x periodic, no flux through the v bounds).
  PetscScalar sum;
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, Gp));
  PETSC_ASSERT_OK(VecSum(Gp, &sum));
  EXPECT_LE(std::fabs(PetscRealPart(sum)), 1e-12 * norm(Gp, NORM_1));
}

INSTANTIATE_TEST_SUITE_P(Vlasov, VlasovJacobian, ::testing::Values("landau", "two_stream", "two_stream_dissipation"));

// dG/dU is the linearisation at the state of the last rhs_jacobian, whatever happens to that state
// afterwards. Relinearising at a second state, in either order of MatMult and MatMultTranspose, must
// give what a fresh Jacobian gives (exactly), and the dot product must hold on a grid that 2 ranks split
// in x (40 x 20) as well as in v (20 x 40).
class VlasovRelinearise : public ::testing::TestWithParam<std::array<const char *, 2>> {};

TEST_P(VlasovRelinearise, SnapshotAndDotProduct) {
  ScopedOptions o;
  small_grid(o, "two_stream", GetParam()[0], GetParam()[1]);
  o.set("-vlasov_dissipation", "0.5");
  Scene scene;
  OwnedVec p, U1, U2, x, y, Jx, Jty, Jx_fresh, Jty_fresh;
  OwnedMat J, Jfresh;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.sim.create_state(U1.out()));
  for (Vec *v : {U2.out(), x.out(), y.out(), Jx.out(), Jty.out(), Jx_fresh.out(), Jty_fresh.out()})
    PETSC_ASSERT_OK(VecDuplicate(U1, v));
  PETSC_ASSERT_OK(fill_random(U1, 0.0, 1.0, 51));
  PETSC_ASSERT_OK(fill_random(U2, 0.0, 1.0, 52));
  PETSC_ASSERT_OK(fill_random(x, -1, 1, 53));
  PETSC_ASSERT_OK(fill_random(y, -1, 1, 54));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
  PETSC_ASSERT_OK(scene.model->create_jacobian(Jfresh.out()));
  // Fresh: linearise at U2 and apply.
  PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U2, Jfresh));
  PETSC_ASSERT_OK(MatMult(Jfresh, x, Jx_fresh));
  PETSC_ASSERT_OK(MatMultTranspose(Jfresh, y, Jty_fresh));
  // Linearise at U1 and use both products, then relinearise at U2 and change U2 afterwards.
  PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U1, J));
  PETSC_ASSERT_OK(MatMultTranspose(J, y, Jty));
  PETSC_ASSERT_OK(MatMult(J, x, Jx));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U2, J));
  PETSC_ASSERT_OK(VecCopy(U2, U1));
  PETSC_ASSERT_OK(VecSet(U2, 3.0));
  PETSC_ASSERT_OK(MatMultTranspose(J, y, Jty));
  PETSC_ASSERT_OK(MatMult(J, x, Jx));
  EXPECT_EQ(rel_diff(Jx, Jx_fresh), 0.0);
  EXPECT_EQ(rel_diff(Jty, Jty_fresh), 0.0);
  const PetscReal lhs = dot(Jx, y), rhs = dot(x, Jty);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s x %s] <J x, y> = %.15e, <x, J^T y> = %.15e\n", GetParam()[0], GetParam()[1],
              (double)lhs, (double)rhs);
  EXPECT_GT(std::fabs(lhs), 1.0);
  EXPECT_LE(rel_diff(lhs, rhs), 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Vlasov, VlasovRelinearise,
                         ::testing::Values(std::array<const char *, 2>{"20", "40"},
                                           std::array<const char *, 2>{"40", "20"}));

// G = rhs(U) against a straightforward reference built here from a ghosted copy of U
// (DMGlobalToLocal): D_x by its stencil, D_v as differences of the face values (-1, 7, 7, -1) / 12
// with no flux through the outer faces and f = 0 beyond the velocity bounds, E = -K rho with K by a
// direct DFT, and the dissipation with Q = L^2, L the second difference without flux through the
// bounds. On grids that 2 ranks split in x (40 x 20) and in v (20 x 40); two states in turn, with a
// transpose product in between: no stale ghost or field is read.
struct RhsCase {
  const char *nx, *nv, *dissipation;
};
std::ostream &operator<<(std::ostream &os, const RhsCase &c) { return os << c.nx << "x" << c.nv << "_d" << c.dissipation; }
class VlasovRhs : public ::testing::TestWithParam<RhsCase> {};

PetscErrorCode vlasov_rhs_reference(const Grid &grid, DM dm, Vec U, PetscReal c_diss, PetscReal E_cfl, Vec G,
                                    PetscReal *Emax) {
  Vec Ul;
  const PetscScalar **f;
  PetscScalar **g;
  PetscInt xs, ys, xm, ym;
  PetscFunctionBeginUser;
  const PetscInt nx = grid.n(), nv = grid.ny();
  const PetscReal h = grid.h(), hv = grid.hy(), L = nx * h;
  PetscCall(DMDAGetCorners(dm, &xs, &ys, nullptr, &xm, &ym, nullptr));
  PetscCall(DMGetLocalVector(dm, &Ul));
  PetscCall(DMGlobalToLocal(dm, U, INSERT_VALUES, Ul));
  PetscCall(DMDAVecGetArrayRead(dm, Ul, &f));
  auto F = [&](PetscInt i, PetscInt j) { return j < 0 || j >= nv ? 0.0 : PetscRealPart(f[j][i]); };
  // rho_i = hv sum_j f_ij over all x (every rank), E = -K rho by a direct DFT.
  std::vector<PetscReal> rho(nx, 0.0), E(nx, 0.0);
  for (PetscInt j = ys; j < ys + ym; ++j)
    for (PetscInt i = xs; i < xs + xm; ++i) rho[i] += hv * F(i, j);
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, rho.data(), (PetscMPIInt)nx, MPIU_REAL, MPI_SUM, grid.comm()));
  for (PetscInt m = 1; 2 * m < nx; ++m) {
    std::complex<double> s = 0; // (-rho)^_m
    for (PetscInt l = 0; l < nx; ++l) s -= rho[l] * std::exp(std::complex<double>(0, -2 * M_PI * m * l / nx));
    const std::complex<double> c = s / std::complex<double>(0, 2 * M_PI * m / L);
    for (PetscInt i = 0; i < nx; ++i)
      E[i] += 2.0 / nx * (c * std::exp(std::complex<double>(0, 2 * M_PI * m * i / nx))).real();
  }
  *Emax = 0;
  for (PetscReal e : E) *Emax = std::max(*Emax, std::fabs(e));
  auto face = [&](PetscInt i, PetscInt q) { // F_{q+1/2}
    if (q < 0 || q > nv - 2) return 0.0;
    return (-F(i, q - 1) + 7 * F(i, q) + 7 * F(i, q + 1) - F(i, q + 2)) / 12;
  };
  auto lap = [&](PetscInt i, PetscInt q) { // (L f)_q, no flux through the bounds
    if (q < 0 || q >= nv) return 0.0;
    return (q > 0 ? F(i, q - 1) - F(i, q) : 0.0) + (q < nv - 1 ? F(i, q + 1) - F(i, q) : 0.0);
  };
  PetscCall(DMDAVecGetArray(dm, G, &g));
  for (PetscInt j = ys; j < ys + ym; ++j) {
    const PetscReal v = grid.y(j);
    for (PetscInt i = xs; i < xs + xm; ++i) {
      const PetscReal dx = (F(i - 2, j) - 8 * F(i - 1, j) + 8 * F(i + 1, j) - F(i + 2, j)) / (12 * h);
      const PetscReal dv = (face(i, j) - face(i, j - 1)) / hv;
      PetscReal r = -v * dx + E[i] * dv;
      if (c_diss > 0) {
        const PetscReal d4x = F(i - 2, j) - 4 * F(i - 1, j) + 6 * F(i, j) - 4 * F(i + 1, j) + F(i + 2, j);
        const PetscReal qv = (j > 0 ? lap(i, j - 1) - lap(i, j) : 0.0) + (j < nv - 1 ? lap(i, j + 1) - lap(i, j) : 0.0);
        r -= c_diss * (std::fabs(v) / (12 * h) * d4x + E_cfl / (12 * hv) * qv);
      }
      g[j][i] = r;
    }
  }
  PetscCall(DMDAVecRestoreArray(dm, G, &g));
  PetscCall(DMDAVecRestoreArrayRead(dm, Ul, &f));
  PetscCall(DMRestoreLocalVector(dm, &Ul));
  PetscFunctionReturn(0);
}

TEST_P(VlasovRhs, MatchesReference) {
  const RhsCase c = GetParam();
  ScopedOptions o;
  small_grid(o, "two_stream", c.nx, c.nv);
  o.set("-vlasov_dissipation", c.dissipation);
  o.set("-vlasov_E_cfl", "1.5");
  Scene scene;
  OwnedVec p, U, G, Gref, y, Jty;
  OwnedMat J;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  for (Vec *v : {G.out(), Gref.out(), y.out(), Jty.out()}) PETSC_ASSERT_OK(VecDuplicate(U, v));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
  const PetscReal c_diss = std::atof(c.dissipation);
  for (int k = 0; k < 2; ++k) {
    // A rough, non-negative state (E of order one), a function of the global (i, j) alone: fill_random
    // would give every rank the same local values, so a ghost taken from the wrong place (the own
    // block's other end) could go unseen.
    {
      PetscScalar **u;
      PetscInt xs, ys, xm, ym;
      PETSC_ASSERT_OK(DMDAGetCorners(scene.state_dm, &xs, &ys, nullptr, &xm, &ym, nullptr));
      PETSC_ASSERT_OK(DMDAVecGetArray(scene.state_dm, U, &u));
      for (PetscInt j = ys; j < ys + ym; ++j)
        for (PetscInt i = xs; i < xs + xm; ++i) {
          const double a = std::sin(12.9898 * i + 78.233 * j + 37.719 * k) * 43758.5453;
          u[j][i] = a - std::floor(a);
        }
      PETSC_ASSERT_OK(DMDAVecRestoreArray(scene.state_dm, U, &u));
    }
    PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G));
    PetscReal Emax;
    PETSC_ASSERT_OK(vlasov_rhs_reference(scene.grid, scene.state_dm, U, c_diss, 1.5, Gref, &Emax));
    const PetscReal err = rel_diff(G, Gref);
    PetscPrintf(PETSC_COMM_WORLD, "  [%s x %s, dissipation %s, state %d] max|E| = %.3e, ||G||_inf = %.3e, rel. diff %.2e\n",
                c.nx, c.nv, c.dissipation, k, (double)Emax, (double)norm(Gref, NORM_INFINITY), (double)err);
    EXPECT_GT(Emax, 0.1);
    EXPECT_LE(err, 1e-13);
    // A transpose product between the two states.
    PETSC_ASSERT_OK(fill_random(y, -1, 1, 71 + k));
    PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U, J));
    PETSC_ASSERT_OK(MatMultTranspose(J, y, Jty));
  }
}

INSTANTIATE_TEST_SUITE_P(Vlasov, VlasovRhs,
                         ::testing::Values(RhsCase{"40", "20", "0"}, RhsCase{"40", "20", "0.5"},
                                           RhsCase{"20", "40", "0"}, RhsCase{"20", "40", "0.5"}),
                         [](const ::testing::TestParamInfo<RhsCase> &i) {
                           return std::string(i.param.nx) + "x" + i.param.nv +
                                  (std::atof(i.param.dissipation) > 0 ? "_dissipation" : "");
                         });

// Functionals: dF/dU against central differences (exact for the linear and quadratic ones).
TEST(VlasovFunctionals, DerivativesMatchCentralDifferences) {
  ScopedOptions o;
  small_grid(o, "two_stream", "20", "24");
  Scene scene;
  OwnedVec U, d, dF, W;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  for (Vec *v : {d.out(), dF.out(), W.out()}) PETSC_ASSERT_OK(VecDuplicate(U, v));
  PETSC_ASSERT_OK(fill_random(U, 0.0, 1.0, 44));
  PETSC_ASSERT_OK(fill_random(d, -1, 1, 45));
  for (const char *name : {"field_energy", "mass", "momentum", "kinetic_energy", "energy", "l2"}) {
    PetscReal F, Fp, Fm, e = 1e-4;
    PETSC_ASSERT_OK(scene.model->functional(name, U, &F, dF));
    PETSC_ASSERT_OK(VecWAXPY(W, e, d, U));
    PETSC_ASSERT_OK(scene.model->functional(name, W, &Fp, nullptr));
    PETSC_ASSERT_OK(VecWAXPY(W, -e, d, U));
    PETSC_ASSERT_OK(scene.model->functional(name, W, &Fm, nullptr));
    const PetscReal fd = (Fp - Fm) / (2 * e), ad = dot(dF, d);
    PetscPrintf(PETSC_COMM_WORLD, "  %-15s F = %.10e  dF.d = %.12e  central difference %.12e\n", name, (double)F,
                (double)ad, (double)fd);
    EXPECT_GT(std::fabs(F), 0.0) << name;
    EXPECT_LE(rel_diff(ad, fd), 1e-7) << name;
  }
  {
    flexipde_test::QuietErrors quiet;
    PetscReal F;
    EXPECT_NE(0, scene.model->functional("nosuch", U, &F, nullptr));
  }
}

// ---------------------------------------------------------------------------------------------
// Conservation over a nonlinear two-stream run: mass to round-off; momentum, energy and the L2 norm
// reported (small drift at this coarse grid).
TEST(VlasovConservation, MassToRoundOffOverNonlinearRun) {
  ScopedOptions o;
  small_grid(o, "two_stream", "32", "64");
  o.set("-vlasov_alpha", "0.01");
  Scene scene;
  OwnedVec p, U;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  std::vector<std::array<PetscReal, 5>> h; // mass, momentum, energy, l2, field energy
  History hist;
  hist.record = [&](PetscReal, Vec V) {
    std::array<PetscReal, 5> a;
    const char *names[] = {"mass", "momentum", "energy", "l2", "field_energy"};
    for (int q = 0; q < 5; ++q) PetscCall(scene.model->functional(names[q], V, &a[q], nullptr));
    h.push_back(a);
    return PetscErrorCode(0);
  };
  PETSC_ASSERT_OK(hist.run(scene, p, 0.1, 40.0, U));
  ASSERT_GT(h.size(), 100u);
  PetscReal dm = 0, dp = 0, de = 0, dl = 0, wmax = 0;
  for (auto &a : h) {
    dm = std::max(dm, std::fabs(a[0] - h[0][0]) / h[0][0]);
    dp = std::max(dp, std::fabs(a[1] - h[0][1]));
    de = std::max(de, std::fabs(a[2] - h[0][2]) / h[0][2]);
    dl = std::max(dl, std::fabs(a[3] - h[0][3]) / h[0][3]);
    wmax = std::max(wmax, a[4]);
  }
  PetscPrintf(PETSC_COMM_WORLD,
              "  two-stream 32x64, T = 40: max rel. change of mass %.2e, energy %.2e, L2 %.2e; max |momentum change| "
              "%.2e; field energy %.3e -> max %.3e\n",
              (double)dm, (double)de, (double)dl, (double)dp, (double)h[0][4], (double)wmax);
  EXPECT_LE(dm, 1e-13);
  EXPECT_GT(wmax, 50 * h[0][4]); // the instability grew (and saturated)
  EXPECT_LE(de, 1e-2);
  EXPECT_TRUE(std::isfinite(norm(U)));
}

// ---------------------------------------------------------------------------------------------
// Linear Landau damping, k = 0.5, alpha = 0.01: E ~ exp(gamma t) cos(omega t - phi), so the field
// energy's peaks fall like exp(2 gamma t) and come every pi / omega. Reference (the roots of the
// Maxwellian dispersion relation): gamma = -0.1533, omega = 1.4156.
TEST(VlasovLandau, DampingRateAndFrequency) {
  ScopedOptions o;
  small_grid(o, "landau", "32", "128");
  Scene scene;
  OwnedVec p, U;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  std::vector<PetscReal> t, W;
  History hist;
  hist.record = [&](PetscReal tt, Vec V) {
    PetscReal w;
    PetscCall(scene.model->functional("field_energy", V, &w, nullptr));
    t.push_back(tt);
    W.push_back(w);
    return PetscErrorCode(0);
  };
  const PetscReal dt = 0.05;
  PETSC_ASSERT_OK(hist.run(scene, p, dt, 30.0, U));
  // Peaks of log W, refined by a parabola through the three samples around each maximum.
  std::vector<PetscReal> tp, lp;
  for (size_t n = 1; n + 1 < W.size(); ++n) {
    if (!(W[n] > W[n - 1] && W[n] >= W[n + 1])) continue;
    const PetscReal a = std::log(W[n - 1]), b = std::log(W[n]), c = std::log(W[n + 1]);
    const PetscReal s = 0.5 * (a - c) / (a - 2 * b + c);
    tp.push_back(t[n] + s * dt);
    lp.push_back(b - 0.25 * (a - c) * s);
  }
  ASSERT_GE(tp.size(), 8u);
  // Least-squares line through the peaks (the first one is left out: the initial transient).
  PetscReal st = 0, sl = 0, stt = 0, stl = 0, m = 0;
  for (size_t q = 1; q < tp.size(); ++q, ++m) {
    st += tp[q];
    sl += lp[q];
    stt += tp[q] * tp[q];
    stl += tp[q] * lp[q];
  }
  const PetscReal gamma = 0.5 * (m * stl - st * sl) / (m * stt - st * st);
  const PetscReal omega = PETSC_PI * (tp.size() - 2) / (tp.back() - tp[1]);
  const PetscReal eg = std::fabs(gamma / -0.1533 - 1), eo = std::fabs(omega / 1.4156 - 1);
  PetscPrintf(PETSC_COMM_WORLD,
              "  Landau 32x128, dt %g, %zu peaks: gamma = %.5f (rel. error %.2e), omega = %.5f (rel. error %.2e)\n",
              (double)dt, tp.size(), (double)gamma, (double)eg, (double)omega, (double)eo);
  EXPECT_LE(eg, 0.01);
  EXPECT_LE(eo, 0.01);
}

// ---------------------------------------------------------------------------------------------
// Two-stream instability, beams at +-2.4 with vt = 1, k = 0.2: the field energy grows like
// exp(2 gamma t) with gamma the root of the dispersion relation
//   eps(omega) = 1 - (1/k^2) int F'(v) / (v - omega/k) dv = 0,
// solved here by Newton's method, the integral by the trapezoidal rule (the integrand is analytic in
// a strip of half-width Im(omega)/k around the real axis, so the rule converges exponentially).
std::complex<double> two_stream_dielectric(std::complex<double> omega, double k, double v0, double vt, double ratio) {
  const double s1 = vt, s2 = vt * std::sqrt(ratio), vmax = v0 + 12 * std::max(s1, s2), dv = 2 * vmax / 20000;
  const std::complex<double> c = omega / k;
  std::complex<double> integral = 0;
  for (int q = 0; q <= 20000; ++q) {
    const double v = -vmax + q * dv, u1 = v - v0, u2 = v + v0;
    const double dF = -0.5 * (u1 / (s1 * s1) * std::exp(-0.5 * u1 * u1 / (s1 * s1)) / (std::sqrt(2 * M_PI) * s1) +
                              u2 / (s2 * s2) * std::exp(-0.5 * u2 * u2 / (s2 * s2)) / (std::sqrt(2 * M_PI) * s2));
    integral += (q == 0 || q == 20000 ? 0.5 : 1.0) * dv * dF / (v - c);
  }
  return 1.0 - integral / (k * k);
}

std::complex<double> two_stream_root(double k, double v0, double vt, double ratio, std::complex<double> omega) {
  for (int it = 0; it < 50; ++it) {
    const std::complex<double> h = 1e-6, f = two_stream_dielectric(omega, k, v0, vt, ratio);
    const std::complex<double> d = (two_stream_dielectric(omega + h, k, v0, vt, ratio) -
                                    two_stream_dielectric(omega - h, k, v0, vt, ratio)) / (2.0 * h);
    const std::complex<double> step = f / d;
    omega -= step;
    if (std::abs(step) < 1e-13) break;
  }
  return omega;
}

TEST(VlasovTwoStream, LinearGrowthMatchesDispersionRelation) {
  ScopedOptions o;
  small_grid(o, "two_stream", "32", "128");
  o.set("-vlasov_alpha", "1e-7"); // a long linear phase: saturation comes after t = 60
  Scene scene;
  OwnedVec p, U;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  const std::complex<double> omega = two_stream_root(0.2, 2.4, 1.0, 1.0, {0.0, 0.2});
  std::vector<PetscReal> t, lw;
  History hist;
  hist.record = [&](PetscReal tt, Vec V) {
    PetscReal w;
    PetscCall(scene.model->functional("field_energy", V, &w, nullptr));
    t.push_back(tt);
    lw.push_back(std::log(w));
    return PetscErrorCode(0);
  };
  PETSC_ASSERT_OK(hist.run(scene, p, 0.1, 50.0, U));
  // Least squares for log W = 2 gamma t + c over the linear phase. The perturbation excites the
  // weakly damped oscillating roots as much as the growing one; from t = 25 on they are a hundred
  // times smaller and the fit sees the growing mode alone.
  PetscReal st = 0, sl = 0, stt = 0, stl = 0, m = 0;
  for (size_t q = 0; q < t.size(); ++q) {
    if (t[q] < 25 - 1e-9) continue;
    st += t[q], sl += lw[q], stt += t[q] * t[q], stl += t[q] * lw[q], m += 1;
  }
  const PetscReal gamma = 0.5 * (m * stl - st * sl) / (m * stt - st * st), err = std::fabs(gamma / omega.imag() - 1);
  PetscPrintf(PETSC_COMM_WORLD,
              "  two-stream 32x128: dispersion relation omega = %.6f + %.6fi, measured gamma = %.5f (rel. error %.2e)\n",
              omega.real(), omega.imag(), (double)gamma, (double)err);
  EXPECT_NEAR(omega.imag(), 0.22584, 1e-4); // the root itself (scipy's Faddeeva function gives 0.225844)
  EXPECT_LE(err, 0.02);
}

// ---------------------------------------------------------------------------------------------
// Taylor tests of Simulation::gradient with respect to the initial-condition parameters, for the
// field energy at T and integrated over time.
struct TaylorCase {
  const char *name;
  Options options;
  PetscReal eps0 = 1e-2;
};
std::ostream &operator<<(std::ostream &os, const TaylorCase &c) { return os << c.name; }
class VlasovTaylor : public ::testing::TestWithParam<TaylorCase> {};

TEST_P(VlasovTaylor, Converges) {
  ScopedOptions o;
  small_grid(o, "two_stream");
  o.set("-ts_dt", "0.1");
  o.set("-ts_max_time", "4");
  for (auto &kv : GetParam().options) o.set(kv.first, kv.second);
  Scene scene;
  OwnedVec p, d;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(VecDuplicate(p, d.out()));
  PETSC_ASSERT_OK(fill_random(d, 0.2, 1.0, 46));
  auto f = [&](Vec q, PetscReal *J, Vec g) { return scene.sim.gradient(q, J, g, nullptr); };
  TaylorResult tr;
  PETSC_ASSERT_OK(taylor_test(f, p, d, GetParam().eps0, 5, tr));
  PetscPrintf(PETSC_COMM_WORLD, "  Taylor [%s, %" PetscInt_FMT " parameters]: g.d = %.6e\n", GetParam().name,
              scene.params.global_size(), (double)tr.gd);
  for (size_t k = 0; k < tr.eps.size(); ++k)
    PetscPrintf(PETSC_COMM_WORLD, "  %10.3e %12.5e %7.3f %12.5e %7.3f\n", (double)tr.eps[k], (double)tr.r1[k],
                k ? (double)tr.ratio1(k) : 0.0, (double)tr.r2[k], k ? (double)tr.ratio2(k) : 0.0);
  const size_t last = tr.eps.size() - 1;
  EXPECT_GT(std::fabs(tr.gd), 0.0);
  EXPECT_NEAR(tr.ratio1(last), 2.0, 0.3);
  EXPECT_NEAR(tr.ratio2(last), 4.0, 0.5) << "gradient is not the derivative of J";
}

INSTANTIATE_TEST_SUITE_P(
    Vlasov, VlasovTaylor,
    ::testing::Values(TaylorCase{"field_energy_at_T", {{"-objective_type", "functional"}}},
                      TaylorCase{"field_energy_target", {{"-objective_type", "functional"}, {"-objective_target", "1e-3"}}, 1e-3},
                      TaylorCase{"field_energy_integral", {{"-objective_type", "functional_integral"}}},
                      TaylorCase{"field_energy_dissipation",
                                 {{"-objective_type", "functional"}, {"-vlasov_dissipation", "1"}}},
                      TaylorCase{"landau_kinetic_energy_rk3",
                                 {{"-vlasov_ic", "landau"},
                                  {"-vlasov_alpha", "0.2"},
                                  {"-ts_rk_type", "3"},
                                  {"-objective_type", "functional"},
                                  {"-objective_functional", "kinetic_energy"}}}),
    [](const ::testing::TestParamInfo<TaylorCase> &i) { return std::string(i.param.name); });

// dJ/dU0 (the gradient with respect to the initial distribution) is consistent with the parameter
// gradient: (dU0/dp d) . dJ/dU0 = dJ/dp . d, with dU0/dp d from central differences of U0(p).
TEST(VlasovGradient, InitialDistributionGradientMatchesParameterGradient) {
  ScopedOptions o;
  small_grid(o, "two_stream");
  o.set("-ts_dt", "0.1");
  o.set("-ts_max_time", "4");
  o.set("-objective_type", "functional");
  Scene scene;
  OwnedVec p, d, q, gp, gu, Up, Um;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  for (Vec *v : {d.out(), q.out(), gp.out()}) PETSC_ASSERT_OK(VecDuplicate(p, v));
  for (Vec *v : {gu.out(), Up.out(), Um.out()}) PETSC_ASSERT_OK(scene.sim.create_state(v));
  PETSC_ASSERT_OK(fill_random(d, 0.2, 1.0, 47));
  PetscReal J;
  PETSC_ASSERT_OK(scene.sim.gradient(p, &J, gp, gu));
  const PetscReal e = 1e-5;
  PETSC_ASSERT_OK(VecWAXPY(q, e, d, p));
  PETSC_ASSERT_OK(scene.sim.initial_condition(q, Up));
  PETSC_ASSERT_OK(VecWAXPY(q, -e, d, p));
  PETSC_ASSERT_OK(scene.sim.initial_condition(q, Um));
  PETSC_ASSERT_OK(VecAXPY(Up, -1.0, Um));
  const PetscReal via_u0 = dot(Up, gu) / (2 * e), via_p = dot(gp, d);
  PetscPrintf(PETSC_COMM_WORLD, "  dJ/dU0 . dU0/dp d = %.12e, dJ/dp . d = %.12e\n", (double)via_u0, (double)via_p);
  EXPECT_GT(std::fabs(via_p), 0.0);
  EXPECT_LE(rel_diff(via_u0, via_p), 1e-7);
}

// Taylor test of dJ/dU0 itself, along a random direction in phase space: J(U0 + eps d) by a
// forward run from the perturbed distribution (the same RK4 steps as the Simulation's).
TEST(VlasovGradient, InitialDistributionTaylor) {
  ScopedOptions o;
  small_grid(o, "two_stream");
  o.set("-ts_dt", "0.1");
  o.set("-ts_max_time", "4");
  o.set("-objective_type", "functional");
  Scene scene;
  OwnedVec p, gp, gu, U0, d, U;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(VecDuplicate(p, gp.out()));
  for (Vec *v : {gu.out(), U0.out(), d.out(), U.out()}) PETSC_ASSERT_OK(scene.sim.create_state(v));
  PetscReal J;
  PETSC_ASSERT_OK(scene.sim.gradient(p, &J, gp, gu));
  PETSC_ASSERT_OK(scene.sim.initial_condition(p, U0));
  PETSC_ASSERT_OK(fill_random(d, -0.01, 0.01, 48));
  History hist;
  auto J_from = [&](PetscReal eps, PetscReal *value) {
    PetscFunctionBeginUser;
    PetscCall(VecWAXPY(U, eps, d, U0));
    PetscCall(hist.run(scene, nullptr, 0.1, 4.0, U));
    PetscCall(scene.model->functional("field_energy", U, value, nullptr));
    PetscFunctionReturn(0);
  };
  PetscReal J0;
  PETSC_ASSERT_OK(J_from(0.0, &J0));
  EXPECT_LE(rel_diff(J0, J), 1e-12) << "the test's run is not the Simulation's discrete map";
  const PetscReal gd = dot(gu, d);
  std::vector<PetscReal> r1, r2;
  for (PetscReal eps = 0.02; eps > 0.001; eps *= 0.5) { // the first-order term dominates from eps ~ 0.05 down
    PetscReal Je;
    PETSC_ASSERT_OK(J_from(eps, &Je));
    r1.push_back(std::fabs(Je - J0));
    r2.push_back(std::fabs(Je - J0 - eps * gd));
    PetscPrintf(PETSC_COMM_WORLD, "  dJ/dU0 Taylor: eps %.5f  r1 %.4e  r2 %.4e\n", (double)eps, (double)r1.back(),
                (double)r2.back());
  }
  EXPECT_GT(std::fabs(gd), 0.0);
  EXPECT_NEAR(r1[r1.size() - 2] / r1.back(), 2.0, 0.2);
  for (size_t k = 1; k < r2.size(); ++k) EXPECT_NEAR(r2[k - 1] / r2[k], 4.0, 0.3) << "dJ/dU0 is not the derivative of J";
}

// J, dJ/dp and dJ/dU0 (in natural ordering) on all ranks against each rank's serial run.
TEST(VlasovRanks, ParallelMatchesSerial) {
  ScopedOptions o;
  small_grid(o, "two_stream", "24", "40");
  o.set("-ts_dt", "0.1");
  o.set("-ts_max_time", "3");
  o.set("-objective_type", "functional_integral");
  o.set("-vlasov_dissipation", "0.5");
  flexipde_test::SceneProblem par, ser;
  PETSC_ASSERT_OK(par.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(ser.setup(PETSC_COMM_SELF));
  OwnedVec gpar, gser, upar, user, npar, nser;
  PETSC_ASSERT_OK(VecDuplicate(par.p, gpar.out()));
  PETSC_ASSERT_OK(VecDuplicate(ser.p, gser.out()));
  PETSC_ASSERT_OK(par.scene.sim.create_state(upar.out()));
  PETSC_ASSERT_OK(ser.scene.sim.create_state(user.out()));
  PetscReal Jpar, Jser;
  PETSC_ASSERT_OK(par.scene.sim.gradient(par.p, &Jpar, gpar, upar));
  PETSC_ASSERT_OK(ser.scene.sim.gradient(ser.p, &Jser, gser, user));
  PETSC_ASSERT_OK(DMDACreateNaturalVector(par.scene.state_dm, npar.out()));
  PETSC_ASSERT_OK(DMDACreateNaturalVector(ser.scene.state_dm, nser.out()));
  PETSC_ASSERT_OK(DMDAGlobalToNaturalBegin(par.scene.state_dm, upar, INSERT_VALUES, npar));
  PETSC_ASSERT_OK(DMDAGlobalToNaturalEnd(par.scene.state_dm, upar, INSERT_VALUES, npar));
  PETSC_ASSERT_OK(DMDAGlobalToNaturalBegin(ser.scene.state_dm, user, INSERT_VALUES, nser));
  PETSC_ASSERT_OK(DMDAGlobalToNaturalEnd(ser.scene.state_dm, user, INSERT_VALUES, nser));
  std::vector<PetscReal> a, b, ua, ub;
  PETSC_ASSERT_OK(flexipde_test::gather_all(gpar, a));
  PETSC_ASSERT_OK(flexipde_test::gather_all(gser, b));
  PETSC_ASSERT_OK(flexipde_test::gather_all(npar, ua));
  PETSC_ASSERT_OK(flexipde_test::gather_all(nser, ub));
  flexipde_test::expect_matches_serial("vlasov dJ/dp", Jpar, Jser, a, b);
  flexipde_test::expect_matches_serial("vlasov dJ/dU0", Jpar, Jser, ua, ub);
}

// The optional dissipation keeps the mass to round-off, removes L2 norm (it only dissipates) and
// reduces the undershoots of filamentation in a nonlinear two-stream run.
TEST(VlasovDissipation, KeepsMassDampsUndershoots) {
  PetscReal fmin[2], l2drop[2];
  for (int c = 0; c < 2; ++c) {
    ScopedOptions o;
    small_grid(o, "two_stream", "32", "64");
    o.set("-vlasov_alpha", "0.01");
    if (c) o.set("-vlasov_dissipation", "1");
    Scene scene;
    OwnedVec p, U;
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
    PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
    PetscReal m0 = -1, m1 = 0, l0 = -1, l1 = 0;
    History hist;
    hist.record = [&](PetscReal, Vec V) {
      PetscCall(scene.model->functional("mass", V, &m1, nullptr));
      PetscCall(scene.model->functional("l2", V, &l1, nullptr));
      if (m0 < 0) m0 = m1, l0 = l1;
      return PetscErrorCode(0);
    };
    PETSC_ASSERT_OK(hist.run(scene, p, 0.1, 60.0, U));
    PETSC_ASSERT_OK(VecMin(U, nullptr, &fmin[c]));
    l2drop[c] = 1 - l1 / l0;
    EXPECT_LE(std::fabs(m1 / m0 - 1), 1e-13);
  }
  PetscPrintf(PETSC_COMM_WORLD, "  two-stream 32x64, T = 60: min f %.3e without, %.3e with -vlasov_dissipation 1; L2 norm "
              "lost %.2e, %.2e\n", (double)fmin[0], (double)fmin[1], (double)l2drop[0], (double)l2drop[1]);
  EXPECT_GT(l2drop[1], l2drop[0]);
  EXPECT_GT(fmin[1], 0.5 * fmin[0]); // undershoots at least halved
}

// Bad set-ups fail with one clear message.
TEST(VlasovScene, RefusesBadSetups) {
  flexipde_test::QuietErrors quiet;
  for (const Options &bad : {Options{{"-vlasov_k", "-1"}}, Options{{"-grid_periodic", "0"}}, Options{{"-vlasov_mode", "0"}}, Options{{"-vlasov_dissipation", "-1"}},
                             Options{{"-objective_type", "functional"}, {"-objective_functional", "nosuch"}}}) {
    ScopedOptions o;
    small_grid(o, "landau");
    for (auto &kv : bad) o.set(kv.first, kv.second);
    Scene scene;
    EXPECT_NE(0, scene.setup(PETSC_COMM_WORLD)) << bad[0].first;
  }
}

} // namespace
