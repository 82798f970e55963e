// Misfit with a whole trajectory of data, integrated in time: for training a coarse model to follow
// reference snapshots (a fine solution averaged onto the coarse grid) rather than one final state.
//
//   J = int_0^T r(t, U) dt,    r = 0.5 w sum_i (u_i(t) - d_i(t))^2,
//
// u the chosen component of U, d(t) linear in time between the snapshots d_s given at times t_s
// (held at the first and last beyond them). dr/dU = w (u - d(t)) in that component, dr/dp = 0. The
// Simulation integrates r with the integrator's own quadrature, so the gradient is exact for the
// discrete scheme; with snapshots at every step and half step, RK4's stages read d where it was given.
#pragma once
#include "flexipde/objective.hpp"
#include <vector>

namespace flexipde {

class TrajectoryMisfit final : public Objective {
public:
  // grid_dm: the grid's one-component DM (the snapshots' layout); the state has `dof` components.
  PetscErrorCode setup(DM grid_dm, PetscInt component, PetscInt dof, PetscReal weight);
  // Appends a snapshot (copied); times must increase.
  PetscErrorCode add_snapshot(PetscReal t, Vec d);
  PetscInt snapshots() const { return (PetscInt)times_.size(); }
  // d(t) into d (grid-shaped).
  PetscErrorCode data_at(PetscReal t, Vec d) const;

  PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) override;
  bool has_integrand() const override { return true; }
  PetscErrorCode integrand(PetscReal t, Vec U, PetscReal *r) override;
  PetscErrorCode integrand_dU(PetscReal t, Vec U, Vec drdU) override;

private:
  PetscErrorCode residual(PetscReal t, Vec U); // work_ = u - d(t)
  DM dm_ = nullptr;
  PetscInt component_ = 0, dof_ = 1;
  PetscReal weight_ = 1;
  std::vector<PetscReal> times_;
  std::vector<OwnedVec> data_;
  OwnedVec work_;
};

} // namespace flexipde
