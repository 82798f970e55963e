// Halo: the ghost values of one component of a DMDA Vec, and, packed, of several arrays in one
// exchange. On whatever number of ranks the suite runs (1, 2; also checked by hand on 3 and 4), every
// ghost a rank reads must be the value its owner holds at that point: here a value that encodes the
// point's global coordinates (and the field), so a ghost taken from the wrong point, rank, strip or
// field shows. 1D and 2D, periodic and walled (beyond a wall a ghost reads 0), widths 1 and 2.
#include "flexipde/grid.hpp"
#include "flexipde/halo.hpp"
#include "test_support.hpp"

using namespace flexipde;

namespace {

PetscReal code(PetscInt i, PetscInt j, PetscInt f) { return 1 + i + 1000.0 * j + 1e6 * f; }

void check(PetscInt dim, bool periodic, PetscInt width) {
  SCOPED_TRACE("dim " + std::to_string(dim) + (periodic ? ", periodic" : ", walls") + ", width " + std::to_string(width));
  GridOptions o;
  o.dim = dim;
  o.n = 13;
  o.ny = dim == 2 ? 9 : 1;
  o.periodic = o.periodic_y = periodic ? PETSC_TRUE : PETSC_FALSE;
  Grid g;
  PETSC_ASSERT_OK(Grid::create(PETSC_COMM_WORLD, width, o, g));
  const PetscInt xm = g.xm(), ym = g.ym(), n = g.n(), ny = g.ny();
  // Two fields over the owned block, with different layouts: f = 0 plain rows, f = 1 interleaved
  // (stride 2 along x, rows padded by 3).
  std::vector<PetscScalar> a0(xm * ym), a1((2 * xm + 3) * ym);
  for (PetscInt jl = 0; jl < ym; ++jl)
    for (PetscInt il = 0; il < xm; ++il) {
      a0[jl * xm + il] = code(g.xs() + il, g.ys() + jl, 0);
      a1[jl * (2 * xm + 3) + 2 * il] = code(g.xs() + il, g.ys() + jl, 1);
    }
  Halo packed, single;
  PETSC_ASSERT_OK(packed.setup_packed(g, width, 2));
  PETSC_ASSERT_OK(single.setup(g, g.dm(), 0, width));
  const Halo::Strided f[2] = {{a0.data(), 1, xm}, {a1.data(), 2, 2 * xm + 3}};
  PETSC_ASSERT_OK(packed.begin(f));
  PETSC_ASSERT_OK(packed.end());
  OwnedVec X;
  PETSC_ASSERT_OK(DMCreateGlobalVector(g.dm(), X.out()));
  {
    PetscScalar *x;
    PETSC_ASSERT_OK(VecGetArray(X, &x));
    std::copy(a0.begin(), a0.end(), x);
    PETSC_ASSERT_OK(VecRestoreArray(X, &x));
  }
  PETSC_ASSERT_OK(single.update(X));
  // Expected ghost at (il, jl): the owning rank's value, wrapped when periodic, 0 beyond a wall.
  auto expect = [&](PetscInt il, PetscInt jl, PetscInt fld) -> PetscReal {
    PetscInt i = g.xs() + il, j = g.ys() + jl;
    if (periodic) i = (i + n) % n, j = (j + ny) % ny;
    if (i < 0 || i >= n || j < 0 || j >= ny) return 0;
    return code(i, j, fld);
  };
  PetscInt checked = 0;
  auto at = [&](PetscInt il, PetscInt jl) {
    for (PetscInt fld = 0; fld < 2; ++fld)
      EXPECT_EQ(PetscRealPart(packed(il, jl, fld)), expect(il, jl, fld)) << "(" << il << ", " << jl << ") field " << fld;
    EXPECT_EQ(PetscRealPart(single(il, jl)), expect(il, jl, 0)) << "(" << il << ", " << jl << ") single";
    ++checked;
  };
  for (PetscInt jl = 0; jl < ym; ++jl)
    for (PetscInt k = 1; k <= width; ++k) at(-k, jl), at(xm - 1 + k, jl);
  if (dim == 2)
    for (PetscInt il = 0; il < xm; ++il)
      for (PetscInt k = 1; k <= width; ++k) at(il, -k), at(il, ym - 1 + k);
  EXPECT_GT(checked, 0);
}

} // namespace

TEST(Halo, GhostsAreTheOwnersValues) {
  for (PetscInt dim : {1, 2})
    for (bool periodic : {true, false})
      for (PetscInt width : {1, 2}) check(dim, periodic, width);
}
