#!/usr/bin/env bash
# The benchmark report: runs the benchmarks one after the other and writes
# bench/results/REPORT.md with every table they print, the command and the time each took,
# the commit and the machine, and PNG plots beside it: trajectories from above against the
# ground truth (the paper's tracking, GICP and KISS-ICP on each input), ms per scan and memory
# over a run, and the loop detector's precision-recall curves. Written to the default OUT, it
# also puts its tables into README.md (scripts/readme-figures.sh).
#
# usage: scripts/bench-report.sh [--quick|--smoke]      (make bench / make bench-quick)
#   full:    benchmark.sh, benchmark-loops.sh, benchmark-mapping.sh, benchmark-sessions.sh,
#            rasterslam-bench-places and rasterslam-bench-map-store (about 90 minutes)
#   --quick: benchmark.sh (150-scan town drives) and benchmark-loops.sh (under 10 minutes)
#   --smoke: benchmark.sh on 40-scan drives without KITTI or KISS-ICP: checks the report's
#            making, not the figures (the test suite runs it)
# env: BUILD (build dir), OUT (default bench/results), and what the benchmarks take (DATA,
#      KISS, KISS_DIR, ANCHORS).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
OUT="${OUT:-$here/bench/results}"
bin="$BUILD/bin"
mode="${1:-full}"
case "$mode" in
  full|--quick|--smoke) ;;
  *) echo "usage: scripts/bench-report.sh [--quick|--smoke]" >&2; exit 2 ;;
esac
for p in rasterslam rasterslam-eval rasterslam-sim; do
  [ -x "$bin/$p" ] || { echo "bench-report: $bin/$p not built (make build)" >&2; exit 1; }
done
command -v jq >/dev/null || { echo "bench-report: jq is needed (scripts/install-deps.sh)" >&2; exit 1; }
mkdir -p "$OUT"
rm -f "$OUT"/*.png  # a plot a failed run did not make must not show the last report's
work="$OUT/work"
rm -rf "$work"
mkdir -p "$work"
report="$OUT/.REPORT.md.tmp-$$"
trap 'rm -f "$report"' EXIT

commit="$(git -C "$here" rev-parse --short HEAD 2>/dev/null || echo unknown)"
git -C "$here" diff --quiet HEAD -- . ':!bench/results' 2>/dev/null || commit="$commit (with uncommitted changes)"
cpu="$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n1)"
mem="$(awk '/MemTotal/{printf "%.0f GB", $2/1048576}' /proc/meminfo)"
{
  echo "# rasterslam benchmark report"
  echo
  echo "- commit: \`$commit\`; made $(date -u '+%Y-%m-%d %H:%M UTC') by \`scripts/bench-report.sh ${mode#--}\`"
  echo "- machine: $(nproc) cores ($cpu), $mem, $(. /etc/os-release 2>/dev/null && echo "$PRETTY_NAME")"
  echo "- every run pinned to one core unless its section says otherwise; timings vary by"
  echo "  about 10 % between identical runs on a shared machine, accuracy figures do not"
  echo
} >"$report"

# section TITLE COMMAND...: runs it with its output into the report, and the time it took.
section() {
  local title=$1; shift
  local log="$work/$(echo "$title" | tr -c 'a-zA-Z0-9\n' '-').log" t0 t1 rc=0
  echo "bench-report: $title ..." >&2
  t0=$(date +%s)
  "$@" >"$log" 2>"$log.err" || rc=$?
  t1=$(date +%s)
  {
    echo "## $title"
    echo
    echo "\`$(echo "$*" | sed "s#$here/##g")\` (${mode#--} mode; $((t1 - t0)) s$([ $rc = 0 ] || echo "; FAILED with exit status $rc"))"
    echo
    echo '```'
    sed "s#$here/##g" "$log"
    [ $rc = 0 ] || tail -n 20 "$log.err"
    echo '```'
    echo
  } >>"$report"
  return 0
}

# plot TITLE FILE: a PNG into the report (only when it was made).
plot() {
  [ -f "$OUT/$2" ] || return 0
  printf '![%s](%s)\n\n' "$1" "$2" >>"$report"
}

bench_env=(BUILD="$BUILD" WORK="$work/tracking")
case "$mode" in
  --smoke) bench_env+=(SIM_SCANS=40 SIM_LIMIT=40 KISS=0 DATA=/nonexistent) ;;
  --quick) bench_env+=(SIM_SCANS=150) ;;
esac
section "Tracking: the paper's method, GICP and KISS-ICP" env "${bench_env[@]}" bash "$here/scripts/benchmark.sh"

# Trajectory plots of what benchmark.sh ran.
t="$work/tracking"
D="${DATA:-$here/../shared/data/kitti00-0000-0100}"
trajplot() {  # trajplot PNG TITLE GT [--calib C] -- EST LABEL [EST LABEL ...]
  local png=$1 title=$2 gt=$3; shift 3
  local pre=() ests=() labels=()
  while [ $# -gt 0 ] && [ "$1" != -- ]; do pre+=("$1"); shift; done
  shift
  while [ $# -gt 1 ]; do [ -f "$1" ] && { ests+=("$1"); labels+=(--label "$2"); }; shift 2; done
  [ -f "$gt" ] && [ ${#ests[@]} -gt 0 ] || return 0
  local also=()
  for e in "${ests[@]:1}"; do also+=(--plot-also "$e"); done
  "$bin/rasterslam-eval" traj --gt "$gt" "${pre[@]}" --est "${ests[0]}" "${also[@]}" "${labels[@]}" \
    --segments 10:40:10 --title "$title" --plot "$OUT/$png" >/dev/null 2>"$work/$png.err" ||
    printf '(plot %s not made: %s)\n\n' "$png" "$(tail -n 1 "$work/$png.err")" >>"$report"
}
echo "### Trajectories from above" >>"$report"
echo >>"$report"
if [ -f "$t/kitti-vc0-tracking/trajectory.kitti" ]; then
  trajplot traj-kitti.png "KITTI 00 frames 0-100, SemanticKITTI poses" "$D/poses_semantickitti.txt" --calib "$D/calib.txt" -- \
    "$t/kitti-vc0-tracking/trajectory.kitti" tracking "$t/kitti-vc0-gicp-baseline/trajectory.kitti" GICP \
    "$t/kitti-vc0-kiss/trajectory.kitti" KISS-ICP
  plot "KITTI 00 frames 0-100 against the SemanticKITTI poses" traj-kitti.png
fi
for scen in town-loop town-vlp16 town-sweep indoor-handheld town-kitti; do
  case "$scen" in
    town-sweep) a=tracking+deskew b=gicp-baseline+deskew ;;
    indoor-handheld) a=indoor b=gicp-indoor ;;
    *) a=tracking b=gicp-baseline ;;
  esac
  trajplot "traj-$scen.png" "rawlogs/$scen.yaml" "$t/sim-$scen-$a/groundtruth.tum" -- \
    "$t/sim-$scen-$a/trajectory.tum" "$a" "$t/sim-$scen-$b/trajectory.tum" "$b" \
    "$t/sim-$scen-kiss/trajectory.kitti" KISS-ICP
  plot "rawlogs/$scen.yaml" "traj-$scen.png"
done

# Cost over a run: ms per scan and resident memory.
runs=()
for r in kitti-vc0-tracking sim-town-loop-tracking sim-town-vlp16-tracking; do
  [ -f "$t/$r/timings.csv" ] && runs+=("$t/$r" --label "$r")
done
if [ ${#runs[@]} -gt 0 ]; then
  "$bin/rasterslam-eval" timings "${runs[@]}" --plot "$OUT/timings-tracking.png" >/dev/null 2>"$work/timings.err" ||
    printf '(plot timings-tracking.png not made: %s)\n\n' "$(tail -n 1 "$work/timings.err")" >>"$report"
  echo "### Cost over a run (the paper's tracking)" >>"$report"
  echo >>"$report"
  plot "ms per scan and memory over a run" timings-tracking.png
fi

if [ "$mode" != --smoke ]; then
  section "Loop closure: BOW against the search baselines" env BUILD="$BUILD" WORK="$work/loops" bash "$here/scripts/benchmark-loops.sh"
  echo "### Precision-recall of the BOW loop detector" >>"$report"
  echo >>"$report"
  for scen in town-vlp16 town-loop; do
    r="$work/loops/$scen-bow"
    [ -f "$r/loops.txt" ] || continue
    "$bin/rasterslam-eval" loops --loops "$r/loops.txt" --gt "$r/groundtruth.tum" --plot "$OUT/pr-$scen.png" >/dev/null 2>"$work/pr.err" ||
      printf '(plot pr-%s.png not made: %s)\n\n' "$scen" "$(tail -n 1 "$work/pr.err")" >>"$report"
    plot "precision-recall, rawlogs/$scen.yaml" "pr-$scen.png"
  done
fi

if [ "$mode" = full ]; then
  section "Mapping: the whole system against tracking alone" env BUILD="$BUILD" WORK="$work/mapping" bash "$here/scripts/benchmark-mapping.sh"
  for f in "$work"/mapping/*-slam/timings.png; do
    [ -f "$f" ] || continue
    n="timings-$(basename "$(dirname "$f")").png"
    cp "$f" "$OUT/$n"
    plot "ms per scan and memory, $(basename "$(dirname "$f")")" "$n"
  done
  section "Lifelong: ten sessions over one town that changes" env BUILD="$BUILD" WORK="$work/sessions" bash "$here/scripts/benchmark-sessions.sh"
  section "Place recognition among distractors" "$bin/rasterslam-bench-places" --scenario "$here/rawlogs/town-loop.yaml" \
    --vocabulary "$here/share/rasterslam/vocab/elevation-k10l4.vocab" --towns 22 --queries 10
  section "Place recognition among 1,000 local maps" "$bin/rasterslam-bench-places" --scenario "$here/rawlogs/town-loop.yaml" \
    --vocabulary "$here/share/rasterslam/vocab/elevation-k10l4.vocab" --towns 42 --queries 10 --local-maps --other-towns 5
  street=()  # the KITTI sample's real street among the towns, when it is there
  [ -d "$D/velodyne" ] && street=(--kitti "$D")
  section "Place recognition among 1,000 local maps and the KITTI street, local-map queries, verified" "$bin/rasterslam-bench-places" --scenario "$here/rawlogs/town-loop.yaml" \
    --vocabulary "$here/share/rasterslam/vocab/elevation-k10l4.vocab" --towns 42 --queries 10 --local-maps --other-towns 5 --query-local-maps --verify "${street[@]}"
  for v in elevation-k10l4 elevation-localmaps-3m-k10l4; do  # the scan and the local-map vocabulary
    section "Place recognition among 1,000 local maps of lifelong.yaml's 3 m band, $v.vocab" "$bin/rasterslam-bench-places" --scenario "$here/rawlogs/town-loop.yaml" \
      --vocabulary "$here/share/rasterslam/vocab/$v.vocab" --towns 42 --queries 10 --local-maps --other-towns 5 --query-local-maps --max-height 3 --verify
  done
  section "Place recognition among 1,000 local maps of the 3 m band, polar contexts fused with the words (verified)" "$bin/rasterslam-bench-places" --scenario "$here/rawlogs/town-loop.yaml" \
    --vocabulary "$here/share/rasterslam/vocab/elevation-localmaps-3m-k10l4.vocab" --towns 42 --queries 10 --local-maps --other-towns 5 --query-local-maps --max-height 3 --verify --polar
  section "Map store: save and load of 1,000 local maps" "$bin/rasterslam-bench-map-store"
fi

mv "$report" "$OUT/REPORT.md"
trap - EXIT
echo "bench-report: wrote $OUT/REPORT.md" >&2
# The README's tables are this report's when it is the committed one (the default OUT).
if [ "$mode" != --smoke ] && [ "$OUT" -ef "$here/bench/results" ]; then
  bash "$here/scripts/readme-figures.sh" >&2
fi
