// Conformance of every registered model (model_registry(): today's and any added later), with its
// parameters as scalars and as fields (-<param>_field 1), on the ranks the suite runs on:
//   - dG/dU (assembled, and matrix-free when offered) against central differences of G, and the
//     matrix-free and assembled products against each other;
//   - dot-product identities <y, J x> = <J^T y, x> for dG/dU, dG/dp and dU0/dp;
//   - dG/dp and dU0/dp against central differences;
//   - the gradient of a misfit (data from 1.05 p) through each integrator with an adjoint that the
//     model admits (RK4, Crank-Nicolson, and the leapfrog for second-order models): a Taylor test
//     (second-order remainders falling ~4x as the step halves), a central difference, and the same
//     gradient through PETSc's own adjoint step (-adjoint_petsc_step 1);
//   - on several ranks, the same J and gradient as one rank alone (each rank solving the whole scene
//     on PETSC_COMM_SELF), to 1e-12.
#include "flexipde/scene.hpp"
#include "test_support.hpp"

using namespace flexipde;
using flexipde_test::dot;
using flexipde_test::fill_random;
using flexipde_test::norm;
using flexipde_test::rel_diff;
using flexipde_test::OptionList;
using flexipde_test::ScopedOptions;

namespace {

struct ConformanceCase {
  std::string model;
  bool fields;
  std::string variant; // a name for `options` (empty: none)
  OptionList options;  // set-up options of a variant whose equations differ (a layer with equations of its own)
  std::string name() const { return model + (variant.empty() ? "" : "_" + variant) + (fields ? "_fields" : "_scalars"); }
};
std::ostream &operator<<(std::ostream &os, const ConformanceCase &c) { return os << c.name(); }

std::vector<ConformanceCase> registered_cases() {
  std::vector<ConformanceCase> cases;
  for (auto &kv : model_registry())
    for (bool f : {false, true}) cases.push_back({kv.first, f, "", {}});
  // the wave's perfectly matched layer: 2D (six in 3D, four in 2D, two in 1D) equations more, and first
  // differences
  for (bool f : {false, true}) {
    cases.push_back({"wave3d", f, "pml", {{"-wave3d_pml_width", "0.25"}, {"-wave3d_pml_alpha", "5"}, {"-da_grid_x", "14"}, {"-da_grid_y", "12"}}});
    cases.push_back({"wave", f, "pml", {{"-wave_pml_width", "0.2"}, {"-wave_pml_alpha", "5"}}});
    cases.push_back({"wave2d", f, "pml", {{"-wave2d_pml_width", "0.2"}, {"-wave2d_pml_alpha", "5"}}});
    cases.push_back({"wave2d", f, "pml_order8", {{"-wave2d_pml_width", "0.3"}, {"-fd_order", "8"}, {"-da_grid_y", "20"}}});
  }
  return cases;
}

// A small scene of the model: few points, a short horizon, stable explicit steps.
void small_scene(ScopedOptions &o, const std::string &model, const OptionList &variant = {}) {
  o.set("-model", model);
  o.set("-da_grid_x", "24");
  o.set("-da_grid_y", "16");
  o.set("-da_grid_z", "12");
  o.set("-ts_dt", "1e-3");
  o.set("-ts_max_time", "0.02");
  // wave2d and wave3d start at rest by default (their waves come from point sources): a pulse gives them dynamics
  o.set("-wave2d_ic", "pulse");
  o.set("-wave3d_ic", "pulse");
  // advection declares its diffusivity only with diffusion on: on here, so that D is checked too
  o.set("-advection_diffusion", "1");
  for (auto &kv : variant) o.set(kv.first, kv.second);
}

// The names of the model's parameters (a throwaway set-up).
std::vector<std::string> parameter_names(const std::string &model, const OptionList &variant) {
  ScopedOptions o;
  small_scene(o, model, variant);
  Scene s;
  std::vector<std::string> names;
  if (s.setup(PETSC_COMM_WORLD)) return names;
  for (PetscInt k = 0; k < s.params.count(); ++k) names.push_back(s.params.info(k).name);
  return names;
}

class ModelConformance : public ::testing::TestWithParam<ConformanceCase> {
protected:
  void SetUp() override {
    const ConformanceCase c = GetParam();
    small_scene(opts_, c.model, c.options);
    names_ = parameter_names(c.model, c.options);
    if (c.fields)
      for (auto &n : names_) opts_.set("-" + n + "_field", "1");
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    any_kind_ = false;
    for (PetscInt k = 0; k < scene.params.count(); ++k)
      any_kind_ |= (scene.params.info(k).kind == ParamKind::Field) == c.fields;
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
    // every entry different, around the model's defaults, so that each one matters
    if (scene.params.global_size() > 0) {
      OwnedVec r;
      PETSC_ASSERT_OK(VecDuplicate(p, r.out()));
      PETSC_ASSERT_OK(fill_random(r, 0.9, 1.1, 41));
      PETSC_ASSERT_OK(VecPointwiseMult(p, p, r));
    }
    PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
    PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 42));
    PETSC_ASSERT_OK(scene.model->set_parameters(p));
  }
  // G at U + s x (x a state direction) or at parameters p + s dp.
  void rhs_at(Vec x, Vec dp, PetscReal s, Vec G) {
    OwnedVec Us, ps;
    PETSC_ASSERT_OK(VecDuplicate(U, Us.out()));
    PETSC_ASSERT_OK(VecCopy(U, Us));
    PETSC_ASSERT_OK(VecDuplicate(p, ps.out()));
    PETSC_ASSERT_OK(VecCopy(p, ps));
    if (x) PETSC_ASSERT_OK(VecAXPY(Us, s, x));
    if (dp) PETSC_ASSERT_OK(VecAXPY(ps, s, dp));
    PETSC_ASSERT_OK(scene.model->set_parameters(ps));
    PETSC_ASSERT_OK(scene.model->rhs(0.1, Us, G));
    PETSC_ASSERT_OK(scene.model->set_parameters(p));
  }
  // (G(+eps) - G(-eps)) / (2 eps) along x or dp.
  void central_difference(Vec x, Vec dp, Vec out) {
    const PetscReal eps = 1e-6;
    OwnedVec Gm;
    PETSC_ASSERT_OK(VecDuplicate(U, Gm.out()));
    rhs_at(x, dp, eps, out);
    rhs_at(x, dp, -eps, Gm);
    PETSC_ASSERT_OK(VecAXPY(out, -1.0, Gm));
    PETSC_ASSERT_OK(VecScale(out, 1.0 / (2 * eps)));
  }

  ScopedOptions opts_;
  std::vector<std::string> names_;
  bool any_kind_ = false;
  Scene scene;
  OwnedVec p, U;
};

} // namespace

TEST_P(ModelConformance, StateJacobianAndTranspose) {
  OwnedMat J, Jmf;
  OwnedVec x, y, Jx, JTy, fd, Jmfx;
  for (auto *v : {&x, &y, &Jx, &JTy, &fd, &Jmfx}) PETSC_ASSERT_OK(VecDuplicate(U, v->out()));
  PETSC_ASSERT_OK(fill_random(x, -1.0, 1.0, 43));
  PETSC_ASSERT_OK(fill_random(y, -1.0, 1.0, 44));
  PETSC_ASSERT_OK(scene.model->create_jacobian(J.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian(0.1, U, J));
  PETSC_ASSERT_OK(MatMult(J, x, Jx));
  central_difference(x, nullptr, fd);
  EXPECT_GT(norm(Jx), 0.0);
  EXPECT_LT(rel_diff(Jx, fd), 1e-6) << "assembled dG/dU against central differences of G";
  PETSC_ASSERT_OK(MatMultTranspose(J, y, JTy));
  EXPECT_LT(rel_diff(dot(y, Jx), dot(JTy, x)), 1e-12);
  PETSC_ASSERT_OK(scene.model->create_jacobian_matrix_free(Jmf.out()));
  if (Jmf) {
    PETSC_ASSERT_OK(MatMult(Jmf, x, Jmfx));
    EXPECT_LT(rel_diff(Jmfx, Jx), 1e-12) << "matrix-free against assembled dG/dU";
    PETSC_ASSERT_OK(MatMultTranspose(Jmf, y, fd));
    EXPECT_LT(rel_diff(fd, JTy), 1e-12) << "matrix-free against assembled (dG/dU)^T";
  }
}

TEST_P(ModelConformance, ParameterJacobianAndTranspose) {
  if (!any_kind_) GTEST_SKIP() << "no parameter of this kind";
  OwnedMat Jp;
  OwnedVec dp, y, Jdp, JTy, fd;
  PETSC_ASSERT_OK(VecDuplicate(p, dp.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, JTy.out()));
  for (auto *v : {&y, &Jdp, &fd}) PETSC_ASSERT_OK(VecDuplicate(U, v->out()));
  PETSC_ASSERT_OK(fill_random(dp, -0.1, 0.1, 45));
  PETSC_ASSERT_OK(fill_random(y, -1.0, 1.0, 46));
  PETSC_ASSERT_OK(scene.model->create_jacobian_p(Jp.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.1, U, Jp));
  PETSC_ASSERT_OK(MatMult(Jp, dp, Jdp));
  central_difference(nullptr, dp, fd);
  // (a parameter may enter U0 only: then G does not depend on it at all)
  if (norm(fd) > 1e-8) EXPECT_LT(rel_diff(Jdp, fd), 1e-6) << "dG/dp against central differences of G";
  else EXPECT_LT(norm(Jdp), 1e-8) << "dG/dp where G does not depend on p";
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, JTy));
  EXPECT_LT(rel_diff(dot(y, Jdp), dot(JTy, dp)), 1e-12);
}

TEST_P(ModelConformance, InitialConditionTranspose) {
  if (!any_kind_) GTEST_SKIP() << "no parameter of this kind";
  const PetscReal eps = 1e-6;
  OwnedVec dp, q, Up, Um, lam, g;
  PETSC_ASSERT_OK(VecDuplicate(p, dp.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, q.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, g.out()));
  for (auto *v : {&Up, &Um, &lam}) PETSC_ASSERT_OK(VecDuplicate(U, v->out()));
  PETSC_ASSERT_OK(fill_random(dp, -0.1, 0.1, 47));
  PETSC_ASSERT_OK(fill_random(lam, -1.0, 1.0, 48));
  PETSC_ASSERT_OK(VecWAXPY(q, eps, dp, p));
  PETSC_ASSERT_OK(scene.sim.initial_condition(q, Up));
  PETSC_ASSERT_OK(VecWAXPY(q, -eps, dp, p));
  PETSC_ASSERT_OK(scene.sim.initial_condition(q, Um));
  PETSC_ASSERT_OK(VecAXPY(Up, -1.0, Um));
  const PetscReal fd = dot(lam, Up) / (2 * eps);
  PETSC_ASSERT_OK(VecSet(g, 0.0));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(scene.sim.initial_condition(p, Um));
  PETSC_ASSERT_OK(scene.model->initial_condition_transpose(p, lam, g));
  const PetscReal adj = dot(g, dp);
  if (std::fabs(fd) < 1e-12 && std::fabs(adj) < 1e-12) return; // U0 independent of these parameters
  EXPECT_LT(rel_diff(adj, fd), 1e-6) << "(dU0/dp)^T against central differences of U0";
}

namespace {

// The integrators a gradient is checked with: RK4 and Crank-Nicolson always, the leapfrog for models
// in second-order form.
std::vector<OptionList> integrators(const Model &m) {
  std::vector<OptionList> list = {{{"-ts_type", "rk"}, {"-ts_rk_type", "4"}}, {{"-ts_type", "cn"}}};
  if (m.second_order_pairs() > 0) list.push_back({{"-ts_type", "leapfrog"}});
  return list;
}

std::string label(const OptionList &o) {
  std::string s;
  for (auto &kv : o) s += std::string(kv.first) + " " + kv.second + " ";
  return s;
}

} // namespace

TEST_P(ModelConformance, GradientTaylorCentralDifferenceAndRanks) {
  if (!any_kind_) GTEST_SKIP() << "no parameter of this kind";
  for (const OptionList &ts : integrators(*scene.model)) {
    SCOPED_TRACE(label(ts));
    ScopedOptions o;
    for (auto &kv : ts) o.set(kv.first, kv.second);
    OwnedVec p_true, g, d, q;
    PetscReal J0;
    flexipde_test::data_and_gradient(scene, p, p_true, g, &J0);
    PETSC_ASSERT_OK(VecDuplicate(p, d.out()));
    PETSC_ASSERT_OK(VecDuplicate(p, q.out()));
    PETSC_ASSERT_OK(fill_random(d, -1.0, 1.0, 49));
    PETSC_ASSERT_OK(VecPointwiseMult(d, d, p)); // relative to each parameter's size
    const PetscReal gd = dot(g, d);
    EXPECT_GT(J0, 0.0);
    EXPECT_GT(std::fabs(gd), 0.0);
    // Taylor: |J(p + h d) - J(p) - h g.d| = O(h^2)
    std::vector<PetscReal> r;
    for (PetscReal h = 1e-2; h > 1e-3; h /= 2) {
      PetscReal Jh;
      PETSC_ASSERT_OK(VecWAXPY(q, h, d, p));
      PETSC_ASSERT_OK(scene.value(q, &Jh));
      r.push_back(std::fabs(Jh - J0 - h * gd));
    }
    for (size_t k = 1; k < r.size(); ++k) {
      const PetscReal ratio = r[k - 1] / r[k];
      EXPECT_GT(ratio, 3.5) << "Taylor remainder ratio at level " << k;
      EXPECT_LT(ratio, 4.5) << "Taylor remainder ratio at level " << k;
    }
    // PETSc's own adjoint step (and the leapfrog through the assembled Jacobians): the same gradient
    {
      ScopedOptions oracle{{"-adjoint_petsc_step", "1"}};
      OwnedVec g_ref;
      PetscReal J_ref;
      PETSC_ASSERT_OK(VecDuplicate(g, g_ref.out()));
      PETSC_ASSERT_OK(scene.gradient(p, &J_ref, g_ref));
      EXPECT_EQ(J_ref, J0);
      EXPECT_LT(rel_diff(g, g_ref), 1e-9) << "gradient against -adjoint_petsc_step 1";
    }
    // central difference of J along d
    const PetscReal h = 1e-5;
    PetscReal Jp, Jm;
    PETSC_ASSERT_OK(VecWAXPY(q, h, d, p));
    PETSC_ASSERT_OK(scene.value(q, &Jp));
    PETSC_ASSERT_OK(VecWAXPY(q, -h, d, p));
    PETSC_ASSERT_OK(scene.value(q, &Jm));
    EXPECT_LT(rel_diff(gd, (Jp - Jm) / (2 * h)), 1e-6);
    // several ranks: each rank alone must find the same J and gradient
    PetscMPIInt size;
    MPI_Comm_size(PETSC_COMM_WORLD, &size);
    if (size > 1) {
      Scene serial;
      PETSC_ASSERT_OK(serial.setup(PETSC_COMM_SELF));
      OwnedVec ps, pts, gs;
      for (auto *v : {&ps, &pts, &gs}) PETSC_ASSERT_OK(serial.params.create_vec(v->out()));
      PETSC_ASSERT_OK(flexipde_test::to_serial_parameters(scene, p, serial, ps));
      PETSC_ASSERT_OK(VecCopy(ps, pts));
      PETSC_ASSERT_OK(VecScale(pts, 1.05));
      PETSC_ASSERT_OK(serial.make_synthetic_data(pts));
      PetscReal Js;
      PETSC_ASSERT_OK(serial.gradient(ps, &Js, gs));
      OwnedVec gpar_serial;
      PETSC_ASSERT_OK(serial.params.create_vec(gpar_serial.out()));
      PETSC_ASSERT_OK(flexipde_test::to_serial_parameters(scene, g, serial, gpar_serial));
      PetscReal worst[2] = {rel_diff(J0, Js), rel_diff(gpar_serial, gs)};
      MPI_Allreduce(MPI_IN_PLACE, worst, 2, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
      EXPECT_LT(worst[0], 1e-12) << "J on " << size << " ranks against one";
      EXPECT_LT(worst[1], 1e-12) << "gradient on " << size << " ranks against one";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Registry, ModelConformance, ::testing::ValuesIn(registered_cases()),
                         [](const ::testing::TestParamInfo<ConformanceCase> &i) { return i.param.name(); });
