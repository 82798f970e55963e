#!/usr/bin/env bash
# The 2D demo of docs/fwi_receivers.md: examples/fwi_2d (layered model with a slow disc, 4 shots,
# 48 receivers, sponge, BLMVM with TV, 40 iterations), then the images in docs/.
#   BUILD_DIR=build NP=2 bash run/fwi_2d.sh [extra fwi_2d options]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
NP=${NP:-1}
mkdir -p results
MPI="mpiexec --oversubscribe -n $NP"
[[ $(id -u) == 0 ]] && MPI="mpiexec --allow-run-as-root --oversubscribe -n $NP"
$MPI "$BUILD_DIR/fwi_2d" -tao_monitor -output results/fwi_2d.h5 "$@" | tee results/fwi_2d.log
/usr/bin/python3 run/plot_fwi_2d.py results/fwi_2d.h5 docs/fwi_2d
