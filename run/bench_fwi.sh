#!/usr/bin/env bash
# Benchmark of the seed FWI scene (the driver's defaults: wave model, n = 1000 on [0,1], dt = 5e-4,
# T = 2.5, i.e. 5000 RK4 steps): forward solve versus adjoint gradient, on 1 and 2 ranks, with one
# scalar speed (-wave_c 0.9) and with a 1000-entry speed field (-wave_c_field 1 -wave_c 0.9).
#
#   run/bench_fwi.sh                       # everything, 7 repetitions, markdown on stdout
#   REPS=5 NPROCS="1" run/bench_fwi.sh     # fewer runs
#
# Environment: FLEXIPDE (binary, default build/flexipde), REPS (7), NPROCS ("1 2"), MPIEXEC
# ("mpiexec", plus --allow-run-as-root as root and --oversubscribe above 2 ranks), PYTHON
# (/usr/bin/python3), OUT (directory for the raw logs, default a new /tmp/bench_fwi.XXXXXX),
# LOAD_MAX (1.0: wait while the 1-minute load average of this machine is above it),
# LOAD_WAIT (1200: give up waiting after this many seconds and measure anyway; the report says so),
# REV (free text for the report: what the binary was built from, e.g. a commit).
#
# What is run, REPS times each, interleaved (one of each per round, so that load changes hit all
# alike), for every rank count and parameter set:
#   startup   -task forward -ts_max_time 5e-4   one time step: process, MPI and PETSc start-up, setup
#   forward   -task forward                     start-up + one forward solve (5000 steps)
#   gradient  -task gradient                    start-up + the synthetic-data forward solve
#                                               + one gradient (forward with trajectory + adjoint)
# each once timed by the wall clock (bash's EPOCHREALTIME around mpiexec) and once with -log_view
# (under GNU time for the peak memory). bench_fwi.py then reports medians and
#   wall clock:  forward solve = forward - startup,   gradient = gradient - forward
#   -log_view:   forward solve = TSStep of the forward run,
#                gradient = Main Stage(gradient run) - Main Stage(forward run)   (max over ranks)
# and the ratio gradient / forward solve.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
FLEXIPDE=${FLEXIPDE:-$root/build/flexipde}
REPS=${REPS:-7}
NPROCS=${NPROCS:-"1 2"}
PYTHON=${PYTHON:-/usr/bin/python3}
LOAD_MAX=${LOAD_MAX:-1.0}
LOAD_WAIT=${LOAD_WAIT:-1200}
OUT=${OUT:-$(mktemp -d /tmp/bench_fwi.XXXXXX)}
mkdir -p "$OUT"

[[ -x "$FLEXIPDE" ]] || { echo "bench_fwi: no executable $FLEXIPDE (build it or set FLEXIPDE)" >&2; exit 1; }
((REPS >= 1)) || { echo "bench_fwi: REPS must be >= 1" >&2; exit 1; }

mpiexec_for() { # mpiexec command line for $1 ranks
  local n=$1
  local cmd=(${MPIEXEC:-mpiexec})
  [[ $(id -u) -eq 0 ]] && cmd+=(--allow-run-as-root)
  ((n > 2)) && cmd+=(--oversubscribe)
  cmd+=(-n "$n")
  echo "${cmd[@]}"
}

load1() { cut -d' ' -f1 /proc/loadavg; }
above() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a > b) }'; }

# Wait for a quiet machine (other jobs make every number here slower and noisier).
waited=0
while above "$(load1)" "$LOAD_MAX" && ((waited < LOAD_WAIT)); do
  echo "bench_fwi: load average $(load1) > $LOAD_MAX, waiting 60 s ($waited s so far)" >&2
  sleep 60
  waited=$((waited + 60))
done
load_before=$(cut -d' ' -f1-3 /proc/loadavg)

declare -A PARAMS=([scalar]="-wave_c 0.9" [field]="-wave_c_field 1 -wave_c 0.9")
declare -A TASK=([startup]="-task forward -ts_max_time 5e-4" [forward]="-task forward" [gradient]="-task gradient")

{
  echo "binary	$FLEXIPDE"
  echo "binary_sha256	$(sha256sum "$FLEXIPDE" | cut -d' ' -f1)"
  [[ -n "${REV:-}" ]] && echo "rev	$REV"
  echo "git	checkout $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo unknown)$(git -C "$root" diff --quiet HEAD -- src include 2>/dev/null || echo ' + uncommitted src/include changes, which the binary may or may not contain')"
  echo "date	$(date -Iseconds)"
  echo "host	$(uname -n) $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')"
  echo "reps	$REPS"
  echo "load_max	$LOAD_MAX"
  echo "load_before	$load_before"
  echo "load_waited_s	$waited"
  for n in $NPROCS; do
    for p in scalar field; do
      for t in startup forward gradient; do
        echo "command	$n	$p	$t	$(mpiexec_for "$n") $FLEXIPDE ${TASK[$t]} ${PARAMS[$p]}"
      done
    done
  done
} > "$OUT/meta.tsv"

# peak resident memory of the largest rank (GNU time on mpiexec), when GNU time is there
if [[ -x /usr/bin/time ]]; then timer=(/usr/bin/time -f %M); else timer=(sh -c 'shift 2; exec "$@"' sh); fi

# run_one TAG KIND CMD...: run CMD, output to $OUT/TAG.KIND.txt; a run that fails is repeated (up to
# 3 attempts, failures recorded in meta.tsv): on a shared machine a run can be killed from outside.
run_one() {
  local tag=$1 kind=$2 attempt rc=1
  shift 2
  for attempt in 1 2 3; do
    t0=$EPOCHREALTIME
    if "$@" > "$OUT/$tag.$kind.txt" 2>&1; then rc=0; else rc=$?; fi
    t1=$EPOCHREALTIME
    ((rc == 0)) && return 0
    echo "bench_fwi: exit status $rc (attempt $attempt): $* (see $OUT/$tag.$kind.txt)" >&2
    echo "failed_run	$tag $kind exit $rc" >> "$OUT/meta.tsv"
  done
  echo "bench_fwi: giving up" >&2
  exit 1
}

echo -e "nprocs\tparams\ttask\trep\twall_s" > "$OUT/wall.tsv"
for ((r = 1; r <= REPS; ++r)); do
  for n in $NPROCS; do
    read -r -a mpi <<< "$(mpiexec_for "$n")"
    for p in scalar field; do
      for t in startup forward gradient; do
        read -r -a args <<< "${TASK[$t]} ${PARAMS[$p]}"
        tag="np${n}_${p}_${t}_${r}"
        run_one "$tag" wall "${mpi[@]}" "$FLEXIPDE" "${args[@]}"
        echo -e "$n\t$p\t$t\t$r\t$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.4f", b - a }')" >> "$OUT/wall.tsv"
        run_one "$tag" log_view "${timer[@]}" -o "$OUT/$tag.rss_kb" "${mpi[@]}" "$FLEXIPDE" "${args[@]}" -log_view
      done
    done
  done
  echo "bench_fwi: round $r/$REPS done, load $(load1)" >&2
done
echo "load_after	$(cut -d' ' -f1-3 /proc/loadavg)" >> "$OUT/meta.tsv"

"$PYTHON" "$here/bench_fwi.py" "$OUT"
echo
echo "Raw logs: $OUT"
