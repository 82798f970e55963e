// The ghost exchange of the pointwise layer's sweeps, which read the owned block of a global Vec in
// place and only its ghost values from a local (ghosted) Vec.
#pragma once
#include "flexipde/grid.hpp"

namespace flexipde {

// A scatter from the global Vec of `dm` into its local Vec that moves the ghost entries alone (every
// component), not the owned block as DMGlobalToLocal does. Null when no rank has a ghost (1 rank,
// walls only). Points beyond a wall have no source and are left as they are.
PetscErrorCode create_ghost_scatter(DM dm, VecScatter *scatter);

} // namespace flexipde
