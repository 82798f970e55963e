// The implicit theta adjoint step of theta_adjoint.hpp against PETSc's own TSAdjointStep_Theta
// (-adjoint_petsc_step), on 1 and 2 ranks: the same J and gradient, for cn, backward Euler,
// the midpoint theta method and an endpoint theta method; linear models with the factored shifted
// operator (sequential LU on 1 rank, redundant LU on 2; PETSc's path forms and factors it at every
// step itself, the same J bitwise), a matrix-free spectral operator (GMRES), the nonlinear
// Vlasov-Poisson model (GMRES on its Jacobian shell), field and scalar parameters, and binomial
// checkpointing (forward steps re-run inside the adjoint); and full storage (for the endpoint forms
// only the solutions) against PETSc's memory trajectory. For the linear models flexipde's step takes
// A^T nu from the transposed solve's equation where PETSc's applies A^T, and solves with a
// factorisation of P^T where PETSc's solves with P's factors transposed. Both steps are the same
// discrete adjoint, so the tolerance is round-off (a 1e-6 change of the endpoint update's coefficient,
// or a sign in the midpoint's, fails cases); each gradient is checked to be nonzero, so the comparison
// means something.
#include "flexipde/scene.hpp"
#include "test_support.hpp"
#include <string>

using namespace flexipde;
using flexipde_test::rel_diff;
using flexipde_test::ScopedOptions;

namespace {

using Options = std::vector<std::pair<const char *, const char *>>;

using ThetaCase = flexipde_test::NamedOptions;

const Options advection = {{"-model", "advection"},    {"-grid_periodic", "1"}, {"-grid_x0", "0"},
                           {"-grid_x1", "6.283185307179586"}, {"-da_grid_x", "64"}, {"-ts_max_time", "0.5"},
                           {"-ts_dt", "0.01"}, {"-advection_a", "0.8"}, {"-true_advection_a", "1.0"}};
const Options wave = {{"-da_grid_x", "81"}, {"-ts_max_time", "0.2"}, {"-ts_dt", "4e-3"}, {"-wave_c_field", "1"},
                      {"-wave_c", "0.9"},   {"-true_wave_c", "1.0"}};
const Options vlasov = {{"-model", "vlasov"},          {"-vlasov_ic", "landau"},  {"-da_grid_x", "16"},
                        {"-da_grid_y", "32"},          {"-objective_type", "functional"}, {"-ts_dt", "0.1"},
                        {"-ts_max_time", "1"}};

Options with(Options base, const Options &more) {
  base.insert(base.end(), more.begin(), more.end());
  return base;
}

struct ThetaRun {
  PetscReal J = 0;
  OwnedVec g;
};

// petsc_step: PETSc's own step (and forming of the implicit operator), else flexipde's.
PetscErrorCode gradient_once(bool petsc_step, ThetaRun &r, const char *trajectory = nullptr) {
  ScopedOptions o;
  if (petsc_step) o.set("-adjoint_petsc_step", "1");
  if (trajectory) o.set("-ts_trajectory_type", trajectory);
  flexipde_test::SceneProblem pb;
  PetscFunctionBeginUser;
  PetscCall(pb.setup(PETSC_COMM_WORLD));
  PetscCall(VecDuplicate(pb.p, r.g.out()));
  PetscCall(pb.scene.gradient(pb.p, &r.J, r.g));
  PetscFunctionReturn(0);
}

class ThetaAdjoint : public ::testing::TestWithParam<ThetaCase> {};

} // namespace

TEST_P(ThetaAdjoint, SameGradientAsPetscTheta) {
  ScopedOptions opts;
  for (auto &o : GetParam().options) opts.set(o.first, o.second);
  ThetaRun direct, petsc;
  PETSC_ASSERT_OK(gradient_once(false, direct));
  PETSC_ASSERT_OK(gradient_once(true, petsc));
  PetscPrintf(PETSC_COMM_WORLD, "  [%s] J = %.15e, |dJ/dp| = %.6e, rel diff J %.2e, gradient %.2e\n", GetParam().name,
              (double)direct.J, (double)flexipde_test::norm(direct.g), (double)rel_diff(direct.J, petsc.J),
              (double)rel_diff(direct.g, petsc.g));
  EXPECT_GT(flexipde_test::norm(petsc.g), 0.0);
  EXPECT_EQ(direct.J, petsc.J); // (also where PETSc forms and factors at every step: the same numbers)
  EXPECT_LE(rel_diff(direct.g, petsc.g), 1e-12); // endpoint forms: the parameter products paired, round-off
}

// Full storage ("store") keeps an endpoint form's solutions only and hands the adjoint U_{k-1} and U_k
// as its two stages; PETSc's memory trajectory stores the stages themselves: the same gradient.
TEST_P(ThetaAdjoint, SameGradientAsPetscMemoryTrajectory) {
  ScopedOptions opts;
  for (auto &o : GetParam().options) opts.set(o.first, o.second);
  ThetaRun store, memory;
  PETSC_ASSERT_OK(gradient_once(false, store));
  PETSC_ASSERT_OK(gradient_once(false, memory, "memory"));
  EXPECT_GT(flexipde_test::norm(memory.g), 0.0);
  EXPECT_EQ(store.J, memory.J);
  EXPECT_LE(rel_diff(store.g, memory.g), 1e-13);
}

INSTANTIATE_TEST_SUITE_P(
    Implicit, ThetaAdjoint,
    ::testing::Values(
        ThetaCase{"advection_upwind_cn", with(advection, {{"-ts_type", "cn"}, {"-advection_scheme", "upwind"}})},
        ThetaCase{"advection_fd4_D_field_cn", with(advection, {{"-ts_type", "cn"}, {"-advection_scheme", "fd4"},
                                                               {"-advection_D_field", "1"}, {"-advection_D", "0.1"},
                                                               {"-true_advection_D", "0.15"}})},
        ThetaCase{"advection_fd2_D_beuler", with(advection, {{"-ts_type", "beuler"}, {"-advection_D", "0.1"}})},
        ThetaCase{"advection_fd2_theta_midpoint", with(advection, {{"-ts_type", "theta"}, {"-ts_theta_theta", "0.6"}})},
        ThetaCase{"advection_spectral_cn", with(advection, {{"-ts_type", "cn"}, {"-advection_scheme", "spectral"}})},
        ThetaCase{"wave_cn", with(wave, {{"-ts_type", "cn"}})},
        ThetaCase{"wave_theta_endpoint",
                  with(wave, {{"-ts_type", "theta"}, {"-ts_theta_theta", "0.7"}, {"-ts_theta_endpoint", "1"}})},
        ThetaCase{"vlasov_landau_cn", with(vlasov, {{"-ts_type", "cn"}})},
        ThetaCase{"vlasov_landau_beuler", with(vlasov, {{"-ts_type", "beuler"}})},
        ThetaCase{"advection_cn_checkpointed", with(advection, {{"-ts_type", "cn"}, {"-checkpoint_budget", "4"}})}),
    flexipde_test::CaseName());
