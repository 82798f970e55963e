// The wave models (the pointwise layer's AcousticWave) against their assembled operators, on 1 and 2 ranks:
//   * rhs(U) equals J U with J the assembled dG/dU;
//   * the leapfrog's adjoint kick (Model::second_order_adjoint, on lambda_q and lambda_p apart) equals the
//     assembled transposes: lambda_q += w (J^T [0; lambda_p])_q and mu += w (dG/dc)^T [0; lambda_p];
//     given a drift s it first applies lambda_p += s lambda_q, bitwise as that drift in a pass of its own;
//   * a whole leapfrog gradient with the kick equals the one through the Jacobians (-adjoint_petsc_step),
//     for a scalar speed (whose gradient is a sum over ranks) and a field, and is bitwise the same with
//     an adjoint monitor (lambda formed for it after every step);
//   * the RK adjoint stage (Model::stage_adjoint) equals the assembled transposes;
//   * the matrix-free dG/dU (create_jacobian_matrix_free) applies J and J^T like the assembled one,
//     and an RK4 gradient (the stage products) equals PETSc's RK adjoint through it (-adjoint_petsc_step).
// Cases: 1D fd2/fd4, Dirichlet/periodic/zero outside the grid (-wave_boundary zero_outside, two-level
// start); 2D Dirichlet/periodic, and with a sponge (the damping is in G_p's p column, which the kick
// does not transpose); 2D at order 8 and 3D, Dirichlet, on blocks large enough to have rows beyond
// the edge strips.
#include "flexipde/scene.hpp"
#include "test_support.hpp"
#include <limits>
#include <string>
#include <vector>

using namespace flexipde;
using flexipde_test::dot;
using flexipde_test::fill_random;
using flexipde_test::norm;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;
using flexipde_test::expect_same_gradient;

namespace {

struct MFCase {
  const char *name;
  std::vector<std::pair<const char *, const char *>> opts;
};

std::vector<MFCase> cases() {
  return {
      {"wave_fd2_dirichlet_field", {{"-da_grid_x", "61"}, {"-wave_c_field", "1"}}},
      {"wave_fd4_dirichlet_field", {{"-da_grid_x", "61"}, {"-wave_c_field", "1"}, {"-fd_order", "4"}}},
      {"wave_fd4_periodic_scalar", {{"-da_grid_x", "61"}, {"-fd_order", "4"}, {"-grid_periodic", "1"}, {"-wave_ic", "rest"}}},
      {"wave_fd2_periodic_field", {{"-da_grid_x", "61"}, {"-wave_c_field", "1"}, {"-grid_periodic", "1"}, {"-wave_ic", "rest"}}},
      // all points updated, zeros outside the grid (the end points have equations and columns)
      {"wave_fd2_zero_outside_field",
       {{"-da_grid_x", "61"}, {"-wave_c_field", "1"}, {"-wave_boundary", "zero_outside"}, {"-wave_ic", "two_level"}}},
      {"wave_fd4_zero_outside_scalar",
       {{"-da_grid_x", "61"}, {"-fd_order", "4"}, {"-wave_boundary", "zero_outside"}, {"-wave_ic", "two_level"}}},
      {"wave2d_dirichlet_field",
       {{"-model", "wave2d"}, {"-da_grid_x", "23"}, {"-da_grid_y", "19"}, {"-wave2d_c_field", "1"},
        {"-wave2d_sponge_width", "0"}, {"-wave2d_ic", "pulse"}, {"-wave2d_ic_width", "0.2"}}},
      {"wave2d_periodic_scalar",
       {{"-model", "wave2d"}, {"-da_grid_x", "23"}, {"-da_grid_y", "19"}, {"-grid_periodic", "1"},
        {"-grid_periodic_y", "1"}, {"-wave2d_sponge_width", "0"}, {"-wave2d_ic", "pulse"}, {"-wave2d_ic_width", "0.2"}}},
      {"wave2d_sponge_field",
       {{"-model", "wave2d"}, {"-da_grid_x", "23"}, {"-da_grid_y", "19"}, {"-wave2d_c_field", "1"},
        {"-wave2d_sponge_width", "0.2"}, {"-wave2d_ic", "pulse"}, {"-wave2d_ic_width", "0.2"}}},
      // blocks with rows beyond the edge strips on 1 and 2 ranks (the kick drifts them row by row ahead
      // of the gather), in 2D, in 3D and at order 8
      {"wave2d_tall_dirichlet_field",
       {{"-model", "wave2d"}, {"-da_grid_x", "23"}, {"-da_grid_y", "31"}, {"-wave2d_c_field", "1"},
        {"-wave2d_sponge_width", "0"}, {"-wave2d_ic", "pulse"}, {"-wave2d_ic_width", "0.2"}}},
      {"wave2d_order8_dirichlet_field",
       {{"-model", "wave2d"}, {"-fd_order", "8"}, {"-da_grid_x", "39"}, {"-da_grid_y", "41"}, {"-wave2d_c_field", "1"},
        {"-wave2d_sponge_width", "0"}, {"-wave2d_ic", "pulse"}, {"-wave2d_ic_width", "0.2"}}},
      {"wave3d_dirichlet_field",
       {{"-model", "wave3d"}, {"-da_grid_x", "17"}, {"-da_grid_y", "15"}, {"-da_grid_z", "29"}, {"-wave3d_c_field", "1"},
        {"-wave3d_sponge_width", "0"}, {"-wave3d_ic", "pulse"}, {"-wave3d_ic_width", "0.2"}}},
  };
}

class MatrixFree : public ::testing::TestWithParam<MFCase> {
protected:
  void SetUp() override {
    for (auto &o : GetParam().opts) opts_.set(o.first, o.second);
    opts_.set("-ts_max_time", "0.1");
    opts_.set("-ts_dt", "2e-3");
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
    PETSC_ASSERT_OK(fill_random(p, 0.8, 1.2, 21)); // a rough speed: every entry matters
    PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
    PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 22));
    PETSC_ASSERT_OK(scene.model->set_parameters(p));
    PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
    PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.0, U, J));
    PETSC_ASSERT_OK(scene.model->create_jacobian_p(Jp.out()));
  }
  ScopedOptions opts_;
  Scene scene;
  OwnedVec p, U;
  OwnedMat J, Jp;
};

std::string mf_name(const ::testing::TestParamInfo<MFCase> &i) { return i.param.name; }

} // namespace

TEST_P(MatrixFree, RhsEqualsAssembledOperator) {
  OwnedVec G, JU;
  PETSC_ASSERT_OK(VecDuplicate(U, G.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, JU.out()));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G));
  PETSC_ASSERT_OK(MatMult(J, U, JU));
  EXPECT_LT(rel_diff(G, JU), 1e-13);
}

// lambda's positions and velocities parts (the kick's split arrays: one component per point each)
static PetscErrorCode split_parts(const Scene &scene, Vec lambda, OwnedVec &q, OwnedVec &p) {
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(scene.grid.dm(), q.out()));
  PetscCall(DMCreateGlobalVector(scene.grid.dm(), p.out()));
  PetscCall(VecStrideGather(lambda, 0, q, INSERT_VALUES));
  PetscCall(VecStrideGather(lambda, 1, p, INSERT_VALUES));
  PetscFunctionReturn(0);
}

TEST_P(MatrixFree, FusedAdjointKickEqualsAssembledTransposes) {
  ASSERT_TRUE(scene.model->has_second_order_adjoint());
  const PetscReal w = 0.37;
  OwnedVec lam, lam_p, JTl, mu, mu_ref;
  PETSC_ASSERT_OK(VecDuplicate(U, lam.out()));
  PETSC_ASSERT_OK(fill_random(lam, -1.0, 1.0, 23));
  // [0; lambda_p]: the q rows zeroed
  PETSC_ASSERT_OK(VecDuplicate(lam, lam_p.out()));
  PETSC_ASSERT_OK(VecCopy(lam, lam_p));
  PETSC_ASSERT_OK(VecStrideScale(lam_p, 0, 0.0));
  PETSC_ASSERT_OK(VecDuplicate(U, JTl.out()));
  PETSC_ASSERT_OK(MatMultTranspose(J, lam_p, JTl));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U, Jp));
  PETSC_ASSERT_OK(scene.params.create_vec(mu_ref.out()));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, lam_p, mu_ref));
  PETSC_ASSERT_OK(VecScale(mu_ref, w));
  // expected lambda: q rows + w (J^T [0; lambda_p])_q, p rows unchanged
  OwnedVec expect;
  PETSC_ASSERT_OK(VecDuplicate(lam, expect.out()));
  PETSC_ASSERT_OK(VecCopy(JTl, expect));
  PETSC_ASSERT_OK(VecStrideScale(expect, 1, 0.0));
  PETSC_ASSERT_OK(VecAYPX(expect, w, lam));
  OwnedVec lq, lp, expect_q, expect_p;
  PETSC_ASSERT_OK(split_parts(scene, lam, lq, lp));
  PETSC_ASSERT_OK(split_parts(scene, expect, expect_q, expect_p));
  // the fused kick, on top of a mu that already holds something (it must add, not overwrite)
  PETSC_ASSERT_OK(scene.params.create_vec(mu.out()));
  PETSC_ASSERT_OK(fill_random(mu, -1.0, 1.0, 24));
  OwnedVec mu0;
  PETSC_ASSERT_OK(VecDuplicate(mu, mu0.out()));
  PETSC_ASSERT_OK(VecCopy(mu, mu0));
  PETSC_ASSERT_OK(scene.model->second_order_adjoint(0.0, U, lq, lp, w, mu, 0.0, nullptr));
  EXPECT_LT(rel_diff(lq, expect_q), 1e-13);
  EXPECT_EQ(rel_diff(lp, expect_p), 0.0);
  PETSC_ASSERT_OK(VecAXPY(mu, -1.0, mu0));
  EXPECT_LT(rel_diff(mu, mu_ref), 1e-12);
  EXPECT_GT(norm(mu_ref), 0.0);
}

// The kick with a drift (the leapfrog adjoint hands it each step's drift transpose lambda_p += s lambda_q)
// gives bitwise the numbers of that drift as a pass of its own followed by the kick without one, with U
// a whole state and the positions alone.
TEST_P(MatrixFree, FusedAdjointKickAppliesTheDrift) {
  const PetscReal w = 0.37, s = 0.29;
  OwnedVec q;
  PETSC_ASSERT_OK(DMCreateGlobalVector(scene.grid.dm(), q.out()));
  PETSC_ASSERT_OK(VecStrideGather(U, 0, q, INSERT_VALUES));
  for (Vec X : {(Vec)U, (Vec)q}) {
    OwnedVec lam, lq, lp, lp0, ref_q, ref_p, mu, mu_ref;
    PETSC_ASSERT_OK(VecDuplicate(U, lam.out()));
    PETSC_ASSERT_OK(fill_random(lam, -1.0, 1.0, 31));
    PETSC_ASSERT_OK(split_parts(scene, lam, lq, lp));
    PETSC_ASSERT_OK(split_parts(scene, lam, ref_q, ref_p));
    PETSC_ASSERT_OK(VecDuplicate(lp, lp0.out()));
    PETSC_ASSERT_OK(VecCopy(lp, lp0));
    PETSC_ASSERT_OK(scene.params.create_vec(mu.out()));
    PETSC_ASSERT_OK(fill_random(mu, -1.0, 1.0, 32));
    PETSC_ASSERT_OK(VecDuplicate(mu, mu_ref.out()));
    PETSC_ASSERT_OK(VecCopy(mu, mu_ref));
    PETSC_ASSERT_OK(VecAXPY(ref_p, s, ref_q)); // the reference: the drift in a pass of its own
    PETSC_ASSERT_OK(scene.model->second_order_adjoint(0.0, X, ref_q, ref_p, w, mu_ref, 0.0, nullptr));
    const PetscScalar *next; // some positions to prefetch (the hint must not change the numbers)
    PETSC_ASSERT_OK(VecGetArrayRead(q, &next));
    PETSC_ASSERT_OK(scene.model->second_order_adjoint(0.0, X, lq, lp, w, mu, s, next));
    PETSC_ASSERT_OK(VecRestoreArrayRead(q, &next));
    EXPECT_EQ(rel_diff(lq, ref_q), 0.0);
    EXPECT_EQ(rel_diff(lp, ref_p), 0.0);
    EXPECT_EQ(rel_diff(mu, mu_ref), 0.0);
    EXPECT_GT(rel_diff(lp, lp0), 0.1); // ... and both moved lambda_p: the drift was applied
  }
}

TEST_P(MatrixFree, LeapfrogGradientFusedEqualsJacobians) {
  expect_same_gradient(scene, p, {{"-ts_type", "leapfrog"}}, {{"-adjoint_petsc_step", "1"}}, 1e-12);
}

// With an adjoint monitor (which may read lambda) the kick's adjoint forms lambda after every step and
// goes on from its split arrays: bitwise the same gradient as without.
TEST_P(MatrixFree, LeapfrogGradientWithAdjointMonitor) {
  expect_same_gradient(scene, p, {{"-ts_type", "leapfrog"}}, {{"-ts_adjoint_monitor", "ascii:/dev/null"}},
                       std::numeric_limits<PetscReal>::min());
}

// The RK stage products (Model::stage_adjoint) against the assembled transposes, every entry (the edge
// rows and columns too): y = J^T x, and mu (on top of what it holds) += (dG/dc)^T x at the stage U; with
// and without the sponge, on blocks whose perimeters lie on walls and between ranks.
TEST_P(MatrixFree, StageAdjointEqualsAssembledTransposes) {
  ASSERT_TRUE(scene.model->has_stage_adjoint());
  OwnedVec x, y, y_ref, mu, mu_ref, G;
  PETSC_ASSERT_OK(VecDuplicate(U, x.out()));
  PETSC_ASSERT_OK(fill_random(x, -1.0, 1.0, 31));
  PETSC_ASSERT_OK(VecDuplicate(U, y.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, y_ref.out()));
  PETSC_ASSERT_OK(MatMultTranspose(J, x, y_ref));
  PETSC_ASSERT_OK(VecDuplicate(U, G.out()));
  PETSC_ASSERT_OK(scene.model->rhs(0.0, U, G)); // (dG/dc's shell reads L u of the last evaluation)
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.0, U, Jp));
  PETSC_ASSERT_OK(scene.params.create_vec(mu_ref.out()));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, x, mu_ref));
  PETSC_ASSERT_OK(scene.params.create_vec(mu.out()));
  PETSC_ASSERT_OK(fill_random(mu, -1.0, 1.0, 32));
  PETSC_ASSERT_OK(VecAXPY(mu_ref, 1.0, mu));
  PETSC_ASSERT_OK(scene.model->stage_adjoint(0.0, U, nullptr, x, y, mu));
  EXPECT_LT(rel_diff(y, y_ref), 1e-13);
  EXPECT_LT(rel_diff(mu, mu_ref), 1e-13);
}

TEST_P(MatrixFree, MatrixFreeJacobianEqualsAssembled) {
  OwnedMat Jmf;
  PETSC_ASSERT_OK(scene.model->create_jacobian_matrix_free(Jmf.out()));
  ASSERT_TRUE((bool)Jmf);
  OwnedVec x, y, y_ref;
  PETSC_ASSERT_OK(VecDuplicate(U, x.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, y.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, y_ref.out()));
  PETSC_ASSERT_OK(fill_random(x, -1.0, 1.0, 25));
  PETSC_ASSERT_OK(MatMult(Jmf, x, y));
  PETSC_ASSERT_OK(MatMult(J, x, y_ref));
  EXPECT_LT(rel_diff(y, y_ref), 1e-13);
  PETSC_ASSERT_OK(MatMultTranspose(Jmf, x, y));
  PETSC_ASSERT_OK(MatMultTranspose(J, x, y_ref));
  EXPECT_LT(rel_diff(y, y_ref), 1e-13);
  EXPECT_GT(norm(y_ref), 0.0);
}

TEST_P(MatrixFree, RkGradientEqualsPetscStep) {
  expect_same_gradient(scene, p, {{"-ts_type", "rk"}, {"-ts_rk_type", "4"}}, {{"-adjoint_petsc_step", "1"}}, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Waves, MatrixFree, ::testing::ValuesIn(cases()), mf_name);
