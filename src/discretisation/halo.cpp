#include "flexipde/halo.hpp"

namespace flexipde {

PetscErrorCode GhostExchange::create(DM dm) {
  PetscInt dof, xs, ys, zs, xm, ym, zm, gxs, gys, gzs, gxm, gym, gzm, rstart, rend;
  ISLocalToGlobalMapping ltog;
  const PetscInt *global;
  std::vector<PetscInt> from, to;
  MPI_Comm comm;
  Vec g, l;
  PetscFunctionBeginUser;
  remote_ = OwnedScatter();
  runs_.clear();
  PetscCall(PetscObjectGetComm((PetscObject)dm, &comm));
  PetscCall(DMDAGetInfo(dm, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, &dof, nullptr, nullptr, nullptr,
                        nullptr, nullptr));
  PetscCall(DMDAGetCorners(dm, &xs, &ys, &zs, &xm, &ym, &zm));
  PetscCall(DMDAGetGhostCorners(dm, &gxs, &gys, &gzs, &gxm, &gym, &gzm));
  PetscCall(DMGetGlobalVector(dm, &g));
  PetscCall(VecGetOwnershipRange(g, &rstart, &rend));
  PetscCall(DMGetLocalToGlobalMapping(dm, &ltog));
  PetscCall(ISLocalToGlobalMappingGetIndices(ltog, &global));
  for (PetscInt k = 0; k < gzm; ++k)
    for (PetscInt j = 0; j < gym; ++j)
      for (PetscInt i = 0; i < gxm; ++i) {
        const PetscInt gi = gxs + i, gj = gys + j, gk = gzs + k;
        if (gi >= xs && gi < xs + xm && gj >= ys && gj < ys + ym && gk >= zs && gk < zs + zm) continue;
        const PetscInt at = ((k * gym + j) * gxm + i) * dof;
        for (PetscInt c = 0; c < dof; ++c) {
          const PetscInt src = global[at + c];
          if (src < 0) continue; // beyond a wall
          if (src >= rstart && src < rend) { // owned here: the global Vec's entry src - rstart
            const PetscInt o = src - rstart;
            if (!runs_.empty() && runs_.back().from + runs_.back().n == o && runs_.back().to + runs_.back().n == at + c)
              ++runs_.back().n;
            else runs_.push_back({o, at + c, 1});
          } else from.push_back(src), to.push_back(at + c);
        }
      }
  PetscCall(ISLocalToGlobalMappingRestoreIndices(ltog, &global));
  PetscInt count = (PetscInt)from.size();
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &count, 1, MPIU_INT, MPI_SUM, comm));
  if (count > 0) {
    OwnedIS isf, ist;
    PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)from.size(), from.data(), PETSC_COPY_VALUES, isf.out()));
    PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)to.size(), to.data(), PETSC_COPY_VALUES, ist.out()));
    PetscCall(DMGetLocalVector(dm, &l));
    PetscCall(VecScatterCreate(g, isf, l, ist, remote_.out()));
    PetscCall(DMRestoreLocalVector(dm, &l));
  }
  PetscCall(DMRestoreGlobalVector(dm, &g));
  PetscFunctionReturn(0);
}

} // namespace flexipde
