#!/usr/bin/env bash
# A cut scene end to end (issue 4): replays it headless without frames and checks its expect
# block (--check), then, from metrics.json, that the cut never changed the DOF count
# (dofs.initial == dofs.final: expect cannot compare two metrics) and that the surface was
# closed after every cut event, and that metrics.json's `expect` holds the same verdicts.
#   replay_cut_scene.sh INCISE SCENE WORKDIR            the full replay
#   replay_cut_scene.sh INCISE SCENE WORKDIR --smoke N  N steps only, no --check (the scene's
#                                                       bounds are for the whole replay), DOFs only
set -euo pipefail
incise=$1 scene=$2 work=$3
smoke_steps=
if [ "${4:-}" = "--smoke" ]; then smoke_steps=${5:?--smoke needs a step count}; fi
rm -rf "$work"
mkdir -p "$work"
metrics=$work/metrics.json
status=0
if [ -n "$smoke_steps" ]; then
  "$incise" replay "$scene" --out "$work" --capture-every 0 --quiet --steps "$smoke_steps" || status=$?
else
  "$incise" replay "$scene" --out "$work" --check --capture-every 0 --quiet || status=$?
fi
[ -f "$metrics" ] || { echo "FAIL: no $metrics (replay exit $status)"; exit 1; }
if [ "$status" -ne 0 ]; then
  echo "FAIL: incise replay exited $status"
  grep -o '"error": "[^"]*"' "$metrics" || true
  exit 1
fi

# "dofs": {"final": F, "initial": I} (the top-level object; bodies[] have a plain "dofs": N).
read -r initial final < <(awk '
  /"dofs": \{/ { inside = 1; next }
  inside && /"initial":/ { gsub(/[^0-9]/, "", $2); initial = $2 }
  inside && /"final":/ { gsub(/[^0-9]/, "", $2); final = $2 }
  inside && /\}/ { inside = 0 }
  END { print (initial == "" ? "none" : initial), (final == "" ? "none" : final) }' "$metrics")
if [ "$initial" = none ] || [ "$final" = none ]; then echo "FAIL: no dofs {initial, final} in $metrics"; exit 1; fi
if [ "$initial" != "$final" ]; then echo "FAIL: dofs.initial $initial != dofs.final $final"; exit 1; fi

if [ -z "$smoke_steps" ]; then
  if ! grep -q '"watertight_after_every_event": true' "$metrics"; then
    echo "FAIL: surface.watertight_after_every_event is not true:"
    grep -E '"(worst_boundary_edges|worst_nonmanifold_edges|watertight_after_every_event)"' "$metrics" || true
    exit 1
  fi
  # metrics.json records the same verdicts as --check printed (each with its value).
  if grep -q '"passed": false' "$metrics"; then
    echo "FAIL: metrics.json records a failed expectation though --check passed:"
    grep -B2 -A2 '"passed": false' "$metrics" || true
    exit 1
  fi
  events=$(grep -o '"events": [0-9][0-9]*' "$metrics" | head -1)
  echo "ok: $(basename "$scene"): dofs $initial == $final, closed after every cut event (${events:-\"events\": ?})"
else
  events=$(grep -o '"events": [0-9][0-9]*' "$metrics" | head -1)
  echo "ok: $(basename "$scene"), $smoke_steps steps: dofs $initial == $final (${events:-no cut events})"
fi
