#!/usr/bin/env bash
# The soak in ctest (issue 35): `incise bench soak` for SECONDS, then its soak.csv checked here
# independently of the bench's own verdict: a row per second or so, no non-finite value, some
# cutting and at least one rebuild of the body, and the RSS between bodies after the warm-up
# (the first 20 %, at least 30 s from a minute on, extended to 10 s past the first rebuild but
# not past half the run: bench/soak.hpp) never more than 10 % of the working size (the largest
# RSS of any row in the warm-up) above the largest between bodies during it (column idle: the
# last body stopped and trimmed; every row unless bodies finish both during and after the warm-up).
#
# usage: soak.sh INCISE OUTDIR [SECONDS]
set -uo pipefail
incise=$1 out=$2 seconds=${3:-120}
rm -rf "$out"
"$incise" bench soak --seconds "$seconds" --out "$out" 2>&1 | tee "$out.log"
status=${PIPESTATUS[0]}
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
[ "$status" = 0 ] || fail "incise bench soak exit $status"
grep -q "^verdict: flat" "$out.log" || fail "no 'verdict: flat' in the bench's output"
csv=$out/soak.csv
[ -s "$csv" ] || { fail "no $csv"; exit 1; }
grep -qi "nan\|inf" "$csv" && fail "a non-finite figure in $csv"
awk -F, -v seconds="$seconds" '
  NR == 1 { next }
  { rows++; t[rows] = $1; rss[rows] = $2; cuts = $5; nonfinite = $7; rebuilds = $8; idle[rows] = $14
    if (nonfinite != 0) bad = bad "non-finite " nonfinite " at " $1 " s; "
    if (rebuilds > 0 && first_rebuild == "") first_rebuild = $1 }
  END {
    warm = seconds >= 60 ? (0.2 * seconds > 30 ? 0.2 * seconds : 30) : 0.2 * seconds
    if (first_rebuild != "") { w = first_rebuild + 10; if (w > seconds / 2) w = seconds / 2; if (w > warm) warm = w }
    if (rows > 0 && t[1] > warm) warm = t[1]
    for (i = 1; i <= rows; i++) if (idle[i] == 1) { if (t[i] > warm) idle_after = 1; else idle_before = 1 }
    by_idle = idle_before && idle_after
    for (i = 1; i <= rows; i++) {
      if (by_idle && idle[i] != 1) continue
      if (t[i] <= warm) { if (rss[i] > peak) peak = rss[i] } else { after++; if (rss[i] > top) top = rss[i] }
    }
    for (i = 1; i <= rows; i++) if (t[i] <= warm && rss[i] > work) work = rss[i]
    if (rows < seconds / 2) bad = bad "only " rows " rows; "
    if (cuts < 10) bad = bad "only " cuts " cut events; "
    if (rebuilds < 1) bad = bad "the body was never rebuilt; "
    if (after < 1 || peak <= 0) bad = bad "no RSS after the warm-up; "
    else if (top > peak + 0.10 * work) bad = bad sprintf("RSS %.1f MiB after the warm-up, %.1f MiB over its peak %.1f MiB: %.1f %% of the working size %.1f MiB; ", top, top - peak, peak, 100 * (top - peak) / work, work)
    printf "soak.csv: %d rows, %d cut events, %d rebuilds, RSS %s: warm-up (%.0f s) peak %.1f MiB, after it %.1f MiB; working size %.1f MiB\n", rows, cuts, rebuilds, by_idle ? "between bodies" : "over every row", warm, peak, top, work
    if (bad != "") { print "FAIL: " bad; exit 1 } }' "$csv" || failures=$((failures + 1))
[ "$failures" = 0 ]
