#!/usr/bin/env bash
# Gradient speed against peers: the seed FWI problem (wave, n = 1000 on [0,1], 5000 leapfrog
# steps of dt = 5e-4, a 1000-entry speed field c, J = 0.5 ||u(T) - d||^2 with d from c = 1) timed
# in one run, on one core, as the median of REPS value+gradient evaluations each:
#   flexipde   -ts_type leapfrog (and rk4 for reference), -timing_repeats: in-process medians;
#              the leapfrog also on 2 ranks and with one scalar speed (1 versus 1000 parameters)
#   reference  run/reference_leapfrog.c: a plain C leapfrog with its hand-written adjoint
#   torch      run/peer_torch.py: the same scheme in PyTorch autograd (python3-torch, installed by
#              run/setup.sh --peers when missing; skipped if it cannot be)
# The gradients are compared entry by entry (flexipde vs reference must agree to <= 1e-8).
# The 2D wave at the model survey's size (101^2, 5000 steps) against the hand-written 2D loop.
# Then scale: forward and gradient throughput (grid-point updates per second) of the 1D wave with
# 10^6 points and the 2D wave with 2000^2 points against hand-written loops (run/reference_leapfrog*.c),
# and gradient time with 1 versus 10^6 (4e6) parameters, on 1 and 2 ranks.
#
#   bash run/bench_peers.sh              # markdown on stdout, raw logs in $OUT
#   REPS=5 SCALE=0 bash run/bench_peers.sh
#   ROUNDS=5 SCALE=0 bash run/bench_peers.sh   # ... and the seed pair again in 5 alternating rounds
#
# Environment: FLEXIPDE (default build/flexipde), REPS (7), SCALE (1: also the large-grid part),
# PYTHON (/usr/bin/python3), OUT (default a new /tmp/bench_peers.XXXXXX), MPIEXEC, PEERS_INSTALL (1),
# REF_CFLAGS (-O3 -march=native -ffp-contract=off: the flags of flexipde's build),
# ROUNDS (0: the seed pair of flexipde and the hand-written loop once; N: also in N alternating rounds).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
FLEXIPDE=${FLEXIPDE:-$root/build/flexipde}
REPS=${REPS:-7}
SCALE=${SCALE:-1}
PYTHON=${PYTHON:-/usr/bin/python3}
OUT=${OUT:-$(mktemp -d /tmp/bench_peers.XXXXXX)}
mkdir -p "$OUT"
MPIEXEC=${MPIEXEC:-mpiexec}
[ "$(id -u)" = 0 ] && MPIEXEC="$MPIEXEC --allow-run-as-root"
[ -x "$FLEXIPDE" ] || { echo "bench_peers: $FLEXIPDE not found (build first: bash run/build.sh)" >&2; exit 1; }

# the hand-written references with the flags of flexipde's own build (CMakeLists.txt, FLEXIPDE_NATIVE)
REF_CFLAGS=${REF_CFLAGS:--O3 -march=native -ffp-contract=off}
cc $REF_CFLAGS -o "$OUT/reference_leapfrog" "$here/reference_leapfrog.c" -lm
seed="-ts_type leapfrog -wave_c_field 1 -wave_c 0.9"

echo "## Gradient speed against peers (seed FWI, 1000 parameters, 5000 steps, 1 core)"
echo
echo "Measured $(date -u +%Y-%m-%dT%H:%MZ) on $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg); $REPS repetitions, medians."
echo
$MPIEXEC -n 1 "$FLEXIPDE" -task gradient $seed -timing_repeats "$REPS" -output "$OUT/flexipde_gradient.h5" > "$OUT/flexipde_leapfrog.log"
$MPIEXEC -n 1 "$FLEXIPDE" -task gradient -ts_type rk -ts_rk_type 4 -wave_c_field 1 -wave_c 0.9 -timing_repeats "$REPS" > "$OUT/flexipde_rk4.log"
# the seed scene on 1 and 2 ranks, with one scalar speed and with the 1000-entry field
for np in 1 2; do
  for cf in 0 1; do
    $MPIEXEC -n $np "$FLEXIPDE" -task gradient -ts_type leapfrog -wave_c_field $cf -wave_c 0.9 -timing_repeats "$REPS" > "$OUT/seed_np${np}_field$cf.log"
  done
done
"$OUT/reference_leapfrog" 1000 5000 5e-4 0.9 "$REPS" "$OUT/reference_gradient.txt" > "$OUT/reference.log"
# the 2D wave at the model survey's size (run/bench_models.sh: 101^2, walls, 5000 leapfrog steps, field c)
# against the hand-written 2D loop at the same size: both gradients and both forwards alone
cc $REF_CFLAGS -o "$OUT/reference_leapfrog_2d" "$here/reference_leapfrog_2d.c" -lm
$MPIEXEC -n 1 "$FLEXIPDE" -task gradient -model wave2d -da_grid_x 101 -da_grid_y 101 -ts_type leapfrog -wave2d_sponge_width 0 \
  -wave2d_ic pulse -wave2d_c_field 1 -wave2d_c 0.9 -true_wave2d_c 1 -timing_repeats "$REPS" > "$OUT/small2d.log"
"$OUT/reference_leapfrog_2d" 101 5000 5e-4 0.9 "$REPS" > "$OUT/reference_small2d.log"
torch_status=0
# PyTorch is installed from Debian (run/setup.sh --peers) when it is missing and Debian's python3 runs
# the peer; PEERS_INSTALL=0 skips that (the peer is then reported as skipped).
if [ "${PEERS_INSTALL:-1}" = 1 ] && [ "$PYTHON" = /usr/bin/python3 ] && ! "$PYTHON" -c 'import torch' 2>/dev/null; then
  bash "$here/setup.sh" --peers >&2 || echo "bench_peers: could not install python3-torch; the PyTorch peer is skipped" >&2
fi
"$PYTHON" "$here/peer_torch.py" 1000 5000 5e-4 0.9 "$(( REPS < 5 ? REPS : 5 ))" "$OUT/torch_gradient.txt" > "$OUT/torch.log" || torch_status=$?
if [ "$SCALE" = 1 ]; then
  big="-da_grid_x 1000000 -ts_type leapfrog -ts_dt 2.5e-7 -ts_max_time 5e-5 -wave_c 0.9"   # 200 steps
  for np in 1 2; do
    $MPIEXEC -n $np "$FLEXIPDE" -task gradient $big -wave_c_field 0 -timing_repeats 5 > "$OUT/big_scalar_np$np.log"
    $MPIEXEC -n $np "$FLEXIPDE" -task gradient $big -wave_c_field 1 -timing_repeats 5 > "$OUT/big_field_np$np.log"
  done
  "$OUT/reference_leapfrog" 1000000 200 2.5e-7 0.9 5 > "$OUT/reference_big.log"
  # 2D: 2000 x 2000 points, 100 leapfrog steps, no sponge (the leapfrog's form), c scalar or a 4e6 field
  big2d="-model wave2d -da_grid_x 2000 -da_grid_y 2000 -ts_type leapfrog -wave2d_sponge_width 0 -wave2d_ic pulse
         -ts_dt 2e-4 -ts_max_time 2e-2 -wave2d_c 0.9 -true_wave2d_c 1"
  for np in 1 2; do
    $MPIEXEC -n $np "$FLEXIPDE" -task gradient $big2d -wave2d_c_field 0 -timing_repeats 3 > "$OUT/big2d_scalar_np$np.log"
    $MPIEXEC -n $np "$FLEXIPDE" -task gradient $big2d -wave2d_c_field 1 -timing_repeats 3 > "$OUT/big2d_field_np$np.log"
  done
  "$OUT/reference_leapfrog_2d" 2000 100 2e-4 0.9 3 > "$OUT/reference_big2d.log"
fi
"$PYTHON" "$here/bench_peers.py" "$OUT" "$torch_status" "$SCALE"
# ROUNDS > 0: the headline pair again, flexipde's seed leapfrog and the hand-written loop, in ROUNDS
# alternating rounds of fresh processes: on a noisy machine one process each can land in different
# minutes (the same forward can take 9 ms in one and 14 ms in the next), a round's two processes rarely do.
ROUNDS=${ROUNDS:-0}
if [ "$ROUNDS" -gt 0 ]; then
  rounds=""
  for r in $(seq "$ROUNDS"); do
    $MPIEXEC -n 1 "$FLEXIPDE" -task gradient $seed -timing_repeats "$REPS" > "$OUT/round${r}_flexipde.log"
    "$OUT/reference_leapfrog" 1000 5000 5e-4 0.9 "$REPS" > "$OUT/round${r}_reference.log"
    fl=$(sed -nE 's/.*forward median ([0-9.]+) s.*gradient median ([0-9.]+) s.*/\1 \2/p' "$OUT/round${r}_flexipde.log")
    ref=$(sed -nE 's/.*value\+gradient median ([0-9.]+) s.*/\1/p' "$OUT/round${r}_reference.log")
    rounds+="$fl $ref"$'\n'
  done
  echo
  echo "### The seed pair in $ROUNDS alternating rounds (flexipde leapfrog, then the hand-written loop; $REPS repetitions each)"
  echo
  echo "| round | flexipde forward (s) | flexipde value + gradient (s) | hand-written (s) | flexipde / hand-written | gradient / forward |"
  echo "|---|---|---|---|---|---|"
  awk 'NF == 3 { ++n; printf "| %d | %.4f | %.4f | %.4f | %.2f | %.2f |\n", n, $1, $2, $3, $2 / $3, $2 / $1; h[n] = $2 / $3; q[n] = $2 / $1 }
       function med(a, n,   i, j, x) { for (i = 2; i <= n; ++i) { x = a[i]; for (j = i - 1; j >= 1 && a[j] > x; --j) a[j + 1] = a[j]; a[j + 1] = x }
                                        return n % 2 ? a[(n + 1) / 2] : 0.5 * (a[n / 2] + a[n / 2 + 1]) }
       END { mh = med(h, n); mq = med(q, n)
             printf "\n- Medians over the rounds: flexipde / hand-written **%.2f** (%.2f-%.2f), gradient / forward **%.2f** (%.2f-%.2f).\n", mh, h[1], h[n], mq, q[1], q[n] }' <<<"$rounds"
fi
echo
echo "Raw logs: $OUT"
