#!/usr/bin/env bash
# How much the 2D wave's absorbing layers reflect: receiver traces of a scene in [0,1]^2 with a sponge
# (-wave2d_sponge_width W) or a perfectly matched layer (-wave2d_pml_width W) along its walls against
# the same scene in [-1,2]^2 without one, where nothing comes back before T. The difference, over the
# direct wave's largest amplitude at the receiver, is the reflection: at normal incidence (receiver
# straight above the source) and oblique (two receivers off the source's vertical, which see the waves
# the top and right layers send back at an angle).
#
#   bash run/absorber_reflection.sh                   # markdown table on stdout
#   LAYERS="sponge:0.1:60 pml:0.1" bash run/absorber_reflection.sh
#
# LAYERS: "sponge:W:sigma_max" and "pml:W[:sigma_max[:alpha_max]]" (PML defaults: the model's).
# Scene: c = 1, h = 1/200, Ricker source f0 = 10 at (0.5, 0.5) (wavelength 0.1, 20 points), RK4,
# dt = 2e-3, T = 0.8; receivers at (0.5, 0.78), (0.7, 0.78), (0.8, 0.7), outside the layers listed
# (the third on the edge of the widest).
# Environment: FLEXIPDE (build/flexipde), PYTHON (/usr/bin/python3), LAYERS, MPIEXEC.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
FLEXIPDE=${FLEXIPDE:-$(dirname "$here")/build/flexipde}
PYTHON=${PYTHON:-/usr/bin/python3}
LAYERS=${LAYERS:-"sponge:0.05:60 pml:0.05 sponge:0.1:60 pml:0.1 sponge:0.15:60 pml:0.15 sponge:0.2:60 pml:0.2"}
MPIEXEC=${MPIEXEC:-mpiexec}
[ "$(id -u)" = 0 ] && MPIEXEC="$MPIEXEC --allow-run-as-root --oversubscribe"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
common="-model wave2d -ts_type rk -ts_rk_type 4 -ts_dt 2e-3 -ts_max_time 0.8 -wave2d_c 1 -true_wave2d_c 1
  -objective_type receivers -survey_sources_x 0.5 -survey_sources_y 0.5 -survey_receivers_x 0.5,0.7,0.8
  -survey_receivers_y 0.78,0.78,0.7 -survey_ricker_f0 10 -checkpoint_memory 100MB -task gradient"
# the reference: three times the domain, the same spacing, no sponge
$MPIEXEC -n 2 "$FLEXIPDE" $common -grid_x0 -1 -grid_x1 2 -grid_y0 -1 -grid_y1 2 -da_grid_x 601 -da_grid_y 601 \
  -wave2d_sponge_width 0 -survey_data_write "$work/reference.h5" > /dev/null
echo "| layer | width W | sigma_max | alpha_max | points in the layer | reflection at (0.5, 0.78), normal | at (0.7, 0.78) | at (0.8, 0.7) |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
for L in $LAYERS; do
  IFS=: read -r kind W S A <<< "$L"
  case $kind in
    sponge) opts="-wave2d_sponge_width $W -wave2d_sponge_strength ${S:-60}"; S=${S:-60}; A="-" ;;
    pml) opts="-wave2d_pml_width $W ${S:+-wave2d_pml_strength $S} ${A:+-wave2d_pml_alpha $A}"
         S=${S:-default}; A=${A:-default} ;;
    *) echo "LAYERS entry $L: sponge:W:S or pml:W[:S[:A]]" >&2; exit 1 ;;
  esac
  $MPIEXEC -n 2 "$FLEXIPDE" $common -da_grid_x 201 -da_grid_y 201 $opts -survey_data_write "$work/layer.h5" > /dev/null
  "$PYTHON" - "$work/layer.h5" "$work/reference.h5" "$kind" "$W" "$S" "$A" <<'PY'
import sys
import h5py
import numpy as np

def traces(name):
    with h5py.File(name, "r") as f:
        d = f["/survey/traces"]
        nrec, nt = int(np.ravel(d.attrs["nrec"])[0]), int(np.ravel(d.attrs["nt"])[0])
        return np.array(d).reshape(-1, nrec, nt)[0]

a, b = traces(sys.argv[1]), traces(sys.argv[2])
kind, w, s, al = sys.argv[3], float(sys.argv[4]), sys.argv[5], sys.argv[6]
r = [np.abs(a[k] - b[k]).max() / np.abs(b[k]).max() for k in range(a.shape[0])]
print("| %s | %g | %s | %s | %d | %.2e | %.2e | %.2e |" % (kind, w, s, al, round(w * 200), r[0], r[1], r[2]))
PY
done
