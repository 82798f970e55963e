#!/usr/bin/env bash
# Benchmark of binomial checkpointing (-checkpoint_budget) on the wave scene: peak memory (resident
# set) and time of one gradient against the number of steps, for full storage and fixed budgets.
#
#   run/bench_checkpoint.sh                          # n = 1e3, 1e4, 1e5 steps; full, 10, 30, 100
#   REPS=1 TIMES="0.5 5" run/bench_checkpoint.sh     # quicker
#
# Scene: -task gradient -wave_c_field 1 -wave_c 0.9 -da_grid_x 1000 -ts_dt 5e-4 -ts_max_time T
# (RK4, 2 x 1000 unknowns, 1000 field parameters), T = 0.5, 5, 50 -> n = 1000, 10000, 100000.
#
# Environment: FLEXIPDE (binary, default build/flexipde), PYTHON (/usr/bin/python3), REPS (3),
# TIMES ("0.5 5 50"), BUDGETS ("full 10 30 100"), NPROCS (1; e.g. "1 2"), MPIEXEC ("mpiexec", with
# --allow-run-as-root as root), OUT (raw logs, default a new /tmp/bench_checkpoint.XXXXXX),
# PNG (plot, default docs/checkpointing.png; empty: no plot).
#
# Every configuration runs REPS times, interleaved, each under GNU time (wall clock, peak resident
# set of the largest process). For each T a forward-only run (-task forward: start-up and one
# forward solve) is the baseline: the gradient task runs start-up, the forward solve that makes the
# synthetic data and one gradient, so
#   gradient time = median(gradient run) - median(forward run)
# and the peak resident set of the gradient run is compared with that of the forward run (no
# trajectory at all). bench_checkpoint.py prints the tables (markdown) and draws the plot.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
FLEXIPDE=${FLEXIPDE:-$root/build/flexipde}
PYTHON=${PYTHON:-/usr/bin/python3}
REPS=${REPS:-3}
TIMES=${TIMES:-"0.5 5 50"}
BUDGETS=${BUDGETS:-"full 10 30 100"}
NPROCS=${NPROCS:-1}
OUT=${OUT:-$(mktemp -d /tmp/bench_checkpoint.XXXXXX)}
PNG=${PNG-$root/docs/checkpointing.png}
mkdir -p "$OUT"

[[ -x "$FLEXIPDE" ]] || { echo "bench_checkpoint: no executable $FLEXIPDE (build it or set FLEXIPDE)" >&2; exit 1; }
[[ -x /usr/bin/time ]] || { echo "bench_checkpoint: needs GNU time (/usr/bin/time, apt-get install time)" >&2; exit 1; }
((REPS >= 1)) || { echo "bench_checkpoint: REPS must be >= 1" >&2; exit 1; }

SCENE=(-wave_c_field 1 -wave_c 0.9 -da_grid_x 1000 -ts_dt 5e-4)

launcher() { # command prefix for $1 ranks (none for one rank: GNU time then sees the process itself)
  local n=$1
  ((n == 1)) && return 0
  local cmd=(${MPIEXEC:-mpiexec})
  [[ $(id -u) -eq 0 ]] && cmd+=(--allow-run-as-root)
  ((n > 2)) && cmd+=(--oversubscribe)
  echo "${cmd[@]} -n $n"
}

{
  echo "binary	$FLEXIPDE"
  echo "git	$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)"
  echo "date	$(date -Iseconds)"
  echo "host	$(uname -n), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), $(free -g | awk '/Mem:/ {print $2}') GB"
  echo "load_before	$(cut -d' ' -f1-3 /proc/loadavg)"
  echo "scene	${SCENE[*]}"
} > "$OUT/meta.tsv"

echo -e "nprocs\tT\tconfig\trep\twall_s\trss_kb\tsteps\tbudget\tstored\trecomputed\toptimum" > "$OUT/runs.tsv"
for ((r = 1; r <= REPS; ++r)); do
  for np in $NPROCS; do
    read -r -a pre <<< "$(launcher "$np")"
    for T in $TIMES; do
      for config in forward $BUDGETS; do
        args=(-task gradient)
        [[ $config == forward ]] && args=(-task forward)
        [[ $config != forward && $config != full ]] && args+=(-checkpoint_budget "$config")
        log="$OUT/np${np}_T${T}_${config}_${r}.txt"
        /usr/bin/time -f "time %e %M" -o "$log.time" "${pre[@]}" "$FLEXIPDE" "${SCENE[@]}" -ts_max_time "$T" "${args[@]}" > "$log" 2>&1 ||
          { echo "bench_checkpoint: run failed, see $log" >&2; exit 1; }
        read -r _ wall rss < <(grep '^time ' "$log.time")
        steps=$(grep -m1 -oE '[0-9]+ steps( of|\))' "$log" | grep -oE '^[0-9]+' || echo 0)
        if [[ $config == forward ]]; then
          budget=-; stored=0; recomputed=0; optimum=0
        else
          read -r budget stored recomputed optimum < <(sed -nE 's/^checkpointing: budget ([0-9]+) .*, ([0-9]+) states stored at most, ([0-9]+) steps recomputed, binomial optimum ([0-9]+)$/\1 \2 \3 \4/p' "$log")
        fi
        echo -e "$np\t$T\t$config\t$r\t$wall\t$rss\t$steps\t$budget\t$stored\t$recomputed\t$optimum" >> "$OUT/runs.tsv"
        echo "bench_checkpoint: np $np T $T $config rep $r: ${wall} s, $((rss / 1024)) MB" >&2
      done
    done
  done
done
echo "load_after	$(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/meta.tsv"

"$PYTHON" "$here/bench_checkpoint.py" "$OUT" ${PNG:+"$PNG"}
echo
echo "Raw logs: $OUT"
