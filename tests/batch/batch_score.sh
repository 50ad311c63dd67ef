#!/usr/bin/env bash
# A batch of the default incision scored against plans moved across it
# (assets/batch/incision.json): summary.csv carries the score's columns, the plan as drawn scores
# within a surface cell and nothing outside its band, the plan 5 mm aside scores about 5 mm and
# tissue outside the band. Usage: batch_score.sh INCISE MANIFEST WORKDIR
set -euo pipefail
incise=$1 manifest=$2 work=$3
rm -rf "$work"
"$incise" batch "$manifest" --out "$work" >"$work.log" 2>&1 || { cat "$work.log"; exit 1; }
summary=$work/summary.csv
column() { head -1 "$summary" | tr ',' '\n' | grep -nx "$1" | cut -d: -f1; }
for key in score.deviation_mean_mm score.deviation_max_mm score.outside_band_mm2 score.length_cut_mm; do
  [ -n "$(column "$key")" ] || { echo "summary.csv has no column $key"; head -1 "$summary"; exit 1; }
done
value() { awk -F, -v job="$1" -v c="$(column "$2")" '$1 == job { print $c }' "$summary"; }
check() { awk -v v="$1" "BEGIN { exit !($2) }" || { echo "$3: $1 fails $2"; cat "$summary"; exit 1; }; }
check "$(value incision-000 score.deviation_max_mm)" "v < 2.5" "the plan as drawn, deviation_max_mm"
check "$(value incision-000 score.outside_band_mm2)" "v == 0" "the plan as drawn, outside_band_mm2"
check "$(value incision-003 score.deviation_mean_mm)" "v > 3.5 && v < 6.5" "the plan 5 mm aside, deviation_mean_mm"
check "$(value incision-003 score.outside_band_mm2)" "v > 0" "the plan 5 mm aside, outside_band_mm2"
check "$(value incision-003 score.length_cut_mm)" "v == 0" "the plan 5 mm aside, length_cut_mm"
echo "ok: $(cut -d, -f1,2 "$summary" | tail -n +2 | tr '\n' ' ')"
