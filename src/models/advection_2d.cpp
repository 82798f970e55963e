// The 2D instances of the advection model (src/models/advection.cpp), compiled apart from the 1D ones.
#define FLEXIPDE_ADVECTION_2D_UNIT
#include "advection.cpp"
