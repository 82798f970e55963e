#!/usr/bin/env bash
# Work-precision study of the advection schemes (docs/work_precision.md): for fd2, fd4, upwind and
# spectral, a smooth (gaussian, width 0.8) and a discontinuous (square, width 2) profile on
# [0, 2 pi), explicit RK4 (a dt/h = 0.5), implicit Crank-Nicolson (a dt/h = 1) and, for the smooth
# profile with fd4 and spectral, RK4 with a small step (a dt/h = 0.1: nearer the spatial error), and a range of N,
# one run of examples/advection_work_precision.cpp each: error at T = 2 pi against the exact
# solution, over/undershoot, the adjoint dJ/da against the exact derivative, and the median wall
# time of REPS forward solves and REPS gradients. Then run/plot_advection.py draws the plot and
# prints the tables.
#
#   run/bench_advection.sh                     # 1 rank, REPS=7, docs/work_precision.png
#   REPS=3 NS="32 64 128" run/bench_advection.sh
#
# Environment: WP (binary, default build/advection_work_precision), REPS (7), NP (ranks, 1),
# NS (N values, "32 64 128 256 512 1024 2048"), NS_SPECTRAL (N for spectral, "16 32 64 128 256 512"),
# PYTHON (/usr/bin/python3), OUT (raw results directory, default a new /tmp/bench_advection.XXXXXX),
# PNG (plot file, default docs/work_precision.png).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
WP=${WP:-$root/build/advection_work_precision}
REPS=${REPS:-7}
NP=${NP:-1}
NS=${NS:-"32 64 128 256 512 1024 2048"}
NS_SPECTRAL=${NS_SPECTRAL:-"16 32 64 128 256 512"}
PYTHON=${PYTHON:-/usr/bin/python3}
OUT=${OUT:-$(mktemp -d /tmp/bench_advection.XXXXXX)}
PNG=${PNG:-$root/docs/work_precision.png}
[[ -x "$WP" ]] || { echo "bench_advection: no executable $WP (build it or set WP)" >&2; exit 1; }
mpi=(mpiexec)
[[ $(id -u) -eq 0 ]] && mpi+=(--allow-run-as-root)
mpi+=(--oversubscribe -n "$NP")

declare -A IC=([smooth]="-advection_ic gaussian -advection_ic_width 0.8" [square]="-advection_ic square -advection_ic_width 2")
declare -A TS=([rk4]="-ts_type rk -ts_rk_type 4 -wp_cfl 0.5" [cn]="-ts_type cn -wp_cfl 1" [rk4_small_dt]="-ts_type rk -ts_rk_type 4 -wp_cfl 0.1")
{
  echo "# $(date -Iseconds) $(uname -n) $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), git $(git -C "$root" rev-parse --short HEAD), NP=$NP REPS=$REPS"
  echo -e "scheme\tprofile\tintegrator\tN\tsteps\tdt\tforward_time\tforward_error\tovershoot\tundershoot\tgradient_time\tgradient\tgradient_exact\tgradient_error\tforward_time_min\tgradient_time_min"
} > "$OUT/results.tsv"
for scheme in fd2 fd4 upwind spectral; do
  ns=$NS
  [[ $scheme == spectral ]] && ns=$NS_SPECTRAL
  for profile in smooth square; do
    integs="rk4 cn"
    [[ $profile == smooth && ($scheme == fd4 || $scheme == spectral) ]] && integs="rk4 cn rk4_small_dt"
    for integ in $integs; do
      for n in $ns; do
        read -r -a args <<< "-advection_scheme $scheme ${IC[$profile]} ${TS[$integ]} -da_grid_x $n -wp_repeats $REPS"
        line=$("${mpi[@]}" "$WP" "${args[@]}" | grep '^wp ')
        vals=$(echo "$line" | sed 's/^wp //; s/[a-z_A-Z]*=//g' | tr ' ' '\t')
        echo -e "$scheme\t$profile\t$integ\t$vals" >> "$OUT/results.tsv"
        echo "bench_advection: $scheme $profile $integ N=$n done" >&2
      done
    done
  done
done
echo "# done $(date -Iseconds), load $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/results.tsv"
"$PYTHON" "$here/plot_advection.py" "$OUT/results.tsv" "$PNG"
echo "Raw results: $OUT/results.tsv"
