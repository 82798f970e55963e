#!/usr/bin/env bash
# Viscous Burgers gradient against the hand-written loop: flexipde (-model burgers, classical RK4,
# and Crank-Nicolson) and run/reference_burgers.c (plain C RK4 storing its stages, with its exact
# discrete adjoint written by hand) on the same discrete problem, in alternating rounds of fresh
# processes on one core:
#
#   u_t + (u^2/2)_x = (nu u_x)_x on [0, 1) periodic, Engquist-Osher flux, nu_{i+1/2} = (nu_i + nu_{i+1})/2,
#   u_0 = sin(2 pi x), J = 0.5 ||u(T) - d||^2 (no h weight) with d = u(T) at nu_true, dJ/dnu for nu
#   one scalar or a field of N values (both at a constant nu):
#     N = 128:  nu = 0.01,  nu_true = 0.02,   dt = 1e-3, T = 0.5   (500 steps;  4 nu dt/h^2 = 0.66, dt/h = 0.13)
#     N = 4096: nu = 1e-3,  nu_true = 1.5e-3, dt = 2e-5, T = 0.05  (2500 steps; 4 nu dt/h^2 = 1.34 at nu,
#               2.01 at nu_true (RK4 stops at 2.78 on the negative axis), dt/h = 0.08)
#
# Each round runs, per scene: flexipde RK4, the reference, then flexipde CN (no reference: the loop is
# RK4 only); each process times REPS forward solves and REPS gradients (value + dJ/dnu: the forward
# storing the trajectory, then the adjoint) after one untimed gradient and prints their medians. The
# table gives the median over the rounds of those per-process medians, and their range; the ratios
# are formed within each process (gradient/forward) or within each round (flexipde / reference), then
# summarised the same way; a line after the table gives flexipde / reference on each process's fastest
# repetition as well (short runs on a loaded machine lose whole time slices to other processes). J and
# ||dJ/dnu|| of flexipde's RK4 and of the reference must agree to 1e-10 (else the script exits 1).
#
#   bash run/bench_burgers.sh                                    # markdown on stdout, logs in $OUT
#   ROUNDS=5 REPS=11 bash run/bench_burgers.sh
#   FLEXIPDE=/path/to/other/build/flexipde bash run/bench_burgers.sh   # another build, same table
#
# Environment: FLEXIPDE (default build/flexipde), ROUNDS (3), REPS (7), CN_REPS (3: a CN gradient at
# N = 4096 takes seconds), CN (1; 0 leaves CN out), OUT (default a new /tmp/bench_burgers.XXXXXX),
# MPIEXEC (mpiexec, --allow-run-as-root as root), PYTHON (python3), CC (cc),
# REF_CFLAGS (-O3 -march=native -ffp-contract=off).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
FLEXIPDE=${FLEXIPDE:-$root/build/flexipde}
ROUNDS=${ROUNDS:-3}
REPS=${REPS:-7}
CN_REPS=${CN_REPS:-3}
CN=${CN:-1}
PYTHON=${PYTHON:-python3}
CC=${CC:-cc}
OUT=${OUT:-$(mktemp -d /tmp/bench_burgers.XXXXXX)}
mkdir -p "$OUT"
MPIEXEC=${MPIEXEC:-mpiexec}
[ "$(id -u)" = 0 ] && MPIEXEC="$MPIEXEC --allow-run-as-root"
[ -x "$FLEXIPDE" ] || { echo "bench_burgers: $FLEXIPDE not found (build first: bash run/build.sh)" >&2; exit 1; }
# a copy, so that a rebuild of the build directory during the rounds cannot mix two binaries
cp "$FLEXIPDE" "$OUT/flexipde"

# the flags of flexipde's own build (CMakeLists.txt, FLEXIPDE_NATIVE)
REF_CFLAGS=${REF_CFLAGS:--O3 -march=native -ffp-contract=off}
$CC $REF_CFLAGS -o "$OUT/reference_burgers" "$here/reference_burgers.c" -lm

# name  N  dt  T  nu  nu_true  field
scenes="n128_scalar  128  1e-3 0.5  0.01 0.02   0
n128_field   128  1e-3 0.5  0.01 0.02   1
n4096_scalar 4096 2e-5 0.05 1e-3 1.5e-3 0
n4096_field  4096 2e-5 0.05 1e-3 1.5e-3 1"

flexipde() { # name N dt T nu nu_true field reps ts-options...
  local n=$2 dt=$3 T=$4 nu=$5 nut=$6 field=$7 reps=$8
  shift 8
  $MPIEXEC -n 1 "$OUT/flexipde" -model burgers -task gradient -da_grid_x "$n" -ts_dt "$dt" -ts_max_time "$T" \
    -burgers_nu "$nu" -true_burgers_nu "$nut" -burgers_nu_field "$field" -timing_repeats "$reps" "$@" </dev/null # mpiexec would read the scene list
}

{
  echo "flexipde: $FLEXIPDE ($(date -u -r "$FLEXIPDE" +%Y-%m-%dT%H:%MZ), sha256 $(sha256sum "$OUT/flexipde" | cut -c1-12))"
  echo "measured: $(date -u +%Y-%m-%dT%H:%MZ) on $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "setup: $ROUNDS rounds, $REPS repetitions per process$([ "$CN" = 1 ] && echo " ($CN_REPS for CN)")"
} > "$OUT/about.txt"
for r in $(seq "$ROUNDS"); do
  while read -r name n dt T nu nut field; do
    flexipde "$name" "$n" "$dt" "$T" "$nu" "$nut" "$field" "$REPS" -ts_type rk -ts_rk_type 4 > "$OUT/round${r}_${name}_rk4.log"
    "$OUT/reference_burgers" "$n" "$dt" "$T" "$nu" "$nut" "$field" "$REPS" </dev/null > "$OUT/round${r}_${name}_reference.log"
    if [ "$CN" = 1 ]; then
      flexipde "$name" "$n" "$dt" "$T" "$nu" "$nut" "$field" "$CN_REPS" -ts_type cn > "$OUT/round${r}_${name}_cn.log"
    fi
  done <<<"$scenes"
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/about.txt"
"$PYTHON" "$here/bench_burgers.py" "$OUT" "$ROUNDS" <<<"$scenes"
echo
echo "Raw logs: $OUT"
