#!/usr/bin/env bash
# An inversion stopped after 4 iterations is resumed from its HDF5 results file for 4 more; the
# resumed run starts from the stored iterate, keeps the history and continues the iteration count,
# and both results files have a consistent XDMF companion.
#   tests/check_restart.sh <mpiexec and its flags...> -- <flexipde> <python>
set -euo pipefail
launcher=()
while [ "$1" != "--" ]; do launcher+=("$1"); shift; done
shift
flexipde=$1 python=$2
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
dir=$(mktemp -d /tmp/flexipde_restart.XXXXXX)
trap 'rm -rf "$dir"' EXIT
opts=(-task invert -da_grid_x 101 -ts_max_time 0.6 -ts_dt 2e-3 -wave_c_field 1 -wave_c 0.9 -true_wave_c_profile gaussian
      -true_wave_c 1 -true_wave_c_bump 0.1 -inv_tikhonov 1e-3)
"${launcher[@]}" "$flexipde" "${opts[@]}" -tao_max_it 4 -output "$dir/first.h5"
cp "$dir/first.h5" "$dir/stopped.h5"
"${launcher[@]}" "$flexipde" "${opts[@]}" -tao_max_it 4 -inv_restart "$dir/stopped.h5" -output "$dir/resumed.h5"
"$python" - "$dir" <<'PY'
import sys, h5py, numpy as np
d = sys.argv[1]
a, b = h5py.File(d + "/stopped.h5", "r"), h5py.File(d + "/resumed.h5", "r")
ia, ib = a["/history/iteration"][:], b["/history/iteration"][:]
fa, fb = a["/history/objective"][:], b["/history/objective"][:]
assert list(ia) == [0, 1, 2, 3, 4], ia
assert list(ib) == list(range(9)), ib
assert np.array_equal(fa, fb[:5]), (fa, fb)
assert fb[5] < fb[4], "the resumed run did not continue from the stored iterate"
assert b["/restart/iteration"][0] == 8 and a["/restart/iteration"][0] == 4
assert np.array_equal(b["/restart/p"][:], b["/fields/wave_c_recovered"][:])
print("restart ok: iterations", list(ib), "objective %.3e -> %.3e" % (fb[4], fb[-1]))
PY
"$python" "$here/check_xdmf.py" "$dir/resumed.xmf" fields_wave_c_recovered fields_U_final_u fields_U_final_v
