#!/usr/bin/env bash
# Benchmark of the Vlasov-Poisson model (Landau set-up, RK4, 100 steps at dt = 2.56/N, i.e. a fixed
# CFL number): forward solve and gradient (-objective_type functional, the field energy at T) on
# N x N phase-space grids, N = 128, 256, 512, on 1 and 2 ranks.
#
#   run/bench_vlasov.sh                         # markdown table on stdout
#   REPS=3 SIZES="128 256" run/bench_vlasov.sh  # fewer
#
# Each (N, ranks) is one process: `flexipde -task gradient -timing_repeats REPS` runs one gradient,
# then REPS more forward solves and REPS more gradients in the same process, and prints the
# medians (MPI_Wtime around Simulation::forward / Simulation::gradient; start-up excluded). The
# gradient is the whole evaluation: forward solve with the trajectory stored, then the adjoint.
# Environment: FLEXIPDE (build/flexipde), REPS (5), SIZES ("128 256 512"), NPROCS ("1 2"),
# MPIEXEC (mpiexec, with --allow-run-as-root --oversubscribe as root).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
FLEXIPDE=${FLEXIPDE:-$(dirname "$here")/build/flexipde}
REPS=${REPS:-5}
SIZES=${SIZES:-"128 256 512"}
NPROCS=${NPROCS:-"1 2"}
MPIEXEC=${MPIEXEC:-mpiexec}
[ "$(id -u)" = 0 ] && MPIEXEC="$MPIEXEC --allow-run-as-root --oversubscribe"

echo "| grid | ranks | forward (s) | gradient (s) | gradient / forward | speed-up forward | speed-up gradient | load |"
echo "|---|---|---|---|---|---|---|---|"
for n in $SIZES; do
  dt=$(awk -v n="$n" 'BEGIN { printf "%.10g", 2.56 / n }')
  T=$(awk -v n="$n" 'BEGIN { printf "%.10g", 256 / n }')
  f1="" g1=""
  for np in $NPROCS; do
    load=$(cut -d' ' -f1 /proc/loadavg)
    line=$($MPIEXEC -n "$np" "$FLEXIPDE" -model vlasov -task gradient -objective_type functional -da_grid_x "$n" \
             -da_grid_y "$n" -ts_dt "$dt" -ts_max_time "$T" -timing_repeats "$REPS" | grep '^timing: .*gradient/forward')
    f=$(sed -E 's/.*forward median ([0-9.]+).*/\1/' <<<"$line")
    g=$(sed -E 's/.*gradient median ([0-9.]+).*/\1/' <<<"$line")
    [ -z "$f1" ] && f1=$f && g1=$g
    awk -v n="$n" -v np="$np" -v f="$f" -v g="$g" -v f1="$f1" -v g1="$g1" -v load="$load" \
      'BEGIN { printf "| %d² | %d | %.3f | %.3f | %.2f | %.2f | %.2f | %s |\n", n, np, f, g, g / f, f1 / f, g1 / g, load }'
  done
done
