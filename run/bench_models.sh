#!/usr/bin/env bash
# Gradient / forward for every model and integrator flexipde offers (1 rank, or NP): the model survey
# of docs/performance.md.
#
#   run/bench_models.sh              # markdown table on stdout
#   REPS=3 run/bench_models.sh       # fewer repetitions
#   NP=2 run/bench_models.sh         # on 2 ranks
#   PROCS=3 run/bench_models.sh      # each case in 3 processes: medians, and the ratios' range
#
# Each line is one process, `flexipde -task gradient -timing_repeats REPS`: one gradient, then REPS
# forward solves and REPS gradients alternately in the same process, and their medians. A gradient is
# the whole value + gradient (forward solve storing the trajectory, then the adjoint). The default
# scenes have the data made at the same parameters, so J = 0 there; the work is the same as at any
# other parameters (the adjoint runs in full).
# On a shared (virtual) machine one process can land 10-20 % away from the next one of the same case;
# with PROCS > 1 each line is the median over PROCS processes (forward, gradient and ratio each), and
# the last column gives the range of the per-process ratios.
# Environment: FLEXIPDE (build/flexipde), REPS (7), NP (1), PROCS (1), MPIEXEC (mpiexec, --allow-run-as-root as root).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
FLEXIPDE=${FLEXIPDE:-$(dirname "$here")/build/flexipde}
REPS=${REPS:-7}
NP=${NP:-1}
MPIEXEC=${MPIEXEC:-mpiexec}
[ "$(id -u)" = 0 ] && MPIEXEC="$MPIEXEC --allow-run-as-root"

PROCS=${PROCS:-1}
if [ "$PROCS" -gt 1 ]; then
  echo "| model | integrator | case | forward (s) | gradient (s) | gradient / forward | ratio range over $PROCS processes |"
  echo "|---|---|---|---:|---:|---:|---|"
else
  echo "| model | integrator | case | forward (s) | gradient (s) | gradient / forward |"
  echo "|---|---|---|---:|---:|---:|"
fi
run() {
  local model=$1 ts=$2 label=$3
  shift 3
  local line lines=""
  for _ in $(seq "$PROCS"); do
    line=$($MPIEXEC -n "$NP" "$FLEXIPDE" "$@" -task gradient -timing_repeats "$REPS" 2>&1 | grep 'gradient/forward' || true)
    if [ -z "$line" ]; then
      echo "| $model | $ts | $label | | | failed |$([ "$PROCS" -gt 1 ] && echo " |")"
      return
    fi
    lines+="$(sed -E 's/.*forward median ([0-9.]+).*gradient median ([0-9.]+).*gradient\/forward ([0-9.]+).*/\1 \2 \3/' <<<"$line")"$'\n'
  done
  # medians of each column (PROCS odd: the middle process; even: the mean of the two middle ones); med
  # sorts its array in place, so the ratios' range is then r[1] .. r[n]
  awk -v m="$model" -v t="$ts" -v l="$label" -v P="$PROCS" '
    function med(a, n,   i, j, x) { for (i = 2; i <= n; ++i) { x = a[i]; for (j = i - 1; j >= 1 && a[j] > x; --j) a[j + 1] = a[j]; a[j + 1] = x }
                                     return n % 2 ? a[(n + 1) / 2] : 0.5 * (a[n / 2] + a[n / 2 + 1]) }
    NF == 3 { ++n; f[n] = $1 + 0; g[n] = $2 + 0; r[n] = $3 + 0 }
    END { if (P == 1) { printf "| %s | %s | %s | %s | %s | %s |\n", m, t, l, f[1], g[1], r[1]; exit }
          mf = med(f, n); mg = med(g, n); mr = med(r, n)
          printf "| %s | %s | %s | %.6f | %.6f | %.3f | %.3f-%.3f |\n", m, t, l, mf, mg, mr, r[1], r[n] }' <<<"$lines"
}
A="-model advection -grid_periodic 1 -da_grid_x 512"
D="-advection_D 0.01 -ts_dt 1e-4 -ts_max_time 0.5" # explicit RK needs the small step with diffusion
for S in upwind fd2 fd4 spectral; do
  for TS in rk4 cn; do
    opt="-ts_type rk -ts_rk_type 4"
    [ $TS = cn ] && opt="-ts_type cn"
    run advection "$TS" "1D N=512 $S" $A -advection_scheme $S $opt
    run advection "$TS" "1D N=512 $S, scalar D" $A -advection_scheme $S $opt $D
    run advection "$TS" "1D N=512 $S, field D" $A -advection_scheme $S $opt $D -advection_D_field 1
  done
done
A2="-model advection -advection_dim 2 -grid_periodic 1 -da_grid_x 128 -da_grid_y 128 -advection_b 0.5 -ts_dt 1e-3 -ts_max_time 0.5"
for S in upwind fd2 spectral; do
  for TS in rk4 cn; do
    opt="-ts_type rk -ts_rk_type 4"
    [ $TS = cn ] && opt="-ts_type cn"
    run advection "$TS" "2D 128^2 $S" $A2 -advection_scheme $S $opt
    run advection "$TS" "2D 128^2 $S, field D" $A2 -advection_scheme $S $opt -advection_D 0.01 -advection_D_field 1
  done
done
for TS in leapfrog rk4 cn; do
  opt="-ts_type $TS"
  [ $TS = rk4 ] && opt="-ts_type rk -ts_rk_type 4"
  run wave "$TS" "seed scene, field c" $opt -wave_c_field 1 -wave_c 0.9
  run wave "$TS" "seed scene, scalar c" $opt -wave_c_field 0 -wave_c 0.9
done
for TS in rk4 cn; do
  opt="-ts_type cn"
  [ $TS = rk4 ] && opt="-ts_type rk -ts_rk_type 4"
  run wave2d "$TS" "101^2, sponge, field c" -model wave2d -da_grid_x 101 -da_grid_y 101 $opt -wave2d_c_field 1
done
run wave2d leapfrog "101^2, walls, field c" -model wave2d -da_grid_x 101 -da_grid_y 101 -ts_type leapfrog -wave2d_sponge_width 0 \
  -wave2d_ic pulse -wave2d_c_field 1 -wave2d_c 0.9 -true_wave2d_c 1
run vlasov rk4 "Landau 128^2" -model vlasov -objective_type functional -da_grid_x 128 -da_grid_y 128 -ts_dt 0.02 -ts_max_time 2
run vlasov cn "Landau 64^2" -model vlasov -objective_type functional -da_grid_x 64 -da_grid_y 64 -ts_type cn -ts_dt 0.1 -ts_max_time 2
