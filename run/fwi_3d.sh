#!/usr/bin/env bash
# The 3D inversion of docs/fwi_3d.md: examples/fwi_3d (dipping layers and a high-velocity ellipsoid made
# by code, 4 shots in NP parallel groups of one rank, 289 receivers, sponge, leapfrog, the whole band
# at once), then the images in docs/.
#   BUILD_DIR=build NP=2 bash run/fwi_3d.sh [extra fwi_3d options]  (run/fwi_example.sh)
exec bash "$(dirname "$0")/fwi_example.sh" fwi_3d "$@"
