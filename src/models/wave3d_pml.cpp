// The 3D instances of the wave model (src/models/wave.cpp) with the perfectly matched layer, compiled
// apart from the others.
#define FLEXIPDE_WAVE_3D_PML_UNIT
#include "wave.cpp"
