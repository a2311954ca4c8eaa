#!/usr/bin/env bash
# Is the benchmark report reproducible? Makes it twice (scripts/bench-report.sh, each into its
# own folder, bench/results untouched) and compares what its accuracy figures come from: every
# estimated trajectory (ours, GICP's, KISS-ICP's), every loop list and every map index, byte
# for byte; then the report's tables with the timing columns masked. Timings differ from run to
# run; nothing else may.
# usage: scripts/bench-repro.sh [--quick|--smoke]     (make bench-repro: --quick)
# (The full report's lifelong, place and map-store tables print timings in their own layouts,
# which this comparison does not mask: it takes the quick and smoke reports.)
# env: BUILD, WORK (default BUILD/bench-repro), and what bench-report.sh takes;
#      COMPARE_ONLY=1 compares the two reports already in WORK/a and WORK/b.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
WORK="${WORK:-$BUILD/bench-repro}"
mode="${1:---quick}"
case "$mode" in
  --quick|--smoke) ;;
  *) echo "usage: scripts/bench-repro.sh [--quick|--smoke]" >&2; exit 2 ;;
esac
if [ "${COMPARE_ONLY:-0}" != 1 ]; then
  rm -rf "$WORK"
  mkdir -p "$WORK"
  for run in a b; do
    echo "bench-repro: report $run ($mode) ..." >&2
    OUT="$WORK/$run" BUILD="$BUILD" bash "$here/scripts/bench-report.sh" "$mode" 2>"$WORK/$run.log" ||
      { echo "bench-repro: report $run failed:" >&2; tail -n 20 "$WORK/$run.log" >&2; exit 1; }
  done
fi
for run in a b; do
  [ -f "$WORK/$run/REPORT.md" ] || { echo "bench-repro: $WORK/$run/REPORT.md missing" >&2; exit 1; }
  # A benchmark that failed the same way twice is not a reproduced figure.
  if grep -q 'FAILED with exit status' "$WORK/$run/REPORT.md"; then
    echo "bench-repro: a benchmark failed in report $run ($WORK/$run/REPORT.md)" >&2
    exit 1
  fi
done

# The result files: trajectories (TUM and KITTI), loop lists, local-map lists.
results() {
  (cd "$1/work" && find . -type f \( -name 'trajectory*.tum' -o -name 'trajectory*.kitti' \
    -o -name 'loops.txt' -o -name 'relocalization.txt' -o -name 'map.rsmap' \) | LC_ALL=C sort)
}
same=0
diffs=()
while read -r f; do
  if [ ! -f "$WORK/b/work/$f" ]; then
    diffs+=("$f (only in the first run)")
  elif cmp -s "$WORK/a/work/$f" "$WORK/b/work/$f"; then
    same=$((same + 1))
  else
    diffs+=("$f")
  fi
done < <(results "$WORK/a")
while read -r f; do
  [ -f "$WORK/a/work/$f" ] || diffs+=("$f (only in the second run)")
done < <(results "$WORK/b")

# The report's table rows with every number that is a timing or a memory masked: in the
# tracking tables (five '|'-separated parts) ms per scan, stage times and peak memory, in the
# loop tables (three parts) the query and verification times; time ratios; lines of timings
# only (reading, vocabulary queries) are left out. A row of another shape is compared whole.
# Runs of spaces count as one: a wider timing (100.3 where it was 53.0) shifts the columns.
tables() {
  sed -n '/^```$/,/^```$/p' "$1" |
    { grep -v -E 'ms|MB|[0-9]+ s\b|scans/s|made |\(.* mode; |^(bin|rawlog) |^ *[0-9]+ +[0-9]+ +[0-9.]+ +[0-9.]+$' || true; } |
    sed -E 's/time [0-9.]+ x/time # x/' |
    awk -F"|" -v OFS="|" 'NF == 5 { gsub(/[0-9.]+/, "#", $1); $2 = "#"; $3 = "#" }
                           NF == 3 { $2 = "#" }
                           { gsub(/ +/, " "); print }'
}
tables "$WORK/a/REPORT.md" >"$WORK/a.tables"
tables "$WORK/b/REPORT.md" >"$WORK/b.tables"
rows=$(grep -c '[0-9]' "$WORK/a.tables" || true)
[ "$rows" -gt 0 ] || { echo "bench-repro: no table rows found in $WORK/a/REPORT.md" >&2; exit 1; }
if ! diff "$WORK/a.tables" "$WORK/b.tables" >"$WORK/tables.diff"; then
  diffs+=("REPORT.md tables (see $WORK/tables.diff)")
fi

if [ "$same" = 0 ]; then
  echo "bench-repro: no result files found under $WORK/a/work" >&2
  exit 1
fi
if [ ${#diffs[@]} -gt 0 ]; then
  echo "bench-repro: NOT reproducible: $same result files identical, ${#diffs[@]} differ:"
  printf '  %s\n' "${diffs[@]}"
  exit 1
fi
echo "bench-repro: reproducible (${mode#--}): $same result files identical in two runs (trajectories of every system, loop lists, maps), and $rows report rows with the timings masked"
