#!/usr/bin/env bash
# The two 2D FWI scenes of the comparison with Devito (docs/performance.md), timed as users run them:
# wave2d on [0,1]^2 with walls, 5-point stencil, float64, one Ricker source at the centre, 41 receivers
# on the line y = 0.2, the misfit integrated in time, the gradient with respect to c (one value per
# point, c = 0.9 against data from c = 1), leapfrog, full storage:
#   small  101^2 points, 5000 steps of dt = 5e-4
#   large  2000^2 points, 100 steps of dt = 5e-5
# each with walls alone and with the sponge (-wave2d_sponge_width 0.15, its damping in the kicks),
# on 1 and 2 ranks; the small scene also with the perfectly matched layer of the same width
# (-wave2d_pml_width 0.15), which takes RK4 (its memory variables have no second-order form), and with
# the sponge under RK4, which tells the integrator's share of the difference from the layer's (at
# 2000^2 the PML's full storage would take 19 GB). Medians of REPS in-process repetitions
# (-timing_repeats) of a forward solve and of a value + gradient, and what full storage held on rank 0.
#
#   bash run/bench_fwi_scenes.sh              # markdown on stdout, raw logs in $OUT
#   LARGE=0 REPS=3 bash run/bench_fwi_scenes.sh
#
# Environment: FLEXIPDE (build/flexipde), OUT (a new /tmp/bench_fwi_scenes.XXXXXX), REPS (5; 3 for the
# large scene), LARGE (1: also the 2000^2 scene, 1.6 GB of trajectory per rank), MPIEXEC.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
FLEXIPDE=${FLEXIPDE:-$root/build/flexipde}
OUT=${OUT:-$(mktemp -d /tmp/bench_fwi_scenes.XXXXXX)}
REPS=${REPS:-5}
LARGE=${LARGE:-1}
MPIEXEC=${MPIEXEC:-mpiexec}
[ "$(id -u)" = 0 ] && MPIEXEC="$MPIEXEC --allow-run-as-root"
[ -x "$FLEXIPDE" ] || { echo "bench_fwi_scenes: $FLEXIPDE not found (build first: bash run/build.sh)" >&2; exit 1; }
mkdir -p "$OUT"

survey="-objective_type receivers -survey_sources_x 0.5 -survey_sources_y 0.5 -survey_receivers_spread 0.1,0.9,41
  -survey_receivers_y 0.2"
scene_args() { # name -> grid and time options
  case $1 in
    small) echo "-da_grid_x 101 -da_grid_y 101 -ts_dt 5e-4 -ts_max_time 2.5" ;;
    large) echo "-da_grid_x 2000 -da_grid_y 2000 -ts_dt 5e-5 -ts_max_time 5e-3" ;;
  esac
}
scenes="small"
[ "$LARGE" = 1 ] && scenes="small large"

echo "## The FWI scenes (41 receivers, field c)"
echo
echo "Measured $(date -u +%Y-%m-%dT%H:%MZ) on $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg); medians of in-process repetitions."
echo
boundary_args() { # boundary -> layer and integrator options
  case $1 in
    walls) echo "-wave2d_sponge_width 0 -ts_type leapfrog" ;;
    sponge) echo "-wave2d_sponge_width 0.15 -ts_type leapfrog" ;;
    sponge_rk4) echo "-wave2d_sponge_width 0.15 -ts_type rk -ts_rk_type 4" ;;
    pml) echo "-wave2d_pml_width 0.15 -ts_type rk -ts_rk_type 4" ;;
  esac
}
echo "| scene | boundary | integrator | ranks | forward (s) | value + gradient (s) | gradient / forward | trajectory on rank 0 (MB) |"
echo "|---|---|---|---:|---:|---:|---:|---:|"
for scene in $scenes; do
  reps=$REPS
  boundaries="walls sponge sponge_rk4 pml"
  [ "$scene" = large ] && reps=$(( REPS < 3 ? REPS : 3 )) && boundaries="walls sponge"
  for boundary in $boundaries; do
    integrator=leapfrog
    case "$(boundary_args $boundary)" in *"-ts_type rk"*) integrator=rk4 ;; esac
    for np in 1 2; do
      log="$OUT/${scene}_${boundary}_np$np.log"
      # shellcheck disable=SC2046
      $MPIEXEC -n $np "$FLEXIPDE" -model wave2d $(scene_args $scene) $(boundary_args $boundary) \
        -wave2d_c_field 1 -wave2d_c 0.9 -true_wave2d_c 1 $survey -task gradient -timing_repeats $reps > "$log"
      fwd=$(sed -n 's/.*forward median \([0-9.e+-]*\) s.*/\1/p' "$log")
      grad=$(sed -n 's/.*gradient median \([0-9.e+-]*\) s.*/\1/p' "$log")
      ratio=$(sed -n 's/.*gradient\/forward \([0-9.e+-]*\).*/\1/p' "$log")
      held=$(sed -n 's/.*full storage held \([0-9.]*\) MB.*/\1/p' "$log" | head -1)
      [ -n "$fwd" ] && [ -n "$grad" ] || { echo "bench_fwi_scenes: no timing in $log" >&2; exit 1; }
      echo "| $scene | ${boundary%_rk4} | $integrator | $np | $fwd | $grad | $ratio | $held |"
    done
  done
done
echo
echo "Raw logs: $OUT"
