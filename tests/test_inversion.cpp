// Inversion (TAO with the adjoint gradient): recovery of a constant speed, a small field inversion
// with Tikhonov regularisation, and the regularisation term and its gradient against an
// independent evaluation on the gathered field; the restart snapshot every N iterations.
#include "flexipde/inversion.hpp"
#include "flexipde/io.hpp"
#include <cstdio>
#include <unistd.h>
#include "flexipde/scene.hpp"
#include "test_support.hpp"

using namespace flexipde;
using flexipde_test::ScopedOptions;

namespace {

using InversionProblem = flexipde_test::SceneProblem;

void print_history(const Inversion &inv) {
  for (auto &h : inv.history())
    PetscPrintf(PETSC_COMM_WORLD, "    it %2d  f %.6e  misfit %.6e  |g| %.3e  rmse %.3e\n", (int)h.iteration,
                (double)h.objective, (double)h.misfit, (double)h.gradient_norm, (double)h.rmse);
}

} // namespace

// 201 points, T = 0.3, dt = 1e-3: RK4 needs dt * 2 c / h <= 2.83, i.e. c <= 7 here, so the whole
// bound box [0.5, 2] is stable.
TEST(Inversion, RecoversConstantSpeed) {
  ScopedOptions opts{{"-da_grid_x", "201"},   {"-ts_max_time", "0.3"},  {"-ts_dt", "1e-3"},
                     {"-ts_type", "rk"},       {"-ts_rk_type", "4"},     {"-wave_c", "0.8"},
                     {"-true_wave_c", "1.0"},  {"-inv_lower", "0.5"},    {"-inv_upper", "2"},
                     {"-tao_type", "blmvm"},   {"-tao_gatol", "1e-12"},  {"-tao_grtol", "0"},
                     {"-tao_gttol", "0"},      {"-tao_max_it", "50"}};
  InversionProblem pb;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  Inversion inv;
  PETSC_ASSERT_OK(inv.setup(pb.scene, pb.p_true));
  PetscReal e0, e1, c;
  PETSC_ASSERT_OK(inv.rmse(pb.p, &e0));
  EXPECT_NEAR(e0, 0.2, 1e-12);
  PETSC_ASSERT_OK(inv.solve(pb.p));
  PETSC_ASSERT_OK(inv.rmse(pb.p, &e1));
  PETSC_ASSERT_OK(pb.scene.params.scalar(pb.p, 0, &c));
  TaoConvergedReason reason;
  PETSC_ASSERT_OK(TaoGetConvergedReason(inv.tao(), &reason));
  PetscPrintf(PETSC_COMM_WORLD, "  recovered c = %.12f (%s, %d evaluations)\n", (double)c, TaoConvergedReasons[reason],
              (int)inv.evaluations());
  print_history(inv);
  EXPECT_NEAR(c, 1.0, 1e-4);
  EXPECT_GT((int)reason, 0) << "TAO did not converge: " << TaoConvergedReasons[reason];
  EXPECT_LT(e1, 1e-4);
  const auto &h = inv.history();
  ASSERT_FALSE(h.empty());
  EXPECT_EQ(h.front().iteration, 0);
  EXPECT_NEAR(h.front().rmse, 0.2, 1e-12);
  EXPECT_LT(h.back().objective, 1e-6 * h.front().objective);
  EXPECT_LT(h.back().rmse, 1e-4);
  for (size_t k = 1; k < h.size(); ++k) {
    EXPECT_EQ(h[k].iteration, h[k - 1].iteration + 1);
    EXPECT_LE(h[k].objective, h[k - 1].objective) << "objective increased at iteration " << k;
  }
  // Without Tikhonov the objective is the misfit.
  for (auto &e : h) EXPECT_EQ(e.objective, e.misfit);
  EXPECT_GE(inv.evaluations(), (PetscInt)h.size());
}

// Bounds are honoured: with the upper bound below the true value the solution sits on the bound.
TEST(Inversion, RespectsBounds) {
  ScopedOptions opts{{"-da_grid_x", "101"}, {"-ts_max_time", "0.3"}, {"-ts_dt", "2e-3"}, {"-wave_c", "0.8"},
                     {"-true_wave_c", "1.0"}, {"-inv_lower", "0.5"},  {"-inv_upper", "0.9"}, {"-tao_max_it", "30"}};
  InversionProblem pb;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  Inversion inv;
  PETSC_ASSERT_OK(inv.setup(pb.scene, nullptr));
  PETSC_ASSERT_OK(inv.solve(pb.p));
  PetscReal c, e;
  PETSC_ASSERT_OK(pb.scene.params.scalar(pb.p, 0, &c));
  EXPECT_LE(c, 0.9 + 1e-14);
  EXPECT_NEAR(c, 0.9, 1e-6);
  PETSC_ASSERT_OK(inv.rmse(pb.p, &e));
  EXPECT_EQ(e, -1) << "rmse without true parameters is reported as -1";
  ASSERT_FALSE(inv.history().empty());
  EXPECT_EQ(inv.history().back().rmse, -1);
}

// A small field inversion with Tikhonov regularisation reduces the parameter error substantially.
TEST(Inversion, FieldWithTikhonov) {
  ScopedOptions opts{{"-da_grid_x", "81"},
                     {"-ts_max_time", "0.6"},
                     {"-ts_dt", "2e-3"},
                     {"-wave_c_field", "1"},
                     {"-wave_c", "0.9"},
                     {"-true_wave_c_profile", "linear"},
                     {"-true_wave_c_left", "0.9"},
                     {"-true_wave_c_right", "1.1"},
                     {"-inv_lower", "0.5"},
                     {"-inv_upper", "2"},
                     {"-inv_tikhonov", "1e-4"},
                     {"-tao_max_it", "40"}};
  InversionProblem pb;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  Inversion inv;
  PETSC_ASSERT_OK(inv.setup(pb.scene, pb.p_true));
  PetscReal e0, e1;
  PETSC_ASSERT_OK(inv.rmse(pb.p, &e0));
  PETSC_ASSERT_OK(inv.solve(pb.p));
  PETSC_ASSERT_OK(inv.rmse(pb.p, &e1));
  PetscPrintf(PETSC_COMM_WORLD, "  field inversion: rmse %.4e -> %.4e in %d iterations\n", (double)e0, (double)e1,
              (int)inv.history().size() - 1);
  EXPECT_NEAR(e0, std::sqrt(0.04 / 3.0), 5e-3); // rms of 0.2 s on [0,1]
  EXPECT_LT(e1, 0.2 * e0);
  const auto &h = inv.history();
  ASSERT_GE(h.size(), 2u);
  EXPECT_LT(h.back().objective, 1e-3 * h.front().objective);
  EXPECT_LT(h.back().rmse, h.front().rmse);
  for (auto &e : h) EXPECT_GE(e.objective, e.misfit); // R >= 0
  PetscReal pmin, pmax;
  PETSC_ASSERT_OK(VecMin(pb.p, nullptr, &pmin));
  PETSC_ASSERT_OK(VecMax(pb.p, nullptr, &pmax));
  EXPECT_GE(pmin, 0.5);
  EXPECT_LE(pmax, 2.0);
}

// evaluate() = J + R with R = 0.5 alpha sum (p_{i+1} - p_i)^2 / h over neighbouring pairs
// (wrapping on periodic grids); R and dR/dp checked entrywise against the gathered field.
class Tikhonov : public ::testing::TestWithParam<bool> {};

TEST_P(Tikhonov, MatchesIndependentEvaluation) {
  const bool periodic = GetParam();
  const PetscReal alpha = 0.3;
  ScopedOptions opts{{"-da_grid_x", "41"},      {"-ts_max_time", "0.05"},       {"-ts_dt", "2e-3"},
                     {"-wave_c_field", "1"},     {"-grid_periodic", periodic ? "1" : "0"},
                     {"-inv_tikhonov", "0.3"}};
  InversionProblem pb;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(flexipde_test::fill_random(pb.p, 0.8, 1.2, 99));
  Inversion inv;
  PETSC_ASSERT_OK(inv.setup(pb.scene, nullptr));
  OwnedVec g, gJ;
  PETSC_ASSERT_OK(VecDuplicate(pb.p, g.out()));
  PETSC_ASSERT_OK(VecDuplicate(pb.p, gJ.out()));
  PetscReal f, J;
  PETSC_ASSERT_OK(inv.evaluate(pb.p, &f, g));
  PETSC_ASSERT_OK(pb.scene.sim.gradient(pb.p, &J, gJ, nullptr));
  PETSC_ASSERT_OK(VecAXPY(g, -1.0, gJ)); // g = dR/dp
  std::vector<PetscReal> pa, ga;
  PETSC_ASSERT_OK(flexipde_test::gather_all(pb.p, pa));
  PETSC_ASSERT_OK(flexipde_test::gather_all(g, ga));
  const PetscInt n = (PetscInt)pa.size();
  const PetscReal h = pb.scene.grid.h();
  PetscReal R = 0;
  std::vector<PetscReal> gR(n, 0.0);
  const PetscInt pairs = periodic ? n : n - 1;
  for (PetscInt i = 0; i < pairs; ++i) {
    const PetscInt j = (i + 1) % n;
    const PetscReal d = pa[j] - pa[i];
    R += 0.5 * alpha * d * d / h;
    gR[i] -= alpha * d / h;
    gR[j] += alpha * d / h;
  }
  PetscReal err = 0, scale = 0;
  for (PetscInt i = 0; i < n; ++i) {
    err = std::max(err, std::fabs(ga[i] - gR[i]));
    scale = std::max(scale, std::fabs(gR[i]));
  }
  EXPECT_GT(R, 0.0);
  EXPECT_LE(flexipde_test::rel_diff(f - J, R), 1e-10) << "R = " << f - J << ", expected " << R;
  EXPECT_LE(err, 1e-10 * scale) << "dR/dp differs from the independent evaluation";
}

INSTANTIATE_TEST_SUITE_P(Inversion, Tikhonov, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool> &i) { return i.param ? "periodic" : "dirichlet"; });

// -inv_checkpoint_every N: the restart snapshot is rewritten every N iterations only (the one of 4
// iterations with N = 3 holds iterations 0..3 and the iterate of iteration 3).
TEST(Inversion, CheckpointEveryN) {
  ScopedOptions opts{{"-da_grid_x", "101"}, {"-ts_max_time", "0.2"}, {"-ts_dt", "2e-3"}, {"-wave_c", "0.8"},
                     {"-true_wave_c", "1.0"}, {"-tao_type", "lmvm"}, {"-tao_gatol", "0"}, {"-tao_grtol", "0"},
                     {"-tao_max_it", "4"}, {"-inv_checkpoint_every", "3"}};
  InversionProblem pb;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  PetscMPIInt rank;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  char file[PETSC_MAX_PATH_LEN] = "";
  if (rank == 0) snprintf(file, sizeof(file), "/tmp/flexipde_checkpoint_every_%d.h5", (int)getpid());
  MPI_Bcast(file, sizeof(file), MPI_CHAR, 0, PETSC_COMM_WORLD);
  Inversion inv;
  PETSC_ASSERT_OK(inv.setup(pb.scene, pb.p_true));
  inv.set_checkpoint_file(file);
  PETSC_ASSERT_OK(inv.solve(pb.p));
  ASSERT_EQ(inv.history().size(), 5u);
  H5Reader r;
  std::vector<PetscReal> it, last;
  OwnedVec p3;
  PETSC_ASSERT_OK(VecDuplicate(pb.p, p3.out()));
  PETSC_ASSERT_OK(r.open(PETSC_COMM_WORLD, file));
  PETSC_ASSERT_OK(r.read_series("/history", "iteration", it));
  PETSC_ASSERT_OK(r.read_series("/restart", "iteration", last));
  PETSC_ASSERT_OK(r.read_vec("/restart", "p", p3));
  PETSC_ASSERT_OK(r.close());
  if (rank == 0) std::remove(file);
  EXPECT_EQ(it, (std::vector<PetscReal>{0, 1, 2, 3}));
  ASSERT_EQ(last.size(), 1u);
  EXPECT_EQ(last[0], 3);
  EXPECT_GT(flexipde_test::rel_diff(p3, pb.p), 0.0) << "the snapshot holds iteration 3's iterate, not the last one";
}
