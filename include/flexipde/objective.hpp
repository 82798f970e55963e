// Objectives J(U(T)) of the final state, with their derivative with respect to the state.
//
// TerminalMisfit compares one component of U(T) (e.g. the wave's u) with data d on the grid:
//   -objective_type l2sq :  J = 0.5 ||u(T) - d||^2        dJ/du = u - d
//   -objective_type l2   :  J = ||u(T) - d||              dJ/du = (u - d) / ||u - d||
// Norms are plain Euclidean sums over grid points (the seed's definition), not quadrature.
#pragma once
#include "flexipde/grid.hpp"
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
  PetscErrorCode set_kind_from_options(MPI_Comm comm);
  void set_kind(Kind k) { kind_ = k; }
  Vec data() const { return data_; } // grid-shaped (dof 1); fill it before use
  PetscErrorCode terminal(Vec UT, PetscReal *J, Vec dJdU) override;

private:
  Kind kind_ = Kind::L2Squared;
  PetscInt component_ = 0, dof_ = 1;
  OwnedVec data_, work_;
};

} // namespace flexipde
