#!/usr/bin/env bash
# The learned-discretisation results of docs/learned_discretisation.md: training of one stencil and of
# a network on 4 random starts, evaluation on 3 held-out starts against classical schemes (and at an
# unseen amplitude, an unseen viscosity and 6 times the training horizon), the gradient cost with 3 and
# with hundreds of weights, and the figures (docs/learned_*.png). Run after run/build.sh; about 3 min on
# 2 cores. Training and evaluation run on one core each: the timings are one-core wall times.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-/usr/bin/python3}
B=build
R=results/learned
mkdir -p $R
log() { echo "== [$SECONDS s] $*"; }
log "Training one stencil (3 weights)"
$B/learned_burgers_train -tao_monitor -output $R/train_stencil.h5 | tee $R/train_stencil.log | grep -v " TAO, "
log "Training a network (227 weights)"
$B/learned_burgers_train -learned_burgers_weights network -tao_max_it 60 -tao_monitor -output $R/train_network.h5 \
  | tee $R/train_network.log | grep -v " TAO, "
NET="-learned_burgers_weights network -learned_burgers_theta_file $R/train_network.h5"
log "Evaluation on held-out starts"
$B/learned_burgers_evaluate -learned_burgers_theta_file $R/train_stencil.h5 -output $R/eval_stencil.h5 | tee $R/eval_stencil.log
$B/learned_burgers_evaluate $NET -output $R/eval_network.h5 | tee $R/eval_network.log
log "Beyond the training: amplitude 2, viscosity 0.003, horizon 3"
$B/learned_burgers_evaluate $NET -learned_burgers_ic_amplitude 2 -eval_resolutions 32,64,128 -output $R/eval_network_amp2.h5 \
  | tee $R/eval_network_amp2.log | grep -E "cells|held-out"
$B/learned_burgers_evaluate $NET -learned_burgers_nu 0.003 -eval_resolutions 32,64,128 -output $R/eval_network_nu003.h5 \
  | tee $R/eval_network_nu003.log | grep -E "cells|held-out"
$B/learned_burgers_evaluate $NET -eval_final_time 3 -eval_sample_every 0.1 -eval_resolutions 32 -output $R/eval_network_long.h5 \
  | tee $R/eval_network_long.log | grep -vE "^ +[0-9]+ cells"
log "Gradient cost: 3 weights against networks of 31, 115 and 451"
$B/learned_burgers_gradient_cost -cost_hidden 4,16,64 -cost_repeats 7 | tee $R/gradient_cost.log
$B/learned_burgers_gradient_cost -cost_hidden 4,16,64 -cost_repeats 7 -da_grid_x 128 -ts_dt 0.00125 -ts_max_time 0.125 \
  | tee $R/gradient_cost_128.log
log "A smaller network (8 hidden units, 59 weights)"
$B/learned_burgers_train -learned_burgers_weights network -learned_burgers_hidden 8 -tao_max_it 60 -output $R/train_network8.h5 \
  | tee $R/train_network8.log | grep -v " TAO, "
$B/learned_burgers_evaluate -learned_burgers_weights network -learned_burgers_hidden 8 -learned_burgers_theta_file $R/train_network8.h5 \
  -eval_resolutions 32 -output $R/eval_network8.h5 | tee $R/eval_network8.log | grep -E "32 cells|held-out"
log "Figures"
"$PYTHON" run/plot_learned.py $R/train_stencil.h5 $R/train_network.h5 $R/eval_stencil.h5 $R/eval_network.h5 docs \
  | tee $R/crossings.md
