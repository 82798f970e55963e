#include "flexipde/grid.hpp"

namespace flexipde {

PetscErrorCode Grid::from_options(MPI_Comm comm, PetscInt stencil_width, const GridOptions &defaults, Grid &grid) {
  GridOptions o = defaults;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, nullptr, "Grid options", "Grid");
  PetscCall(PetscOptionsInt("-da_grid_x", "Number of grid points in x", "Grid", o.n, &o.n, nullptr));
  PetscCall(PetscOptionsReal("-grid_x0", "Left end of the domain in x", "Grid", o.x0, &o.x0, nullptr));
  PetscCall(PetscOptionsReal("-grid_x1", "Right end of the domain in x", "Grid", o.x1, &o.x1, nullptr));
  PetscCall(PetscOptionsBool("-grid_periodic", "Periodic in x (else Dirichlet u = 0 at both ends)", "Grid", o.periodic,
                             &o.periodic, nullptr));
  if (o.dim == 2) {
    PetscCall(PetscOptionsInt("-da_grid_y", "Number of grid points in y", "Grid", o.ny, &o.ny, nullptr));
    PetscCall(PetscOptionsReal("-grid_y0", "Lower end of the domain in y", "Grid", o.y0, &o.y0, nullptr));
    PetscCall(PetscOptionsReal("-grid_y1", "Upper end of the domain in y", "Grid", o.y1, &o.y1, nullptr));
    PetscCall(PetscOptionsBool("-grid_periodic_y", "Periodic in y (else Dirichlet at both ends)", "Grid", o.periodic_y,
                               &o.periodic_y, nullptr));
  }
  PetscOptionsEnd();
  PetscCall(create(comm, stencil_width, o, grid));
  PetscFunctionReturn(0);
}

PetscErrorCode Grid::create(MPI_Comm comm, PetscInt stencil_width, const GridOptions &o_in, Grid &grid) {
  PetscMPIInt size;
  GridOptions o = o_in;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCheck(o.dim == 1 || o.dim == 2, comm, PETSC_ERR_ARG_OUTOFRANGE, "Grid: dimension %" PetscInt_FMT " is not 1 or 2",
             o.dim);
  if (o.dim == 1) {
    o.ny = 1;
    o.periodic_y = PETSC_FALSE;
  }
  PetscCheck(o.x1 > o.x0, comm, PETSC_ERR_ARG_OUTOFRANGE, "Grid: -grid_x1 (%g) must exceed -grid_x0 (%g)",
             (double)o.x1, (double)o.x0);
  PetscCheck(o.n >= 2 * stencil_width + 3, comm, PETSC_ERR_ARG_OUTOFRANGE,
             "Grid: -da_grid_x %" PetscInt_FMT " is too small for a stencil of half-width %" PetscInt_FMT
             " (need at least %" PetscInt_FMT ")",
             o.n, stencil_width, 2 * stencil_width + 3);
  if (o.dim == 2) {
    PetscCheck(o.y1 > o.y0, comm, PETSC_ERR_ARG_OUTOFRANGE, "Grid: -grid_y1 (%g) must exceed -grid_y0 (%g)",
               (double)o.y1, (double)o.y0);
    PetscCheck(o.ny >= 2 * stencil_width + 3, comm, PETSC_ERR_ARG_OUTOFRANGE,
               "Grid: -da_grid_y %" PetscInt_FMT " is too small for a stencil of half-width %" PetscInt_FMT
               " (need at least %" PetscInt_FMT ")",
               o.ny, stencil_width, 2 * stencil_width + 3);
  }
  grid.comm_ = comm;
  grid.opts_ = o;
  grid.sw_ = stencil_width;
  grid.h_ = o.periodic ? (o.x1 - o.x0) / o.n : (o.x1 - o.x0) / (o.n - 1);
  const DMBoundaryType bx = o.periodic ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
  if (o.dim == 1) {
    PetscCheck(o.n / size >= stencil_width, comm, PETSC_ERR_ARG_OUTOFRANGE,
               "Grid: %" PetscInt_FMT " points on %d ranks leaves fewer points per rank than the stencil half-width %" PetscInt_FMT,
               o.n, (int)size, stencil_width);
    PetscCall(DMDACreate1d(comm, bx, o.n, 1, stencil_width, nullptr, grid.dm_.out()));
    PetscCall(DMSetUp(grid.dm_));
    PetscCall(DMDASetUniformCoordinates(grid.dm_, o.x0, o.periodic ? o.x1 - grid.h_ : o.x1, 0, 0, 0, 0));
  } else {
    grid.hy_ = o.periodic_y ? (o.y1 - o.y0) / o.ny : (o.y1 - o.y0) / (o.ny - 1);
    const DMBoundaryType by = o.periodic_y ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
    PetscCall(DMDACreate2d(comm, bx, by, DMDA_STENCIL_BOX, o.n, o.ny, PETSC_DECIDE, PETSC_DECIDE, 1, stencil_width,
                           nullptr, nullptr, grid.dm_.out()));
    PetscCall(DMSetUp(grid.dm_));
    PetscInt px, py;
    PetscCall(DMDAGetInfo(grid.dm_, nullptr, nullptr, nullptr, nullptr, &px, &py, nullptr, nullptr, nullptr, nullptr,
                          nullptr, nullptr, nullptr));
    PetscCheck(o.n / px >= stencil_width && o.ny / py >= stencil_width, comm, PETSC_ERR_ARG_OUTOFRANGE,
               "Grid: %" PetscInt_FMT " x %" PetscInt_FMT " points on %d x %d ranks leaves fewer points per rank than the "
               "stencil half-width %" PetscInt_FMT,
               o.n, o.ny, (int)px, (int)py, stencil_width);
    PetscCall(DMDASetUniformCoordinates(grid.dm_, o.x0, o.periodic ? o.x1 - grid.h_ : o.x1, o.y0,
                                        o.periodic_y ? o.y1 - grid.hy_ : o.y1, 0, 0));
  }
  PetscCall(DMDAGetCorners(grid.dm_, &grid.xs_, &grid.ys_, nullptr, &grid.xm_, &grid.ym_, nullptr));
  if (o.dim == 1) {
    grid.ys_ = 0;
    grid.ym_ = 1;
  }
  const PetscInt *lx, *ly;
  PetscInt px = size, py = 1;
  if (o.dim == 2)
    PetscCall(DMDAGetInfo(grid.dm_, nullptr, nullptr, nullptr, nullptr, &px, &py, nullptr, nullptr, nullptr, nullptr,
                          nullptr, nullptr, nullptr));
  PetscCall(DMDAGetOwnershipRanges(grid.dm_, &lx, o.dim == 2 ? &ly : nullptr, nullptr));
  grid.lx_.assign(lx, lx + px);
  if (o.dim == 2) grid.ly_.assign(ly, ly + py);
  PetscFunctionReturn(0);
}

PetscErrorCode Grid::create_dm(PetscInt dof, DM *dm, PetscInt width, bool star) const {
  const PetscInt sw = width < 0 ? sw_ : width;
  const DMBoundaryType bx = opts_.periodic ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
  PetscFunctionBeginUser;
  if (opts_.dim == 1) {
    PetscCall(DMDACreate1d(comm_, bx, opts_.n, dof, sw, lx_.data(), dm));
    PetscCall(DMSetUp(*dm));
    PetscCall(DMDASetUniformCoordinates(*dm, opts_.x0, opts_.periodic ? opts_.x1 - h_ : opts_.x1, 0, 0, 0, 0));
  } else {
    const DMBoundaryType by = opts_.periodic_y ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
    PetscCall(DMDACreate2d(comm_, bx, by, star ? DMDA_STENCIL_STAR : DMDA_STENCIL_BOX, opts_.n, opts_.ny,
                           (PetscInt)lx_.size(), (PetscInt)ly_.size(), dof, sw, lx_.data(), ly_.data(), dm));
    PetscCall(DMSetUp(*dm));
    PetscCall(DMDASetUniformCoordinates(*dm, opts_.x0, opts_.periodic ? opts_.x1 - h_ : opts_.x1, opts_.y0,
                                        opts_.periodic_y ? opts_.y1 - hy_ : opts_.y1, 0, 0));
  }
  PetscFunctionReturn(0);
}

} // namespace flexipde
