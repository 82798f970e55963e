// Parameter vectors and the learned_burgers model:
//   - dJ/dtheta of a trajectory misfit (TrajectoryMisfit, what the training minimises) by a Taylor test,
//     one stencil (3 weights) and a network (7 H + 3), remainders falling ~2x without and ~4x with the
//     gradient term as the step halves;
//   - the reverse-mode transpose (dG/dtheta)^T against the forward-mode tangent dG/dtheta by the
//     dot-product identity, and the tangent against central differences of G;
//   - several ranks against one (J and gradient to 1e-12);
//   - zero weights are the Engquist-Osher scheme of -model burgers; any weights keep a constant state
//     (consistency) and sum_i G_i = 0 (conservation);
//   - the vector's options: a list, a file, and a wrong count refused.
#include "flexipde/trajectory_misfit.hpp"
#include "test_support.hpp"
#include <cstdio>
#include <fstream>

using namespace flexipde;
using flexipde_test::dot;
using flexipde_test::fill_random;
using flexipde_test::norm;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

struct LearnedCase {
  std::string name, weights, hidden;
};
std::ostream &operator<<(std::ostream &os, const LearnedCase &c) { return os << c.name; }

void learned_scene(ScopedOptions &o, const LearnedCase &c) {
  o.set("-model", "learned_burgers");
  o.set("-da_grid_x", "24");
  o.set("-ts_dt", "0.005");
  o.set("-ts_max_time", "0.15");
  o.set("-learned_burgers_weights", c.weights);
  o.set("-learned_burgers_hidden", c.hidden);
}

class LearnedBurgersGradient : public ::testing::TestWithParam<LearnedCase> {
protected:
  void SetUp() override {
    learned_scene(opts_, GetParam());
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
    PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
    // Data: the start shrinking and shifting in time, at a few times (not a solution of the scheme).
    OwnedVec d;
    PETSC_ASSERT_OK(scene.sim.initial_condition(p, U));
    PETSC_ASSERT_OK(misfit.setup(scene.grid.dm(), 0, 1, 1.0 / 24));
    PETSC_ASSERT_OK(VecDuplicate(U, d.out()));
    for (int k = 0; k <= 3; ++k) {
      PETSC_ASSERT_OK(VecCopy(U, d));
      PETSC_ASSERT_OK(VecScale(d, 1 - 0.15 * k));
      PETSC_ASSERT_OK(VecShift(d, 0.02 * k));
      PETSC_ASSERT_OK(misfit.add_snapshot(0.05 * k, d));
    }
    scene.sim.set_objective(&misfit);
  }
  ScopedOptions opts_;
  Scene scene;
  TrajectoryMisfit misfit;
  OwnedVec p, U;
};

} // namespace

TEST_P(LearnedBurgersGradient, TaylorTest) {
  OwnedVec g, d, q;
  PetscReal J0;
  PETSC_ASSERT_OK(VecDuplicate(p, g.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, d.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, q.out()));
  PETSC_ASSERT_OK(scene.gradient(p, &J0, g));
  PETSC_ASSERT_OK(fill_random(d, -0.5, 0.5, 51));
  const PetscReal gd = dot(g, d);
  EXPECT_GT(J0, 0.0);
  EXPECT_GT(std::fabs(gd), 0.0);
  std::vector<PetscReal> r1, r2;
  for (PetscReal h = 4e-3; h > 2e-4; h /= 2) {
    PetscReal Jh;
    PETSC_ASSERT_OK(VecWAXPY(q, h, d, p));
    PETSC_ASSERT_OK(scene.value(q, &Jh));
    r1.push_back(std::fabs(Jh - J0)), r2.push_back(std::fabs(Jh - J0 - h * gd));
  }
  for (size_t k = 1; k < r1.size(); ++k) {
    EXPECT_NEAR(r1[k - 1] / r1[k], 2.0, 0.2) << "first-order remainder ratio at level " << k;
    EXPECT_NEAR(r2[k - 1] / r2[k], 4.0, 0.5) << "second-order remainder ratio at level " << k;
  }
}

TEST_P(LearnedBurgersGradient, ReverseTransposeAgainstTangent) {
  OwnedMat Jp;
  OwnedVec dp, y, Jdp, JTy, Gp, Gm, q;
  PETSC_ASSERT_OK(VecDuplicate(p, dp.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, JTy.out()));
  PETSC_ASSERT_OK(VecDuplicate(p, q.out()));
  for (auto *v : {&y, &Jdp, &Gp, &Gm}) PETSC_ASSERT_OK(VecDuplicate(U, v->out()));
  PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 52));
  PETSC_ASSERT_OK(fill_random(dp, -0.3, 0.3, 53));
  PETSC_ASSERT_OK(fill_random(y, -1.0, 1.0, 54));
  PETSC_ASSERT_OK(scene.model->set_parameters(p));
  PETSC_ASSERT_OK(scene.model->create_jacobian_p(Jp.out()));
  PETSC_ASSERT_OK(scene.model->rhs_jacobian_p(0.1, U, Jp));
  PETSC_ASSERT_OK(MatMult(Jp, dp, Jdp));
  PETSC_ASSERT_OK(MatMultTranspose(Jp, y, JTy));
  EXPECT_GT(norm(Jdp), 0.0);
  EXPECT_LT(rel_diff(dot(y, Jdp), dot(JTy, dp)), 1e-12) << "<y, dG/dtheta dp> = <(dG/dtheta)^T y, dp>";
  const PetscReal eps = 1e-6;
  PETSC_ASSERT_OK(VecWAXPY(q, eps, dp, p));
  PETSC_ASSERT_OK(scene.model->set_parameters(q));
  PETSC_ASSERT_OK(scene.model->rhs(0.1, U, Gp));
  PETSC_ASSERT_OK(VecWAXPY(q, -eps, dp, p));
  PETSC_ASSERT_OK(scene.model->set_parameters(q));
  PETSC_ASSERT_OK(scene.model->rhs(0.1, U, Gm));
  PETSC_ASSERT_OK(VecAXPY(Gp, -1.0, Gm));
  PETSC_ASSERT_OK(VecScale(Gp, 1 / (2 * eps)));
  EXPECT_LT(rel_diff(Jdp, Gp), 1e-6) << "dG/dtheta dp against central differences of G";
}

TEST_P(LearnedBurgersGradient, SeveralRanksAsOne) {
  PetscMPIInt size;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  if (size == 1) GTEST_SKIP() << "one rank";
  OwnedVec g, ps, gs, gpar;
  PetscReal J, Js;
  PETSC_ASSERT_OK(VecDuplicate(p, g.out()));
  PETSC_ASSERT_OK(scene.gradient(p, &J, g));
  Scene serial;
  TrajectoryMisfit ms;
  PETSC_ASSERT_OK(serial.setup(PETSC_COMM_SELF));
  for (auto *v : {&ps, &gs, &gpar}) PETSC_ASSERT_OK(serial.params.create_vec(v->out()));
  PETSC_ASSERT_OK(flexipde_test::to_serial_parameters(scene, p, serial, ps));
  OwnedVec Us, d;
  PETSC_ASSERT_OK(serial.sim.create_state(Us.out()));
  PETSC_ASSERT_OK(serial.sim.initial_condition(ps, Us));
  PETSC_ASSERT_OK(ms.setup(serial.grid.dm(), 0, 1, 1.0 / 24));
  PETSC_ASSERT_OK(VecDuplicate(Us, d.out()));
  for (int k = 0; k <= 3; ++k) {
    PETSC_ASSERT_OK(VecCopy(Us, d));
    PETSC_ASSERT_OK(VecScale(d, 1 - 0.15 * k));
    PETSC_ASSERT_OK(VecShift(d, 0.02 * k));
    PETSC_ASSERT_OK(ms.add_snapshot(0.05 * k, d));
  }
  serial.sim.set_objective(&ms);
  PETSC_ASSERT_OK(serial.gradient(ps, &Js, gs));
  PETSC_ASSERT_OK(flexipde_test::to_serial_parameters(scene, g, serial, gpar));
  PetscReal worst[2] = {rel_diff(J, Js), rel_diff(gpar, gs)};
  MPI_Allreduce(MPI_IN_PLACE, worst, 2, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
  EXPECT_LT(worst[0], 1e-12) << "J on " << size << " ranks against one";
  EXPECT_LT(worst[1], 1e-12) << "dJ/dtheta on " << size << " ranks against one";
}

INSTANTIATE_TEST_SUITE_P(Weights, LearnedBurgersGradient,
                         ::testing::Values(LearnedCase{"stencil", "constant", "4"}, LearnedCase{"network", "network", "12"}),
                         [](const ::testing::TestParamInfo<LearnedCase> &i) { return i.param.name; });

// Zero weights give the first-order Engquist-Osher flux of -model burgers: the same G to round-off.
TEST(LearnedBurgers, ZeroWeightsAreTheBurgersScheme) {
  ScopedOptions o{{"-da_grid_x", "24"}, {"-learned_burgers_theta", "0,0,0"}, {"-learned_burgers_nu", "0.013"}, {"-burgers_nu", "0.013"}};
  Scene a, b;
  OwnedVec pa, pb, U, Ga, Gb;
  {
    ScopedOptions m{{"-model", "learned_burgers"}};
    PETSC_ASSERT_OK(a.setup(PETSC_COMM_WORLD));
  }
  {
    ScopedOptions m{{"-model", "burgers"}};
    PETSC_ASSERT_OK(b.setup(PETSC_COMM_WORLD));
  }
  PETSC_ASSERT_OK(a.params.create_vec(pa.out()));
  PETSC_ASSERT_OK(a.parameters_from_options("", pa));
  PETSC_ASSERT_OK(b.params.create_vec(pb.out()));
  PETSC_ASSERT_OK(b.parameters_from_options("", pb));
  PETSC_ASSERT_OK(a.sim.create_state(U.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Ga.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, Gb.out()));
  PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 55));
  PETSC_ASSERT_OK(a.model->set_parameters(pa));
  PETSC_ASSERT_OK(b.model->set_parameters(pb));
  PETSC_ASSERT_OK(a.model->rhs(0, U, Ga));
  PETSC_ASSERT_OK(b.model->rhs(0, U, Gb));
  EXPECT_GT(norm(Gb), 1.0);
  EXPECT_LT(rel_diff(Ga, Gb), 1e-14);
}

// Any weights, even far from a sensible scheme: a constant state stays (G = 0) and sum_i G_i = 0.
TEST(LearnedBurgers, ConsistentAndConservativeForAnyWeights) {
  ScopedOptions o{{"-model", "learned_burgers"}, {"-da_grid_x", "24"}, {"-learned_burgers_weights", "network"},
                  {"-learned_burgers_hidden", "6"}};
  Scene s;
  OwnedVec p, U, G;
  PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(s.params.create_vec(p.out()));
  PETSC_ASSERT_OK(fill_random(p, -3.0, 3.0, 56));
  PETSC_ASSERT_OK(s.sim.create_state(U.out()));
  PETSC_ASSERT_OK(VecDuplicate(U, G.out()));
  PETSC_ASSERT_OK(s.model->set_parameters(p));
  for (PetscReal c : {-0.8, 0.3, 1.7}) {
    PETSC_ASSERT_OK(VecSet(U, c));
    PETSC_ASSERT_OK(s.model->rhs(0, U, G));
    EXPECT_LT(norm(G, NORM_INFINITY), 1e-12) << "G at the constant state " << c;
  }
  PetscReal sum, gmax;
  PETSC_ASSERT_OK(fill_random(U, -1.0, 1.0, 57));
  PETSC_ASSERT_OK(s.model->rhs(0, U, G));
  PETSC_ASSERT_OK(VecSum(G, &sum));
  gmax = norm(G, NORM_INFINITY);
  EXPECT_GT(gmax, 1.0);
  EXPECT_LT(std::fabs(sum), 1e-12 * gmax * 24) << "sum_i G_i (conservation)";
}

// -<vector> takes all entries or refuses; -<vector>_file reads a text file.
TEST(ParameterVector, OptionsListAndFile) {
  ScopedOptions o{{"-model", "learned_burgers"}, {"-da_grid_x", "24"}};
  Scene s;
  OwnedVec p;
  std::vector<PetscReal> v;
  PETSC_ASSERT_OK(s.setup(PETSC_COMM_WORLD));
  PETSC_ASSERT_OK(s.params.create_vec(p.out()));
  const PetscInt k = s.params.find("learned_burgers_theta");
  ASSERT_GE(k, 0);
  EXPECT_EQ(s.params.info(k).kind, ParamKind::Vector);
  {
    ScopedOptions l{{"-learned_burgers_theta", "0.25,-0.5,0.125"}};
    PETSC_ASSERT_OK(s.parameters_from_options("", p));
    PETSC_ASSERT_OK(s.params.vector_values(p, k, v));
    EXPECT_EQ(v, (std::vector<PetscReal>{0.25, -0.5, 0.125}));
  }
  {
    ScopedOptions l{{"-learned_burgers_theta", "1,2"}};
    flexipde_test::QuietErrors quiet;
    EXPECT_NE(s.parameters_from_options("", p), 0) << "two values for three entries";
  }
  const std::string file = "learned_theta_test_" + std::to_string(flexipde_test::is_rank0() ? 0 : 1) + ".txt";
  {
    std::ofstream f(file);
    f << "0.5 1e-1\n-2,\n";
  }
  {
    ScopedOptions l{{"-learned_burgers_theta_file", file.c_str()}};
    PETSC_ASSERT_OK(s.parameters_from_options("", p));
    PETSC_ASSERT_OK(s.params.vector_values(p, k, v));
    EXPECT_EQ(v, (std::vector<PetscReal>{0.5, 0.1, -2.0}));
  }
  std::remove(file.c_str());
}
