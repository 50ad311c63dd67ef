#!/usr/bin/env bash
# The default scene end to end: a short replay with capture, twice; same state hash, frames
# written, expectations checked. Usage: replay_smoke.sh INCISE SCENE WORKDIR
set -euo pipefail
incise=$1 scene=$2 work=$3
rm -rf "$work"
"$incise" replay "$scene" --steps 12 --capture-every 6 --size 160x120 --out "$work/a" --quiet
"$incise" replay "$scene" --steps 12 --capture-every 0 --out "$work/b" --quiet
hash_a=$(grep -o '"state_hash": "[^"]*"' "$work/a/metrics.json")
hash_b=$(grep -o '"state_hash": "[^"]*"' "$work/b/metrics.json")
[ "$hash_a" = "$hash_b" ] || { echo "state hash differs with and without capture: $hash_a vs $hash_b"; exit 1; }
frames=$(ls "$work/a/frames" | grep -c '^frame_0000[0-9][0-9]\.png$')
[ "$frames" -eq 3 ] || { echo "expected 3 frames (steps 0, 6, 12), found $frames"; exit 1; }
for f in "$work/a/frames"/*.png; do
  head -c 8 "$f" | od -An -tx1 | grep -q '89 50 4e 47 0d 0a 1a 0a' || { echo "$f is not a PNG"; exit 1; }
done
grep -q '"nonfinite_events": 0' "$work/a/metrics.json" || { echo "non-finite events in the default scene"; exit 1; }
echo "ok: $hash_a, $frames frames"
