// The 3D instances of the wave model (src/models/wave.cpp) without a layer or with the sponge, compiled
// apart from the others.
#define FLEXIPDE_WAVE_3D_UNIT
#include "wave.cpp"
