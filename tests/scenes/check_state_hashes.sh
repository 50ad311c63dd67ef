#!/usr/bin/env bash
# Replays every scene listed in state_hashes.txt headless and compares its hashes with those
# recorded there: the motion hash (positions, velocities and dv, the state hash before it took
# the cut topology in) and the state hash (everything that decides the future). A refactoring
# must leave the simulation bit for bit as it was. Each replay also checks the scene's `expect`
# block (--check), so every shipped scene's expectations hold.
#   check_state_hashes.sh INCISE SCENES_DIR HASHES_FILE WORKDIR
set -euo pipefail
incise=$1 scenes=$2 hashes=$3 work=$4
rm -rf "$work"
mkdir -p "$work"
failed=0
while read -r name expected expected_state _; do
  case "$name" in ''|'#'*) continue ;; esac
  out=$work/$name
  if ! "$incise" replay "$scenes/$name.json" --out "$out" --capture-every 0 --quiet --check >"$out.log" 2>&1; then
    echo "FAIL: $name: incise replay exited non-zero"; tail -5 "$out.log"; failed=1; continue
  fi
  got=$(grep -o '"motion_hash": *"0x[0-9a-f]*"' "$out/metrics.json" | grep -o '0x[0-9a-f]*' || true)
  got_state=$(grep -o '"state_hash": *"0x[0-9a-f]*"' "$out/metrics.json" | grep -o '0x[0-9a-f]*' || true)
  if [ "$got" = "$expected" ] && [ "$got_state" = "$expected_state" ]; then
    echo "ok:   $name $got $got_state"
  else
    echo "FAIL: $name: motion_hash ${got:-none} (recorded $expected), state_hash ${got_state:-none} (recorded $expected_state)"; failed=1
  fi
done <"$hashes"
exit $failed
