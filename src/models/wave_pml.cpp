// The perfectly matched layer's instances of the wave model (src/models/wave.cpp), compiled apart from
// the others.
#define FLEXIPDE_WAVE_PML_UNIT
#include "wave.cpp"
