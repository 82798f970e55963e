#!/usr/bin/env bash
# The test suite: install what is missing, build, run ctest (1- and 2-rank MPI tests).
set -euo pipefail
cd "$(dirname "$0")/.."
bash run/setup.sh
bash run/build.sh
ctest --test-dir "${BUILD_DIR:-build}" --output-on-failure
