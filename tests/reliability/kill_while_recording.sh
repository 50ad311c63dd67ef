#!/usr/bin/env bash
# kill -9 while recording (issue 35). Starts `incise session --record` (and the window,
# `incise run --record`, under Xvfb) and kills it with SIGKILL at seeded random points. For
# every recording left behind:
#   - `trajectory info` reads it (exit 0: it ends on a chunk boundary; exit 2: a torn tail,
#     reported as such) and counts exactly the whole chunks on disk (walked here with od);
#   - what a torn tail drops is less than one chunk;
#   - the poses kept (time, position, orientation) are, bit for bit, the first poses of an
#     uninterrupted recording (the scripted device on simulated time is deterministic; the
#     forces are not, as solver.realtime stops CGs by the wall clock);
#   - `incise replay` of what was kept runs (exit 0).
# SIGKILL almost never lands inside a chunk's write, so every killed recording is also cut at
# a random byte of its last chunk (a torn write, as a crash during that write would leave):
# info must report exactly that chunk's bytes as dropped and the chunks before it as kept, and
# the replay of the rest must run. A reader that refused a torn tail fails here.
#
# usage: kill_while_recording.sh INCISE SCENE WORKDIR [KILLS] [WINDOW_KILLS] [SEED] [STEPS]
set -uo pipefail
incise=$1 scene=$2 work=$3
kills=${4:-20} window_kills=${5:-3} seed=${6:-35} steps=${7:-60}
dt=0.01                  # the scene's solver.dt (replay steps = kept time / dt)
max_chunk=$((16 + 250 * 80))  # the largest chunk the session writes (250 samples)
RANDOM=$seed
rm -rf "$work" && mkdir -p "$work" || exit 1
failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
now_ms() { echo $(($(date +%s%N) / 1000000)); }
u32_at() { od -An -tu4 -j "$2" -N4 "$1" | tr -d ' '; }

# Prints "whole_chunks last_sample_chunk_index last_sample_chunk_offset last_sample_chunk_bytes"
# for the chunks wholly on disk (every field is 4-byte aligned: one od for the whole file).
walk_chunks() {
  local file=$1 size offset=32 count=0 index=-1 last=0 bytes=0 payload words
  size=$(stat -c %s "$file")
  mapfile -t words < <(od -An -tu4 -v -w4 "$file")
  while [ $((offset + 16)) -le "$size" ]; do
    payload=${words[$(((offset + 8) / 4))]// /}
    [ $((offset + 16 + payload)) -le "$size" ] || break
    # "CHNK" read as a little-endian u32; the rest are CG stop chunks ("CGST")
    if [ "${words[$((offset / 4))]// /}" = 1263421507 ]; then index=$count last=$offset bytes=$((16 + payload)); fi
    count=$((count + 1))
    offset=$((offset + 16 + payload))
  done
  echo "$count $index $last $bytes"
}

# check FILE LABEL [REFERENCE_CSV]: the properties above; sets kept_samples and info_rc.
check() {
  local file=$1 label=$2 reference=${3:-} info chunks size walked t_last replay_steps
  info=$("$incise" trajectory info "$file" 2>&1)
  info_rc=$?
  info_text=$info
  echo "$label: $(echo "$info" | tr '\n' ' ')"
  if [ "$info_rc" != 0 ] && [ "$info_rc" != 2 ]; then fail "$label: trajectory info exit $info_rc"; return; fi
  kept_samples=$(echo "$info" | sed -n 's/.*: \([0-9]*\) samples in \([0-9]*\) chunks.*/\1/p' | head -1)
  chunks=$(echo "$info" | sed -n 's/.*: \([0-9]*\) samples in \([0-9]*\) chunks.*/\2/p' | head -1)
  walked=$(walk_chunks "$file")
  [ "$chunks" = "${walked%% *}" ] || fail "$label: info reads $chunks chunks, $walked whole on disk"
  size=$(stat -c %s "$file")
  if [ "$info_rc" = 2 ]; then
    local dropped from
    dropped=$(echo "$info" | sed -n 's/.*kept; \([0-9]*\) bytes of a torn chunk after byte \([0-9]*\).*/\1/p')
    from=$(echo "$info" | sed -n 's/.*kept; \([0-9]*\) bytes of a torn chunk after byte \([0-9]*\).*/\2/p')
    if [ -z "$dropped" ]; then fail "$label: damage that is not a torn tail"; return; fi
    [ "$dropped" -lt "$max_chunk" ] || fail "$label: $dropped bytes dropped, more than one chunk"
    [ $((from + dropped)) = "$size" ] || fail "$label: kept $from + dropped $dropped != $size bytes"
  fi
  if [ -n "$reference" ]; then
    "$incise" trajectory export "$file" --csv --out "$file.csv" 2>/dev/null
    head -n "$(wc -l <"$file.csv")" "$reference" | cut -d, -f1-8 | cmp -s - <(cut -d, -f1-8 "$file.csv") ||
      fail "$label: the poses kept are not the first poses of the uninterrupted recording"
  fi
  [ "${kept_samples:-0}" -gt 0 ] || return 0  # died before its first chunk: nothing to replay
  t_last=$(echo "$info" | sed -n 's/.* \.\. \([0-9.]*\) s$/\1/p' | head -1)
  replay_steps=$(awk -v t="$t_last" -v dt="$dt" 'BEGIN { print int(t / dt) }')
  "$incise" replay "$scene" --trajectory "$file" --steps "$replay_steps" --capture-every 0 --quiet \
    --out "$file.replay" >/dev/null 2>&1 || fail "$label: replay of what was kept ($replay_steps steps) exit $?"
}

# tear FILE LABEL [REFERENCE_CSV]: cut a copy inside its last sample chunk (a torn write of
# it: the CG stop chunks after it go too) and check info names exactly that loss.
tear() {
  local file=$1 label=$2 reference=${3:-} count index last bytes cut copy=$1.torn.traj before=$kept_samples
  read -r count index last bytes <<<"$(walk_chunks "$file")"
  [ "$index" -ge 0 ] || return 0
  cut=$((last + 1 + RANDOM % (bytes - 1)))
  head -c "$cut" "$file" >"$copy"
  check "$copy" "$label torn at byte $cut" "$reference"
  [ "$info_rc" = 2 ] || { fail "$label: a copy cut at byte $cut (inside its last sample chunk) reads as complete"; return; }
  echo "$info_text" | grep -q "torn tail: $index complete chunks kept; $((cut - last)) bytes of a torn chunk after byte $last were dropped" ||
    fail "$label: info does not say that chunk $index's $((cut - last)) bytes after byte $last were dropped"
  [ $((before - kept_samples)) -le 250 ] || fail "$label: tearing the last chunk lost $((before - kept_samples)) samples"
  torn_checked=$((torn_checked + 1))
}

# --- the headless session ---
reference_csv=$work/reference.csv
# The uninterrupted run's time, the shorter of two runs: a session keeps to real time, and one
# started beside a busy neighbour (ctest runs two tests at once) may take several times longer.
full_ms=
for pass in 1 2; do
  start=$(now_ms)
  "$incise" session "$scene" --steps "$steps" --record "$work/reference.traj" --out "$work/reference" --quiet ||
    { echo "FAIL: the uninterrupted session failed"; exit 1; }
  took=$(($(now_ms) - start))
  if [ -z "$full_ms" ] || [ "$took" -lt "$full_ms" ]; then full_ms=$took; fi
done
"$incise" trajectory export "$work/reference.traj" --csv --out "$reference_csv" || exit 1
echo "uninterrupted session: $steps steps in $full_ms ms, $(($(wc -l <"$reference_csv") - 1)) samples"

killed=0 torn_by_kill=0 empty=0 torn_checked=0
for i in $(seq 1 "$kills"); do
  file=$work/kill_$i.traj
  # Between a quarter and five sixths of the uninterrupted run's time (before, the world is
  # still being built and the file holds its header alone; later, a run on a quieter machine
  # than the reference's may have finished).
  delay=$((full_ms / 4 + RANDOM % (full_ms * 7 / 12 + 1)))
  "$incise" session "$scene" --steps "$steps" --record "$file" --out "$work/out_$i" --quiet >/dev/null 2>&1 &
  pid=$!
  sleep "$(awk -v ms="$delay" 'BEGIN { printf "%.3f", ms / 1000 }')"
  kill -KILL "$pid" 2>/dev/null
  wait "$pid" 2>/dev/null
  rc=$?
  if [ "$rc" = 137 ]; then killed=$((killed + 1)); label="kill $i at ${delay} ms"; else
    label="run $i (finished before its kill at ${delay} ms, exit $rc)"
    # It ran faster than the reference: draw the next kills within its time.
    full_ms=$((delay * 6 / 7))
  fi
  check "$file" "$label" "$reference_csv"
  [ "$info_rc" = 2 ] && torn_by_kill=$((torn_by_kill + 1))
  [ "${kept_samples:-0}" = 0 ] && empty=$((empty + 1))
  tear "$file" "$label" "$reference_csv"
done

# --- the window under Xvfb (real time: its samples are checked, not compared) ---
window_killed=0
display_runner=()
if [ -z "${DISPLAY:-}" ]; then
  if command -v xvfb-run >/dev/null 2>&1; then display_runner=(xvfb-run -a -s "-screen 0 1280x800x24"); else window_kills=0; echo "no display and no xvfb-run: window kills skipped"; fi
fi
trajectory=$(dirname "$scene")/../trajectories/$(basename "$scene" .json).traj
for i in $(seq 1 "$window_kills"); do
  file=$work/window_$i.traj pidfile=$work/window_$i.pid
  delay=$((2000 + RANDOM % 2000))
  "${display_runner[@]}" sh -c 'echo $$ >"$0"; exec "$@"' "$pidfile" "$incise" run "$scene" --device replay --play "$trajectory" \
    --record "$file" --frames 100000 >/dev/null 2>&1 &
  runner=$!
  sleep "$(awk -v ms="$delay" 'BEGIN { printf "%.3f", ms / 1000 }')"
  if [ -s "$pidfile" ] && kill -KILL "$(cat "$pidfile")" 2>/dev/null; then window_killed=$((window_killed + 1)); fi
  wait "$runner" 2>/dev/null
  [ -e "$file" ] || { fail "window $i: no recording after ${delay} ms"; continue; }
  check "$file" "window kill $i at ${delay} ms"
  tear "$file" "window kill $i"
done

echo "kill -9: $killed of $kills sessions killed ($torn_by_kill left a torn tail, $empty before their first chunk), $window_killed of $window_kills windows killed; $torn_checked copies torn inside their last sample chunk; $failures failure(s)"
[ "$killed" -ge $((kills / 2)) ] || fail "only $killed of $kills sessions were killed before they finished"
[ "$failures" = 0 ]
