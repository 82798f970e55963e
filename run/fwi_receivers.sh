#!/usr/bin/env bash
# The 1D receiver FWI table of docs/fwi_receivers.md: the seed's linear profile (c = 0.9 -> 1.0 on
# [0,1], start 0.85 -> 1.0, n = 1000, T = 2.5, dt = 5e-4, 5000 leapfrog steps), three Ricker shots
# (f0 = 5 at x = 0.02, 0.5, 0.98), receivers at both ends or along the domain, Tikhonov 1e-6,
# inverted with BLMVM, LMVM and Adam (TAO's -tao_type adam); the data are written to and read back
# from HDF5. Writes results/fwi_receivers/*.h5, *.log and table.md.
#   BUILD_DIR=build NP=1 ITS=200 bash run/fwi_receivers.sh
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
NP=${NP:-1}        # 1 rank: the fastest for 1000 points on a busy 2-core machine
ITS=${ITS:-200}
ADAM_LR=${ADAM_LR:-3e-3}
OUT=results/fwi_receivers
mkdir -p "$OUT"
MPI="mpiexec --oversubscribe -n $NP"
[[ $(id -u) == 0 ]] && MPI="mpiexec --allow-run-as-root --oversubscribe -n $NP"
SCENE="-da_grid_x 1000 -ts_dt 5e-4 -ts_max_time 2.5 -ts_type leapfrog -wave_c_field 1 -wave_ic zero
  -true_wave_c_profile linear -true_wave_c_left 0.9 -true_wave_c_right 1.0
  -wave_c_profile linear -wave_c_left 0.85 -wave_c_right 1.0
  -objective_type receivers -survey_sources_x 0.02,0.5,0.98 -survey_ricker_f0 5
  -inv_lower 0.5 -inv_upper 2 -inv_tikhonov 1e-6 -tao_max_it $ITS"
declare -A RECV=([ends]="-survey_receivers_x 0.002,0.998" [spread]="-survey_receivers_spread 0.002,0.998,21")
echo "| receivers | method | iterations | gradient evaluations | misfit J | velocity RMSE | time (s) |" > "$OUT/table.md"
echo "| --- | --- | --- | --- | --- | --- | --- |" >> "$OUT/table.md"
for rec in ends spread; do
  data="$OUT/data_$rec.h5"
  # synthetic traces from the true model, written once, then read back by every inversion
  $MPI "$BUILD_DIR/flexipde" -task gradient $SCENE ${RECV[$rec]} -survey_data_write "$data" > "$OUT/data_$rec.log"
  for method in blmvm lmvm adam; do
    extra=""
    [[ $method == adam ]] && extra="-tao_adam_lr $ADAM_LR"
    log="$OUT/${rec}_$method.log"
    start=$(date +%s.%N)
    $MPI "$BUILD_DIR/flexipde" -task invert $SCENE ${RECV[$rec]} -survey_data_file "$data" -tao_type $method $extra \
      -output "$OUT/${rec}_$method.h5" > "$log"
    t=$(/usr/bin/python3 -c "print($(date +%s.%N) - $start)")
    line=$(grep "^invert:" "$log" | head -1)
    its=$(sed -E 's/.* after ([0-9]+) iterations.*/\1/' <<<"$line")
    evals=$(sed -E 's/.*, ([0-9]+) gradient evaluations.*/\1/' <<<"$line")
    rmse=$(sed -E 's/.*-> ([0-9.e+-]+).*/\1/' <<<"$line")
    J=$(/usr/bin/python3 -c "import h5py; print('%.3e' % h5py.File('$OUT/${rec}_$method.h5')['history/misfit'][-1])")
    printf "| %s | %s | %s | %s | %s | %s | %.0f |\n" "$rec" "$method" "$its" "$evals" "$J" "$rmse" "$t" >> "$OUT/table.md"
    echo "$rec $method: $line"
  done
done
cat "$OUT/table.md"
/usr/bin/python3 run/plot_fwi_receivers.py "$OUT" docs/fwi_receivers_1d.png
