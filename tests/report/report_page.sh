#!/usr/bin/env bash
# issue 33: a short replay with --report, its page rendered by headless Chromium and checked.
#   report_page.sh INCISE SCENE WORKDIR SCREENSHOT_CHECK [DOCS_PNG]
# Asserts: report.html and replay.mp4 (H.264, yuv420p) are written; the page refers to nothing
# outside the run folder; `incise report` refuses a folder that is not a run and plots a
# session's; Chromium loads
# the page with no console error; the screenshot is not uniform and each plot's region holds
# a plot. With DOCS_PNG, also writes the README's small screenshot there.
# Exit 77 (skipped) after the checks that need no browser when chromium is not installed.
set -euo pipefail
incise=$1 scene=$2 work=$3 check=$4 docs_png=${5:-}
fail() { echo "FAIL: $*"; exit 1; }
source "$(dirname "$0")/render_page.sh"
rm -rf "$work"
mkdir -p "$work"
run=$work/run
"$incise" replay "$scene" --steps 60 --capture-every 10 --size 320x240 --out "$run" --report --quiet
page=$run/report.html
[ -s "$page" ] || fail "$page not written"

# Nothing outside the run folder: every src/href is a data: URI or a relative path inside it
# that exists, no URL anywhere (base64 has no ':'), no CSS url().
grep -qE 'https?://|url\(' "$page" && fail "the page names a URL: $(grep -oE 'https?://[^"]*|url\([^)]*' "$page" | head -3)"
refs=$(grep -oE '(src|href)="[^"]*"' "$page" | sed -E 's/^(src|href)="//; s/"$//' | grep -v '^data:' || true)
refs+=$'\n'$(grep -oE '"frames/[^"]*"' "$page" | tr -d '"' || true)
while read -r ref; do
  [ -z "$ref" ] && continue
  case "$ref" in /* | *..* | *:*) fail "the page refers outside its folder: $ref" ;; esac
  [ -e "$run/$ref" ] || fail "the page refers to $ref, which is not in $run"
done <<< "$refs"
plots=$(grep -c '<img class="plot"' "$page")
[ "$plots" -ge 6 ] || fail "expected at least 6 plots on the page, found $plots"
grep -q '<tr class="pass">' "$page" || fail "no passed expectation on the page"

# The video: H.264 in yuv420p from the 7 frames (steps 0, 10, ..., 60).
if command -v ffprobe > /dev/null; then
  probe=$(ffprobe -v error -select_streams v:0 -count_frames \
          -show_entries stream=codec_name,pix_fmt,width,height,nb_read_frames -of csv=p=0 "$run/replay.mp4")
  [ "$probe" = "h264,320,240,yuv420p,7" ] || fail "replay.mp4: $probe (expected h264,320,240,yuv420p,7)"
  echo "replay.mp4: $probe"
fi

# A session's folder (session.json and steps.csv, no frames): plotted, the frames said missing.
"$incise" session "$(dirname "$scene")/haptics_block.json" --steps 20 --out "$work/session" --report --quiet
grep -q 'Haptic session, 20 steps' "$work/session/report.html" || fail "the session's page does not describe it"
[ "$(wc -l < "$work/session/steps.csv")" -eq 21 ] || fail "the session's steps.csv has not 20 rows"
session_plots=$(grep -c '<img class="plot"' "$work/session/report.html")
[ "$session_plots" -ge 5 ] || fail "the session's page has $session_plots plots"
grep -q 'no frames were captured' "$work/session/report.html" || fail "the session's page does not say it has no frames"

# Not a run folder: refused, the missing file named.
mkdir -p "$work/empty"
if "$incise" report "$work/empty" 2> "$work/refusal.txt"; then fail "incise report accepted $work/empty"; fi
grep -q "$work/empty/metrics.json" "$work/refusal.txt" || fail "the refusal does not name metrics.json: $(cat "$work/refusal.txt")"

render_page "$page" "$work" 4200 "$check" 6

if [ -n "$docs_png" ]; then
  # The README's picture: the top of the page at half scale, kept small.
  timeout 120 "${headless[@]/--window-size=1200,4200/--window-size=1100,1900}" --force-device-scale-factor=0.5 \
    --screenshot="$docs_png" "file://$page" > /dev/null 2>&1
  size=$(stat -c %s "$docs_png")
  [ "$size" -lt 153600 ] || fail "$docs_png is $size bytes (keep it under 150 KB)"
  echo "wrote $docs_png ($size bytes)"
fi
echo "ok: $plots plots, page $(stat -c %s "$page") bytes"
