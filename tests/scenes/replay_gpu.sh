#!/usr/bin/env bash
# The GPU backend from the command line (issue 6): a short replay of a cut scene with
# --backend gpu, twice (the same state hash: the GPU step is deterministic), with capture (the
# render context and the physics context on one thread), metrics naming the backend; and the
# same replay where compute is unavailable (INCISE_GPU_REQUIRE_GL=9.9 asks for a GL no driver
# has) must exit non-zero saying what was found, without metrics of a run.
# Usage: replay_gpu.sh INCISE SCENE WORKDIR STEPS
set -euo pipefail
incise=$1 scene=$2 work=$3 steps=$4
rm -rf "$work"
"$incise" replay "$scene" --backend gpu --steps "$steps" --capture-every "$steps" --size 160x120 --out "$work/a" --quiet
"$incise" replay "$scene" --backend gpu --steps "$steps" --capture-every 0 --out "$work/b" --quiet
hash_a=$(grep -o '"state_hash": "[^"]*"' "$work/a/metrics.json")
hash_b=$(grep -o '"state_hash": "[^"]*"' "$work/b/metrics.json")
[ "$hash_a" = "$hash_b" ] || { echo "gpu replays differ: $hash_a vs $hash_b"; exit 1; }
grep -q '"name": "gpu"' "$work/a/metrics.json" || { echo "metrics.json does not name the gpu backend"; exit 1; }
grep -q '"bytes_uploaded": [1-9]' "$work/a/metrics.json" || { echo "metrics.json has no gpu uploads"; exit 1; }
grep -q '"nonfinite_events": 0' "$work/a/metrics.json" || { echo "non-finite events on the gpu"; exit 1; }
[ -f "$work/a/frames/frame_000000.png" ] || { echo "no frame captured"; exit 1; }
set +e
message=$(INCISE_GPU_REQUIRE_GL=9.9 "$incise" replay "$scene" --backend gpu --steps 1 --out "$work/c" --quiet 2>&1)
code=$?
set -e
[ "$code" -ne 0 ] || { echo "a gpu replay without compute exited 0: $message"; exit 1; }
[ "$code" -lt 128 ] || { echo "a gpu replay without compute crashed (exit $code): $message"; exit 1; }
for expected in "solver.backend: 'gpu'" "OpenGL 9.9" "found OpenGL"; do
  case "$message" in *"$expected"*) ;; *) echo "expected '$expected' in: $message"; exit 1 ;; esac
done
echo "ok: $hash_a; refused: $(echo "$message" | head -1)"
