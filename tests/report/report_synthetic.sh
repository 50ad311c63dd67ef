#!/usr/bin/env bash
# `incise report` on a run folder written here by hand, with what a replay does not write
# yet or not always: tool positions in steps.csv (tool_x, tool_y, tool_z), a score.json and
# a failed expectation; and no frames. Asserts the cut path is drawn from above over the
# organ at rest, the score is a table, the failure is marked, the missing frames are said.
#   report_synthetic.sh INCISE WORKDIR
set -euo pipefail
incise=$1 work=$2
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$work"
run=$work/run
mkdir -p "$run"
cat > "$run/metrics.json" << 'JSON'
{"scene": "synthetic", "scene_file": "does/not/exist.json", "steps": 40, "dt_s": 0.01, "sim_time_s": 0.4,
 "expect": [{"metric": "cut.events", "value": 3, "min": 10, "passed": false},
            {"metric": "nonfinite_events", "value": 0, "max": 0, "passed": true}],
 "ms_per_step": {"median": 1.5, "p95": 2.0}, "frames": {"every_steps": 10}}
JSON
cat > "$run/score.json" << 'JSON'
{"length_cut_mm": 41.5, "deviation_mean_mm": 0.8, "deviation_max_mm": 2.1, "depth_mean_mm": 9.7,
 "depth_range_mm": 1.2, "outside_band_mm2": 0, "duration_s": 1.9, "force_peak_N": 3.4, "force_mean_N": 1.1, "strokes": 1}
JSON
# A stroke along x at y = 5 mm, cutting from step 10 to 30; the organ a grid of points.
awk 'BEGIN {
  print "step,time_s,ms_total,ms_solve,cg_iterations,tool_force_x,tool_force_y,tool_force_z,elastic_energy_J,kinetic_energy_J,links_severed,cut_event,tool_x,tool_y,tool_z"
  for (k = 1; k <= 40; ++k) {
    cut = (k >= 10 && k <= 30) ? 1 : 0
    printf "%d,%.2f,2.0,1.5,%d,0.1,0.2,%.1f,0.01,0.001,%d,%d,%.4f,0.005,0.04\n", k, k * 0.01, 20 + k % 5, -cut - 0.5, 3 * cut, cut, -0.03 + k * 0.0015
  }
}' > "$run/steps.csv"
awk 'BEGIN { print "x,y"; for (i = -8; i <= 8; ++i) for (j = -4; j <= 4; ++j) printf "%.3f,%.3f\n", i * 0.005, j * 0.005 }' > "$run/rest_top.csv"
"$incise" report "$run"
page=$run/report.html
command -v gnuplot > /dev/null || { echo "gnuplot is not installed: the plots were not drawn"; exit 77; }
grep -q '<img class="plot" id="top_view"' "$page" || fail "no view from above"
[ -s "$run/report/top_view.png" ] || fail "top_view.png not drawn"
grep -q '<td>deviation_max_mm</td><td>2.1</td>' "$page" || fail "the score is not a table"
grep -q '<tr class="fail"><td>cut.events</td>' "$page" || fail "the failed expectation is not marked"
grep -q '1 of 2 passed' "$page" || fail "the expectations' count is wrong"
grep -q 'no frames were captured' "$page" || fail "the missing frames are not said"
grep -q 'scene description unavailable: does/not/exist.json' "$page" || fail "the missing scene file is not said"
grep -q 'Cut path from above: not drawn' "$page" && fail "the cut path was said missing"
echo "ok: $(grep -c '<img class="plot"' "$page") plots"
