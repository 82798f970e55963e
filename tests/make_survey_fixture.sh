#!/usr/bin/env bash
# make_survey_fixture.sh FLEXIPDE OUTDIR: data files for the survey bad-input ctest cases.
#   OUTDIR/survey_fixture.h5      traces of the small 1D survey below (2 receivers at 0.2, 0.8, T = 0.2)
#   OUTDIR/survey_fixture_nan.h5  the same with one sample set to NaN
set -euo pipefail
flexipde=$1
out=$2
mkdir -p "$out"
"$flexipde" -task gradient -da_grid_x 101 -ts_max_time 0.2 -ts_dt 2e-3 -wave_ic zero -objective_type receivers \
  -survey_sources_x 0.5 -survey_receivers_x 0.2,0.8 -survey_data_write "$out/survey_fixture.h5"
cp "$out/survey_fixture.h5" "$out/survey_fixture_nan.h5"
/usr/bin/python3 - "$out/survey_fixture_nan.h5" <<'PY'
import sys, h5py
with h5py.File(sys.argv[1], "r+") as f:
    f["survey/traces"][150] = float("nan")   # receiver 1, sample 49
PY
echo "survey fixtures written to $out"
