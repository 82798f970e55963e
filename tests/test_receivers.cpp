// Receivers, Ricker point sources and the time-integrated receiver misfit (survey.hpp), and the Adam
// TAO type (tao_adam.hpp):
//   - Taylor tests of dJ/dc (c a field) with two shots, for -ts_type rk and cn,
//   - the same in 2D (wave2d with its sponge, and with the PML under RK4) with Taylor and 1 vs 2 ranks, and
//     the sponge absorbing,
//   - a parallel run against a serial one (PETSC_COMM_SELF on every rank), two shots,
//   - the synthetic misfit at the true model: zero to round-off with cn (data at its step states),
//   - the data file round trip (-survey_data_write, then -survey_data_file gives the same J), and
//     receivers from a text file (-survey_receivers_file) against the same ones from a list,
//   - the discrete delta of a source integrates to one, receivers interpolate linear functions exactly,
//   - Tikhonov + smoothed TV in 2D (Taylor test of the regularised objective), TV of a step,
//   - 3D: trilinear and sinc weights on a 3D grid, the injection against the sampling's transpose, positions
//     (lists, an "x y z" file, refusals) and the data file with z, with a stand-in model (SourceProbe3D),
//   - Adam's first two steps against hand-computed values on a quadratic.
// Scenes are small (101 points, 0.6 time units) so that the file runs in a few seconds.
#include "flexipde/inversion.hpp"
#include "flexipde/survey.hpp"
#include "flexipde/tao_adam.hpp"
#include "flexipde/taylor.hpp"
#include "test_support.hpp"
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <unistd.h>

using namespace flexipde;
using flexipde_test::fill_random;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;
using flexipde_test::SceneProblem;

namespace {

// Two shots at 0.3 and 0.7, eight receivers, c a field; the true model is linear 0.9 -> 1.1.
void survey_options(ScopedOptions &o, const char *ts_type) {
  o.set("-da_grid_x", "101");
  o.set("-ts_max_time", "0.6");
  o.set("-ts_dt", std::string(ts_type) == "cn" ? "5e-3" : "2e-3");
  o.set("-ts_type", ts_type);
  o.set("-wave_c_field", "1");
  o.set("-wave_c", "1.0");
  o.set("-wave_ic", "zero");
  o.set("-true_wave_c_profile", "linear");
  o.set("-true_wave_c_left", "0.9");
  o.set("-true_wave_c_right", "1.1");
  o.set("-objective_type", "receivers");
  o.set("-survey_sources_x", "0.3,0.7");
  o.set("-survey_receivers_spread", "0.05,0.95,8");
  o.set("-survey_ricker_f0", "6");
}

// A Taylor test of the scene's gradient (summed over its shots) in a random direction of size 0.05:
// remainders falling 2x and 4x per halving of the step at the last of `levels` levels.
void expect_taylor(SceneProblem &sp, unsigned long seed, PetscInt levels, const std::string &label) {
  OwnedVec d;
  PETSC_ASSERT_OK(VecDuplicate(sp.p, d.out()));
  PETSC_ASSERT_OK(fill_random(d, -0.05, 0.05, seed));
  TaylorResult tr;
  auto f = [&](Vec q, PetscReal *J, Vec g) { return sp.scene.gradient(q, J, g); };
  PETSC_ASSERT_OK(taylor_test(f, sp.p, d, 1.0, levels, tr));
  const size_t last = tr.eps.size() - 1;
  for (size_t k = 1; k <= last; ++k)
    PetscPrintf(PETSC_COMM_WORLD, "  [%s] eps %.3e r1 %.3e (%.3f) r2 %.3e (%.3f)\n", label.c_str(), (double)tr.eps[k],
                (double)tr.r1[k], (double)tr.ratio1(k), (double)tr.r2[k], (double)tr.ratio2(k));
  EXPECT_GT(std::fabs(tr.gd), 0.0);
  EXPECT_NEAR(tr.ratio1(last), 2.0, 0.2);
  EXPECT_NEAR(tr.ratio2(last), 4.0, 0.3) << label << ": dJ/dc is not the derivative of the receiver misfit";
}

class ReceiverMisfit : public ::testing::TestWithParam<const char *> {};

TEST_P(ReceiverMisfit, TaylorTestTwoShots) {
  ScopedOptions o;
  survey_options(o, GetParam());
  SceneProblem sp;
  PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
  ASSERT_NE(sp.scene.objective.survey(), nullptr);
  EXPECT_EQ(sp.scene.objective.survey()->shots(), 2);
  expect_taylor(sp, 11, 5, GetParam());
}

TEST_P(ReceiverMisfit, ParallelMatchesSerial) {
  ScopedOptions o;
  survey_options(o, GetParam());
  flexipde_test::expect_parallel_matches_serial(std::string("receivers ") + GetParam());
}

INSTANTIATE_TEST_SUITE_P(Wave, ReceiverMisfit, ::testing::Values("rk", "cn"));

// Frequency bands: data and sources through the same low-pass filter. The true model fits the
// filtered data (the filtered source makes them, the equation being linear and time-invariant) far
// better than the start does; the misfit of the start falls with the band (the filter removes energy);
// the gradient in a band passes the Taylor test; the whole band restores the original misfit; and the
// result is the same on 2 ranks as on one.
TEST(FrequencyBands, FilteredSourceMakesFilteredData) {
  ScopedOptions o;
  survey_options(o, "cn");
  SceneProblem sp;
  PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
  PetscReal J_full, J_band, J_true_band, J_restored;
  PETSC_ASSERT_OK(sp.scene.value(sp.p, &J_full));
  PETSC_ASSERT_OK(sp.scene.set_frequency_band(3.0));
  PETSC_ASSERT_OK(sp.scene.value(sp.p, &J_band));
  PETSC_ASSERT_OK(sp.scene.value(sp.p_true, &J_true_band));
  PetscPrintf(PETSC_COMM_WORLD, "  misfit of the start: whole band %.3e, below 3: %.3e; of the true model below 3: %.3e\n",
              (double)J_full, (double)J_band, (double)J_true_band);
  EXPECT_LT(J_band, 0.5 * J_full);
  EXPECT_LT(J_true_band, 1e-3 * J_band);
  expect_taylor(sp, 12, 5, "band below 3");
  PETSC_ASSERT_OK(sp.scene.set_frequency_band(0.0));
  PETSC_ASSERT_OK(sp.scene.value(sp.p, &J_restored));
  EXPECT_EQ(J_restored, J_full);
}

TEST(FrequencyBands, ParallelMatchesSerial) {
  ScopedOptions o;
  survey_options(o, "rk");
  flexipde_test::expect_parallel_matches_serial("band below 4", [](Scene &s) { return s.set_frequency_band(4.0); });
}

// The 2D scene: wave2d on 31 x 31 points with its sponge, one shot, a line of receivers.
void survey2d_options(ScopedOptions &o) {
  o.set("-model", "wave2d");
  o.set("-da_grid_x", "31");
  o.set("-da_grid_y", "31");
  o.set("-ts_max_time", "0.5");
  o.set("-ts_dt", "4e-3");
  o.set("-wave2d_c_field", "1");
  o.set("-wave2d_c", "1.0");
  o.set("-true_wave2d_c_profile", "linear");
  o.set("-true_wave2d_c_left", "0.9");
  o.set("-true_wave2d_c_right", "1.2");
  o.set("-objective_type", "receivers");
  o.set("-survey_sources_x", "0.35,0.6");
  o.set("-survey_sources_y", "0.3");
  o.set("-survey_receivers_spread", "0.2,0.8,6");
  o.set("-survey_receivers_y", "0.65");
  o.set("-survey_ricker_f0", "5");
}

TEST(ReceiverMisfit2D, TaylorTest) {
  for (const char *how : {"linear", "sinc"}) { // sources and receivers tied to the grid by either weights
    ScopedOptions o;
    survey2d_options(o);
    o.set("-survey_interpolation", how);
    SceneProblem sp;
    PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
    EXPECT_EQ(sp.scene.grid.dim(), 2);
    expect_taylor(sp, 5, 4, std::string("2D, ") + how);
  }
}

TEST(ReceiverMisfit2D, ParallelMatchesSerial) {
  for (const char *how : {"linear", "sinc"}) {
    ScopedOptions o;
    survey2d_options(o);
    o.set("-survey_interpolation", how);
    flexipde_test::expect_parallel_matches_serial(std::string("receivers 2D, ") + how);
  }
}

// The same scene with the perfectly matched layer instead of the sponge, under RK4: the receivers'
// misfit and the PML's memory variables in the fused RK adjoint (the integrand's share added at every
// stage), Taylor test and 1 against 2 ranks.
TEST(ReceiverMisfit2D, PmlRk4) {
  ScopedOptions o;
  survey2d_options(o);
  o.set("-wave2d_pml_width", "0.2");
  o.set("-ts_type", "rk");
  o.set("-ts_rk_type", "4");
  {
    SceneProblem sp;
    PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
    expect_taylor(sp, 7, 4, "2D, PML, RK4");
  }
  flexipde_test::expect_parallel_matches_serial("receivers 2D, PML, RK4");
}

// A sponge absorbs: the energy left in the box after the pulse has reached the edges is far below
// that of the walls alone.
TEST(Wave2D, SpongeAbsorbs) {
  PetscReal norms[2];
  for (int k = 0; k < 2; ++k) {
    ScopedOptions o{{"-model", "wave2d"}, {"-da_grid_x", "61"}, {"-da_grid_y", "61"}, {"-wave2d_ic", "pulse"},
                    {"-wave2d_ic_width", "0.08"}, {"-ts_dt", "4e-3"}, {"-ts_max_time", "1.5"},
                    {"-wave2d_sponge_width", k ? "0.2" : "0"}};
    Scene s;
    OwnedVec p, U;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(s.params.create_vec(p.out()));
    PETSC_ASSERT_OK(s.parameters_from_options("", p));
    PETSC_ASSERT_OK(s.sim.create_state(U.out()));
    PETSC_ASSERT_OK(s.sim.forward(p, U));
    PETSC_ASSERT_OK(VecStrideNorm(U, 1, NORM_2, &norms[k])); // v: the 2D wake behind the front keeps u != 0
  }
  PetscPrintf(PETSC_COMM_WORLD, "  ||v(T)|| walls %.3e, sponge %.3e\n", (double)norms[0], (double)norms[1]);
  EXPECT_LT(norms[1], 0.1 * norms[0]); // measured 0.064 (61 x 61, W = 0.2, sigma_max = 60)
}

// Tikhonov + smoothed TV in 2D: Inversion::evaluate (misfit + regularisation) passes the Taylor test.
TEST(Regularisation, TaylorTest2D) {
  ScopedOptions o;
  survey2d_options(o);
  o.set("-inv_tikhonov", "1e-4");
  o.set("-inv_tv", "1e-4");
  o.set("-inv_tv_eps", "0.1");
  SceneProblem sp;
  PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
  Inversion inv;
  PETSC_ASSERT_OK(inv.setup(sp.scene, sp.p_true));
  OwnedVec d, q;
  PETSC_ASSERT_OK(VecDuplicate(sp.p, d.out()));
  PETSC_ASSERT_OK(VecDuplicate(sp.p, q.out()));
  PETSC_ASSERT_OK(fill_random(q, 0.9, 1.1, 3)); // a rough field, so that both terms matter
  PETSC_ASSERT_OK(fill_random(d, -0.05, 0.05, 7));
  PetscReal J, F;
  PETSC_ASSERT_OK(sp.scene.value(q, &J));
  PETSC_ASSERT_OK(inv.evaluate(q, &F, d)); // d is overwritten below; only F is used here
  PetscPrintf(PETSC_COMM_WORLD, "  misfit %.3e, regularisation %.3e\n", (double)J, (double)(F - J));
  EXPECT_GT(F - J, J); // the regularisation dominates the rough field
  PETSC_ASSERT_OK(fill_random(d, -0.05, 0.05, 7));
  TaylorResult tr;
  auto f = [&](Vec x, PetscReal *v, Vec g) { return inv.evaluate(x, v, g); };
  PETSC_ASSERT_OK(taylor_test(f, q, d, 0.02, 4, tr));
  const size_t last = tr.eps.size() - 1;
  EXPECT_NEAR(tr.ratio1(last), 2.0, 0.2);
  EXPECT_NEAR(tr.ratio2(last), 4.0, 0.3) << "the regularisation's gradient is not its derivative";
}

// Smoothed TV of a 1D step of height H: sum_i sqrt((dp_i/h)^2 + eps^2) h over the n-1 differences.
TEST(Regularisation, TotalVariationOfAStep) {
  ScopedOptions o;
  survey_options(o, "rk");
  o.set("-inv_tv", "2.0");
  o.set("-inv_tv_eps", "0.5");
  SceneProblem sp;
  PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
  Inversion inv;
  PETSC_ASSERT_OK(inv.setup(sp.scene, nullptr));
  const PetscReal H = 0.2, eps = 0.5, h = sp.scene.grid.h();
  const PetscInt n = sp.scene.grid.n();
  OwnedVec f, g;
  PETSC_ASSERT_OK(DMCreateGlobalVector(sp.scene.grid.dm(), f.out()));
  PETSC_ASSERT_OK(VecDuplicate(sp.p, g.out()));
  {
    Array a(f);
    PETSC_ASSERT_OK(a.error());
    for (PetscInt il = 0; il < sp.scene.grid.xm(); ++il) a[il] = sp.scene.grid.xs() + il < n / 2 ? 1.0 : 1.0 + H;
  }
  PETSC_ASSERT_OK(sp.scene.params.set_field(sp.p, 0, f));
  PetscReal J, F;
  PETSC_ASSERT_OK(sp.scene.value(sp.p, &J));
  PETSC_ASSERT_OK(inv.evaluate(sp.p, &F, g));
  const PetscReal expected = 2.0 * (std::sqrt(H * H / (h * h) + eps * eps) * h + (n - 2) * eps * h);
  EXPECT_NEAR(F - J, expected, 1e-12 * expected);
}

// With cn the quadrature visits the step states only, where the recorded data are exact: the
// misfit of the true model is round-off; with rk4 the stages leave a small floor.
TEST(ReceiverMisfit, TrueModelFitsItsOwnData) {
  for (const char *ts : {"cn", "rk"}) {
    ScopedOptions o;
    survey_options(o, ts);
    SceneProblem sp;
    PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
    PetscReal J0, J;
    PETSC_ASSERT_OK(sp.scene.value(sp.p, &J0)); // c = 1: a real misfit, for scale
    PETSC_ASSERT_OK(sp.scene.value(sp.p_true, &J));
    PetscPrintf(PETSC_COMM_WORLD, "  [%s] J(c_true) = %.3e, J(c = 1) = %.3e\n", ts, (double)J, (double)J0);
    EXPECT_GT(J0, 1e-6);
    EXPECT_LT(J, (std::string(ts) == "cn" ? 1e-24 : 1e-5) * J0);
  }
}

TEST(ReceiverMisfit, DataFileRoundTrip) {
  const std::string file = "/tmp/flexipde_test_survey_" + std::to_string(getpid()) + ".h5";
  std::string shared = file;
  { // one name for all ranks: rank 0's
    char buf[256];
    std::snprintf(buf, sizeof buf, "%s", file.c_str());
    MPI_Bcast(buf, sizeof buf, MPI_CHAR, 0, PETSC_COMM_WORLD);
    shared = buf;
  }
  PetscReal Jw, Jr;
  {
    ScopedOptions o;
    survey_options(o, "rk");
    o.set("-survey_data_write", shared);
    SceneProblem sp;
    PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(sp.scene.value(sp.p, &Jw));
  }
  {
    ScopedOptions o;
    survey_options(o, "rk");
    o.set("-survey_data_file", shared);
    o.set("-true_wave_c_left", "0.5"); // ignored: the data come from the file
    SceneProblem sp;
    PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(sp.scene.value(sp.p, &Jr));
  }
  if (flexipde_test::is_rank0()) std::remove(shared.c_str());
  EXPECT_GT(Jw, 0.0);
  EXPECT_LE(rel_diff(Jw, Jr), 1e-14);
}

// Receivers from a text file give the same J as the same receivers from -survey_receivers_x.
TEST(ReceiverMisfit, ReceiversFromFile) {
  char name[256];
  std::snprintf(name, sizeof name, "/tmp/flexipde_test_receivers_%d.txt", (int)getpid());
  MPI_Bcast(name, sizeof name, MPI_CHAR, 0, PETSC_COMM_WORLD);
  if (flexipde_test::is_rank0()) {
    FILE *f = std::fopen(name, "w");
    ASSERT_NE(f, nullptr);
    std::fprintf(f, "# x\n0.1\n0.45\n\n0.9\n");
    std::fclose(f);
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  PetscReal J[2];
  for (int k = 0; k < 2; ++k) {
    ScopedOptions o;
    survey_options(o, "rk");
    (void)PetscOptionsClearValue(nullptr, "-survey_receivers_spread"); // o clears it again at the end
    if (k == 0) o.set("-survey_receivers_x", "0.1,0.45,0.9");
    else o.set("-survey_receivers_file", name);
    SceneProblem sp;
    PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
    EXPECT_EQ(sp.scene.objective.survey()->receivers(), 3);
    PETSC_ASSERT_OK(sp.scene.value(sp.p, &J[k]));
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  if (flexipde_test::is_rank0()) std::remove(name);
  EXPECT_GT(J[0], 0.0);
  EXPECT_EQ(J[0], J[1]);
}

// The discrete delta sums to one over all ranks (weights), and R reproduces a linear field.
TEST(ReceiverMisfit, InterpolationWeights) {
  ScopedOptions o{{"-da_grid_x", "37"}};
  Grid grid;
  GridOptions go;
  PETSC_ASSERT_OK(Grid::from_options(PETSC_COMM_WORLD, 1, go, grid));
  for (PetscReal x : {0.0, 0.123, 0.5, 0.77, 1.0}) {
    PointStencil st;
    PETSC_ASSERT_OK(point_stencil(grid, x, 0.0, 0.0, &st));
    PetscReal sum = 0, value = 0;
    for (PetscInt k = 0; k < st.n; ++k) {
      sum += st.weight[k];
      value += st.weight[k] * grid.x(grid.xs() + st.local[k]); // interpolates f(x) = x
    }
    PetscReal tot[2] = {sum, value};
    MPI_Allreduce(MPI_IN_PLACE, tot, 2, MPIU_REAL, MPI_SUM, PETSC_COMM_WORLD);
    EXPECT_NEAR(tot[0], 1.0, 1e-14) << "x = " << x;
    EXPECT_NEAR(tot[1], x, 1e-14) << "x = " << x;
  }
}

// The windowed sinc: exact on grid points, weights summing to 1 away from walls, and far more accurate
// than linear interpolation between points (sin(2 pi 5 x) sampled at 10 and 4 points per wavelength).
TEST(ReceiverMisfit, SincInterpolation) {
  ScopedOptions o{{"-da_grid_x", "51"}};
  Grid grid;
  GridOptions go;
  PETSC_ASSERT_OK(Grid::from_options(PETSC_COMM_WORLD, 1, go, grid));
  auto sample = [&](PetscReal x, Interpolation how, const std::function<PetscReal(PetscReal)> &f, PetscReal out[3]) {
    PointStencil st;
    PetscErrorCode ierr = point_stencil(grid, x, 0.0, 0.0, &st, how);
    out[0] = out[1] = 0, out[2] = 0;
    for (PetscInt k = 0; k < st.n; ++k) {
      out[0] += st.weight[k];
      out[1] += st.weight[k] * f(grid.x(grid.xs() + st.local[k]));
      out[2] = std::max(out[2], (PetscReal)st.n);
    }
    MPI_Allreduce(MPI_IN_PLACE, out, 2, MPIU_REAL, MPI_SUM, PETSC_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, out + 2, 1, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
    return ierr;
  };
  PetscReal periods = 5; // on [0, 1]: 10 points per wavelength
  auto f = [&](PetscReal x) { return std::sin(2 * PETSC_PI * periods * x) + 0.3; };
  for (PetscInt i : {0, 7, 25, 50}) { // on a grid point: that point alone
    PetscReal r[3];
    PETSC_ASSERT_OK(sample(grid.x(i), Interpolation::Sinc, f, r));
    EXPECT_NEAR(r[0], 1.0, 1e-14);
    EXPECT_NEAR(r[1], f(grid.x(i)), 1e-14);
  }
  for (PetscReal ppw : {10.0, 4.0}) {
    periods = 50 / ppw;
    PetscReal worst[2] = {0, 0}, sums = 0;
    for (PetscReal x = 0.2013; x < 0.8; x += 0.0371) { // off the grid, more than 4 cells from the walls
      PetscReal rl[3], rs[3];
      PETSC_ASSERT_OK(sample(x, Interpolation::Linear, f, rl));
      PETSC_ASSERT_OK(sample(x, Interpolation::Sinc, f, rs));
      EXPECT_EQ(rs[2] > 0 ? 1 : 0, 1);
      worst[0] = std::max(worst[0], std::fabs(rl[1] - f(x)));
      worst[1] = std::max(worst[1], std::fabs(rs[1] - f(x)));
      sums = std::max(sums, std::fabs(rs[0] - 1));
    }
    PetscPrintf(PETSC_COMM_WORLD, "  [%.0f points per wavelength] max error linear %.2e, sinc %.2e; sinc weights sum to 1 within %.1e\n",
                (double)ppw, (double)worst[0], (double)worst[1], (double)sums);
    EXPECT_LT(worst[1], 2e-3);
    EXPECT_LT(worst[1], 0.05 * worst[0]);
    EXPECT_LT(sums, 2e-3);
  }
}

// Injection and sampling are each other's transposes: the source's forcing of v (G with the source
// less G without, at a time t) equals w(t) / cell volume times R^T e_r, R's row of a receiver at the
// source's position, at every point; and <R u, e_r> = <u, R^T e_r> for a random u. 2D, sinc and
// linear, off-grid positions, on any number of ranks.
TEST(ReceiverMisfit2D, InjectionIsSamplingTransposed) {
  for (const char *how : {"sinc", "linear"}) {
    ScopedOptions o{{"-model", "wave2d"},          {"-da_grid_x", "31"},           {"-da_grid_y", "31"},
                    {"-ts_max_time", "0.1"},       {"-ts_dt", "4e-3"},             {"-wave2d_c_field", "1"},
                    {"-objective_type", "receivers"}, {"-survey_sources_x", "0.4137"}, {"-survey_sources_y", "0.2871"},
                    {"-survey_receivers_x", "0.4137"}, {"-survey_receivers_y", "0.2871"}, {"-survey_ricker_f0", "5"},
                    {"-survey_interpolation", how}};
    SceneProblem sp;
    PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
    Survey *survey = sp.scene.objective.survey();
    ASSERT_NE(survey, nullptr);
    PETSC_ASSERT_OK(survey->select_shot(0));
    PETSC_ASSERT_OK(sp.scene.model->set_parameters(sp.p));
    OwnedVec U, Gon, Goff, q, ur, e;
    PETSC_ASSERT_OK(sp.scene.sim.create_state(U.out()));
    PETSC_ASSERT_OK(VecDuplicate(U, Gon.out()));
    PETSC_ASSERT_OK(VecDuplicate(U, Goff.out()));
    PETSC_ASSERT_OK(VecDuplicate(U, q.out()));
    PETSC_ASSERT_OK(flexipde_test::fill_random(U, -1.0, 1.0, 91));
    const PetscReal t = 0.21;
    PETSC_ASSERT_OK(sp.scene.model->rhs(t, U, Gon));
    PETSC_ASSERT_OK(sp.scene.model->set_point_source(nullptr));
    PETSC_ASSERT_OK(sp.scene.model->rhs(t, U, Goff));
    PETSC_ASSERT_OK(survey->select_shot(0));
    PETSC_ASSERT_OK(VecAXPY(Gon, -1.0, Goff)); // the injection
    Mat R = survey->receiver_matrix();
    PETSC_ASSERT_OK(MatCreateVecs(R, nullptr, e.out())); // one entry per receiver
    PETSC_ASSERT_OK(VecDuplicate(e, ur.out()));
    PETSC_ASSERT_OK(VecSet(e, 1.0)); // one receiver
    PETSC_ASSERT_OK(MatMultTranspose(R, e, q));
    // R^T e_r sits in u (component 0), the injection in v (component 1)
    Ricker w;
    w.f0 = 5, w.t0 = 1.2 / 5;
    const PetscReal scale = w(t) / sp.scene.grid.cell_volume();
    PetscReal diff = 0, norm = 0, nonzero = 0;
    {
      const PetscScalar *a, *b;
      PetscInt n;
      PETSC_ASSERT_OK(VecGetLocalSize(q, &n));
      PETSC_ASSERT_OK(VecGetArrayRead(q, &a));
      PETSC_ASSERT_OK(VecGetArrayRead(Gon, &b));
      for (PetscInt k = 0; k < n / 2; ++k) {
        diff = std::max(diff, std::fabs(scale * PetscRealPart(a[2 * k]) - PetscRealPart(b[2 * k + 1])));
        norm = std::max(norm, std::fabs(PetscRealPart(b[2 * k + 1])));
        nonzero += PetscRealPart(a[2 * k]) != 0.0;
        diff = std::max(diff, std::fabs(PetscRealPart(b[2 * k]))); // nothing injected into u
      }
      PETSC_ASSERT_OK(VecRestoreArrayRead(q, &a));
      PETSC_ASSERT_OK(VecRestoreArrayRead(Gon, &b));
    }
    MPI_Allreduce(MPI_IN_PLACE, &diff, 1, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &norm, 1, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &nonzero, 1, MPIU_REAL, MPI_SUM, PETSC_COMM_WORLD);
    PETSC_ASSERT_OK(MatMult(R, U, ur));
    PetscReal Ru, uq;
    PETSC_ASSERT_OK(VecDot(ur, e, &Ru));
    PETSC_ASSERT_OK(VecDot(U, q, &uq));
    PetscPrintf(PETSC_COMM_WORLD, "  [%s] %d points, injection - w/V R^T e: %.1e of %.1e; <Ru, e> %.15e, <u, R^T e> %.15e\n", how,
                (int)nonzero, (double)diff, (double)norm, (double)Ru, (double)uq);
    EXPECT_GT(norm, 0.0);
    EXPECT_LE(diff, 1e-12 * norm);
    EXPECT_EQ(nonzero, std::string(how) == "sinc" ? 64 : 4);
    EXPECT_LE(std::fabs(Ru - uq), 1e-13 * std::max(std::fabs(Ru), 1.0));
  }
}

// A wavelet read from a file: exact at its samples, cubic between them (exact for a cubic, end intervals
// included), 0 outside
// them; the Ricker wavelet sampled every 1e-3 into a file gives the Ricker run's misfit and gradient
// (to the interpolation's error); unreadable, non-increasing, malformed and one-sample files are refused.
TEST(ReceiverMisfit, WaveletFromFile) {
  Wavelet cubic;
  for (int k = 0; k <= 10; ++k) cubic.t.push_back(0.1 * k * k), cubic.w.push_back(0.0);
  for (size_t k = 0; k < cubic.t.size(); ++k) cubic.w[k] = std::pow(cubic.t[k], 3) - 2 * cubic.t[k];
  for (PetscReal x : {0.05, 0.15, 0.55, 2.0, 5.3, 7.9, 9.5}) EXPECT_NEAR(cubic(x), x * x * x - 2 * x, 1e-10 * (1 + x * x * x)) << x;
  EXPECT_EQ(cubic(cubic.t[3]), cubic.w[3]);
  EXPECT_EQ(cubic(-0.01), 0.0);
  EXPECT_EQ(cubic(10.01), 0.0);

  const std::string name = "flexipde_test_wavelet_" + std::to_string(getpid()) + ".txt";
  PetscMPIInt rank;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  auto write = [&](const std::string &text) {
    if (rank == 0) {
      std::FILE *f = std::fopen(name.c_str(), "w");
      std::fputs(text.c_str(), f);
      std::fclose(f);
    }
    MPI_Barrier(PETSC_COMM_WORLD);
  };
  Ricker r;
  r.f0 = 6, r.t0 = 1.2 / 6;
  std::string text = "# t w\n";
  char line[64];
  for (int k = 0; k <= 700; ++k) {
    std::snprintf(line, sizeof line, "%.17g %.17g\n", 1e-3 * k, r(1e-3 * k));
    text += line;
  }
  write(text);
  PetscReal J[2];
  OwnedVec g[2];
  for (int k = 0; k < 2; ++k) {
    ScopedOptions o;
    survey_options(o, "rk");
    if (k) o.set("-survey_wavelet_file", name);
    SceneProblem sp;
    PETSC_ASSERT_OK(sp.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(VecDuplicate(sp.p, g[k].out()));
    PETSC_ASSERT_OK(sp.scene.gradient(sp.p, &J[k], g[k]));
  }
  PetscPrintf(PETSC_COMM_WORLD, "  [wavelet file] J %.12e against %.12e (Ricker), gradient rel diff %.1e\n", (double)J[1],
              (double)J[0], (double)rel_diff(g[1], g[0]));
  EXPECT_GT(J[0], 0.0);
  EXPECT_LT(rel_diff(J[1], J[0]), 1e-6);
  EXPECT_LT(rel_diff(g[1], g[0]), 1e-5);
  for (const char *bad : {"0 1\n0.1 2\n0.1 3\n", "0 1\n0.1 two\n", "0 1\n", ""}) {
    write(bad);
    ScopedOptions o;
    survey_options(o, "rk");
    o.set("-survey_wavelet_file", name);
    Scene scene;
    PetscErrorCode ierr;
    {
      flexipde_test::QuietErrors q;
      ierr = scene.setup(PETSC_COMM_WORLD);
    }
    EXPECT_NE(ierr, 0) << "accepted: " << bad;
  }
  if (rank == 0) std::remove(name.c_str());
  ScopedOptions o;
  survey_options(o, "rk");
  o.set("-survey_wavelet_file", "/nonexistent/wavelet.txt");
  Scene scene;
  flexipde_test::QuietErrors q;
  EXPECT_EQ(scene.setup(PETSC_COMM_WORLD), PETSC_ERR_FILE_OPEN);
}

// ---- 3D ----

// The 3D grid of these tests: 13 x 15 x 17 points on [0, 1]^3, ghost width 4 (the sinc's half-width);
// z the longest direction, so that PETSc splits z among 2 ranks and the owned blocks start at zs > 0.
PetscErrorCode grid3d(MPI_Comm comm, Grid &grid) {
  GridOptions go;
  go.dim = 3, go.n = 13, go.ny = 15, go.nz = 17;
  return Grid::create(comm, 4, go, grid);
}

// The global (i, j, k) of owned point q: q = ((k - zs) ym + (j - ys)) xm + (i - xs).
void owned_ijk(const Grid &g, PetscInt q, PetscInt ijk[3]) {
  ijk[0] = g.xs() + q % g.xm(), ijk[1] = g.ys() + (q / g.xm()) % g.ym(), ijk[2] = g.zs() + q / (g.xm() * g.ym());
}

// Trilinear and sinc weights on a 3D grid, on any number of ranks: on a grid point that point alone with
// weight 1; between points 8 (linear) or 8^3 (sinc) points whose weights sum to 1 (sinc: within 1e-3,
// more than 4 cells from the walls), the trilinear ones reproducing a + b x + c y + d z + e xyz exactly.
// (On 2 ranks the second point's stencils straddle the ranks' boundary in z.)
TEST(ReceiverMisfit3D, PointStencilWeights) {
  Grid grid;
  PETSC_ASSERT_OK(grid3d(PETSC_COMM_WORLD, grid));
  ASSERT_EQ(grid.dim(), 3);
  auto f = [](PetscReal x, PetscReal y, PetscReal z) { return 0.3 + 1.7 * x - 0.8 * y + 2.1 * z + 0.9 * x * y * z; };
  for (Interpolation how : {Interpolation::Linear, Interpolation::Sinc}) {
    const char *label = how == Interpolation::Linear ? "linear" : "sinc";
    for (auto p : {std::array<PetscInt, 3>{0, 0, 0}, {6, 7, 8}, {12, 14, 16}, {2, 11, 3}, {10, 1, 12}}) {
      PointStencil st;
      PETSC_ASSERT_OK(point_stencil(grid, grid.x(p[0]), grid.y(p[1]), grid.z(p[2]), &st, how));
      PetscReal at[3] = {0, 0, 0}; // weight at p, |weight| elsewhere, points
      for (PetscInt m = 0; m < st.n; ++m) {
        PetscInt ijk[3];
        owned_ijk(grid, st.local[m], ijk);
        const bool here = ijk[0] == p[0] && ijk[1] == p[1] && ijk[2] == p[2];
        at[here ? 0 : 1] += here ? st.weight[m] : std::fabs(st.weight[m]);
        at[2] += 1;
      }
      MPI_Allreduce(MPI_IN_PLACE, at, 3, MPIU_REAL, MPI_SUM, PETSC_COMM_WORLD);
      EXPECT_NEAR(at[0], 1.0, 1e-14) << label << " at grid point " << p[0] << " " << p[1] << " " << p[2];
      EXPECT_EQ(at[1], 0.0) << label << " at grid point " << p[0] << " " << p[1] << " " << p[2];
      EXPECT_EQ(at[2], 1.0) << label << " at grid point " << p[0] << " " << p[1] << " " << p[2];
    }
    for (auto x : {std::array<PetscReal, 3>{0.4613, 0.5271, 0.4838}, {0.3377, 0.4102, 0.5313}}) {
      PointStencil st;
      PETSC_ASSERT_OK(point_stencil(grid, x[0], x[1], x[2], &st, how));
      PetscReal sum[3] = {0, 0, (PetscReal)st.n}; // weights, interpolated f, points
      for (PetscInt m = 0; m < st.n; ++m) {
        PetscInt ijk[3];
        owned_ijk(grid, st.local[m], ijk);
        sum[0] += st.weight[m];
        sum[1] += st.weight[m] * f(grid.x(ijk[0]), grid.y(ijk[1]), grid.z(ijk[2]));
      }
      MPI_Allreduce(MPI_IN_PLACE, sum, 3, MPIU_REAL, MPI_SUM, PETSC_COMM_WORLD);
      const PetscReal error = sum[1] - f(x[0], x[1], x[2]);
      PetscPrintf(PETSC_COMM_WORLD, "  [3D %s] (%g, %g, %g): %d points, weights sum to 1 %+.1e, f error %.1e\n", label,
                  (double)x[0], (double)x[1], (double)x[2], (int)sum[2], (double)(sum[0] - 1), (double)error);
      if (how == Interpolation::Linear) {
        EXPECT_EQ(sum[2], 8.0);
        EXPECT_NEAR(sum[0], 1.0, 1e-14);
        EXPECT_NEAR(sum[1], f(x[0], x[1], x[2]), 1e-14);
      } else {
        EXPECT_EQ(sum[2], 512.0);
        EXPECT_NEAR(sum[0], 1.0, 1e-3);
      }
    }
  }
}

// A stand-in for a 3D model that takes point sources (u, v per point; the source forces v as the wave
// does, through the PointSource the survey hands it): enough for a Survey on a 3D grid without the 3D
// wave. `dim` 2 makes it a 2D one (a 2D survey that must refuse 3D data).
class SourceProbe3D final : public Model {
public:
  explicit SourceProbe3D(PetscInt dim = 3) : dim_(dim) {}
  const char *name() const override { return "source_probe"; }
  PetscInt dof() const override { return 2; }
  const char *component_name(PetscInt c) const override { return c ? "v" : "u"; }
  PetscInt stencil_width(MPI_Comm) const override { return 4; }
  PetscInt dim() const override { return dim_; }
  PetscErrorCode setup(const Grid &, DM, Parameters &) override { return 0; }
  PetscErrorCode create_jacobian(Mat *J) override {
    *J = nullptr;
    return 0;
  }
  PetscErrorCode create_jacobian_p(Mat *Jp) override {
    *Jp = nullptr;
    return 0;
  }
  PetscErrorCode set_parameters(Vec) override { return 0; }
  // G = the source's forcing density in v at its points, 0 elsewhere.
  PetscErrorCode rhs(PetscReal t, Vec, Vec G) override {
    PetscFunctionBeginUser;
    PetscCall(VecSet(G, 0.0));
    if (!source_) PetscFunctionReturn(0);
    Array g(G);
    PetscCall(g.error());
    for (PetscInt k = 0; k < source_->stencil.n; ++k) g[source_->stencil.local[k] * 2 + 1] += source_->density(k, t);
    PetscFunctionReturn(0);
  }
  PetscErrorCode rhs_jacobian(PetscReal, Vec, Mat) override { return 0; }
  PetscErrorCode rhs_jacobian_p(PetscReal, Vec, Mat) override { return 0; }
  PetscErrorCode spectrum(Spectrum *) override { return 0; }
  bool accepts_point_source() const override { return true; }
  PetscErrorCode set_point_source(const PointSource *s) override {
    source_ = s;
    return 0;
  }
  PetscErrorCode initial_condition(Vec, Vec U0) override { return VecSet(U0, 0.0); }
  PetscErrorCode initial_condition_transpose(Vec, Vec, Vec) override { return 0; }

private:
  PetscInt dim_;
  const PointSource *source_ = nullptr;
};

// A Survey on a 3D grid (or `dim` below 3) with the probe model, from the options in force.
struct Survey3D {
  Grid grid;
  SourceProbe3D model;
  OwnedDM dm;
  Survey survey;
  explicit Survey3D(PetscInt dim = 3) : model(dim) {}
  PetscErrorCode setup(MPI_Comm comm) {
    PetscFunctionBeginUser;
    if (model.dim() == 3) PetscCall(grid3d(comm, grid));
    else {
      GridOptions go;
      go.dim = model.dim(), go.n = 17, go.ny = 15;
      PetscCall(Grid::create(comm, 4, go, grid));
    }
    PetscCall(grid.create_dm(model.dof(), dm.out()));
    PetscCall(survey.setup(grid, model, dm, 0, model.dof()));
    PetscFunctionReturn(0);
  }
};

// As ReceiverMisfit2D.InjectionIsSamplingTransposed in 3D: the source's forcing of v at a time t equals
// w(t) / (h hy hz) times R^T e_r, R's row of a receiver at the source's position, at every point, on 8
// (linear) or 512 (sinc) points; and <R u, e_r> = <u, R^T e_r> for a random u. On any number of ranks.
TEST(ReceiverMisfit3D, InjectionIsSamplingTransposed) {
  for (const char *how : {"sinc", "linear"}) {
    ScopedOptions o{{"-survey_sources_x", "0.4613"},   {"-survey_sources_y", "0.5271"},   {"-survey_sources_z", "0.4838"},
                    {"-survey_receivers_x", "0.4613"}, {"-survey_receivers_y", "0.5271"}, {"-survey_receivers_z", "0.4838"},
                    {"-survey_ricker_f0", "5"},        {"-survey_interpolation", how}};
    Survey3D s;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    EXPECT_EQ(s.survey.shots(), 1);
    EXPECT_EQ(s.survey.receivers(), 1);
    OwnedVec U, G, q, ur, e;
    PETSC_ASSERT_OK(DMCreateGlobalVector(s.dm, U.out()));
    PETSC_ASSERT_OK(VecDuplicate(U, G.out()));
    PETSC_ASSERT_OK(VecDuplicate(U, q.out()));
    PETSC_ASSERT_OK(flexipde_test::fill_random(U, -1.0, 1.0, 91));
    const PetscReal t = 0.21;
    PETSC_ASSERT_OK(s.model.rhs(t, U, G)); // the injection
    Mat R = s.survey.receiver_matrix();
    PETSC_ASSERT_OK(MatCreateVecs(R, nullptr, e.out()));
    PETSC_ASSERT_OK(VecDuplicate(e, ur.out()));
    PETSC_ASSERT_OK(VecSet(e, 1.0));
    PETSC_ASSERT_OK(MatMultTranspose(R, e, q));
    Ricker w;
    w.f0 = 5, w.t0 = 1.2 / 5;
    const PetscReal vol = s.grid.h() * s.grid.hy() * s.grid.hz(), scale = w(t) / vol;
    EXPECT_EQ(s.grid.cell_volume(), vol);
    PetscReal diff = 0, norm = 0, nonzero = 0;
    {
      ConstArray a(q), b(G);
      PETSC_ASSERT_OK(a.error());
      PETSC_ASSERT_OK(b.error());
      for (PetscInt k = 0; k < s.grid.local_points(); ++k) {
        diff = std::max(diff, std::fabs(scale * PetscRealPart(a[2 * k]) - PetscRealPart(b[2 * k + 1])));
        norm = std::max(norm, std::fabs(PetscRealPart(b[2 * k + 1])));
        nonzero += PetscRealPart(a[2 * k]) != 0.0;
        diff = std::max(diff, std::fabs(PetscRealPart(a[2 * k + 1]))); // R samples u alone
      }
    }
    MPI_Allreduce(MPI_IN_PLACE, &diff, 1, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &norm, 1, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &nonzero, 1, MPIU_REAL, MPI_SUM, PETSC_COMM_WORLD);
    PETSC_ASSERT_OK(MatMult(R, U, ur));
    PetscReal Ru, uq;
    PETSC_ASSERT_OK(VecDot(ur, e, &Ru));
    PETSC_ASSERT_OK(VecDot(U, q, &uq));
    PetscPrintf(PETSC_COMM_WORLD, "  [3D %s] %d points, injection - w/V R^T e: %.1e of %.1e; <Ru, e> %.15e, <u, R^T e> %.15e\n",
                how, (int)nonzero, (double)diff, (double)norm, (double)Ru, (double)uq);
    EXPECT_GT(norm, 0.0);
    EXPECT_LE(diff, 1e-12 * norm);
    EXPECT_EQ(nonzero, std::string(how) == "sinc" ? 512 : 8);
    EXPECT_LE(std::fabs(Ru - uq), 1e-13 * std::max(std::fabs(Ru), 1.0));
  }
}

// R u for a random u (every rank gets rank 0's values).
PetscErrorCode sample(Survey3D &s, std::vector<PetscReal> &out) {
  OwnedVec U, y;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(s.dm, U.out()));
  PetscCall(flexipde_test::fill_random(U, -1.0, 1.0, 17));
  PetscCall(MatCreateVecs(s.survey.receiver_matrix(), nullptr, y.out()));
  PetscCall(MatMult(s.survey.receiver_matrix(), U, y));
  PetscCall(flexipde_test::gather_all(y, out));
  PetscFunctionReturn(0);
}

// 3D positions: receivers from an "x y z" file sample as the same receivers from the lists (a single
// -survey_receivers_z for all of them); a 3D survey without z, or with a point outside the box in z,
// is refused.
TEST(ReceiverMisfit3D, Positions) {
  char name[256];
  std::snprintf(name, sizeof name, "/tmp/flexipde_test_receivers3d_%d.txt", (int)getpid());
  MPI_Bcast(name, sizeof name, MPI_CHAR, 0, PETSC_COMM_WORLD);
  if (flexipde_test::is_rank0()) {
    FILE *f = std::fopen(name, "w");
    ASSERT_NE(f, nullptr);
    std::fprintf(f, "# x y z\n0.1 0.45 0.7\n0.45 0.2 0.7\n\n0.9 0.8 0.7\n");
    std::fclose(f);
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  std::vector<PetscReal> y[2];
  for (int k = 0; k < 2; ++k) {
    ScopedOptions o{{"-survey_interpolation", "sinc"}};
    if (k == 0) {
      o.set("-survey_receivers_x", "0.1,0.45,0.9");
      o.set("-survey_receivers_y", "0.45,0.2,0.8");
      o.set("-survey_receivers_z", "0.7");
    } else o.set("-survey_receivers_file", name);
    Survey3D s;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    EXPECT_EQ(s.survey.receivers(), 3);
    PETSC_ASSERT_OK(sample(s, y[k]));
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  if (flexipde_test::is_rank0()) std::remove(name);
  ASSERT_EQ(y[0].size(), 3u);
  EXPECT_EQ(y[0], y[1]);
  EXPECT_NE(y[0][0], 0.0);

  const std::vector<std::pair<std::vector<std::pair<const char *, const char *>>, PetscErrorCode>> bad = {
      {{{"-survey_receivers_x", "0.5"}, {"-survey_receivers_y", "0.5"}}, PETSC_ERR_ARG_WRONG}, // no z
      {{{"-survey_receivers_x", "0.5"}, {"-survey_receivers_y", "0.5"}, {"-survey_receivers_z", "1.2"}},
       PETSC_ERR_ARG_OUTOFRANGE},
      {{{"-survey_receivers_x", "0.5"}, {"-survey_receivers_y", "0.5"}, {"-survey_receivers_z", "0.5"},
        {"-survey_sources_x", "0.5"}, {"-survey_sources_y", "0.5"}, {"-survey_sources_z", "-0.1"}},
       PETSC_ERR_ARG_OUTOFRANGE},
      {{{"-survey_receivers_x", "0.5,0.6"}, {"-survey_receivers_y", "0.5"}, {"-survey_receivers_z", "0.5,0.6,0.7"}},
       PETSC_ERR_ARG_SIZ}};
  for (const auto &b : bad) {
    ScopedOptions o;
    for (const auto &kv : b.first) o.set(kv.first, kv.second);
    Survey3D s;
    PetscErrorCode ierr;
    {
      flexipde_test::QuietErrors q;
      ierr = s.setup(PETSC_COMM_WORLD);
    }
    EXPECT_EQ(ierr, b.second) << "options starting " << b.first[0].second;
  }
}

// Records traces of u = a random U (one per shot, the same for each of its samples) as the Scene does
// in time: samples 0, 1 and 2 at t = 0, 0.1, 0.2 of every shot; end_recording writes -survey_data_write.
PetscErrorCode record(Survey3D &s) {
  OwnedVec U;
  PetscReal r;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(s.dm, U.out()));
  PetscCall(s.survey.begin_recording(0.1, 0.2));
  for (PetscInt shot = 0; shot < s.survey.shots(); ++shot) {
    PetscCall(flexipde_test::fill_random(U, -1.0, 1.0, 5 + shot));
    PetscCall(s.survey.select_shot(shot));
    PetscCall(s.survey.record_initial(U));
    PetscCall(s.survey.integrand(0.1, U, &r));
    PetscCall(s.survey.terminal(U, &r, nullptr));
  }
  PetscCall(s.survey.end_recording());
  PetscFunctionReturn(0);
}

// The 3D data file: written with receivers_z and sources_z, read back to the same traces; refused by a
// survey whose receivers differ in z only, and by a 2D survey (the file holds 3D data).
TEST(ReceiverMisfit3D, DataFileRoundTrip) {
  char file[256];
  std::snprintf(file, sizeof file, "/tmp/flexipde_test_survey3d_%d.h5", (int)getpid());
  MPI_Bcast(file, sizeof file, MPI_CHAR, 0, PETSC_COMM_WORLD);
  auto options = [](ScopedOptions &o, const char *rz) {
    o.set("-survey_sources_x", "0.3,0.7");
    o.set("-survey_sources_y", "0.5");
    o.set("-survey_sources_z", "0.25,0.75");
    o.set("-survey_receivers_spread", "0.1,0.9,5");
    o.set("-survey_receivers_y", "0.4");
    o.set("-survey_receivers_z", rz);
  };
  std::vector<PetscReal> written;
  {
    ScopedOptions o;
    options(o, "0.6");
    o.set("-survey_data_write", file);
    Survey3D s;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    EXPECT_EQ(s.survey.shots(), 2);
    PETSC_ASSERT_OK(record(s));
    written = s.survey.traces(); // on rank 0
  }
  {
    ScopedOptions o;
    options(o, "0.6");
    o.set("-survey_data_file", file);
    Survey3D s;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    PetscBool read;
    PETSC_ASSERT_OK(s.survey.read_data(0.2, &read));
    EXPECT_TRUE(read);
    EXPECT_EQ(s.survey.samples(), 3);
    if (flexipde_test::is_rank0()) {
      EXPECT_EQ(written.size(), 2u * 5u * 3u);
      EXPECT_EQ(s.survey.traces(), written);
    }
  }
  {
    ScopedOptions o;
    options(o, "0.61"); // z differs
    o.set("-survey_data_file", file);
    Survey3D s;
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    PetscBool read;
    flexipde_test::QuietErrors q;
    EXPECT_EQ(s.survey.read_data(0.2, &read), PETSC_ERR_FILE_UNEXPECTED);
  }
  {
    ScopedOptions o{{"-survey_sources_x", "0.3,0.7"}, {"-survey_sources_y", "0.5"}, {"-survey_receivers_spread", "0.1,0.9,5"},
                    {"-survey_receivers_y", "0.4"}, {"-survey_data_file", file}};
    Survey3D s(2);
    PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
    EXPECT_EQ(s.grid.dim(), 2);
    PetscBool read;
    flexipde_test::QuietErrors q;
    EXPECT_EQ(s.survey.read_data(0.2, &read), PETSC_ERR_FILE_UNEXPECTED);
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  if (flexipde_test::is_rank0()) std::remove(file);
}

// ---- Adam ----

// f(x) = 0.5 sum_i a_i (x_i - b_i)^2, a_i = i + 1, b_i = 0.1 i.
PetscErrorCode quadratic(Tao, Vec x, PetscReal *f, Vec g, void *) {
  PetscInt lo, hi;
  PetscReal local = 0;
  PetscFunctionBeginUser;
  PetscCall(VecGetOwnershipRange(x, &lo, &hi));
  {
    ConstArray X(x);
    Array G(g);
    PetscCall(X.error());
    PetscCall(G.error());
    for (PetscInt i = lo; i < hi; ++i) {
      const PetscReal a = i + 1, r = PetscRealPart(X[i - lo]) - 0.1 * i;
      local += 0.5 * a * r * r;
      G[i - lo] = a * r;
    }
  }
  PetscCallMPI(MPI_Allreduce(&local, f, 1, MPIU_REAL, MPI_SUM, PETSC_COMM_WORLD));
  PetscFunctionReturn(0);
}

TEST(TaoAdam, HandComputedFirstSteps) {
  ScopedOptions o{{"-tao_adam_lr", "0.05"}, {"-tao_adam_epsilon", "1e-3"}, {"-tao_max_it", "2"}};
  const PetscInt n = 6;
  OwnedTao tao;
  OwnedVec x;
  PETSC_ASSERT_OK(register_tao_adam());
  PETSC_ASSERT_OK(VecCreateMPI(PETSC_COMM_WORLD, PETSC_DECIDE, n, x.out()));
  PETSC_ASSERT_OK(VecSet(x, 1.0));
  PETSC_ASSERT_OK(TaoCreate(PETSC_COMM_WORLD, tao.out()));
  PETSC_ASSERT_OK(TaoSetType(tao, "adam"));
  PETSC_ASSERT_OK(TaoSetObjectiveAndGradient(tao, nullptr, quadratic, nullptr));
  PETSC_ASSERT_OK(TaoSetSolution(tao, x));
  PETSC_ASSERT_OK(TaoSetFromOptions(tao));
  PETSC_ASSERT_OK(TaoSolve(tao));
  PetscInt its;
  PETSC_ASSERT_OK(TaoGetIterationNumber(tao, &its));
  EXPECT_EQ(its, 2);
  // By hand: t = 1: m = 0.1 g0, v = 0.001 g0^2, mhat = g0, vhat = g0^2,
  //   x1 = x0 - lr g0 / (|g0| + eps);
  // t = 2: m = 0.9 m + 0.1 g1, v = 0.999 v + 0.001 g1^2, mhat = m / (1 - 0.81), vhat = v / (1 - 0.998001),
  //   x2 = x1 - lr mhat / (sqrt(vhat) + eps).
  const PetscReal lr = 0.05, eps = 1e-3;
  std::vector<PetscReal> got;
  PETSC_ASSERT_OK(flexipde_test::gather_all(x, got));
  for (PetscInt i = 0; i < n; ++i) {
    const PetscReal a = i + 1, b = 0.1 * i;
    const PetscReal g0 = a * (1.0 - b), x1 = 1.0 - lr * g0 / (std::fabs(g0) + eps);
    const PetscReal g1 = a * (x1 - b);
    const PetscReal m = 0.9 * 0.1 * g0 + 0.1 * g1, v = 0.999 * 0.001 * g0 * g0 + 0.001 * g1 * g1;
    const PetscReal x2 = x1 - lr * (m / (1 - 0.81)) / (std::sqrt(v / (1 - 0.998001)) + eps);
    EXPECT_NEAR(got[i], x2, 1e-14) << "entry " << i;
  }
}

// With bounds Adam projects: a step that would cross the bound stops on it.
TEST(TaoAdam, ProjectsOntoBounds) {
  ScopedOptions o{{"-tao_adam_lr", "0.5"}, {"-tao_max_it", "1"}};
  const PetscInt n = 4;
  OwnedTao tao;
  OwnedVec x, lo, hi;
  PETSC_ASSERT_OK(register_tao_adam());
  PETSC_ASSERT_OK(VecCreateMPI(PETSC_COMM_WORLD, PETSC_DECIDE, n, x.out()));
  PETSC_ASSERT_OK(VecDuplicate(x, lo.out()));
  PETSC_ASSERT_OK(VecDuplicate(x, hi.out()));
  PETSC_ASSERT_OK(VecSet(x, 1.0));
  PETSC_ASSERT_OK(VecSet(lo, 0.8));
  PETSC_ASSERT_OK(VecSet(hi, 2.0));
  PETSC_ASSERT_OK(TaoCreate(PETSC_COMM_WORLD, tao.out()));
  PETSC_ASSERT_OK(TaoSetType(tao, "adam"));
  PETSC_ASSERT_OK(TaoSetObjectiveAndGradient(tao, nullptr, quadratic, nullptr));
  PETSC_ASSERT_OK(TaoSetVariableBounds(tao, lo, hi));
  PETSC_ASSERT_OK(TaoSetSolution(tao, x));
  PETSC_ASSERT_OK(TaoSetFromOptions(tao));
  PETSC_ASSERT_OK(TaoSolve(tao));
  PetscReal xmin;
  PETSC_ASSERT_OK(VecMin(x, nullptr, &xmin));
  EXPECT_NEAR(xmin, 0.8, 1e-15); // 1 - 0.5 would be 0.5, below the bound
}

} // namespace
