#!/usr/bin/env bash
# The 2D demo of docs/fwi_receivers.md: examples/fwi_2d (layered model with a slow disc, 4 shots,
# 48 receivers, sponge, BLMVM with TV, 40 iterations), then the images in docs/.
#   BUILD_DIR=build NP=2 bash run/fwi_2d.sh [extra fwi_2d options]  (run/fwi_example.sh)
exec bash "$(dirname "$0")/fwi_example.sh" fwi_2d "$@"
