// A structured, distributed grid: a DMDA in one, two or three dimensions (x; y for 2D and 3D models
// or the velocity of a 1D1V phase space; z), with physical bounds and per-direction boundary type.
//
// Options: -da_grid_x N, -da_grid_y M and -da_grid_z L (PETSc's own; a scene reads the options of its
// dimensions alone), -grid_x0, -grid_x1, -grid_periodic, in 2D and 3D -grid_y0, -grid_y1,
// -grid_periodic_y, and in 3D -grid_z0, -grid_z1, -grid_periodic_z.
// Dirichlet directions include both end points: x_i = x0 + i h, h = (x1-x0)/(N-1). Periodic
// directions exclude the right end: h = (x1-x0)/N. A model decides the dimension (Model::dim());
// the grid of a 1D scene has no second direction at all.
//
// Local indexing: owned points are (i, j, k) with xs <= i < xs+xm, ys <= j < ys+ym, zs <= k < zs+zm;
// a point's position in the owned block is ((k - zs) * ym + (j - ys)) * xm + (i - xs) (x fastest, as
// in a DMDA Vec). A direction the grid lacks has one point (ny = ym = 1 in 1D, nz = zm = 1 below 3D).
#pragma once
#include "flexipde/petsc.hpp"
#include <vector>

namespace flexipde {

struct GridOptions {
  PetscInt dim = 1;
  PetscInt n = 1000, ny = 1, nz = 1;
  PetscReal x0 = 0.0, x1 = 1.0, y0 = 0.0, y1 = 1.0, z0 = 0.0, z1 = 1.0;
  PetscBool periodic = PETSC_FALSE, periodic_y = PETSC_FALSE, periodic_z = PETSC_FALSE;
};

class Grid {
public:
  // Reads the options above; `stencil_width` is the ghost width the discretisation needs.
  static PetscErrorCode from_options(MPI_Comm comm, PetscInt stencil_width, const GridOptions &defaults,
                                     Grid &grid);
  static PetscErrorCode create(MPI_Comm comm, PetscInt stencil_width, const GridOptions &opts, Grid &grid);

  // A DMDA with `dof` components per point and the same parallel layout as the scalar grid; `width`
  // ghost points (default: the grid's), a star stencil if `star` (the pattern of a matrix it creates).
  PetscErrorCode create_dm(PetscInt dof, DM *dm, PetscInt width = -1, bool star = false) const;

  DM dm() const { return dm_; }  // scalar (dof = 1) grid, for parameter fields and data
  MPI_Comm comm() const { return comm_; }
  PetscInt dim() const { return opts_.dim; }
  PetscInt n() const { return opts_.n; }   // points in x
  PetscInt ny() const { return opts_.ny; } // points in y (1 in 1D)
  PetscInt nz() const { return opts_.nz; } // points in z (1 in 1D and 2D)
  PetscInt points() const { return opts_.n * opts_.ny * opts_.nz; }
  PetscReal h() const { return h_; } // spacing in x
  PetscReal hy() const { return hy_; }
  PetscReal hz() const { return hz_; }
  PetscReal x0() const { return opts_.x0; }
  PetscReal x1() const { return opts_.x1; }
  PetscReal y0() const { return opts_.y0; }
  PetscReal y1() const { return opts_.y1; }
  PetscReal z0() const { return opts_.z0; }
  PetscReal z1() const { return opts_.z1; }
  bool periodic() const { return opts_.periodic; }
  bool periodic_y() const { return opts_.periodic_y; }
  bool periodic_z() const { return opts_.periodic_z; }
  PetscInt xs() const { return xs_; }  // first owned index in x
  PetscInt xm() const { return xm_; }  // number of owned points in x
  PetscInt ys() const { return ys_; }  // first owned index in y (0 in 1D)
  PetscInt ym() const { return ym_; }  // owned points in y (1 in 1D)
  PetscInt zs() const { return zs_; }  // first owned index in z (0 below 3D)
  PetscInt zm() const { return zm_; }  // owned points in z (1 below 3D)
  PetscInt local_points() const { return xm_ * ym_ * zm_; }
  // The same by direction d (0: x, 1: y, 2: z).
  PetscInt n(int d) const { return d == 0 ? opts_.n : d == 1 ? opts_.ny : opts_.nz; }
  PetscReal h(int d) const { return d == 0 ? h_ : d == 1 ? hy_ : hz_; }
  PetscReal lower(int d) const { return d == 0 ? opts_.x0 : d == 1 ? opts_.y0 : opts_.z0; }
  PetscReal upper(int d) const { return d == 0 ? opts_.x1 : d == 1 ? opts_.y1 : opts_.z1; }
  bool periodic(int d) const { return d == 0 ? opts_.periodic : d == 1 ? opts_.periodic_y : opts_.periodic_z; }
  PetscInt start(int d) const { return d == 0 ? xs_ : d == 1 ? ys_ : zs_; }
  PetscInt owned(int d) const { return d == 0 ? xm_ : d == 1 ? ym_ : zm_; }
  PetscInt stencil_width() const { return sw_; }
  PetscReal x(PetscInt i) const { return opts_.x0 + i * h_; }
  PetscReal y(PetscInt j) const { return opts_.y0 + j * hy_; }
  PetscReal z(PetscInt k) const { return opts_.z0 + k * hz_; }
  // Cell volume of the discrete inner product (h in 1D, h hy in 2D, h hy hz in 3D).
  PetscReal cell_volume() const { return opts_.dim == 3 ? h_ * hy_ * hz_ : opts_.dim == 2 ? h_ * hy_ : h_; }
  bool is_boundary(PetscInt i) const { return !opts_.periodic && (i == 0 || i == opts_.n - 1); }
  bool is_boundary_y(PetscInt j) const { return opts_.dim >= 2 && !opts_.periodic_y && (j == 0 || j == opts_.ny - 1); }

private:
  MPI_Comm comm_ = MPI_COMM_NULL;
  GridOptions opts_;
  PetscReal h_ = 0, hy_ = 1, hz_ = 1;
  PetscInt xs_ = 0, xm_ = 0, ys_ = 0, ym_ = 1, zs_ = 0, zm_ = 1, sw_ = 1;
  OwnedDM dm_;
  std::vector<PetscInt> lx_, ly_, lz_;
};

} // namespace flexipde
