#!/usr/bin/env bash
# The Marmousi-like inversion of docs/fwi_receivers.md: examples/fwi_marmousi (a section with dipping
# layers, a fault and a high-velocity body, made by code; PML, shots in parallel on NP groups of one
# rank, frequency bands), then the images in docs/.
#   BUILD_DIR=build NP=2 bash run/fwi_marmousi.sh [extra fwi_marmousi options]  (run/fwi_example.sh)
exec bash "$(dirname "$0")/fwi_example.sh" fwi_marmousi "$@"
