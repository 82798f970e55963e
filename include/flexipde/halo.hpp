// Ghost values of one component of a DMDA Vec, for stencil sweeps that read the owned block in place.
//
// A star stencil of half-width w at owned point (i, j) reads (i +- k, j) and (i, j +- k), k <= w. A
// Halo communicates and stores only the values of one component at the points within w of the owned
// block along each axis (strips of w x ym on the left and right, xm x w below and above; in 1D the
// two ends), so a sweep reads owned values straight from the global Vec's array and ghosts from
// here: no copy of the state, unlike DMGlobalToLocal, which copies every component of every point.
// Points beyond a Dirichlet wall do not exist and read as 0; periodic directions wrap (the DMDA's
// local-to-global map decides). A grid with no ghost on any rank (1 rank, Dirichlet) communicates
// nothing. Offsets are relative to the owned block: il = i - xs, jl = j - ys.
#pragma once
#include "flexipde/grid.hpp"
#include <vector>

namespace flexipde {

class Halo {
public:
  // dm: the DMDA of the Vecs to exchange (same layout as grid), comp: the component, width <= the
  // DMDA's stencil width.
  PetscErrorCode setup(const Grid &grid, DM dm, PetscInt comp, PetscInt width);
  // Start / finish filling the ghost values from X (collective). Owned values may be read between.
  PetscErrorCode begin(Vec X);
  PetscErrorCode end(Vec X);
  PetscErrorCode update(Vec X) {
    PetscFunctionBeginUser;
    PetscCall(begin(X));
    PetscCall(end(X));
    PetscFunctionReturn(0);
  }

  // Packed mode: the ghosts of `nfields` arrays in one exchange (one message per neighbour for all of
  // them, where separate Halos send one each). Each rank packs the values its neighbours read, the
  // strips within `width` of its block's edges, of every array, and only those move.
  PetscErrorCode setup_packed(const Grid &grid, PetscInt width, PetscInt nfields);
  // One array laid out over the owned block: the value at (il, jl) is a[jl * sy + il * sx].
  struct Strided {
    const PetscScalar *a;
    PetscInt sx, sy;
  };
  // Packs the nfields arrays' strips and starts the exchange / finishes it (collective).
  PetscErrorCode begin(const Strided *fields);
  PetscErrorCode end();

  // Ghost value at (il, jl) (of field f in packed mode): exactly one of il in [-w, 0) or [xm, xm + w),
  // jl in [-w, 0) or [ym, ym + w) (jl = 0 in 1D), the other inside the owned block.
  PetscScalar operator()(PetscInt il, PetscInt jl, PetscInt f = 0) const {
    const PetscScalar *b = buf_.data() + f * nghost_;
    if (il < 0) return b[left_ + jl * w_ + (il + w_)];
    if (il >= xm_) return b[right_ + jl * w_ + (il - xm_)];
    if (jl < 0) return b[bottom_ + (jl + wy_) * xm_ + il];
    return b[top_ + (jl - ym_) * xm_ + il];
  }
  PetscInt width() const { return w_; }
  PetscInt xm() const { return xm_; }
  PetscInt ym() const { return ym_; }

  // Ghost row jl (2D: jl in [-w, 0) or [ym, ym + w)): its xm values, contiguous (of field f).
  const PetscScalar *ghost_row(PetscInt jl, PetscInt f = 0) const {
    const PetscScalar *b = buf_.data() + f * nghost_;
    return jl < 0 ? b + bottom_ + (jl + wy_) * xm_ : b + top_ + (jl - ym_) * xm_;
  }
  // Whether any rank has a ghost to receive (else begin/end do nothing).
  bool communicates() const { return scatter_ != nullptr; }

private:
  // The ghost points' layout (left_ .. top_, nghost_ per field) and, for each, the global index of
  // its point in grid.dm() (-1 beyond a wall).
  PetscErrorCode layout(const Grid &grid, DM dm, PetscInt comp, PetscInt width, std::vector<PetscInt> &global);
  PetscInt w_ = 0, wy_ = 0, xm_ = 0, ym_ = 0;
  PetscInt left_ = 0, right_ = 0, bottom_ = 0, top_ = 0, nghost_ = 0, nfields_ = 1;
  std::vector<PetscScalar> buf_;
  OwnedVec seq_;        // wraps buf_
  OwnedScatter scatter_; // null when no rank has a ghost
  OwnedVec pack_;       // packed mode: this rank's strips of every field (the scatter's source)
};

// A scatter from a global Vec of the DMDA `dm` to the ghost entries of its ghosted local Vecs (every
// component; entries beyond a wall and owned entries are not written), for sweeps that read the owned
// block in place: *scatter null when no rank has a ghost to receive (1 rank with walls).
PetscErrorCode create_ghost_scatter(DM dm, VecScatter *scatter);

} // namespace flexipde
