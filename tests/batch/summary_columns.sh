# summary_columns SUMMARY.csv: the columns a rerun must reproduce (job, outcome, state_hash
# and the override keys: every column before `scene`), without the timings after it. The
# manifests it reads override with scalars, so none of these fields is quoted with a comma.
summary_columns() {
  local last
  last=$(head -1 "$1" | tr ',' '\n' | grep -n '^scene$' | cut -d: -f1)
  cut -d, -f1-$((last - 1)) "$1"
}
