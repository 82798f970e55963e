// Objectives J(U(T)) of the final state, with their derivative with respect to the state. Each
// looks at one component u of U (-objective_component, default the first); the Scene picks one
// with -objective_type.
//
// TerminalMisfit compares u(T) (e.g. the wave's u) with data d on the grid:
//   -objective_type l2sq        :  J = 0.5 ||u(T) - d||^2        dJ/du = u - d
//   -objective_type l2          :  J = ||u(T) - d||              dJ/du = (u - d) / ||u - d||
// MeanSquare needs no data:
//   -objective_type mean_square :  J = (1/N) sum_i u_i(T)^2      dJ/du = 2 u / N
// Norms are plain sums over the N grid points (the seed's definition), not quadrature.
//
// An objective may also integrate over time, J = J_T(U(T)) + int_0^T r(t, U) dt: it then answers
// has_integrand() and provides r, dr/dU and dr/dp; the Simulation integrates r with the
// integrator's own quadrature (PETSc's quadrature TS) and TSAdjoint adds dr/dU to lambda and
// dr/dp to mu, so the gradient is exact for the discrete scheme.
//   -objective_type receivers      :  J = sum_shots 0.5 int_0^T sum_r (u(x_r,t) - d_r(t))^2 dt (survey.hpp)
//   -objective_type time_variation :  J = int_0^T ||u_t||^2 dt = int_0^T ||G(t, U; p)||^2 dt
//                                     dr/dU = 2 (dG/dU)^T G,   dr/dp = 2 (dG/dp)^T G
// (all components of U, plain sum over grid points; no terminal part).
#pragma once
#include "flexipde/grid.hpp"
#include "flexipde/model.hpp"
#include <memory>
#include <string>

namespace flexipde {

class Objective {
public:
  virtual ~Objective() = default;
  // J at the final state; dJdU (state-shaped) is filled when not null.
  virtual PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) = 0;

  // The integrand r(t, U; p). The parameters are those the model was last given (the Simulation
  // sets them before each solve), so p is not passed again. r is collective and the same on every
  // rank. drdU is state-shaped, drdp parameter-shaped; both are overwritten.
  virtual bool has_integrand() const { return false; }
  virtual PetscErrorCode integrand(PetscReal t, Vec U, PetscReal *r) {
    (void)t, (void)U;
    *r = 0;
    return 0;
  }
  virtual PetscErrorCode integrand_dU(PetscReal t, Vec U, Vec drdU) {
    (void)t, (void)U;
    return VecSet(drdU, 0.0);
  }
  virtual PetscErrorCode integrand_dp(PetscReal t, Vec U, Vec drdp) {
    (void)t, (void)U;
    return VecSet(drdp, 0.0);
  }
  // What r reads: component c of the state (else dr/dU is 0 in it), the parameters (else dr/dp = 0).
  // The leapfrog's adjoint applies the two half-kicks of a time level in one sweep when r reads no
  // velocity, and skips dr/dp when r reads no parameter.
  virtual bool integrand_reads_component(PetscInt c) const {
    (void)c;
    return true;
  }
  virtual bool integrand_reads_parameters() const { return true; }
  // Optional, for an integrand whose dr/dU is sparse (the receivers): lambda += w dr/dU(t, U) in place,
  // without a state-sized dr/dU. U is a state or, for an integrand that reads no velocity, the positions
  // alone (m per grid point, as the leapfrog's adjoint stores them); such an objective's integrand()
  // takes the positions alone too (the leapfrog's split steps hand it them). lambda is shaped as a state
  // or, for such an integrand, as the positions (the leapfrog's adjoint keeps lambda_q apart).
  virtual bool adds_integrand_dU() const { return false; }
  virtual PetscErrorCode integrand_dU_add(PetscReal t, Vec U, PetscReal w, Vec lambda) {
    (void)t, (void)U, (void)w;
    SETERRQ(PetscObjectComm((PetscObject)lambda), PETSC_ERR_SUP, "This objective has no integrand_dU_add");
  }
};

class TerminalMisfit final : public Objective {
public:
  enum class Kind { L2Squared, L2 };
  PetscErrorCode setup(const Grid &grid, PetscInt component, PetscInt dof);
  void set_kind(Kind k) { kind_ = k; }
  Vec data() const { return data_; } // grid-shaped (dof 1); fill it before use
  PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) override;

private:
  Kind kind_ = Kind::L2Squared;
  PetscInt component_ = 0, dof_ = 1;
  OwnedVec data_, work_;
};

class MeanSquare final : public Objective {
public:
  PetscErrorCode setup(const Grid &grid, PetscInt component, PetscInt dof);
  PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) override;

private:
  PetscInt component_ = 0, dof_ = 1, n_ = 1;
  OwnedVec work_;
};

// J = int_0^T ||G(t, U; p)||^2 dt, the time variation of the solution (u_t = G). Needs the model
// for G, dG/dU and dG/dp; owns its own copies of those matrices, because an implicit TS shifts
// the Simulation's.
class TimeVariation final : public Objective {
public:
  PetscErrorCode setup(Model &model, DM state_dm, bool with_parameters);
  PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) override;
  bool has_integrand() const override { return true; }
  PetscErrorCode integrand(PetscReal t, Vec U, PetscReal *r) override;
  PetscErrorCode integrand_dU(PetscReal t, Vec U, Vec drdU) override;
  PetscErrorCode integrand_dp(PetscReal t, Vec U, Vec drdp) override;

private:
  Model *model_ = nullptr;
  OwnedVec G_;
  OwnedMat J_, Jp_;
};

// The objective chosen with -objective_type, behind one object: the Scene, the Simulation and the
// callers hold the same SelectedObjective whatever the choice. data() is the misfit's data, or
// null for an objective that needs none.
class Survey; // survey.hpp: -objective_type receivers

class SelectedObjective final : public Objective {
public:
  // model and state_dm are needed by time_variation only.
  PetscErrorCode setup(const Grid &grid, PetscInt component, PetscInt dof, Model *model = nullptr,
                       DM state_dm = nullptr, bool with_parameters = false);
  PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) override;
  bool has_integrand() const override { return chosen_ && chosen_->has_integrand(); }
  PetscErrorCode integrand(PetscReal t, Vec U, PetscReal *r) override { return chosen_->integrand(t, U, r); }
  PetscErrorCode integrand_dU(PetscReal t, Vec U, Vec drdU) override { return chosen_->integrand_dU(t, U, drdU); }
  PetscErrorCode integrand_dp(PetscReal t, Vec U, Vec drdp) override { return chosen_->integrand_dp(t, U, drdp); }
  bool integrand_reads_component(PetscInt c) const override { return chosen_->integrand_reads_component(c); }
  bool integrand_reads_parameters() const override { return chosen_->integrand_reads_parameters(); }
  bool adds_integrand_dU() const override { return chosen_->adds_integrand_dU(); }
  PetscErrorCode integrand_dU_add(PetscReal t, Vec U, PetscReal w, Vec lambda) override {
    return chosen_->integrand_dU_add(t, U, w, lambda);
  }
  Vec data() const { return misfit_ ? misfit_->data() : nullptr; }
  // The survey (sources, receivers, traces) of -objective_type receivers, else null.
  Survey *survey() const { return survey_; }

private:
  Survey *survey_ = nullptr; // chosen_, when it is the receiver misfit
  std::unique_ptr<Objective> chosen_;
  TerminalMisfit *misfit_ = nullptr; // chosen_, when it is a misfit
};

} // namespace flexipde
