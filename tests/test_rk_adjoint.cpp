// The explicit RK adjoint step of rk_adjoint.hpp against PETSc's own TSAdjointStep_RK
// (-adjoint_petsc_step), on 1 and 2 ranks: the same gradient to 1e-12 (the two differ only in the
// rounding of b_i W_i), for every model that runs with TSRK, scalar and field parameters, tableaux of
// 2 to 4 stages (non-FSAL: rk_adjoint.hpp's path) and an FSAL one (3bs: handed back to PETSc's, so the
// two must agree exactly), objectives with a cost integrand (receivers, time variation) among them. Each
// case's gradient is also nonzero, so the comparison means something.
#include "flexipde/scene.hpp"
#include "test_support.hpp"
#include <array>
#include <cstdlib>
#include <string>

using namespace flexipde;
using flexipde_test::expect_same_gradient;
using flexipde_test::ScopedOptions;

namespace {

struct RkCase {
  const char *name;
  std::vector<std::pair<const char *, const char *>> opts;
  PetscReal tol;
};

std::vector<RkCase> rk_cases() {
  return {
      {"wave_rk4_field", {{"-da_grid_x", "61"}, {"-wave_c_field", "1"}, {"-ts_rk_type", "4"}}, 1e-12},
      {"wave_rk3_scalar_fd4_periodic",
       {{"-da_grid_x", "61"}, {"-fd_order", "4"}, {"-grid_periodic", "1"}, {"-wave_ic", "rest"}, {"-ts_rk_type", "3"}},
       1e-12},
      {"advection_upwind_diffusion_rk2a",
       {{"-model", "advection"}, {"-grid_periodic", "1"}, {"-da_grid_x", "64"}, {"-advection_scheme", "upwind"},
        {"-advection_D", "0.01"}, {"-ts_rk_type", "2a"}, {"-ts_dt", "2e-3"}},
       1e-12},
      {"wave_rk3bs_field_petsc", {{"-da_grid_x", "61"}, {"-wave_c_field", "1"}, {"-ts_rk_type", "3bs"}}, 1e-300},
      {"wave2d_sponge_rk4_field",
       {{"-model", "wave2d"}, {"-da_grid_x", "23"}, {"-da_grid_y", "19"}, {"-wave2d_c_field", "1"},
        {"-wave2d_sponge_width", "0.2"}, {"-wave2d_ic", "pulse"}, {"-wave2d_ic_width", "0.2"}, {"-ts_rk_type", "4"}},
       1e-12},
      {"advection_upwind_rk1fe",
       {{"-model", "advection"}, {"-grid_periodic", "1"}, {"-da_grid_x", "64"}, {"-advection_scheme", "upwind"},
        {"-ts_rk_type", "1fe"}, {"-ts_dt", "2e-3"}},
       1e-12},
      {"advection_fd2_diffusion_field_rk4",
       {{"-model", "advection"}, {"-grid_periodic", "1"}, {"-da_grid_x", "64"}, {"-advection_scheme", "fd2"},
        {"-advection_D", "0.01"}, {"-advection_D_field", "1"}, {"-advection_ic_amplitude_param", "1"}, {"-ts_rk_type", "4"}},
       1e-12},
      {"advection_spectral_rk4",
       {{"-model", "advection"}, {"-grid_periodic", "1"}, {"-da_grid_x", "64"}, {"-advection_scheme", "spectral"},
        {"-ts_rk_type", "4"}},
       1e-12},
      {"advection_spectral_D_rk4",
       {{"-model", "advection"}, {"-grid_periodic", "1"}, {"-da_grid_x", "64"}, {"-advection_scheme", "spectral"},
        {"-advection_D", "0.01"}, {"-ts_rk_type", "4"}},
       1e-12},
      {"advection_2d_spectral_D_rk3",
       {{"-model", "advection"}, {"-advection_dim", "2"}, {"-grid_periodic", "1"}, {"-da_grid_x", "16"},
        {"-da_grid_y", "12"}, {"-advection_scheme", "spectral"}, {"-advection_D", "0.01"}, {"-advection_b", "-0.6"},
        {"-ts_rk_type", "3"}},
       1e-12},
      {"advection_spectral_D_field_rk4",
       {{"-model", "advection"}, {"-grid_periodic", "1"}, {"-da_grid_x", "64"}, {"-advection_scheme", "spectral"},
        {"-advection_D", "0.01"}, {"-advection_D_field", "1"}, {"-advection_D_profile", "gaussian"},
        {"-advection_D_bump", "0.02"}, {"-advection_ic_amplitude_param", "1"}, {"-ts_rk_type", "4"}},
       5e-12}, // P applied to the sum of the stages' field sums, not to each: round-off of a longer sum
      {"advection_2d_spectral_D_field_rk4",
       {{"-model", "advection"}, {"-advection_dim", "2"}, {"-grid_periodic", "1"}, {"-da_grid_x", "16"},
        {"-da_grid_y", "12"}, {"-advection_scheme", "spectral"}, {"-advection_D", "0.01"}, {"-advection_D_field", "1"},
        {"-advection_D_profile", "gaussian"}, {"-advection_D_bump", "0.02"}, {"-advection_b", "-0.6"}, {"-ts_rk_type", "4"}},
       5e-12}, // P applied to the sum of the stages' field sums, not to each: round-off of a longer sum
      {"advection_2d_fd4_D_field_order4_rk4",
       {{"-model", "advection"}, {"-advection_dim", "2"}, {"-grid_periodic", "1"}, {"-da_grid_x", "16"},
        {"-da_grid_y", "16"}, {"-advection_scheme", "fd4"}, {"-fd_order", "4"}, {"-advection_D", "0.02"},
        {"-advection_D_field", "1"}, {"-advection_D_profile", "gaussian"}, {"-advection_D_bump", "0.01"},
        {"-advection_b", "-0.6"}, {"-ts_rk_type", "4"}},
       1e-12},
      {"advection_2d_fd2_D_field_rk4",
       {{"-model", "advection"}, {"-advection_dim", "2"}, {"-grid_periodic", "1"}, {"-da_grid_x", "16"},
        {"-da_grid_y", "12"}, {"-advection_D", "0.02"}, {"-advection_D_field", "1"}, {"-advection_b", "-0.6"},
        {"-ts_rk_type", "4"}},
       1e-12},
      // Cost integrands: the receivers' sparse dr/dU, from the stages' positions alone (the records the
      // wave's full storage keeps), from whole stages re-run by checkpointing, in 2D with the PML;
      // the time variation's dense dr/dU and its dr/dp.
      {"wave_rk4_receivers",
       {{"-da_grid_x", "101"}, {"-wave_c_field", "1"}, {"-wave_ic", "zero"}, {"-ts_max_time", "0.3"},
        {"-objective_type", "receivers"}, {"-survey_sources_x", "0.45"}, {"-survey_receivers_spread", "0.3,0.7,5"},
        {"-survey_ricker_f0", "6"}, {"-ts_rk_type", "4"}},
       1e-12},
      {"wave_rk4_receivers_checkpointed",
       {{"-da_grid_x", "101"}, {"-wave_c_field", "1"}, {"-wave_ic", "zero"}, {"-ts_max_time", "0.3"},
        {"-objective_type", "receivers"}, {"-survey_sources_x", "0.45"}, {"-survey_receivers_spread", "0.3,0.7,5"},
        {"-survey_ricker_f0", "6"}, {"-ts_rk_type", "4"}, {"-checkpoint_budget", "5"}},
       1e-12},
      {"wave2d_pml_rk4_receivers",
       {{"-model", "wave2d"}, {"-da_grid_x", "25"}, {"-da_grid_y", "21"}, {"-wave2d_c_field", "1"},
        {"-wave2d_pml_width", "0.2"}, {"-ts_max_time", "0.3"}, {"-objective_type", "receivers"},
        {"-survey_sources_x", "0.5"}, {"-survey_sources_y", "0.5"}, {"-survey_receivers_spread", "0.3,0.7,4"},
        {"-survey_receivers_y", "0.35"}, {"-survey_ricker_f0", "5"}, {"-ts_rk_type", "4"}},
       1e-12},
      {"advection_time_variation_D_field_rk3",
       {{"-model", "advection"}, {"-grid_periodic", "1"}, {"-da_grid_x", "64"}, {"-advection_scheme", "fd2"},
        {"-advection_D", "0.01"}, {"-advection_D_field", "1"}, {"-objective_type", "time_variation"},
        {"-ts_rk_type", "3"}},
       1e-12},
      {"vlasov_landau_rk4",
       {{"-model", "vlasov"}, {"-vlasov_ic", "landau"}, {"-da_grid_x", "16"}, {"-da_grid_y", "32"},
        {"-objective_type", "functional"}, {"-ts_rk_type", "4"}, {"-ts_dt", "0.05"}, {"-ts_max_time", "1"}},
       1e-12},
  };
}

// A scene with an explicit RK TS (0.1 time units of 2e-3) and the case's options, and its p.
struct RkScene {
  void set_up(const std::vector<std::pair<const char *, const char *>> &opts) {
    opts_.set("-ts_max_time", "0.1");
    opts_.set("-ts_dt", "2e-3");
    opts_.set("-ts_type", "rk");
    for (auto &o : opts) opts_.set(o.first, o.second);
    PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
    PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
    PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  }
  ScopedOptions opts_;
  Scene scene;
  OwnedVec p;
};

class RkAdjoint : public ::testing::TestWithParam<RkCase>, public RkScene {
protected:
  void SetUp() override { set_up(GetParam().opts); }
};

std::string rk_name(const ::testing::TestParamInfo<RkCase> &i) { return i.param.name; }

} // namespace

TEST_P(RkAdjoint, SameGradientAsPetscRk) {
  expect_same_gradient(scene, p, {}, {{"-adjoint_petsc_step", "1"}}, GetParam().tol);
}

INSTANTIATE_TEST_SUITE_P(Models, RkAdjoint, ::testing::ValuesIn(rk_cases()), rk_name);

// A scalar c's gradient from the wave's fused sweeps (its pointwise terms accumulated over the whole
// adjoint and summed once) against the reference path (-adjoint_petsc_step: PETSc's RK step, the
// leapfrog's through the Jacobians, summed at every stage or kick): the same sum in another order, so
// equal to round-off, for the RK stage and the leapfrog kick, both stencil orders, walls and periodic.
TEST(WaveScalarSum, SameGradientAsPetscStep) {
  for (const char *ts : {"rk", "leapfrog"})
    for (const char *order : {"2", "4"})
      for (const char *periodic : {"0", "1"}) {
        SCOPED_TRACE(std::string(ts) + ", order " + order + ", periodic " + periodic);
        RkScene s;
        s.set_up({{"-da_grid_x", "41"}, {"-wave_c_field", "0"}, {"-fd_order", order}, {"-ts_type", ts},
                  {"-ts_rk_type", "4"}, {"-grid_periodic", periodic}, {"-wave_ic", "rest"}});
        expect_same_gradient(s.scene, s.p, {}, {{"-adjoint_petsc_step", "1"}}, 1e-12);
      }
}

// The fused RK adjoint on advection (the integrator forms a stage's combination W_i of the later
// stages' dLambda, the layer's gather applies the transposes): the gradient of PETSc's RK step
// (-adjoint_petsc_step) to round-off, for tableaux whose stages combine 0 to 2 later stages' dLambda
// (rk4, rk3, rk2a), 1D and 2D.
TEST(RkStageCombination, AdvectionSameGradientAsPetscStep) {
  const std::pair<const char *, const char *> tableaux[] = {{"4", "fd2"}, {"3", "fd4"}, {"2a", "upwind"}};
  for (const auto &[rk, scheme] : tableaux)
    for (const char *dim : {"1", "2"}) {
      SCOPED_TRACE(std::string("-ts_rk_type ") + rk + ", dim " + dim);
      RkScene s;
      s.set_up({{"-model", "advection"}, {"-advection_dim", dim}, {"-advection_scheme", scheme}, {"-grid_periodic", "1"}, {"-da_grid_x", "24"},
                {"-da_grid_y", "16"}, {"-advection_D", "0.02"}, {"-advection_D_field", "1"}, {"-advection_b", "-0.6"},
                {"-advection_ic_amplitude_param", "1"}, {"-ts_rk_type", rk}, {"-ts_dt", "1e-3"}});
      expect_same_gradient(s.scene, s.p, {}, {{"-adjoint_petsc_step", "1"}}, 1e-12);
    }
}

// A field D with fd2 and fd4 faces: the fused RK adjoint gives the gradient of PETSc's RK step
// (-adjoint_petsc_step) to round-off, for each advection scheme (taps of radius 1 and 2) and tableaux
// with 1 to 3 later stages, on however many ranks the test runs.
TEST(AdvectionFieldD, SameGradientAsPetscStep) {
  const std::array<const char *, 3> cases[] = {
      {"4", "fd2", "2"}, {"3", "fd4", "2"}, {"4", "upwind", "2"}, {"2a", "upwind", "2"}, {"4", "fd4", "4"}};
  for (const char *dim : {"1", "2"})
    for (const auto &[rk, scheme, order] : cases) {
      SCOPED_TRACE(std::string("dim ") + dim + ", -ts_rk_type " + rk + ", " + scheme + ", faces of order " + order);
      RkScene s;
      s.set_up({{"-model", "advection"}, {"-advection_dim", dim}, {"-advection_scheme", scheme}, {"-fd_order", order},
                {"-grid_periodic", "1"}, {"-da_grid_x", "20"}, {"-da_grid_y", "16"}, {"-advection_D", "0.02"},
                {"-advection_D_field", "1"}, {"-advection_b", "-0.6"}, {"-advection_ic_amplitude_param", "1"},
                {"-ts_rk_type", rk}, {"-ts_dt", "1e-3"}});
      expect_same_gradient(s.scene, s.p, {}, {{"-adjoint_petsc_step", "1"}}, 1e-12);
    }
}

// The 2D wave's RK adjoint stages (the pointwise layer's Model::stage_adjoint: (dG/dU)^T and (dG/dc)^T in
// one gather sweep) give the gradient of PETSc's RK adjoint through its two Jacobian transposes
// (-adjoint_petsc_step) to round-off, for field and scalar speeds (the scalar's sums deferred to one
// reduction), with and without the sponge, on grids that 2 ranks split along x (23 x 19) and along y
// (19 x 23).
namespace {

std::vector<RkCase> wave2d_stage_cases() {
  const auto all = rk_cases();
  auto wave2d = [](const char *name, const char *nx, const char *ny, const char *field, const char *sponge,
                   const char *rk) {
    return RkCase{name,
                  {{"-model", "wave2d"}, {"-da_grid_x", nx}, {"-da_grid_y", ny}, {"-wave2d_c_field", field},
                   {"-wave2d_sponge_width", sponge}, {"-wave2d_ic", "pulse"}, {"-wave2d_ic_width", "0.2"},
                   {"-ts_rk_type", rk}},
                  1e-12};
  };
  return {
      wave2d("wave2d_rk4_field", "23", "19", "1", "0", "4"),
      wave2d("wave2d_rk3_scalar", "19", "23", "0", "0", "3"),
      all[4], // wave2d_sponge_rk4_field
      wave2d("wave2d_sponge_rk3_scalar", "19", "23", "0", "0.2", "3"),
  };
}

class RkStagesWave2D : public RkAdjoint {};

} // namespace

TEST_P(RkStagesWave2D, SameGradientAsJacobianTransposes) {
  ASSERT_TRUE(scene.model->has_stage_adjoint());
  expect_same_gradient(scene, p, {}, {{"-adjoint_petsc_step", "1"}}, GetParam().tol);
}

INSTANTIATE_TEST_SUITE_P(Wave2D, RkStagesWave2D, ::testing::ValuesIn(wave2d_stage_cases()), rk_name);

