// Flux-form models on rows long enough that the layer's sweeps over unchecked points form each face
// along x once per block of points (several blocks per row, the last one partial): G against its
// derivative point by point (central differences of G against the tangent sweep, which forms G's
// faces at each point), and the transposes of dG/dU and dG/dp (the face blocks' gather) against the
// tangent products (dot-product identities), for a field parameter, on 1 and 2 ranks.
#include "flexipde/scene.hpp"
#include "test_support.hpp"

using namespace flexipde;
using flexipde_test::dot;
using flexipde_test::fill_random;
using flexipde_test::norm;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

struct LongRowCase {
  const char *model, *parameter, *nx, *ny;
};
std::ostream &operator<<(std::ostream &os, const LongRowCase &c) { return os << c.model; }

class FluxFaces : public ::testing::TestWithParam<LongRowCase> {
protected:
  void SetUp() override {
    const LongRowCase c = GetParam();
    opts_.set("-model", c.model);
    opts_.set("-da_grid_x", c.nx);
    opts_.set("-da_grid_y", c.ny);
    opts_.set(std::string("-") + c.parameter + "_field", "1");
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
    OwnedVec r;
    PETSC_ASSERT_OK(VecDuplicate(p, r.out()));
    PETSC_ASSERT_OK(fill_random(r, 0.5, 1.5, 51));
    PETSC_ASSERT_OK(VecPointwiseMult(p, p, r));
    PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
    PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 52));
    PETSC_ASSERT_OK(scene.model->set_parameters(p));
  }
  // (G(U + eps x, p + eps dp) - G(U - eps x, p - eps dp)) / (2 eps)
  void central_difference(Vec x, Vec dp, Vec out) {
    const PetscReal eps = 1e-6;
    OwnedVec Us, ps, Gm;
    PETSC_ASSERT_OK(VecDuplicate(U, Us.out()));
    PETSC_ASSERT_OK(VecDuplicate(U, Gm.out()));
    PETSC_ASSERT_OK(VecDuplicate(p, ps.out()));
    for (PetscReal s : {eps, -eps}) {
      PETSC_ASSERT_OK(VecWAXPY(Us, x ? s : 0.0, x ? x : U, U));
      PETSC_ASSERT_OK(VecWAXPY(ps, dp ? s : 0.0, dp ? dp : p, p));
      PETSC_ASSERT_OK(scene.model->set_parameters(ps));
      PETSC_ASSERT_OK(scene.model->rhs(0.1, Us, s > 0 ? out : Gm.get()));
    }
    PETSC_ASSERT_OK(scene.model->set_parameters(p));
    PETSC_ASSERT_OK(VecAXPY(out, -1.0, Gm));
    PETSC_ASSERT_OK(VecScale(out, 1.0 / (2 * eps)));
  }
  ScopedOptions opts_;
  Scene scene;
  OwnedVec p, U;
};

TEST_P(FluxFaces, StateDerivativeAndTranspose) {
  OwnedMat J;
  OwnedVec x, y, Jx, JTy, JTy_assembled, fd;
  for (auto *v : {&x, &y, &Jx, &JTy, &JTy_assembled, &fd}) PETSC_ASSERT_OK(VecDuplicate(U, v->out()));
  PETSC_ASSERT_OK(fill_random(x, -1.0, 1.0, 53));
  PETSC_ASSERT_OK(fill_random(y, -1.0, 1.0, 54));
  PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.1, U, J));
  PETSC_ASSERT_OK(MatMult(J, x, Jx));
  central_difference(x, nullptr, fd);
  EXPECT_GT(norm(Jx), 0.0);
  EXPECT_LT(rel_diff(Jx, fd), 1e-6) << "assembled dG/dU against central differences of G";
  // the explicit RK adjoint's transpose (the gather) against the dot-product identity and the
  // assembled matrix's transpose
  PETSC_ASSERT_OK(scene.model->stage_adjoint(0.1, U, nullptr, y, JTy, nullptr));
  EXPECT_LT(rel_diff(dot(y, Jx), dot(JTy, x)), 1e-12);
  PETSC_ASSERT_OK(MatMultTranspose(J, y, JTy_assembled));
  EXPECT_LT(rel_diff(JTy, JTy_assembled), 1e-12);
}

TEST_P(FluxFaces, ParameterDerivativeAndTranspose) {
  OwnedMat Jp;
  OwnedVec dp, y, Jdp, JTy, fd;
  PETSC_ASSERT_OK(VecDuplicate(p, dp.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, JTy.out()));
  for (auto *v : {&y, &Jdp, &fd}) PETSC_ASSERT_OK(VecDuplicate(U, v->out()));
  PETSC_ASSERT_OK(fill_random(dp, -0.1, 0.1, 55));
  PETSC_ASSERT_OK(fill_random(y, -1.0, 1.0, 56));
  PETSC_ASSERT_OK(scene.model->create_jacobian_p(Jp.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.1, U, Jp));
  PETSC_ASSERT_OK(MatMult(Jp, dp, Jdp));
  central_difference(nullptr, dp, fd);
  EXPECT_GT(norm(Jdp), 0.0);
  EXPECT_LT(rel_diff(Jdp, fd), 1e-6) << "dG/dp against central differences of G";
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, JTy));
  EXPECT_LT(rel_diff(dot(y, Jdp), dot(JTy, dp)), 1e-12);
}

// 700 points: blocks of faces of 256 (G) and 128 (gather) and a partial one, on either rank.
INSTANTIATE_TEST_SUITE_P(LongRows, FluxFaces,
                         ::testing::Values(LongRowCase{"burgers", "burgers_nu", "700", "8"},
                                           LongRowCase{"flux_test", "flux_test_k", "700", "8"},
                                           LongRowCase{"flux_test4", "flux_test4_k", "700", "8"},
                                           LongRowCase{"flux_test_2d", "flux_test_2d_k", "300", "8"},
                                           LongRowCase{"advection", "advection_D", "700", "8"}),
                         [](const auto &info) { return std::string(info.param.model); });

} // namespace
