#!/usr/bin/env bash
# What one gradient run costs as a user starts it: the whole process (set-up, the data's forward solve,
# one value + gradient with full storage, exit) in wall time and peak memory per rank, for the acoustic
# wave's leapfrog scenes of run/bench_throughput.sh, by two builds side by side: each repetition runs
# the current build and then the previous one, so both see the same machine.
#
#   FLEXIPDE_PREV=/tmp/flexipde_prev bash run/bench_setup.sh     # markdown on stdout, raw logs in $OUT
#   N2=401 N3=41 REPS=1 bash run/bench_setup.sh                  # a quick pass, the current build only
#
# Environment: FLEXIPDE (build/flexipde), FLEXIPDE_PREV (none: the current build only), OUT (a new
# /tmp/bench_setup.XXXXXX), REPS (3), N2 (1001), N3 (101), STEPS (100), MPIEXEC (mpiexec,
# --allow-run-as-root as root), PYTHON (/usr/bin/python3).
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
FLEXIPDE=${FLEXIPDE:-$root/build/flexipde}
FLEXIPDE_PREV=${FLEXIPDE_PREV:-}
OUT=${OUT:-$(mktemp -d /tmp/bench_setup.XXXXXX)}
REPS=${REPS:-3}
N2=${N2:-1001}
N3=${N3:-101}
STEPS=${STEPS:-100}
MPIEXEC=${MPIEXEC:-mpiexec}
[ "$(id -u)" = 0 ] && MPIEXEC="$MPIEXEC --allow-run-as-root"
for b in "$FLEXIPDE" $FLEXIPDE_PREV; do
  [ -x "$b" ] || { echo "bench_setup: $b not found (build first: bash run/build.sh)" >&2; exit 1; }
done
mkdir -p "$OUT"

# scene options of (dim, order): walls, a pulse, one c per point, STEPS steps of dt = f h
scene() {
  local dim=$1 order=$2 n f
  n=$([ "$dim" = 2 ] && echo "$N2" || echo "$N3")
  f=$(awk -v d="$dim" -v o="$order" 'BEGIN { print d == 2 ? (o == 2 ? 0.4 : 0.3) : (o == 2 ? 0.3 : 0.25) }')
  local dt
  dt=$(awk -v f="$f" -v n="$n" 'BEGIN { printf "%.12g", f / (n - 1) }')
  local m=wave${dim}d grid="-da_grid_x $n -da_grid_y $n"
  [ "$dim" = 3 ] && grid="$grid -da_grid_z $n"
  echo "-task gradient -model $m $grid -${m}_sponge_width 0 -${m}_ic pulse -${m}_c_field 1 -${m}_c 0.9 -true_${m}_c 1" \
    "-ts_type leapfrog -fd_order $order -ts_dt $dt -ts_max_time $(awk -v s="$STEPS" -v d="$dt" 'BEGIN { printf "%.12g", s * d }')"
}

# rows: dim order ranks build wall_s max_rss_MB
rows="$OUT/rows.tsv"
: > "$rows"
for dim in 2 3; do
  for order in 2 8; do
    opts=$(scene $dim $order)
    for np in 1 2; do
      for rep in $(seq "$REPS"); do
        for build in current prev; do
          bin=$FLEXIPDE
          if [ $build = prev ]; then [ -n "$FLEXIPDE_PREV" ] || continue; bin=$FLEXIPDE_PREV; fi
          log="$OUT/${build}_${dim}d_o${order}_np${np}_$rep.log"
          t0=$(date +%s.%N)
          # shellcheck disable=SC2086
          $MPIEXEC -n $np /usr/bin/time -f "peak_rss_kb %M" "$bin" $opts > "$log" 2>&1
          t1=$(date +%s.%N)
          grep -q "(leapfrog, $STEPS steps)" "$log" || { echo "bench_setup: $log did not take $STEPS leapfrog steps" >&2; exit 1; }
          rss=$(grep -oE 'peak_rss_kb [0-9]+' "$log" | cut -d' ' -f2 | sort -n | tail -n 1) # (ranks' lines may interleave)
          printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' $dim $order $np $build \
            "$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')" $((rss / 1024)) >> "$rows"
        done
      done
    done
  done
done

echo "### One gradient run as a process: wall time and peak memory per rank (medians of $REPS, [min, max])"
echo
echo "Grids ${N2}^2 and ${N3}^3, $STEPS leapfrog steps, full storage; raw logs in $OUT."
echo
echo "| dim | order | ranks | build | process wall (s) | peak memory per rank (MB) |"
echo "|---|---|---|---|---|---|"
"${PYTHON:-/usr/bin/python3}" - "$rows" <<'PY'
import statistics, sys
groups = {}
for line in open(sys.argv[1]):
    d, o, p, b, w, r = line.split()
    groups.setdefault((int(d), int(o), int(p), b), []).append((float(w), int(r)))
for (d, o, p, b), v in sorted(groups.items()):
    w, r = [x[0] for x in v], [x[1] for x in v]
    print("| %d | %d | %d | %s | %.2f [%.2f, %.2f] | %d [%d, %d] |" % (d, o, p, b, statistics.median(w), min(w), max(w),
                                                                    statistics.median(r), min(r), max(r)))
PY
