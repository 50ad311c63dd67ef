#!/usr/bin/env bash
# `incise bench performance --report-only`: OUT/report.html from a recorded performance.csv
# (tests/report/performance_sample.csv: a --quick run's 4 rows), rendered and checked as the
# run's page is; and a CSV with no row gives a page that says so.
#   performance_report.sh INCISE SAMPLE_CSV WORKDIR SCREENSHOT_CHECK
set -euo pipefail
incise=$1 sample=$2 work=$3 check=$4
fail() { echo "FAIL: $*"; exit 1; }
source "$(dirname "$0")/render_page.sh"
rm -rf "$work"
mkdir -p "$work/bench" "$work/empty"
cp "$sample" "$work/bench/performance.csv"
"$incise" bench performance --report-only --out "$work/bench"
page=$work/bench/report.html
[ "$(grep -c '<img class="plot"' "$page")" -eq 1 ] || fail "no plot on $page"
rows=$(grep -c '^<tr><td>' "$page")
[ "$rows" -eq 4 ] || fail "expected 4 table rows, found $rows"
grep -qE 'https?://|url\(' "$page" && fail "the page names a URL"
head -1 "$sample" > "$work/empty/performance.csv"
"$incise" bench performance --report-only --out "$work/empty"
grep -q 'holds no row' "$work/empty/report.html" || fail "the empty CSV's page does not say it has no row"

render_page "$page" "$work" 1400 "$check" 1
echo "ok: $rows rows"
