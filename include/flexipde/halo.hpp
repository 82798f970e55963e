// The ghost exchange of the pointwise layer's sweeps, which read the owned block of a global Vec in
// place and only its ghost values from a local (ghosted) Vec.
#pragma once
#include "flexipde/grid.hpp"
#include "flexipde/petsc.hpp"
#include <algorithm>
#include <vector>

namespace flexipde {

// to[0, n) = from[0, n). A run of a few entries (the strips and periodic wraps of a halo, one pair
// per row) is copied in line: a call to memmove for each would cost more than the copy.
inline void copy_entries(const PetscScalar *from, PetscInt n, PetscScalar *to) {
  if (n > 32) {
    std::copy(from, from + n, to);
    return;
  }
  for (PetscInt k = 0; k < n; ++k) to[k] = from[k];
}

// Fills the ghost entries of a DM's local Vec (every component) from its global Vec, not the owned
// block as DMGlobalToLocal does. Ghosts a rank owns itself (a periodic wrap within the rank: every
// ghost on one rank) are copied by `copy_own` from the owned array, in runs; the others travel in a
// VecScatter (none when no rank has such a ghost). A scatter costs about a microsecond of calls
// even when nothing leaves the rank, as much as a sweep of G over a few hundred points.
// Points beyond a wall have no source and are left as they are.
class GhostExchange {
public:
  PetscErrorCode create(DM dm);
  // the ghosts held by other ranks: on their way, then in place (collective when any rank has some)
  PetscErrorCode begin(Vec x, Vec local) const {
    return remote_ ? VecScatterBegin(remote_, x, local, INSERT_VALUES, SCATTER_FORWARD) : 0;
  }
  PetscErrorCode end(Vec x, Vec local) const {
    return remote_ ? VecScatterEnd(remote_, x, local, INSERT_VALUES, SCATTER_FORWARD) : 0;
  }
  // ghosted[to] = owned[from] for the ghosts this rank owns (owned: x's local array, ghosted: local's)
  void copy_own(const PetscScalar *owned, PetscScalar *ghosted) const {
    for (const Run &r : runs_) copy_entries(owned + r.from, r.n, ghosted + r.to);
  }

private:
  struct Run {
    PetscInt from, to, n;
  };
  OwnedScatter remote_;
  std::vector<Run> runs_;
};

} // namespace flexipde
