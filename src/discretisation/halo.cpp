#include "flexipde/halo.hpp"

namespace flexipde {

PetscErrorCode Halo::setup(const Grid &grid, DM dm, PetscInt comp, PetscInt width) {
  PetscInt dof, sw, gxs, gys, gxm, gym;
  ISLocalToGlobalMapping ltog;
  PetscFunctionBeginUser;
  PetscCall(DMDAGetInfo(dm, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, &dof, &sw, nullptr, nullptr,
                        nullptr, nullptr));
  PetscCheck(width <= sw && comp >= 0 && comp < dof, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE,
             "Halo: width %" PetscInt_FMT " beyond the DMDA's stencil width %" PetscInt_FMT
             " or component %" PetscInt_FMT " not in [0, %" PetscInt_FMT ")",
             width, sw, comp, dof);
  PetscCall(DMDAGetGhostCorners(dm, &gxs, &gys, nullptr, &gxm, &gym, nullptr));
  PetscCall(DMGetLocalToGlobalMapping(dm, &ltog));
  w_ = width;
  wy_ = grid.dim() == 2 ? width : 0;
  xm_ = grid.xm();
  ym_ = grid.ym();
  left_ = 0;
  right_ = left_ + ym_ * w_;
  bottom_ = right_ + ym_ * w_;
  top_ = bottom_ + wy_ * xm_;
  const PetscInt n = top_ + wy_ * xm_;
  buf_.assign(n, 0.0);
  // local (ghosted) index of every halo point, -1 beyond a wall
  std::vector<PetscInt> local(n, -1);
  auto index = [&](PetscInt il, PetscInt jl) -> PetscInt {
    const PetscInt i = grid.xs() + il, j = grid.ys() + jl;
    if (i < gxs || i >= gxs + gxm || j < gys || j >= gys + gym) return -1;
    return ((j - gys) * gxm + (i - gxs)) * dof + comp;
  };
  for (PetscInt jl = 0; jl < ym_; ++jl)
    for (PetscInt k = 0; k < w_; ++k) {
      local[left_ + jl * w_ + k] = index(k - w_, jl);
      local[right_ + jl * w_ + k] = index(xm_ + k, jl);
    }
  for (PetscInt k = 0; k < wy_; ++k)
    for (PetscInt il = 0; il < xm_; ++il) {
      local[bottom_ + k * xm_ + il] = index(il, k - wy_);
      local[top_ + k * xm_ + il] = index(il, ym_ + k);
    }
  // ghosts beyond a DM_BOUNDARY_GHOSTED wall are in the ghosted box but map to -1
  std::vector<PetscInt> global(n, -1), from, to;
  for (PetscInt k = 0; k < n; ++k)
    if (local[k] >= 0) PetscCall(ISLocalToGlobalMappingApply(ltog, 1, &local[k], &global[k]));
  for (PetscInt k = 0; k < n; ++k)
    if (global[k] >= 0) {
      from.push_back(global[k]);
      to.push_back(k);
    }
  PetscInt count = (PetscInt)from.size();
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &count, 1, MPIU_INT, MPI_SUM, grid.comm()));
  scatter_.reset();
  seq_.reset();
  if (count == 0) PetscFunctionReturn(0);
  PetscCall(VecCreateSeqWithArray(PETSC_COMM_SELF, 1, n, buf_.data(), seq_.out()));
  OwnedIS isf, ist;
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)from.size(), from.data(), PETSC_COPY_VALUES, isf.out()));
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)to.size(), to.data(), PETSC_COPY_VALUES, ist.out()));
  Vec X;
  PetscCall(DMGetGlobalVector(dm, &X));
  PetscCall(VecScatterCreate(X, isf, seq_, ist, scatter_.out()));
  PetscCall(DMRestoreGlobalVector(dm, &X));
  PetscFunctionReturn(0);
}

PetscErrorCode Halo::begin(Vec X) {
  PetscFunctionBeginUser;
  if (scatter_) PetscCall(VecScatterBegin(scatter_, X, seq_, INSERT_VALUES, SCATTER_FORWARD));
  PetscFunctionReturn(0);
}

PetscErrorCode Halo::end(Vec X) {
  PetscFunctionBeginUser;
  if (scatter_) PetscCall(VecScatterEnd(scatter_, X, seq_, INSERT_VALUES, SCATTER_FORWARD));
  PetscFunctionReturn(0);
}

} // namespace flexipde
