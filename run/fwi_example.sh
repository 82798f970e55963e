#!/usr/bin/env bash
# One of the inversion examples on NP ranks, its log and HDF5 results in results/, then its images in docs/:
#   fwi_2d        layered model with a slow disc, 4 shots, 48 receivers, sponge, BLMVM with TV (NP = 1)
#   fwi_marmousi  Marmousi-like section made by code, PML, shots in NP groups of one rank, bands (NP = 2)
#   fwi_3d        3D layers and a high-velocity body, 4 shots in NP groups, 289 receivers (NP = 2)
#   BUILD_DIR=build NP=2 bash run/fwi_example.sh fwi_3d [extra options of the example]
set -euo pipefail
cd "$(dirname "$0")/.."
example=${1:?usage: run/fwi_example.sh fwi_2d|fwi_marmousi|fwi_3d [options]}
shift
BUILD_DIR=${BUILD_DIR:-build}
PYTHON=${PYTHON:-/usr/bin/python3}
groups=()
case "$example" in
fwi_2d) NP=${NP:-1} ;;
fwi_marmousi | fwi_3d) NP=${NP:-2}; groups=(-shot_groups "$NP") ;;
*) echo "fwi_example: unknown example '$example' (known: fwi_2d, fwi_marmousi, fwi_3d)" >&2; exit 2 ;;
esac
mkdir -p results
MPI="mpiexec --oversubscribe -n $NP"
[[ $(id -u) == 0 ]] && MPI="mpiexec --allow-run-as-root --oversubscribe -n $NP"
$MPI "$BUILD_DIR/$example" "${groups[@]}" -tao_monitor -output "results/$example.h5" "$@" | tee "results/$example.log"
"$PYTHON" "run/plot_$example.py" "results/$example.h5" "docs/$example" | tee -a "results/$example.log"
