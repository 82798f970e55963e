// The seed's degenerate scene in small: a snapshot taken when the pulse sits on a wall has nearly
// equal minima at c = 0.6, 1.0 and 1.4 (see docs/fwi.md). -inv_scan must find the exact one.
#include "flexipde/inversion.hpp"
#include "test_support.hpp"

using namespace flexipde;
using flexipde_test::ScopedOptions;

TEST(InversionScan, FindsTheExactMinimumAmongNearlyEqualOnes) {
  // 201 points, dt = 2.5e-3 (RK4 at half the CFL limit), T = 2.5: the speed-1 pulse ends on a wall.
  ScopedOptions opts{{"-da_grid_x", "201"}, {"-ts_max_time", "2.5"}, {"-ts_dt", "2.5e-3"}, {"-wave_c", "0.8"},
                     {"-true_wave_c", "1.0"}, {"-inv_lower", "0.5"},  {"-inv_upper", "2"},     {"-inv_scan", "151"}};
  Scene scene;
  PETSC_ASSERT_OK(scene.setup(PETSC_COMM_WORLD));
  OwnedVec p, p_true, U;
  PETSC_ASSERT_OK(scene.params.create_vec(p.out()));
  PETSC_ASSERT_OK(scene.params.create_vec(p_true.out()));
  PETSC_ASSERT_OK(scene.parameters_from_options("", p));
  PETSC_ASSERT_OK(scene.parameters_from_options("true_", p_true));
  PETSC_ASSERT_OK(scene.make_synthetic_data(p_true));

  // The landscape really has competing minima: J at 0.6 and 1.4 is tiny compared with J at 0.8.
  PETSC_ASSERT_OK(scene.sim.create_state(U.out()));
  auto J_at = [&](PetscReal c) {
    PetscReal J = -1;
    OwnedVec q;
    if (scene.params.create_vec(q.out()) || scene.params.set_scalar(q, 0, c) || scene.sim.forward(q, U) ||
        scene.objective.terminal(U, &J, nullptr))
      return (PetscReal)-1;
    return J;
  };
  const PetscReal J08 = J_at(0.8), J06 = J_at(0.6), J14 = J_at(1.4);
  ASSERT_GT(J08, 0);
  EXPECT_LT(J06, 1e-3 * J08);
  EXPECT_LT(J14, 1e-3 * J08);

  Inversion inv;
  PETSC_ASSERT_OK(inv.setup(scene, p_true));
  PETSC_ASSERT_OK(inv.solve(p));
  PetscReal c;
  PETSC_ASSERT_OK(scene.params.scalar(p, 0, &c));
  PetscPrintf(PETSC_COMM_WORLD, "  scan start %.5f -> recovered c = %.10f; J(0.6) = %.3e, J(1.4) = %.3e, J(0.8) = %.3e\n",
              (double)inv.scan_start(), (double)c, (double)J06, (double)J14, (double)J08);
  EXPECT_NEAR(c, 1.0, 1e-4);
  EXPECT_NEAR(inv.scan_start(), 1.0, 0.02);
  EXPECT_GT((int)inv.converged_reason(), 0);
  ASSERT_FALSE(inv.history().empty());
  EXPECT_LT(inv.history().back().misfit, std::min(J06, J14));
}
