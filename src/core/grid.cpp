#include "flexipde/grid.hpp"

namespace flexipde {

PetscErrorCode Grid::from_options(MPI_Comm comm, PetscInt stencil_width, const GridOptions &defaults, Grid &grid) {
  GridOptions o = defaults;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, nullptr, "Grid options", "Grid");
  PetscCall(PetscOptionsInt("-da_grid_x", "Number of grid points", "Grid", o.n, &o.n, nullptr));
  PetscCall(PetscOptionsReal("-grid_x0", "Left end of the domain", "Grid", o.x0, &o.x0, nullptr));
  PetscCall(PetscOptionsReal("-grid_x1", "Right end of the domain", "Grid", o.x1, &o.x1, nullptr));
  PetscCall(PetscOptionsBool("-grid_periodic", "Periodic domain (else Dirichlet u = 0 at both ends)", "Grid",
                             o.periodic, &o.periodic, nullptr));
  PetscOptionsEnd();
  PetscCall(create(comm, stencil_width, o, grid));
  PetscFunctionReturn(0);
}

PetscErrorCode Grid::create(MPI_Comm comm, PetscInt stencil_width, const GridOptions &o, Grid &grid) {
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCheck(o.x1 > o.x0, comm, PETSC_ERR_ARG_OUTOFRANGE, "Grid: -grid_x1 (%g) must exceed -grid_x0 (%g)",
             (double)o.x1, (double)o.x0);
  PetscCheck(o.n >= 2 * stencil_width + 3, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "Grid: -da_grid_x %" PetscInt_FMT " is too small for a stencil of half-width %" PetscInt_FMT
             " (need at least %" PetscInt_FMT ")",
             o.n, stencil_width, 2 * stencil_width + 3);
  PetscCheck(o.n / size >= stencil_width, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "Grid: %" PetscInt_FMT " points on %d ranks leaves fewer points per rank than the stencil half-width %" PetscInt_FMT,
             o.n, (int)size, stencil_width);
  grid.comm_ = comm;
  grid.opts_ = o;
  grid.sw_ = stencil_width;
  grid.h_ = o.periodic ? (o.x1 - o.x0) / o.n : (o.x1 - o.x0) / (o.n - 1);
  PetscCall(DMDACreate1d(comm, o.periodic ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED, o.n, 1, stencil_width,
                         nullptr, grid.dm_.out()));
  PetscCall(DMSetUp(grid.dm_));
  PetscCall(DMDASetUniformCoordinates(grid.dm_, o.x0, o.periodic ? o.x1 - grid.h_ : o.x1, 0, 0, 0, 0));
  PetscCall(DMDAGetCorners(grid.dm_, &grid.xs_, nullptr, nullptr, &grid.xm_, nullptr, nullptr));
  const PetscInt *lx;
  PetscCall(DMDAGetOwnershipRanges(grid.dm_, &lx, nullptr, nullptr));
  grid.lx_.assign(lx, lx + size);
  PetscFunctionReturn(0);
}

PetscErrorCode Grid::create_dm(PetscInt dof, DM *dm) const {
  PetscFunctionBeginUser;
  PetscCall(DMDACreate1d(comm_, opts_.periodic ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED, opts_.n, dof, sw_,
                         lx_.data(), dm));
  PetscCall(DMSetUp(*dm));
  PetscCall(DMDASetUniformCoordinates(*dm, opts_.x0, opts_.periodic ? opts_.x1 - h_ : opts_.x1, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

} // namespace flexipde
