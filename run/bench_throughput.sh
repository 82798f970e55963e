#!/usr/bin/env bash
# Throughput of the acoustic wave's leapfrog and its exact adjoint against the machine's bandwidth:
# grid-point updates per second (interior points x steps / time) of a forward solve alone and of a
# value + gradient (full storage), space order 2 and 8,
#   stream     run/stream_triad.c: one-thread triad bandwidth (and two copies at once, the 2-rank
#              rows' bandwidth); bound = bandwidth / 32 B for the forward (a step reads u_k, u_{k-1}, c
#              and writes u_{k+1}) and bandwidth / 88 B for the gradient (the storing forward's 32 B
#              plus an adjoint step's 56: reads u_k, c, mu_{k+1}, mu_{k+2}, g, writes mu_k, g)
#   reference  run/reference_wave.c: hand-written C loops, one thread, 2D (N2^2) and 3D (N3^3)
#   flexipde   -model wave2d and wave3d on 1 and 2 ranks, the same scenes (walls, -<m>_ic pulse, one c
#              per point, c = 0.9 against data from c = 1, no sponge); its J and ||dJ/dc|| are compared
#              with the reference's (the same scene: equal to ~1e-12).
# STEPS leapfrog steps of dt = f h, f = 0.4 (order 2) and 0.3 (order 8) in 2D, 0.3 and 0.25 in 3D
# (the stability limits for c = 1 are 0.71, 0.55, 0.58 and 0.45).
#
#   bash run/bench_throughput.sh                       # markdown on stdout, raw logs in $OUT
#   N2=201 N3=41 REPS=3 bash run/bench_throughput.sh   # a quick pass
#
# Environment: FLEXIPDE (build/flexipde), OUT (a new /tmp/bench_throughput.XXXXXX), REPS (5), N2 (1001),
# N3 (101), STEPS (100), MPIEXEC (mpiexec, --allow-run-as-root as root), REF_CFLAGS
# (-O3 -march=native -ffp-contract=off: the flags of flexipde's build).
# Full storage takes (STEPS + 1) n^dim 8 bytes: 0.81 GB for 1001^2 and 0.83 GB for 101^3 at 100 steps.
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
FLEXIPDE=${FLEXIPDE:-$root/build/flexipde}
OUT=${OUT:-$(mktemp -d /tmp/bench_throughput.XXXXXX)}
REPS=${REPS:-5}
N2=${N2:-1001}
N3=${N3:-101}
STEPS=${STEPS:-100}
MPIEXEC=${MPIEXEC:-mpiexec}
[ "$(id -u)" = 0 ] && MPIEXEC="$MPIEXEC --allow-run-as-root"
[ -x "$FLEXIPDE" ] || { echo "bench_throughput: $FLEXIPDE not found (build first: bash run/build.sh)" >&2; exit 1; }
mkdir -p "$OUT"

# the hand-written references with the flags of flexipde's own build (CMakeLists.txt, FLEXIPDE_NATIVE)
REF_CFLAGS=${REF_CFLAGS:--O3 -march=native -ffp-contract=off}
cc $REF_CFLAGS -o "$OUT/stream_triad" "$here/stream_triad.c"
cc $REF_CFLAGS -o "$OUT/reference_wave" "$here/reference_wave.c" -lm

# grid size, time step and final time of a (dim, order) scene
npoints() { [ "$1" = 2 ] && echo "$N2" || echo "$N3"; }
step_of() {
  awk -v dim="$1" -v order="$2" -v n="$3" -v steps="$STEPS" 'BEGIN {
    f = dim == 2 ? (order == 2 ? 0.4 : 0.3) : (order == 2 ? 0.3 : 0.25)
    dt = f / (n - 1); printf "%.12g %.12g\n", dt, steps * dt }'
}

# bandwidth: one copy, then two at once (their medians summed)
"$OUT/stream_triad" > "$OUT/stream_1.log"
"$OUT/stream_triad" > "$OUT/stream_2a.log" &
"$OUT/stream_triad" > "$OUT/stream_2b.log" &
wait
triad() { sed -nE 's/^stream triad: .*median ([0-9.]+) GB\/s/\1/p' "$@"; }
bw1=$(triad "$OUT/stream_1.log")
bw2=$(triad "$OUT/stream_2a.log" "$OUT/stream_2b.log" | awk '{ s += $1 } END { print s }')

# rows: dim order ranks code n forward_s gradient_s J gradnorm
rows="$OUT/rows.tsv"
: > "$rows"
for dim in 2 3; do
  n=$(npoints $dim)
  for order in 2 8; do
    read -r dt T < <(step_of $dim $order "$n")
    log="$OUT/reference_${dim}d_o${order}.log"
    "$OUT/reference_wave" $dim "$n" "$STEPS" "$dt" 0.9 $order 0 60 "$REPS" > "$log"
    fwd=$(sed -nE 's/.* forward: .*forward median ([0-9.]+) s.*/\1/p' "$log")
    grad=$(sed -nE 's/.*value\+gradient median ([0-9.]+) s.*/\1/p' "$log")
    J=$(sed -nE 's/.*order [0-9]+: .*J = ([-0-9.e+]+), .*/\1/p' "$log")
    gn=$(sed -nE 's/.*\|\|dJ\/dc\|\| = ([-0-9.e+]+),.*/\1/p' "$log")
    printf '%s\t%s\t1\treference\t%s\t%s\t%s\t%s\t%s\n' $dim $order "$n" "$fwd" "$grad" "$J" "$gn" >> "$rows"
  done
done
# flexipde: the reference's scenes
flexipde_scene() {
  local dim=$1 n=$2
  case $dim in
  2) echo "-model wave2d -da_grid_x $n -da_grid_y $n -wave2d_sponge_width 0 -wave2d_ic pulse -wave2d_c_field 1 -wave2d_c 0.9 -true_wave2d_c 1" ;;
  3) echo "-model wave3d -da_grid_x $n -da_grid_y $n -da_grid_z $n -wave3d_sponge_width 0 -wave3d_ic pulse -wave3d_c_field 1 -wave3d_c 0.9 -true_wave3d_c 1" ;;
  *) echo "bench_throughput: no flexipde scene for dim $dim" >&2; return 1 ;;
  esac
}
for dim in 2 3; do
  n=$(npoints $dim)
  scene=$(flexipde_scene $dim "$n")
  for order in 2 8; do
    read -r dt T < <(step_of $dim $order "$n")
    for np in 1 2; do
      log="$OUT/flexipde_${dim}d_o${order}_np${np}.log"
      # shellcheck disable=SC2086
      $MPIEXEC -n $np "$FLEXIPDE" -task gradient $scene -ts_type leapfrog -fd_order $order -ts_dt "$dt" -ts_max_time "$T" \
        -timing_repeats "$REPS" > "$log" 2>&1
      grep -q "(leapfrog, $STEPS steps)" "$log" ||
        { echo "bench_throughput: $log did not take $STEPS leapfrog steps" >&2; exit 1; }
      fwd=$(sed -nE 's/.*forward median ([0-9.]+) s.*/\1/p' "$log")
      grad=$(sed -nE 's/.*gradient median ([0-9.]+) s.*/\1/p' "$log" | tail -n 1)
      J=$(sed -nE 's/^gradient: J = ([-0-9.e+]+), .*/\1/p' "$log")
      gn=$(sed -nE 's/^gradient: .*\|\|dJ\/dp\|\| = ([-0-9.e+]+) .*/\1/p' "$log")
      printf '%s\t%s\t%s\tflexipde\t%s\t%s\t%s\t%s\t%s\n' $dim $order $np "$n" "$fwd" "$grad" "$J" "$gn" >> "$rows"
    done
  done
done

echo "## Wave leapfrog throughput against the bandwidth bound"
echo
echo "Measured $(date -u +%Y-%m-%dT%H:%MZ) on $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg); $REPS repetitions, medians;"
echo "$STEPS steps, 2D on ${N2}^2 points, 3D on ${N3}^3. Triad bandwidth (median): $bw1 GB/s on one thread, $bw2 GB/s for two copies at once."
echo "Point-updates: interior points x steps per second (M = 1e6). Bound: bandwidth / 32 B (forward), / 88 B (value + gradient)."
echo
echo "| dim | order | ranks | code | forward (s) | value + gradient (s) | forward Mpt/s | gradient Mpt/s | forward bound Mpt/s | forward / bound | gradient bound Mpt/s | gradient / bound |"
echo "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
awk -F'\t' -v steps="$STEPS" -v bw1="$bw1" -v bw2="$bw2" '{
  pts = ($1 == 2 ? ($5 - 2) ^ 2 : ($5 - 2) ^ 3) * steps
  bw = ($3 == 1 ? bw1 : bw2) * 1e9
  fb = bw / 32; gb = bw / 88
  printf "| %s | %s | %s | %s | %.4f | %.4f | %.0f | %.0f | %.0f | %.2f | %.0f | %.2f |\n", $1, $2, $3, $4, $6, $7,
         pts / $6 / 1e6, pts / $7 / 1e6, fb / 1e6, pts / $6 / fb, gb / 1e6, pts / $7 / gb
}' "$rows"
echo
echo "### flexipde against the hand-written loop (one thread), and the scenes' agreement"
echo
echo "Times are flexipde's over the reference's; J and the gradient norm as printed (13 digits: a difference of 0 means below ~1e-13)."
echo
echo "| dim | order | ranks | forward flexipde / reference | gradient flexipde / reference | J flexipde | J reference | J relative difference | gradient norm relative difference |"
echo "|---|---|---|---:|---:|---|---|---:|---:|"
awk -F'\t' '
  $4 == "reference" { f[$1 "," $2] = $6; g[$1 "," $2] = $7; J[$1 "," $2] = $8; N[$1 "," $2] = $9 }
  $4 == "flexipde" { k = $1 "," $2; row[++m] = $0; key[m] = k }
  END { for (i = 1; i <= m; ++i) { split(row[i], r, "\t"); k = key[i]
          dj = (r[8] - J[k]) / J[k]; dn = (r[9] - N[k]) / N[k]
          printf "| %s | %s | %s | %.2f | %.2f | %s | %s | %.1e | %.1e |\n", r[1], r[2], r[3], r[6] / f[k], r[7] / g[k],
                 r[8], J[k], dj < 0 ? -dj : dj, dn < 0 ? -dn : dn } }' "$rows"
echo
echo "Raw logs: $OUT"
