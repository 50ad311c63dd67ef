#!/usr/bin/env bash
# The stability sweep on the batch path (issue 36): `bench stability --quick --emit-manifest`
# in 3 parts, run as two shards of the batch, merged: the joined stability.csv is byte for byte
# the unsharded sweep's (REFERENCE: bench_stability_quick's, the runs are deterministic), and
# the merge writes the sweep's summary (with the thin-slice study), plot and page. A merge
# before every part is done joins nothing and says so.
# Usage: batch_bench_parts.sh INCISE REFERENCE_CSV WORKDIR
set -euo pipefail
incise=$1 reference=$2 work=$3
fail() { echo "FAIL: $*"; exit 1; }
[ -s "$reference" ] || fail "no reference sweep $reference (bench_stability_quick runs first)"
rm -rf "$work"
mkdir -p "$work"
"$incise" bench stability --quick --emit-manifest "$work/stability.json" --parts 3
"$incise" batch "$work/stability.json" --list | tee "$work/list.txt"
grep -q "stability_part_2 bench stability part 2/3" "$work/list.txt" || fail "--list does not show the parts"
"$incise" batch "$work/stability.json" --out "$work/out" --shard 0/2 2> "$work/shard0.log" || { cat "$work/shard0.log"; fail "shard 0/2"; }
if "$incise" batch merge "$work/out" 2> "$work/early.log"; then fail "a merge with a part missing succeeded"; fi
grep -q "bench stability: 2 of 3 parts finished ok" "$work/early.log" || { cat "$work/early.log"; fail "the early merge does not say what is missing"; }
[ ! -e "$work/out/bench/stability/stability.csv" ] || fail "the early merge joined an incomplete sweep"
"$incise" batch "$work/stability.json" --out "$work/out" --shard 1/2 2> "$work/shard1.log" || { cat "$work/shard1.log"; fail "shard 1/2"; }
"$incise" batch merge "$work/out" 2> "$work/merge.log" || { cat "$work/merge.log"; fail "merge"; }
joined=$work/out/bench/stability
cmp "$joined/stability.csv" "$reference" || { diff "$reference" "$joined/stability.csv" | head; fail "the joined sweep differs from the unsharded one"; }
grep -q '^Thin-slice study' "$joined/stability_summary.txt" || fail "no thin-slice study in the joined summary"
[ -s "$joined/report.html" ] || fail "no page for the joined sweep"
parts=0
for p in 0 1 2; do
  rows=$(($(wc -l < "$work/out/jobs/stability_part_$p/stability.csv") - 1))
  parts=$((parts + rows))
done
total=$(($(wc -l < "$reference") - 1))
[ "$parts" -eq "$total" ] || fail "the parts ran $parts runs, the sweep has $total"
[ "$(grep -c ',ok,' "$work/out/summary.csv")" -eq 3 ] || fail "summary.csv: $(cat "$work/out/summary.csv")"
echo "ok: 3 parts ($parts runs) in 2 shards joined into the unsharded sweep, byte for byte"
