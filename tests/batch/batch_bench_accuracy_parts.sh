#!/usr/bin/env bash
# The accuracy report on the batch path (issue 36): `bench accuracy --quick --cases
# bend,b1,traction --emit-manifest` in 3 parts (one unit each: the hexagon, the square, traction),
# run as two shards of the batch, merged, against the unsharded report of the same cases run here
# first. (The cut cases are left out for time: their body's references take most of the quick
# report, minutes here; the whole quick report joins the same way, docs/batch.md.) Every column of the joined accuracy.csv but the wall times (ms_per_step,
# preconditioner_build_ms, ms_per_step_jacobi, speedup_vs_jacobi: no two runs share them) is byte for byte the unsharded one's, and references.json is identical: each
# part solves the references of its own bodies, as the whole run does. A merge before every part
# is done joins nothing and says so.
# Usage: batch_bench_accuracy_parts.sh INCISE WORKDIR
set -euo pipefail
incise=$1 work=$2
cases=bend,b1,traction
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$work"
mkdir -p "$work"
# The CSV without its wall-time columns (found by name in the header).
untimed() {
  awk -F, -v OFS=, 'NR == 1 { for (i = 1; i <= NF; ++i)
                                if ($i == "ms_per_step" || $i == "preconditioner_build_ms" || $i == "ms_per_step_jacobi" ||
                                    $i == "speedup_vs_jacobi") drop[i] = 1 }
                    { line = ""; for (i = 1; i <= NF; ++i) if (!(i in drop)) line = line (line == "" ? "" : ",") $i; print line }' "$1"
}
start=$(date +%s)
"$incise" bench accuracy --quick --cases "$cases" --out "$work/whole" 2> "$work/whole.log" || { tail "$work/whole.log"; fail "the unsharded report"; }
whole_s=$(($(date +%s) - start))
"$incise" bench accuracy --quick --cases "$cases" --emit-manifest "$work/accuracy.json" --parts 3
"$incise" batch "$work/accuracy.json" --list | tee "$work/list.txt"
grep -q "accuracy_part_2 bench accuracy part 2/3" "$work/list.txt" || fail "--list does not show the parts"
start=$(date +%s)
"$incise" batch "$work/accuracy.json" --out "$work/out" --shard 0/2 2> "$work/shard0.log" || { cat "$work/shard0.log"; fail "shard 0/2"; }
shard0_s=$(($(date +%s) - start))
if "$incise" batch merge "$work/out" 2> "$work/early.log"; then fail "a merge with a part missing succeeded"; fi
grep -q "bench accuracy: 2 of 3 parts finished ok" "$work/early.log" || { cat "$work/early.log"; fail "the early merge does not say what is missing"; }
[ ! -e "$work/out/bench/accuracy/accuracy.csv" ] || fail "the early merge joined an incomplete report"
start=$(date +%s)
"$incise" batch "$work/accuracy.json" --out "$work/out" --shard 1/2 2> "$work/shard1.log" || { cat "$work/shard1.log"; fail "shard 1/2"; }
shard1_s=$(($(date +%s) - start))
"$incise" batch merge "$work/out" 2> "$work/merge.log" || { cat "$work/merge.log"; fail "merge"; }
joined=$work/out/bench/accuracy
head -1 "$joined/accuracy.csv" | grep -q ',ms_per_step,' || fail "no ms_per_step column in the joined CSV"
untimed "$work/whole/accuracy.csv" > "$work/whole_untimed.csv"
untimed "$joined/accuracy.csv" > "$work/joined_untimed.csv"
cmp "$work/joined_untimed.csv" "$work/whole_untimed.csv" || { diff "$work/whole_untimed.csv" "$work/joined_untimed.csv" | head; fail "the joined report differs from the unsharded one"; }
cmp "$joined/references.json" "$work/whole/references.json" || fail "the joined references.json differs from the unsharded one"
[ -s "$joined/report.html" ] || fail "no page for the joined report"
rows=0
for p in 0 1 2; do
  rows=$((rows + $(wc -l < "$work/out/jobs/accuracy_part_$p/accuracy.csv") - 1))
done
total=$(($(wc -l < "$work/whole/accuracy.csv") - 1))
[ "$rows" -eq "$total" ] || fail "the parts made $rows rows, the unsharded report $total"
[ "$(grep -c ',ok,' "$work/out/summary.csv")" -eq 3 ] || fail "summary.csv: $(cat "$work/out/summary.csv")"
echo "ok: 3 parts ($rows rows) in 2 shards joined into the unsharded report (every column but the wall times);" \
     "unsharded ${whole_s} s, shard 0/2 ${shard0_s} s, shard 1/2 ${shard1_s} s"
