#!/usr/bin/env bash
# Benchmark: runs pipeline configs on the same inputs, one after the other, and prints for
# each: ms per scan (median and 95th percentile of the whole path, and the median of every
# stage), peak memory, and accuracy (ATE; KITTI-devkit relative translation and rotation
# errors). Inputs: the KITTI sample (../shared/data/kitti00-0000-0100, against the
# SemanticKITTI and the official poses, 10..80 m segments) and a simulated town drive.
#
# usage: scripts/benchmark.sh [CONFIG.yaml ...]
#   default configs: share/rasterslam/config/tracking.yaml (the paper's tracking) and
#   share/rasterslam/config/gicp-baseline.yaml.  Env: BUILD (build dir), DATA, SIM_SCANS.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
DATA="${DATA:-$here/../shared/data/kitti00-0000-0100}"
WORK="${WORK:-$BUILD/bench}"
SIM_SCANS="${SIM_SCANS:-300}"
bin="$BUILD/bin"
# One core, as the goals are stated: OpenCV would otherwise spread some work over both.
PIN=""
command -v taskset >/dev/null 2>&1 && PIN="taskset -c 0"
[ $# -gt 0 ] || set -- "$here/share/rasterslam/config/tracking.yaml" "$here/share/rasterslam/config/gicp-baseline.yaml"
mkdir -p "$WORK"

# A value of a rasterslam-eval --json object by its jq path: json "$j" .ate_rmse_m (empty for null).
json() { jq -r "$2 // empty" <<<"$1"; }
yamlv() { sed -n "s/^ *$2: *\([-0-9.eE+]*\).*/\1/p" "$1" | head -n1; }
# median of column $2 (1-based) of a CSV with a header
colmed() { awk -F, -v c="$2" 'NR>1{print $c}' "$1" | sort -g | awk '{a[NR]=$1} END{if(NR) print a[int((NR+1)/2)]; else print 0}'; }

header() {
  printf '%-16s %7s %7s | %6s %6s %6s %6s | %7s | %7s %9s %7s | %7s %7s\n' config "ms/scan" p95 read raster odom other "peak MB" "RTE %" "RRE deg/m" "ATE m" "RTE %" "ATE m"
  printf '%-16s %7s %7s | %27s | %7s | %25s | %15s\n' "" median "" "stage medians (ms)" "" "$1" "$2"
}

row() {  # row NAME OUTDIR JSON1 JSON2
  local t="$2/timings.csv" y="$2/run.yaml"
  local other
  other=$(awk -F, 'NR>1{print $11+$12}' "$t" | sort -g | awk '{a[NR]=$1} END{print a[int((NR+1)/2)]}')
  printf '%-16s %7.1f %7.1f | %6.2f %6.2f %6.2f %6.2f | %7.0f | %7.3f %9.4f %7.3f | %7s %7s\n' "$1" \
    "$(yamlv "$y" ms_per_scan_median)" "$(yamlv "$y" ms_per_scan_p95)" \
    "$(colmed "$t" 8)" "$(colmed "$t" 9)" "$(colmed "$t" 10)" "$other" "$(yamlv "$y" peak_rss_mb)" \
    "$(json "$3" .rel_trans_pct)" "$(json "$3" .rel_rot_deg_per_m)" "$(json "$3" .ate_rmse_m)" \
    "${4:+$(printf '%.3f' "$(json "$4" .rel_trans_pct)")}" "${4:+$(printf '%.3f' "$(json "$4" .ate_rmse_m)")}"
}

rate_note() {  # speed ratio of the first config against the last
  local a b
  a=$(yamlv "$1/run.yaml" ms_per_scan_median); b=$(yamlv "$2/run.yaml" ms_per_scan_median)
  awk -v a="$a" -v b="$b" -v n1="$3" -v n2="$4" 'BEGIN{printf "%s runs %.1f times the rate of %s (median ms/scan %.1f vs %.1f)\n", n1, b/a, n2, a, b}'
}

# --- KITTI ---------------------------------------------------------------------------
if [ -d "$DATA" ]; then
  for vc in 0 0.205; do
    rawlog="$WORK/kitti00-0000-0100-vc$vc.rawlog"
    [ -f "$rawlog" ] || "$bin/kitti2rawlog" --velodyne "$DATA/velodyne" --poses "$DATA/poses_semantickitti.txt" \
        --calib "$DATA/calib.txt" --times "$DATA/times.txt" --compress 0 --vertical-correction-deg "$vc" -o "$rawlog" >/dev/null
    echo "KITTI 00 frames 0-100 (101 HDL-64E scans, 84 m; plain rawlog; vertical angle correction $vc deg); relative errors on 10..80 m segments"
    header "vs SemanticKITTI poses" "vs official"
    outs=(); names=()
    for cfg in "$@"; do
      name="$(basename "$cfg" .yaml)"; out="$WORK/kitti-vc$vc-$name"
      $PIN "$bin/rasterslam" run --rawlog "$rawlog" --config "$cfg" --out "$out" --quiet >/dev/null
      sem=$("$bin/rasterslam-eval" traj --gt "$DATA/poses_semantickitti.txt" --calib "$DATA/calib.txt" --est "$out/trajectory.kitti" --segments 10:80:10 --json)
      off=$("$bin/rasterslam-eval" traj --gt "$DATA/poses_official.txt" --calib "$DATA/calib.txt" --est "$out/trajectory.kitti" --segments 10:80:10 --json)
      row "$name" "$out" "$sem" "$off"
      outs+=("$out"); names+=("$name")
    done
    [ ${#outs[@]} -lt 2 ] || rate_note "${outs[0]}" "${outs[-1]}" "${names[0]}" "${names[-1]}"
    echo
  done
else
  echo "benchmark: $DATA not found: KITTI part skipped" >&2
fi

# --- Simulation --------------------------------------------------------------------------
sim="$WORK/town-loop-$SIM_SCANS.rawlog"
[ -f "$sim" ] || "$bin/rasterslam-sim" --scenario "$here/rawlogs/town-loop.yaml" --scans "$SIM_SCANS" -o "$sim" >/dev/null 2>&1
echo "Simulated town (rawlogs/town-loop.yaml, $SIM_SCANS HDL-64E scans; gz rawlog); relative errors on 50..200 m segments"
header "vs simulator ground truth" ""
outs=(); names=()
for cfg in "$@"; do
  name="$(basename "$cfg" .yaml)"; out="$WORK/sim-$name"
  $PIN "$bin/rasterslam" run --rawlog "$sim" --config "$cfg" --out "$out" --quiet >/dev/null
  gt=$("$bin/rasterslam-eval" traj --gt "$out/groundtruth.tum" --est "$out/trajectory.tum" --segments 50:200:50 --json)
  row "$name" "$out" "$gt" ""
  outs+=("$out"); names+=("$name")
done
[ ${#outs[@]} -lt 2 ] || rate_note "${outs[0]}" "${outs[-1]}" "${names[0]}" "${names[-1]}"
echo "(one process per run, pinned to one core; 'other' = mapping + loop stages; peak MB = the process's RSS high-water mark)"
