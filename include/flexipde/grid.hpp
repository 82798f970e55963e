// A structured, distributed grid: a DMDA in one dimension (two for phase space and 2D models
// later), with physical bounds and per-direction boundary type.
//
// Options (prefix -grid_): -da_grid_x N (PETSc's own), -grid_x0, -grid_x1, -grid_periodic.
// Dirichlet grids include both end points: x_i = x0 + i h, h = (x1-x0)/(N-1). Periodic grids
// exclude the right end: h = (x1-x0)/N.
#pragma once
#include "flexipde/petsc.hpp"
#include <vector>

namespace flexipde {

struct GridOptions {
  PetscInt n = 1000;
  PetscReal x0 = 0.0, x1 = 1.0;
  PetscBool periodic = PETSC_FALSE;
};

class Grid {
public:
  // Reads the options above; `stencil_width` is the ghost width the discretisation needs.
  static PetscErrorCode from_options(MPI_Comm comm, PetscInt stencil_width, const GridOptions &defaults,
                                     Grid &grid);
  static PetscErrorCode create(MPI_Comm comm, PetscInt stencil_width, const GridOptions &opts, Grid &grid);

  // A DMDA with `dof` components per point and the same parallel layout as the scalar grid.
  PetscErrorCode create_dm(PetscInt dof, DM *dm) const;

  DM dm() const { return dm_; }  // scalar (dof = 1) grid, for parameter fields and data
  MPI_Comm comm() const { return comm_; }
  PetscInt n() const { return opts_.n; }
  PetscReal h() const { return h_; }
  PetscReal x0() const { return opts_.x0; }
  PetscReal x1() const { return opts_.x1; }
  bool periodic() const { return opts_.periodic; }
  PetscInt xs() const { return xs_; }  // first owned index
  PetscInt xm() const { return xm_; }  // number of owned points
  PetscInt stencil_width() const { return sw_; }
  PetscReal x(PetscInt i) const { return opts_.x0 + i * h_; }
  bool is_boundary(PetscInt i) const { return !opts_.periodic && (i == 0 || i == opts_.n - 1); }

private:
  MPI_Comm comm_ = MPI_COMM_NULL;
  GridOptions opts_;
  PetscReal h_ = 0;
  PetscInt xs_ = 0, xm_ = 0, sw_ = 1;
  OwnedDM dm_;
  std::vector<PetscInt> lx_;
};

} // namespace flexipde
