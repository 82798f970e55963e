#!/usr/bin/env bash
# The main job: install what is missing, build, then on 2 MPI ranks first the seed notebook's own
# problem exactly as the notebook ran it (examples/scenes/notebook_fwi_*.opts: loss, gradient, Adam,
# L-BFGS), with a table of the notebook's figures beside flexipde's, then what flexipde does beyond
# it: the seed full-waveform inversions with bounds and regularisation, a receiver-based 1D inversion,
# the 2D scenes and the 3D one. HDF5 results (+ XDMF for ParaView), PNG plots and results/summary.md in results/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash run/setup.sh
bash run/build.sh
PYTHON=${PYTHON:-/usr/bin/python3}
NP=${NP:-2}
MPI="mpiexec -n $NP"
[[ $(id -u) -eq 0 ]] && MPI="mpiexec --allow-run-as-root --oversubscribe -n $NP"
BIN=build/flexipde
mkdir -p results
log() { echo "== [$SECONDS s] $*"; }
# case_run NAME COMMAND...: runs the command, its output to the terminal (without TAO's per-iteration
# lines) and to results/NAME.log, whose first line is "$ COMMAND" (the summary quotes it).
case_run() {
  local name=$1
  shift
  { echo "\$ $*"; "$@"; } 2>&1 | tee "results/$name.log" | grep -v " TAO, "
}

# The seed notebook's problem, as the notebook ran it: n = 1000, the two-level start, 5000 steps of
# the leapfrog recurrence on all points with zeros outside the grid, J = ||u - d||.
NB_LINEAR="-options_file examples/scenes/notebook_fwi_linear.opts"
NB_CONSTANT="-options_file examples/scenes/notebook_fwi_constant.opts"
SNAPSHOT="-inv_checkpoint_every 100" # the restart snapshot in the -output file: every 100 iterations
log "Notebook scenes: the numpy float64 reference (run/notebook_reference.py)"
"$PYTHON" run/notebook_reference.py
log "Notebook scene, linear c: loss and gradient"
case_run notebook_linear_gradient $MPI $BIN $NB_LINEAR -task gradient -output results/notebook_linear_gradient.h5
log "Notebook scene, constant c: loss and gradient at c = 0.8"
case_run notebook_constant_gradient $MPI $BIN $NB_CONSTANT -task gradient -output results/notebook_constant_gradient.h5
log "Notebook scene, constant c: Adam (lr 1e-3, 1000 iterations) from 0.8"
case_run notebook_constant_adam $MPI $BIN $NB_CONSTANT -task invert -tao_type adam -tao_adam_lr 1e-3 \
  -tao_max_it 1000 -tao_monitor $SNAPSHOT -output results/notebook_constant_adam.h5
log "Notebook scene, linear c: Adam (lr 1e-3, 1000 iterations)"
case_run notebook_linear_adam $MPI $BIN $NB_LINEAR -task invert -tao_type adam -tao_adam_lr 1e-3 \
  -tao_max_it 1000 -tao_monitor $SNAPSHOT -output results/notebook_linear_adam.h5
log "Notebook scene, linear c: L-BFGS (LMVM), gradient tolerance 1e-5, at most 1000 iterations"
case_run notebook_linear_lmvm $MPI $BIN $NB_LINEAR -task invert -tao_type lmvm -tao_gatol 1e-5 \
  -tao_max_it 1000 -tao_monitor $SNAPSHOT -output results/notebook_linear_lmvm.h5
log "Notebook scene, linear c: L-BFGS (LMVM) that also stops on a relative decrease of J below 1e-5 (scipy's tol)"
case_run notebook_linear_lmvm_frtol $MPI $BIN $NB_LINEAR -task invert -tao_type lmvm -tao_gatol 1e-5 -inv_frtol 1e-5 \
  -tao_max_it 1000 -tao_monitor $SNAPSHOT -output results/notebook_linear_lmvm_frtol.h5
log "Notebook scene, linear c, beyond the notebook: BLMVM with bounds [0.5, 2] and Tikhonov 1e-2"
case_run notebook_linear_blmvm $MPI $BIN $NB_LINEAR -task invert -tao_type blmvm -inv_lower 0.5 -inv_upper 2 \
  -inv_tikhonov 1e-2 -tao_max_it 500 -tao_monitor $SNAPSHOT -output results/notebook_linear_blmvm.h5
log "The notebook's figures beside flexipde's"
"$PYTHON" run/summarise_fwi.py --notebook results | tee results/notebook_table.md

# Beyond the notebook. Seed scene (driver defaults): n = 1000 on [0,1], u = 0 at both ends, dt = 5e-4, T = 2.5,
# travelling Gaussian u0 = exp(-(5(x-0.5))^2), v0 = -c u0', integrated with the leapfrog
# (Stormer-Verlet, the seed's scheme; -ts_type rk runs the same cases with RK4).
TS=${TS:--ts_type leapfrog}
BOUNDS="$TS -inv_lower 0.5 -inv_upper 2 -tao_type blmvm -tao_monitor"

log "Case 1a: constant c, data from c = 1.0, BLMVM started at c = 0.8 (the seed's start)"
$MPI $BIN -task invert -wave_c 0.8 -true_wave_c 1.0 $BOUNDS -output results/fwi_constant_from_0.8.h5 \
  | tee results/fwi_constant_from_0.8.log
log "Case 1b: the same data, start chosen by a 151-point scan of the bounds, then BLMVM"
$MPI $BIN -task invert -wave_c 0.8 -true_wave_c 1.0 $BOUNDS -inv_scan 151 \
  -output results/fwi_constant.h5 | tee results/fwi_constant.log
log "Case 1c: objective landscape J(c) of the seed scene"
$MPI $BIN -task landscape $TS -true_wave_c 1.0 -landscape_lower 0.5 -landscape_upper 1.5 -landscape_n 101 \
  -output results/fwi_landscape.h5 | tail -n 3

LINEAR="-wave_c_field 1 -true_wave_c_profile linear -true_wave_c_left 0.9 -true_wave_c_right 1.0 \
        -wave_c_profile linear -wave_c_left 0.85 -wave_c_right 1.0"
log "Case 2: linear profile 0.9 -> 1.0 from 0.85 -> 1.0, 1000 parameters, BLMVM with bounds"
$MPI $BIN -task invert $LINEAR $BOUNDS -tao_max_it ${MAX_IT:-500} -inv_tikhonov ${TIKHONOV:-1e-2} $SNAPSHOT \
  -output results/fwi_linear_blmvm.h5 | tee results/fwi_linear_blmvm.log | grep -v " TAO, "
log "Case 2 with LMVM (no bounds)"
$MPI $BIN -task invert $LINEAR -tao_type lmvm -tao_max_it ${MAX_IT:-500} -inv_tikhonov ${TIKHONOV:-1e-2} $SNAPSHOT \
  -output results/fwi_linear_lmvm.h5 | tee results/fwi_linear_lmvm.log | grep -v " TAO, "

log "Case 3: the linear profile from traces: 3 Ricker shots, 21 receivers along the domain, BLMVM"
RECEIVERS="-ts_type leapfrog -wave_ic zero -objective_type receivers -survey_sources_x 0.02,0.5,0.98 -survey_ricker_f0 5
  -survey_receivers_spread 0.002,0.998,21 -inv_lower 0.5 -inv_upper 2 -inv_tikhonov 1e-6"
$MPI $BIN -task gradient $LINEAR $RECEIVERS -survey_data_write results/fwi_receivers_data.h5 > /dev/null
$MPI $BIN -task invert $LINEAR $RECEIVERS -survey_data_file results/fwi_receivers_data.h5 -tao_max_it ${RECEIVER_IT:-100} \
  $SNAPSHOT -output results/fwi_receivers_blmvm.h5 | tee results/fwi_receivers_blmvm.log | grep -v " TAO, "

log "Case 4: 2D layered model with a slow disc, 4 shots, 48 receivers, sponge, BLMVM + TV (examples/fwi_2d)"
$MPI build/fwi_2d -tao_max_it ${FWI2D_IT:-40} -output results/fwi_2d.h5 | tee results/fwi_2d.log | grep -v " TAO, "
"$PYTHON" run/plot_fwi_2d.py results/fwi_2d.h5 results/fwi_2d
log "Case 5: Marmousi-like section (layers, fault, high-velocity body), 12 shots in $NP groups, 3 frequency bands (examples/fwi_marmousi)"
$MPI build/fwi_marmousi -shot_groups "$NP" -output results/fwi_marmousi.h5 | tee results/fwi_marmousi.log | grep -v " TAO, "
"$PYTHON" run/plot_fwi_marmousi.py results/fwi_marmousi.h5 results/fwi_marmousi
log "Case 6: 3D layers and a high-velocity body, 4 shots in $NP groups, 289 receivers, BLMVM + TV (examples/fwi_3d)"
$MPI build/fwi_3d -shot_groups "$NP" -output results/fwi_3d.h5 | tee results/fwi_3d.log | grep -v " TAO, "
"$PYTHON" run/plot_fwi_3d.py results/fwi_3d.h5 results/fwi_3d

log "Learned discretisation: one Burgers stencil trained on 32 cells, checked on held-out starts (docs/learned_discretisation.md)"
$MPI build/learned_burgers_train -output results/learned_stencil.h5 | tee results/learned_stencil.log
$MPI build/learned_burgers_evaluate -learned_burgers_theta_file results/learned_stencil.h5 -eval_resolutions 32,64 \
  -output results/learned_stencil_eval.h5 | tee results/learned_stencil_eval.log | grep -E "consistency|cells|held-out"

log "Plots"
"$PYTHON" run/plot_fwi.py results/notebook_constant_adam.h5 results/notebook_linear_adam.h5 results/notebook_linear_lmvm.h5 \
  results/notebook_linear_lmvm_frtol.h5 results/notebook_linear_blmvm.h5 results/fwi_constant_from_0.8.h5 results/fwi_constant.h5 results/fwi_linear_blmvm.h5 \
  results/fwi_linear_lmvm.h5 results/fwi_receivers_blmvm.h5 -o results
"$PYTHON" run/summarise_fwi.py results > results/summary.md
cat results/summary.md
