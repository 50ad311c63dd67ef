#!/usr/bin/env bash
# mpirun -n 2 incise batch: each rank takes its shard, rank 0 merges; the summary must be the
# whole batch's. Exits 77 (ctest: skipped) when incise is built without MPI.
# Usage: batch_mpi.sh INCISE MANIFEST WORKDIR HAVE_MPI MPIEXEC
set -euo pipefail
incise=$1 manifest=$2 work=$3 have_mpi=$4 mpiexec=$5
if [ "$have_mpi" != "ON" ] || [ ! -x "$mpiexec" ]; then
  echo "skipped: incise is built without MPI (apt-get install libopenmpi-dev openmpi-bin, then reconfigure)"
  exit 77
fi
rm -rf "$work"
source "$(dirname "$0")/summary_columns.sh"
"$incise" batch "$manifest" --out "$work/one" 2> "$work.one.log" || true
# As root (containers, CI) OpenMPI wants to be told; --oversubscribe: more ranks than cores.
root=()
[ "$(id -u)" -eq 0 ] && root=(--allow-run-as-root)
"$mpiexec" "${root[@]}" --oversubscribe -n 2 "$incise" batch "$manifest" --out "$work/ranks" > "$work.mpi.log" 2>&1 || true
grep -q 'shard 0/2: 3 jobs, 3 run' "$work.mpi.log" && grep -q 'shard 1/2: 2 jobs, 2 run' "$work.mpi.log" || {
  echo "the ranks did not take shards 0/2 and 1/2:"; cat "$work.mpi.log"; exit 1; }
[ -f "$work/ranks/summary.csv" ] || { echo "rank 0 did not merge"; cat "$work.mpi.log"; exit 1; }
diff <(summary_columns "$work/one/summary.csv") <(summary_columns "$work/ranks/summary.csv") || {
  echo "mpirun's summary differs from the whole batch's"; exit 1; }
echo "ok: mpirun -n 2 gives the whole batch's summary ($(grep -c ',ok,' "$work/ranks/summary.csv") jobs ok)"
