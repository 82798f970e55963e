#!/usr/bin/env bash
# The Marmousi-like inversion of docs/fwi_receivers.md: examples/fwi_marmousi (a section with dipping
# layers, a fault and a high-velocity body, made by code; PML, shots in parallel on NP groups of one
# rank, frequency bands), then the images in docs/.
#   BUILD_DIR=build NP=2 bash run/fwi_marmousi.sh [extra fwi_marmousi options]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
NP=${NP:-2}
PYTHON=${PYTHON:-/usr/bin/python3}
mkdir -p results
MPI="mpiexec --oversubscribe -n $NP"
[[ $(id -u) == 0 ]] && MPI="mpiexec --allow-run-as-root --oversubscribe -n $NP"
$MPI "$BUILD_DIR/fwi_marmousi" -shot_groups "$NP" -tao_monitor -output results/fwi_marmousi.h5 "$@" | tee results/fwi_marmousi.log
"$PYTHON" run/plot_fwi_marmousi.py results/fwi_marmousi.h5 docs/fwi_marmousi
