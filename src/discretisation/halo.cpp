#include "flexipde/halo.hpp"
#include "flexipde/petsc.hpp"
#include <vector>

namespace flexipde {

PetscErrorCode create_ghost_scatter(DM dm, VecScatter *scatter) {
  PetscInt dim, dof, xs, ys, zs, xm, ym, zm, gxs, gys, gzs, gxm, gym, gzm;
  ISLocalToGlobalMapping ltog;
  const PetscInt *global;
  std::vector<PetscInt> from, to;
  MPI_Comm comm;
  PetscFunctionBeginUser;
  *scatter = nullptr;
  PetscCall(PetscObjectGetComm((PetscObject)dm, &comm));
  PetscCall(DMDAGetInfo(dm, &dim, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, &dof, nullptr, nullptr, nullptr,
                        nullptr, nullptr));
  PetscCall(DMDAGetCorners(dm, &xs, &ys, &zs, &xm, &ym, &zm));
  PetscCall(DMDAGetGhostCorners(dm, &gxs, &gys, &gzs, &gxm, &gym, &gzm));
  PetscCall(DMGetLocalToGlobalMapping(dm, &ltog));
  PetscCall(ISLocalToGlobalMappingGetIndices(ltog, &global));
  for (PetscInt k = 0; k < gzm; ++k)
    for (PetscInt j = 0; j < gym; ++j)
      for (PetscInt i = 0; i < gxm; ++i) {
        const PetscInt gi = gxs + i, gj = gys + j, gk = gzs + k;
        if (gi >= xs && gi < xs + xm && gj >= ys && gj < ys + ym && gk >= zs && gk < zs + zm) continue;
        const PetscInt l = ((k * gym + j) * gxm + i) * dof;
        for (PetscInt c = 0; c < dof; ++c)
          if (global[l + c] >= 0) from.push_back(global[l + c]), to.push_back(l + c);
      }
  PetscCall(ISLocalToGlobalMappingRestoreIndices(ltog, &global));
  PetscInt count = (PetscInt)from.size();
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &count, 1, MPIU_INT, MPI_SUM, comm));
  if (count == 0) PetscFunctionReturn(0);
  OwnedIS isf, ist;
  Vec g, l;
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)from.size(), from.data(), PETSC_COPY_VALUES, isf.out()));
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)to.size(), to.data(), PETSC_COPY_VALUES, ist.out()));
  PetscCall(DMGetGlobalVector(dm, &g));
  PetscCall(DMGetLocalVector(dm, &l));
  PetscCall(VecScatterCreate(g, isf, l, ist, scatter));
  PetscCall(DMRestoreLocalVector(dm, &l));
  PetscCall(DMRestoreGlobalVector(dm, &g));
  (void)dim;
  PetscFunctionReturn(0);
}

} // namespace flexipde
