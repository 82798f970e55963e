// The acoustic wave at space order 2, 4 and 8 (-fd_order), in 1D, 2D and 3D:
//   - convergence against an exact solution: G at the standing mode u = prod_d sin(2 pi x_d) (walls
//     at 0 and 1, v = 0) is [0, c^2 Lap_h u], and Lap_h u -> -D (2 pi)^2 u at the stencil's order as h
//     halves (the odd reflection beyond the walls is exact for this mode, so the rows next to the walls
//     keep the order too);
//   - at order 8, the gradient of a field c: a Taylor test (remainders falling ~2x and ~4x as the step
//     halves) in 1D with the leapfrog, in 2D with RK4, and in 3D with the leapfrog, the sponge and a
//     survey whose source and receivers lie between grid points (windowed-sinc weights), and the same J
//     and gradient on PETSC_COMM_WORLD as on PETSC_COMM_SELF (each rank the serial problem).
#include "flexipde/scene.hpp"
#include "flexipde/taylor.hpp"
#include "test_support.hpp"
#include <cmath>

using namespace flexipde;
using flexipde_test::fill_random;
using flexipde_test::ScopedOptions;

namespace {

struct OrderCase {
  const char *model;
  int order;
};
std::ostream &operator<<(std::ostream &os, const OrderCase &c) { return os << c.model << "_order" << c.order; }

// max over the points off the walls of |G_v - c^2 (-dim (2 pi)^2) u| on an n-point (per direction)
// grid, c = 0.8; reduced over the ranks.
PetscReal laplacian_error(const OrderCase &oc, PetscInt n) {
  const std::string m = oc.model;
  const int dim = m == "wave3d" ? 3 : m == "wave2d" ? 2 : 1;
  ScopedOptions opts{{"-model", oc.model},
                     {"-fd_order", std::to_string(oc.order).c_str()},
                     {"-da_grid_x", std::to_string(n).c_str()},
                     {"-da_grid_y", std::to_string(n).c_str()},
                     {"-da_grid_z", std::to_string(n).c_str()},
                     {("-" + m + "_sponge_width").c_str(), "0"},
                     {("-" + m + "_c").c_str(), "0.8"}};
  Scene scene;
  OwnedVec p, U, G;
  PetscReal err = -1;
  if (scene.setup(PETSC_COMM_WORLD) || scene.params.create_vec(p.out()) || scene.parameters_from_options("", p) ||
      scene.model->set_parameters(p) || scene.sim.create_state(U.out()) || VecDuplicate(U, G.out()))
    return err;
  const Grid &g = scene.grid;
  const PetscReal k = 2 * PETSC_PI, c = 0.8;
  auto mode = [&](PetscInt i, PetscInt j, PetscInt l) {
    return std::sin(k * g.x(i)) * (dim > 1 ? std::sin(k * g.y(j)) : 1.0) * (dim > 2 ? std::sin(k * g.z(l)) : 1.0);
  };
  {
    PetscScalar *u;
    if (VecGetArray(U, &u)) return err;
    PetscInt q = 0;
    for (PetscInt l = g.zs(); l < g.zs() + g.zm(); ++l)
      for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j)
        for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i, ++q) u[2 * q] = mode(i, j, l), u[2 * q + 1] = 0.0;
    if (VecRestoreArray(U, &u)) return err;
  }
  if (scene.model->rhs(0.0, U, G)) return err;
  const PetscScalar *gv;
  if (VecGetArrayRead(G, &gv)) return err;
  err = 0;
  PetscInt q = 0;
  for (PetscInt l = g.zs(); l < g.zs() + g.zm(); ++l)
    for (PetscInt j = g.ys(); j < g.ys() + g.ym(); ++j)
      for (PetscInt i = g.xs(); i < g.xs() + g.xm(); ++i, ++q) {
        if (i == 0 || i == g.n() - 1 || (dim > 1 && (j == 0 || j == g.ny() - 1)) || (dim > 2 && (l == 0 || l == g.nz() - 1)))
          continue;
        const PetscReal exact = -c * c * dim * k * k * mode(i, j, l);
        err = std::max(err, std::fabs(PetscRealPart(gv[2 * q + 1]) - exact));
      }
  if (VecRestoreArrayRead(G, &gv)) return -1;
  MPI_Allreduce(MPI_IN_PLACE, &err, 1, MPIU_REAL, MPI_MAX, PETSC_COMM_WORLD);
  return err;
}

class WaveSpaceOrder : public ::testing::TestWithParam<OrderCase> {};

} // namespace

TEST_P(WaveSpaceOrder, LaplacianConvergesAtTheStencilOrder) {
  const OrderCase oc = GetParam();
  // h = 1/24 and 1/48: the order-8 error stays well above round-off (about 1e-10 of c^2 |Lap u|)
  const PetscReal e1 = laplacian_error(oc, 25), e2 = laplacian_error(oc, 49);
  ASSERT_GT(e1, 0.0) << "set-up or rhs failed";
  ASSERT_GT(e2, 0.0);
  const PetscReal observed = std::log2(e1 / e2);
  PetscPrintf(PETSC_COMM_WORLD, "  [%s order %d] max error %.3e -> %.3e, observed order %.3f\n", oc.model, oc.order,
              (double)e1, (double)e2, (double)observed);
  EXPECT_GT(observed, oc.order - 0.3);
  EXPECT_LT(observed, oc.order + 0.5);
}

INSTANTIATE_TEST_SUITE_P(Wave, WaveSpaceOrder,
                         ::testing::Values(OrderCase{"wave", 2}, OrderCase{"wave", 4}, OrderCase{"wave", 8},
                                           OrderCase{"wave2d", 2}, OrderCase{"wave2d", 4}, OrderCase{"wave2d", 8},
                                           OrderCase{"wave3d", 2}, OrderCase{"wave3d", 4}, OrderCase{"wave3d", 8}),
                         [](const ::testing::TestParamInfo<OrderCase> &i) {
                           return std::string(i.param.model) + "_order" + std::to_string(i.param.order);
                         });

namespace {

// The order-8 gradient scenes: a field c, synthetic data from a smooth true c.
struct GradientCase {
  const char *name;
  flexipde_test::OptionList options;
};
std::ostream &operator<<(std::ostream &os, const GradientCase &c) { return os << c.name; }

const GradientCase order8_cases[] = {
    {"wave_leapfrog",
     {{"-model", "wave"},
      {"-fd_order", "8"},
      {"-ts_type", "leapfrog"},
      {"-da_grid_x", "81"},
      {"-ts_dt", "2e-3"},
      {"-ts_max_time", "0.3"},
      {"-wave_c_field", "1"},
      {"-wave_c", "0.9"},
      {"-true_wave_c", "1.0"},
      {"-true_wave_c_profile", "gaussian"},
      {"-true_wave_c_bump", "0.1"}}},
    {"wave2d_rk4",
     {{"-model", "wave2d"},
      {"-fd_order", "8"},
      {"-ts_type", "rk"},
      {"-ts_rk_type", "4"},
      {"-da_grid_x", "31"},
      {"-da_grid_y", "29"},
      {"-ts_dt", "4e-3"},
      {"-ts_max_time", "0.12"},
      {"-wave2d_ic", "pulse"},
      {"-wave2d_ic_width", "0.15"},
      {"-wave2d_c_field", "1"},
      {"-wave2d_c", "0.9"},
      {"-true_wave2d_c", "1.0"}}},
    {"wave3d_leapfrog_survey",
     {{"-model", "wave3d"},
      {"-fd_order", "8"},
      {"-ts_type", "leapfrog"},
      {"-da_grid_x", "23"},
      {"-da_grid_y", "21"},
      {"-da_grid_z", "20"},
      {"-ts_dt", "5e-3"},
      {"-ts_max_time", "0.35"},
      {"-wave3d_sponge_width", "0.2"},
      {"-wave3d_c_field", "1"},
      {"-wave3d_c", "0.9"},
      {"-true_wave3d_c", "1.0"},
      {"-objective_type", "receivers"},
      {"-survey_interpolation", "sinc"},
      {"-survey_ricker_f0", "5"},
      {"-survey_sources_x", "0.43"},
      {"-survey_sources_y", "0.52"},
      {"-survey_sources_z", "0.37"},
      {"-survey_receivers_spread", "0.3,0.7,4"},
      {"-survey_receivers_y", "0.47"},
      {"-survey_receivers_z", "0.62"}}},
};

class WaveOrder8Gradient : public ::testing::TestWithParam<GradientCase> {};

} // namespace

TEST_P(WaveOrder8Gradient, TaylorTest) {
  ScopedOptions opts;
  for (const auto &o : GetParam().options) opts.set(o.first, o.second);
  flexipde_test::SceneProblem pb;
  PETSC_ASSERT_OK(pb.setup(PETSC_COMM_WORLD));
  OwnedVec d;
  PETSC_ASSERT_OK(VecDuplicate(pb.p, d.out()));
  PETSC_ASSERT_OK(fill_random(d, 0.5, 1.5, 17)); // c up everywhere: J's first-order change is clear of 0
  auto f = [&](Vec q, PetscReal *J, Vec g) { return pb.scene.sim.gradient(q, J, g, nullptr); };
  TaylorResult tr;
  PETSC_ASSERT_OK(taylor_test(f, pb.p, d, 1e-2, 4, tr));
  ASSERT_EQ(tr.eps.size(), (size_t)4);
  EXPECT_GT(std::fabs(tr.gd), 0.0);
  for (size_t k = 1; k < tr.eps.size(); ++k)
    PetscPrintf(PETSC_COMM_WORLD, "  [%s] eps %.2e: r1 ratio %.3f, r2 ratio %.3f\n", GetParam().name, (double)tr.eps[k],
                (double)tr.ratio1(k), (double)tr.ratio2(k));
  const size_t last = tr.eps.size() - 1;
  EXPECT_NEAR(tr.ratio1(last), 2.0, 0.2);
  EXPECT_NEAR(tr.ratio2(last), 4.0, 0.5) << "gradient is not the derivative of J";
}

TEST_P(WaveOrder8Gradient, ParallelMatchesSerial) {
  ScopedOptions opts;
  for (const auto &o : GetParam().options) opts.set(o.first, o.second);
  flexipde_test::expect_parallel_matches_serial(GetParam().name);
}

INSTANTIATE_TEST_SUITE_P(Wave, WaveOrder8Gradient, ::testing::ValuesIn(order8_cases),
                         [](const ::testing::TestParamInfo<GradientCase> &i) { return std::string(i.param.name); });
