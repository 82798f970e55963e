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
#pragma once
#include "flexipde/grid.hpp"
#include <memory>
#include <string>

namespace flexipde {

class Objective {
public:
  virtual ~Objective() = default;
  // J at the final state; dJdU (state-shaped) is filled when not null.
  virtual PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) = 0;
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

// The objective chosen with -objective_type, behind one object: the Scene, the Simulation and the
// callers hold the same SelectedObjective whatever the choice. data() is the misfit's data, or
// null for an objective that needs none.
class SelectedObjective final : public Objective {
public:
  PetscErrorCode setup(const Grid &grid, PetscInt component, PetscInt dof);
  PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) override;
  Vec data() const { return misfit_ ? misfit_->data() : nullptr; }

private:
  std::unique_ptr<Objective> chosen_;
  TerminalMisfit *misfit_ = nullptr; // chosen_, when it is a misfit
};

} // namespace flexipde
