#include "flexipde/halo.hpp"
#include <algorithm>

namespace flexipde {

PetscErrorCode Halo::layout(const Grid &grid, DM dm, PetscInt comp, PetscInt width, std::vector<PetscInt> &global) {
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
  nghost_ = top_ + wy_ * xm_;
  // local (ghosted) index of every halo point, -1 beyond a wall
  std::vector<PetscInt> local(nghost_, -1);
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
  global.assign(nghost_, -1);
  for (PetscInt k = 0; k < nghost_; ++k)
    if (local[k] >= 0) PetscCall(ISLocalToGlobalMappingApply(ltog, 1, &local[k], &global[k]));
  PetscFunctionReturn(0);
}

PetscErrorCode Halo::setup(const Grid &grid, DM dm, PetscInt comp, PetscInt width) {
  std::vector<PetscInt> global, from, to;
  PetscFunctionBeginUser;
  PetscCall(layout(grid, dm, comp, width, global));
  nfields_ = 1;
  pack_.reset();
  buf_.assign(nghost_, 0.0);
  for (PetscInt k = 0; k < nghost_; ++k)
    if (global[k] >= 0) {
      from.push_back(global[k]);
      to.push_back(k);
    }
  PetscInt count = (PetscInt)from.size();
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &count, 1, MPIU_INT, MPI_SUM, grid.comm()));
  scatter_.reset();
  seq_.reset();
  if (count == 0) PetscFunctionReturn(0);
  PetscCall(VecCreateSeqWithArray(PETSC_COMM_SELF, 1, nghost_, buf_.data(), seq_.out()));
  OwnedIS isf, ist;
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)from.size(), from.data(), PETSC_COPY_VALUES, isf.out()));
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)to.size(), to.data(), PETSC_COPY_VALUES, ist.out()));
  Vec X;
  PetscCall(DMGetGlobalVector(dm, &X));
  PetscCall(VecScatterCreate(X, isf, seq_, ist, scatter_.out()));
  PetscCall(DMRestoreGlobalVector(dm, &X));
  PetscFunctionReturn(0);
}

namespace {

// The packed strips of a block of xm x ym points (w wide along x, wy along y): left (il < w), right
// (il >= xm - w), bottom (jl < wy), top (jl >= ym - wy), in that order; a corner point sits in two.
PetscInt strips_size(PetscInt xm, PetscInt ym, PetscInt w, PetscInt wy) { return 2 * ym * w + 2 * wy * xm; }

// Where owned point (il, jl) of such a block is packed (one of its places).
PetscInt strip_index(PetscInt il, PetscInt jl, PetscInt xm, PetscInt ym, PetscInt w, PetscInt wy) {
  if (il < w) return jl * w + il;
  if (il >= xm - w) return ym * w + jl * w + (il - (xm - w));
  if (jl < wy) return 2 * ym * w + jl * xm + il;
  return 2 * ym * w + wy * xm + (jl - (ym - wy)) * xm + il;
}

} // namespace

PetscErrorCode Halo::setup_packed(const Grid &grid, PetscInt width, PetscInt nfields) {
  std::vector<PetscInt> global, from, to;
  PetscInt px, py;
  const PetscInt *lx, *ly;
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCheck(nfields >= 1, grid.comm(), PETSC_ERR_ARG_OUTOFRANGE, "Halo: %" PetscInt_FMT " fields", nfields);
  PetscCall(layout(grid, grid.dm(), 0, width, global));
  nfields_ = nfields;
  buf_.assign((size_t)nfields * nghost_, 0.0);
  scatter_.reset();
  seq_.reset();
  pack_.reset();
  PetscCheck(xm_ >= w_ && ym_ >= wy_, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, // (a rank's own condition)
             "Halo: the owned block (%" PetscInt_FMT " x %" PetscInt_FMT ") is narrower than the halo width %" PetscInt_FMT,
             xm_, ym_, w_);
  // Every rank's block (DMDA ranks run along x first), its strips' size and where they start in the
  // packed Vec; a point's owning rank from its index in the PETSc ordering (the ranks' ranges in turn).
  PetscCallMPI(MPI_Comm_size(grid.comm(), &size));
  PetscCall(DMDAGetInfo(grid.dm(), nullptr, nullptr, nullptr, nullptr, &px, &py, nullptr, nullptr, nullptr, nullptr,
                        nullptr, nullptr, nullptr));
  PetscCall(DMDAGetOwnershipRanges(grid.dm(), &lx, grid.dim() == 2 ? &ly : nullptr, nullptr));
  std::vector<PetscInt> bxm(size), bym(size), first(size + 1, 0), poff(size + 1, 0);
  for (PetscMPIInt r = 0; r < size; ++r) {
    bxm[r] = lx[r % px];
    bym[r] = grid.dim() == 2 ? ly[r / px] : 1;
    first[r + 1] = first[r] + bxm[r] * bym[r];
    poff[r + 1] = poff[r] + nfields * strips_size(bxm[r], bym[r], w_, wy_);
  }
  for (PetscInt k = 0; k < nghost_; ++k) {
    const PetscInt g = global[k];
    if (g < 0) continue;
    const PetscInt r = (PetscInt)(std::upper_bound(first.begin(), first.end(), g) - first.begin()) - 1;
    const PetscInt lo = g - first[r], S = strips_size(bxm[r], bym[r], w_, wy_);
    const PetscInt s = strip_index(lo % bxm[r], lo / bxm[r], bxm[r], bym[r], w_, wy_);
    for (PetscInt f = 0; f < nfields; ++f) {
      from.push_back(poff[r] + f * S + s);
      to.push_back(f * nghost_ + k);
    }
  }
  PetscInt count = (PetscInt)from.size();
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &count, 1, MPIU_INT, MPI_SUM, grid.comm()));
  if (count == 0) PetscFunctionReturn(0);
  PetscCall(VecCreateMPI(grid.comm(), nfields * strips_size(xm_, ym_, w_, wy_), PETSC_DETERMINE, pack_.out()));
  PetscCall(VecCreateSeqWithArray(PETSC_COMM_SELF, 1, nfields * nghost_, buf_.data(), seq_.out()));
  OwnedIS isf, ist;
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)from.size(), from.data(), PETSC_COPY_VALUES, isf.out()));
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, (PetscInt)to.size(), to.data(), PETSC_COPY_VALUES, ist.out()));
  PetscCall(VecScatterCreate(pack_, isf, seq_, ist, scatter_.out()));
  PetscFunctionReturn(0);
}

PetscErrorCode Halo::begin(const Strided *fields) {
  PetscFunctionBeginUser;
  if (!scatter_) PetscFunctionReturn(0);
  PetscCheck(pack_, PETSC_COMM_SELF, PETSC_ERR_ORDER, "Halo: begin(fields) needs setup_packed");
  PetscScalar *p;
  PetscCall(VecGetArrayWrite(pack_, &p));
  const PetscInt S = strips_size(xm_, ym_, w_, wy_);
  for (PetscInt f = 0; f < nfields_; ++f) {
    const Strided &F = fields[f];
    PetscScalar *q = p + f * S;
    auto at = [&](PetscInt il, PetscInt jl) { return F.a[jl * F.sy + il * F.sx]; };
    for (PetscInt jl = 0; jl < ym_; ++jl)
      for (PetscInt k = 0; k < w_; ++k) {
        q[jl * w_ + k] = at(k, jl);
        q[ym_ * w_ + jl * w_ + k] = at(xm_ - w_ + k, jl);
      }
    for (PetscInt k = 0; k < wy_; ++k)
      for (PetscInt il = 0; il < xm_; ++il) {
        q[2 * ym_ * w_ + k * xm_ + il] = at(il, k);
        q[2 * ym_ * w_ + wy_ * xm_ + k * xm_ + il] = at(il, ym_ - wy_ + k);
      }
  }
  PetscCall(VecRestoreArrayWrite(pack_, &p));
  PetscCall(VecScatterBegin(scatter_, pack_, seq_, INSERT_VALUES, SCATTER_FORWARD));
  PetscFunctionReturn(0);
}

PetscErrorCode Halo::end() {
  PetscFunctionBeginUser;
  if (scatter_) PetscCall(VecScatterEnd(scatter_, pack_, seq_, INSERT_VALUES, SCATTER_FORWARD));
  PetscFunctionReturn(0);
}

PetscErrorCode Halo::begin(Vec X) {
  PetscFunctionBeginUser;
  PetscCheck(!pack_, PETSC_COMM_SELF, PETSC_ERR_ORDER, "Halo: a packed Halo exchanges arrays (begin(fields))");
  if (scatter_) PetscCall(VecScatterBegin(scatter_, X, seq_, INSERT_VALUES, SCATTER_FORWARD));
  PetscFunctionReturn(0);
}

PetscErrorCode Halo::end(Vec X) {
  PetscFunctionBeginUser;
  if (scatter_) PetscCall(VecScatterEnd(scatter_, X, seq_, INSERT_VALUES, SCATTER_FORWARD));
  PetscFunctionReturn(0);
}

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
