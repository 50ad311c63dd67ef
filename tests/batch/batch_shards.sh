#!/usr/bin/env bash
# incise batch end to end on sweep.json: the whole batch in one process; the same as two
# shards merged (same rows, same state hashes); a failed job recorded while the others run;
# resume. Usage: batch_shards.sh INCISE MANIFEST WORKDIR
set -euo pipefail
incise=$1 manifest=$2 work=$3
rm -rf "$work"
source "$(dirname "$0")/summary_columns.sh"

# --list: the expanded jobs, nothing written.
"$incise" batch "$manifest" --list --out "$work/listed" > "$work.list.log"
grep -q ': 5 jobs$' "$work.list.log" && grep -q '^2 beam-002 efg_beam.json bodies.0.resolution=0.005 bodies.0.material.E=20000000.0$' "$work.list.log" || {
  cat "$work.list.log"; exit 1; }
[ ! -e "$work/listed" ] || { echo "--list wrote into --out"; exit 1; }

# The whole batch: the bad job fails, so the exit code is 1, and the others all ran.
if "$incise" batch "$manifest" --out "$work/all" 2> "$work.all.log"; then
  echo "a batch with a failed job exited 0"; cat "$work.all.log"; exit 1
fi
grep -q 'shard 0/1: 5 jobs, 5 run, 0 finished before, 1 failed' "$work.all.log" || { cat "$work.all.log"; exit 1; }
grep -q '1 of 5 jobs failed' "$work.all.log" || { echo "the failure is not said"; cat "$work.all.log"; exit 1; }
summary=$work/all/summary.csv
[ "$(grep -c ',ok,0x[0-9a-f]\{16\},' "$summary")" -eq 4 ] || { echo "expected 4 ok jobs with a state hash:"; cat "$summary"; exit 1; }
grep '^bad_modulus,failed,,' "$summary" | grep -q 'bodies\[0\].material.E' || {
  echo "the bad job's row does not name its field:"; cat "$summary"; exit 1; }
grep -q '"outcome": "failed"' "$work/all/jobs/bad_modulus/outcome.json"
[ -f "$work/all/jobs/beam-001/metrics.json" ] && [ -f "$work/all/jobs/beam-001/steps.csv" ] || { echo "a job's metrics are missing"; exit 1; }
[ ! -d "$work/all/jobs/beam-001/frames" ] || { echo "frames written unasked"; exit 1; }
[ "$(ls "$work/all/jobs/block/frames" | grep -c '^frame_0000[01][0-9]\.png$')" -eq 3 ] || {
  echo "the block job's frames (steps 0, 5, 10) are missing:"; ls -R "$work/all/jobs/block"; exit 1; }
# Different moduli give different states: the overrides reached the scene.
[ "$(cut -d, -f3 "$summary" | grep -c '^0x')" -eq "$(cut -d, -f3 "$summary" | grep '^0x' | sort -u | wc -l)" ] || {
  echo "two jobs of the grid share a state hash:"; cat "$summary"; exit 1; }

# Two shards into one folder, then the merge: the same summary but for the timings.
"$incise" batch "$manifest" --out "$work/sharded" --shard 0/2 2> "$work.s0.log" || true
"$incise" batch "$manifest" --out "$work/sharded" --shard 1/2 2> "$work.s1.log" || true
grep -q 'shard 0/2: 3 jobs, 3 run' "$work.s0.log" && grep -q 'shard 1/2: 2 jobs, 2 run' "$work.s1.log" || {
  cat "$work.s0.log" "$work.s1.log"; exit 1; }
"$incise" batch merge "$work/sharded" 2> /dev/null && { echo "merge of a batch with a failed job exited 0"; exit 1; }
diff <(summary_columns "$summary") <(summary_columns "$work/sharded/summary.csv") || {
  echo "the two shards merged differ from the whole batch"; exit 1; }

# Resume: a rerun runs nothing; with one outcome removed, it runs that job only, to the same state.
before=$(stat -c %Y.%s "$work/all/jobs/beam-000/outcome.json")
"$incise" batch "$manifest" --out "$work/all" 2> "$work.resume.log" || true
grep -q 'shard 0/1: 5 jobs, 0 run, 5 finished before, 1 failed' "$work.resume.log" || { cat "$work.resume.log"; exit 1; }
[ "$before" = "$(stat -c %Y.%s "$work/all/jobs/beam-000/outcome.json")" ] || { echo "a finished job was rewritten"; exit 1; }
cp "$summary" "$work/summary.before.csv"
rm "$work/all/jobs/beam-002/outcome.json"
"$incise" batch "$manifest" --out "$work/all" 2> "$work.resume.log" || true
grep -q 'shard 0/1: 5 jobs, 1 run, 4 finished before' "$work.resume.log" || { cat "$work.resume.log"; exit 1; }
diff <(summary_columns "$work/summary.before.csv") <(summary_columns "$summary") || { echo "the resumed job differs"; exit 1; }
# Another manifest into the same folder is refused before it runs anything.
other=$(dirname "$manifest")/../../assets/batch/example.json
if "$incise" batch "$other" --out "$work/all" 2> "$work.other.log"; then echo "another batch ran into the folder"; exit 1; fi
grep -q 'holds another batch' "$work.other.log" || { cat "$work.other.log"; exit 1; }
[ ! -d "$work/all/jobs/block-000" ] || { echo "another batch's job ran"; exit 1; }

echo "ok: $(grep -c . "$summary") lines in summary.csv; two shards merged match the whole batch; resume skips finished jobs"
