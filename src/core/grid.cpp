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
  if (o.dim >= 2) {
    PetscCall(PetscOptionsInt("-da_grid_y", "Number of grid points in y", "Grid", o.ny, &o.ny, nullptr));
    PetscCall(PetscOptionsReal("-grid_y0", "Lower end of the domain in y", "Grid", o.y0, &o.y0, nullptr));
    PetscCall(PetscOptionsReal("-grid_y1", "Upper end of the domain in y", "Grid", o.y1, &o.y1, nullptr));
    PetscCall(PetscOptionsBool("-grid_periodic_y", "Periodic in y (else Dirichlet at both ends)", "Grid", o.periodic_y,
                               &o.periodic_y, nullptr));
  }
  if (o.dim == 3) {
    PetscCall(PetscOptionsInt("-da_grid_z", "Number of grid points in z", "Grid", o.nz, &o.nz, nullptr));
    PetscCall(PetscOptionsReal("-grid_z0", "Lower end of the domain in z", "Grid", o.z0, &o.z0, nullptr));
    PetscCall(PetscOptionsReal("-grid_z1", "Upper end of the domain in z", "Grid", o.z1, &o.z1, nullptr));
    PetscCall(PetscOptionsBool("-grid_periodic_z", "Periodic in z (else Dirichlet at both ends)", "Grid", o.periodic_z,
                               &o.periodic_z, nullptr));
  }
  PetscOptionsEnd();
  PetscCall(create(comm, stencil_width, o, grid));
  PetscFunctionReturn(0);
}

PetscErrorCode Grid::create(MPI_Comm comm, PetscInt stencil_width, const GridOptions &o_in, Grid &grid) {
  PetscMPIInt size;
  GridOptions o = o_in;
  static const char *axis[] = {"x", "y", "z"};
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCheck(o.dim >= 1 && o.dim <= 3, comm, PETSC_ERR_ARG_OUTOFRANGE, "Grid: dimension %" PetscInt_FMT " is not 1, 2 or 3",
             o.dim);
  if (o.dim < 2) o.ny = 1, o.periodic_y = PETSC_FALSE;
  if (o.dim < 3) o.nz = 1, o.periodic_z = PETSC_FALSE;
  grid.comm_ = comm;
  grid.opts_ = o;
  grid.sw_ = stencil_width;
  for (int d = 0; d < o.dim; ++d) {
    const PetscInt n = grid.n(d);
    const PetscReal lo = grid.lower(d), hi = grid.upper(d);
    PetscCheck(hi > lo, comm, PETSC_ERR_ARG_OUTOFRANGE, "Grid: -grid_%s1 (%g) must exceed -grid_%s0 (%g)", axis[d], (double)hi,
               axis[d], (double)lo);
    PetscCheck(n >= 2 * stencil_width + 3, comm, PETSC_ERR_ARG_OUTOFRANGE,
               "Grid: -da_grid_%s %" PetscInt_FMT " is too small for a stencil of half-width %" PetscInt_FMT
               " (need at least %" PetscInt_FMT ")",
               axis[d], n, stencil_width, 2 * stencil_width + 3);
    const PetscReal h = grid.periodic(d) ? (hi - lo) / n : (hi - lo) / (n - 1);
    (d == 0 ? grid.h_ : d == 1 ? grid.hy_ : grid.hz_) = h;
  }
  const DMBoundaryType bx = o.periodic ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
  const DMBoundaryType by = o.periodic_y ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
  const DMBoundaryType bz = o.periodic_z ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
  if (o.dim == 1) {
    PetscCheck(o.n / size >= stencil_width, comm, PETSC_ERR_ARG_OUTOFRANGE,
               "Grid: %" PetscInt_FMT " points on %d ranks leaves fewer points per rank than the stencil half-width %" PetscInt_FMT,
               o.n, (int)size, stencil_width);
    PetscCall(DMDACreate1d(comm, bx, o.n, 1, stencil_width, nullptr, grid.dm_.out()));
  } else if (o.dim == 2)
    PetscCall(DMDACreate2d(comm, bx, by, DMDA_STENCIL_BOX, o.n, o.ny, PETSC_DECIDE, PETSC_DECIDE, 1, stencil_width,
                           nullptr, nullptr, grid.dm_.out()));
  else
    PetscCall(DMDACreate3d(comm, bx, by, bz, DMDA_STENCIL_BOX, o.n, o.ny, o.nz, PETSC_DECIDE, PETSC_DECIDE, PETSC_DECIDE, 1,
                           stencil_width, nullptr, nullptr, nullptr, grid.dm_.out()));
  PetscCall(DMSetUp(grid.dm_));
  PetscInt procs[3] = {size, 1, 1};
  if (o.dim > 1) {
    PetscCall(DMDAGetInfo(grid.dm_, nullptr, nullptr, nullptr, nullptr, &procs[0], &procs[1], &procs[2], nullptr, nullptr,
                          nullptr, nullptr, nullptr, nullptr));
    bool fits = true;
    for (int d = 0; d < o.dim; ++d) fits = fits && grid.n(d) / procs[d] >= stencil_width;
    PetscCheck(fits, comm, PETSC_ERR_ARG_OUTOFRANGE,
               "Grid: %" PetscInt_FMT " x %" PetscInt_FMT " x %" PetscInt_FMT " points on %d x %d x %d ranks leaves fewer "
               "points per rank than the stencil half-width %" PetscInt_FMT,
               o.n, o.ny, o.nz, (int)procs[0], (int)procs[1], (int)procs[2], stencil_width);
  }
  PetscCall(DMDASetUniformCoordinates(grid.dm_, o.x0, o.periodic ? o.x1 - grid.h_ : o.x1, o.y0,
                                      o.periodic_y ? o.y1 - grid.hy_ : o.y1, o.z0, o.periodic_z ? o.z1 - grid.hz_ : o.z1));
  PetscCall(DMDAGetCorners(grid.dm_, &grid.xs_, &grid.ys_, &grid.zs_, &grid.xm_, &grid.ym_, &grid.zm_));
  if (o.dim < 2) grid.ys_ = 0, grid.ym_ = 1;
  if (o.dim < 3) grid.zs_ = 0, grid.zm_ = 1;
  const PetscInt *lx, *ly, *lz;
  PetscCall(DMDAGetOwnershipRanges(grid.dm_, &lx, o.dim >= 2 ? &ly : nullptr, o.dim == 3 ? &lz : nullptr));
  grid.lx_.assign(lx, lx + procs[0]);
  if (o.dim >= 2) grid.ly_.assign(ly, ly + procs[1]);
  if (o.dim == 3) grid.lz_.assign(lz, lz + procs[2]);
  PetscFunctionReturn(0);
}

PetscErrorCode Grid::create_dm(PetscInt dof, DM *dm, PetscInt width, bool star) const {
  const PetscInt sw = width < 0 ? sw_ : width;
  const DMBoundaryType bx = opts_.periodic ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
  const DMBoundaryType by = opts_.periodic_y ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
  const DMBoundaryType bz = opts_.periodic_z ? DM_BOUNDARY_PERIODIC : DM_BOUNDARY_GHOSTED;
  const DMDAStencilType st = star ? DMDA_STENCIL_STAR : DMDA_STENCIL_BOX;
  PetscFunctionBeginUser;
  if (opts_.dim == 1) PetscCall(DMDACreate1d(comm_, bx, opts_.n, dof, sw, lx_.data(), dm));
  else if (opts_.dim == 2)
    PetscCall(DMDACreate2d(comm_, bx, by, st, opts_.n, opts_.ny, (PetscInt)lx_.size(), (PetscInt)ly_.size(), dof, sw,
                           lx_.data(), ly_.data(), dm));
  else
    PetscCall(DMDACreate3d(comm_, bx, by, bz, st, opts_.n, opts_.ny, opts_.nz, (PetscInt)lx_.size(), (PetscInt)ly_.size(),
                           (PetscInt)lz_.size(), dof, sw, lx_.data(), ly_.data(), lz_.data(), dm));
  PetscCall(DMSetUp(*dm));
  PetscCall(DMDASetUniformCoordinates(*dm, opts_.x0, opts_.periodic ? opts_.x1 - h_ : opts_.x1, opts_.y0,
                                      opts_.periodic_y ? opts_.y1 - hy_ : opts_.y1, opts_.z0,
                                      opts_.periodic_z ? opts_.z1 - hz_ : opts_.z1));
  PetscFunctionReturn(0);
}

} // namespace flexipde
