// GhostExchange (include/flexipde/halo.hpp) against DMGlobalToLocal: the same value at every ghost
// position that has a source (a star stencil's corners aside), nothing written on the owned block or
// beyond a wall, on 1D and 2D DMDAs, periodic and walled, star and box stencils, one and two
// components. On one rank every ghost of a periodic direction is a copy within the rank; on two ranks
// some travel and (2D, periodic along the undivided direction) some do not.
// Run them with:   build/tests/unit_tests --gtest_filter='GhostExchange*'
#include "flexipde/halo.hpp"
#include "test_support.hpp"

using namespace flexipde;

namespace {

struct Layout {
  int dim;
  DMBoundaryType bx, by;
  DMDAStencilType stencil;
  PetscInt nx, ny, dof, width;
};

// Local entries of `dm` that differ between the exchange and DMGlobalToLocal (summed over the ranks),
// and the number of ghost entries the exchange filled on this rank (*filled).
PetscErrorCode count_differences(const Layout &l, PetscInt *differences, PetscInt *filled) {
  OwnedDM dm;
  OwnedVec g, expected, got;
  const PetscScalar unset = -7.0; // what no fill writes
  PetscFunctionBeginUser;
  if (l.dim == 1) PetscCall(DMDACreate1d(PETSC_COMM_WORLD, l.bx, l.nx, l.dof, l.width, nullptr, dm.out()));
  else
    PetscCall(DMDACreate2d(PETSC_COMM_WORLD, l.bx, l.by, l.stencil, l.nx, l.ny, PETSC_DECIDE, PETSC_DECIDE, l.dof,
                           l.width, nullptr, nullptr, dm.out()));
  PetscCall(DMSetUp(dm));
  PetscCall(DMCreateGlobalVector(dm, g.out()));
  PetscCall(DMCreateLocalVector(dm, expected.out()));
  PetscCall(DMCreateLocalVector(dm, got.out()));
  PetscInt rstart, n;
  PetscCall(VecGetOwnershipRange(g, &rstart, nullptr));
  PetscCall(VecGetLocalSize(g, &n));
  {
    Array a(g);
    PetscCall(a.error());
    for (PetscInt k = 0; k < n; ++k) a.data()[k] = 1.0 + 0.5 * (rstart + k); // distinct values
  }
  // expected: DMGlobalToLocal's values at the ghosts, `unset` on the owned block and where it writes nothing
  PetscCall(VecSet(expected, unset));
  PetscCall(DMGlobalToLocal(dm, g, INSERT_VALUES, expected));
  PetscInt xs, ys, xm, ym, gxs, gys, gxm, gym;
  PetscCall(DMDAGetCorners(dm, &xs, &ys, nullptr, &xm, &ym, nullptr));
  PetscCall(DMDAGetGhostCorners(dm, &gxs, &gys, nullptr, &gxm, &gym, nullptr));
  {
    Array e(expected);
    PetscCall(e.error());
    for (PetscInt j = ys; j < ys + ym; ++j)
      for (PetscInt i = xs; i < xs + xm; ++i)
        for (PetscInt c = 0; c < l.dof; ++c) e.data()[(((j - gys) * gxm) + i - gxs) * l.dof + c] = unset;
  }
  GhostExchange ex;
  PetscCall(ex.create(dm));
  PetscCall(VecSet(got, unset));
  PetscCall(ex.begin(g, got));
  {
    ConstArray o(g);
    Array a(got);
    PetscCall(o.error());
    PetscCall(a.error());
    ex.copy_own(o.data(), a.data());
  }
  PetscCall(ex.end(g, got));
  PetscInt local, diff = 0, fill = 0;
  PetscCall(VecGetLocalSize(got, &local));
  {
    ConstArray e(expected), a(got);
    PetscCall(e.error());
    PetscCall(a.error());
    for (PetscInt k = 0; k < local; ++k) {
      // a star stencil's DMGlobalToLocal leaves the corners of the ghosted box; the exchange may fill them
      const PetscInt i = gxs + (k / l.dof) % gxm, j = gys + (k / l.dof) / gxm;
      const bool corner = (i < xs || i >= xs + xm) && (j < ys || j >= ys + ym);
      if (!(l.stencil == DMDA_STENCIL_STAR && l.dim == 2 && corner) && a.data()[k] != e.data()[k]) ++diff;
      if (a.data()[k] != unset) ++fill;
    }
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &diff, 1, MPIU_INT, MPI_SUM, PETSC_COMM_WORLD));
  *differences = diff, *filled = fill;
  PetscFunctionReturn(0);
}

} // namespace

TEST(GhostExchange, SameGhostsAsGlobalToLocal) {
  const DMBoundaryType P = DM_BOUNDARY_PERIODIC, W = DM_BOUNDARY_GHOSTED;
  const Layout layouts[] = {
      {1, P, P, DMDA_STENCIL_STAR, 32, 1, 1, 2},   {1, P, P, DMDA_STENCIL_STAR, 32, 1, 2, 4},
      {1, W, W, DMDA_STENCIL_STAR, 32, 1, 1, 3},   {2, P, P, DMDA_STENCIL_BOX, 12, 10, 1, 2},
      {2, P, W, DMDA_STENCIL_STAR, 12, 16, 2, 4},  {2, W, P, DMDA_STENCIL_BOX, 16, 12, 1, 1},
      {2, W, W, DMDA_STENCIL_STAR, 12, 12, 1, 2},
  };
  int size;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  for (const Layout &l : layouts) {
    PetscInt differences = -1, filled = 0;
    PETSC_ASSERT_OK(count_differences(l, &differences, &filled));
    EXPECT_EQ(differences, 0) << "dim " << l.dim << " dof " << l.dof << " width " << l.width << " periodic "
                              << (l.bx == P) << (l.by == P);
    // a periodic direction has ghosts to fill on every rank (walls alone on one rank: none)
    if (l.bx == P || (l.dim == 2 && l.by == P)) EXPECT_GT(filled, 0);
    if (size == 1 && l.bx == W && (l.dim == 1 || l.by == W)) EXPECT_EQ(filled, 0);
  }
}
