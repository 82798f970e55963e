#!/usr/bin/env bash
# Gradient / forward for every model and integrator flexipde offers (1 rank, or NP): the model survey
# of docs/performance.md.
#
#   run/bench_models.sh              # markdown table on stdout
#   REPS=3 run/bench_models.sh       # fewer repetitions
#   NP=2 run/bench_models.sh         # on 2 ranks
#   PROCS=3 run/bench_models.sh      # each case in 3 processes: medians, and the ratios' range
#   MODELS=wave,wave2d run/bench_models.sh                    # these models' rows only
#   CASES=spectral run/bench_models.sh                          # the rows whose case names contain this
#   BASELINE=/other/build/flexipde PROCS=3 run/bench_models.sh # against another build, side by side
#
# Each line is one process, `flexipde -task gradient -timing_repeats REPS`: one gradient, then REPS
# forward solves and REPS gradients alternately in the same process, and their medians. A gradient is
# the whole value + gradient (forward solve storing the trajectory, then the adjoint). The default
# scenes have the data made at the same parameters, so J = 0 there; the work is the same as at any
# other parameters (the adjoint runs in full).
# On a shared (virtual) machine one process can land 10-20 % away from the next one of the same case;
# with PROCS > 1 each line is the median over PROCS processes (forward, gradient and ratio each), and
# the last column gives the range of the per-process ratios.
# With BASELINE, each case runs PROCS processes of each build, alternating, and the table gives both
# builds' medians and this build's time over the baseline's (forward and gradient).
# Environment: FLEXIPDE (build/flexipde), REPS (7), NP (1), PROCS (1), MODELS (all), CASES (all), BASELINE (none),
# MPIEXEC (mpiexec, --allow-run-as-root as root).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
FLEXIPDE=${FLEXIPDE:-$(dirname "$here")/build/flexipde}
REPS=${REPS:-7}
NP=${NP:-1}
MPIEXEC=${MPIEXEC:-mpiexec}
[ "$(id -u)" = 0 ] && MPIEXEC="$MPIEXEC --allow-run-as-root"

PROCS=${PROCS:-1}
MODELS=${MODELS:-}
CASES=${CASES:-}
BASELINE=${BASELINE:-}
[ -z "$BASELINE" ] || [ -x "$BASELINE" ] || { echo "bench_models: BASELINE=$BASELINE is not an executable" >&2; exit 1; }
if [ -n "$BASELINE" ]; then
  echo "| model | integrator | case | forward (s) | gradient (s) | baseline forward (s) | baseline gradient (s) | forward / baseline | gradient / baseline |"
  echo "|---|---|---|---:|---:|---:|---:|---:|---:|"
elif [ "$PROCS" -gt 1 ]; then
  echo "| model | integrator | case | forward (s) | gradient (s) | gradient / forward | ratio range over $PROCS processes |"
  echo "|---|---|---|---:|---:|---:|---|"
else
  echo "| model | integrator | case | forward (s) | gradient (s) | gradient / forward |"
  echo "|---|---|---|---:|---:|---:|"
fi
# forward and gradient medians of one process of build $1 (empty when it failed)
timing() {
  local bin=$1
  shift
  $MPIEXEC -n "$NP" "$bin" "$@" -task gradient -timing_repeats "$REPS" 2>&1 | grep 'gradient/forward' |
    sed -E 's/.*forward median ([0-9.]+).*gradient median ([0-9.]+).*/\1 \2/' || true
}
run() {
  local model=$1 ts=$2 label=$3
  shift 3
  if [ -n "$MODELS" ] && [[ ",$MODELS," != *",$model,"* ]]; then return; fi
  if [ -n "$CASES" ] && [[ "$label" != *"$CASES"* ]]; then return; fi
  local line lines=""
  if [ -n "$BASELINE" ]; then # this build and the baseline alternately, PROCS processes each
    for _ in $(seq "$PROCS"); do
      local a b
      a=$(timing "$FLEXIPDE" "$@")
      b=$(timing "$BASELINE" "$@")
      if [ -z "$a" ] || [ -z "$b" ]; then
        echo "| $model | $ts | $label | | | | | failed | |"
        return
      fi
      lines+="$a $b"$'\n'
    done
    awk -v m="$model" -v t="$ts" -v l="$label" '
      function med(a, n,   i, j, x) { for (i = 2; i <= n; ++i) { x = a[i]; for (j = i - 1; j >= 1 && a[j] > x; --j) a[j + 1] = a[j]; a[j + 1] = x }
                                       return n % 2 ? a[(n + 1) / 2] : 0.5 * (a[n / 2] + a[n / 2 + 1]) }
      NF == 4 { ++n; f[n] = $1 + 0; g[n] = $2 + 0; bf[n] = $3 + 0; bg[n] = $4 + 0 }
      END { mf = med(f, n); mg = med(g, n); mbf = med(bf, n); mbg = med(bg, n)
            printf "| %s | %s | %s | %.4g | %.4g | %.4g | %.4g | %.2f | %.2f |\n", m, t, l, mf, mg, mbf, mbg, mf / mbf, mg / mbg }' <<<"$lines"
    return
  fi
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
