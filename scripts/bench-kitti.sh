#!/usr/bin/env bash
# Runs one or more pipeline configs on the KITTI sample (../shared/data/kitti00-0000-0100)
# and prints, side by side: ms per scan (median, p95), peak memory, and accuracy against the
# SemanticKITTI and the official poses (relative errors on 10..80 m segments, ATE).
# usage: scripts/bench-kitti.sh [CONFIG.yaml ...]   (default: the GICP baseline)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
DATA="${DATA:-$here/../shared/data/kitti00-0000-0100}"
WORK="${WORK:-$BUILD/bench}"
[ -d "$DATA" ] || { echo "bench-kitti: data folder $DATA not found" >&2; exit 1; }
[ $# -gt 0 ] || set -- "$here/share/rasterslam/config/gicp-baseline.yaml"
mkdir -p "$WORK"
rawlog="$WORK/kitti00-0000-0100.rawlog"
if [ ! -f "$rawlog" ]; then
  "$BUILD/bin/kitti2rawlog" --velodyne "$DATA/velodyne" --poses "$DATA/poses_semantickitti.txt" \
    --calib "$DATA/calib.txt" --times "$DATA/times.txt" -o "$rawlog" >/dev/null
fi
json() { sed -n "s/.*\"$2\": \([-0-9.eE+]*\).*/\1/p" <<<"$1"; }
yamlv() { sed -n "s/^ *$2: *\([-0-9.eE+]*\).*/\1/p" "$1" | head -n1; }
printf '%-24s %9s %9s %8s %8s %10s %8s %9s\n' config "ms/scan" "p95" "peak MB" "RTE %" "RRE deg/m" "ATE m" "RTE % off"
for cfg in "$@"; do
  name="$(basename "$cfg" .yaml)"
  out="$WORK/$name"
  "$BUILD/bin/rasterslam" run --rawlog "$rawlog" --config "$cfg" --out "$out" --quiet >/dev/null
  sem=$("$BUILD/bin/rasterslam-eval" traj --gt "$DATA/poses_semantickitti.txt" --calib "$DATA/calib.txt" \
        --est "$out/trajectory.kitti" --segments 10:80:10 --json)
  off=$("$BUILD/bin/rasterslam-eval" traj --gt "$DATA/poses_official.txt" --calib "$DATA/calib.txt" \
        --est "$out/trajectory.kitti" --segments 10:80:10 --json)
  printf '%-24s %9.1f %9.1f %8.0f %8.3f %10.4f %8.3f %9.3f\n' "$name" \
    "$(yamlv "$out/run.yaml" ms_per_scan_median)" "$(yamlv "$out/run.yaml" ms_per_scan_p95)" \
    "$(yamlv "$out/run.yaml" peak_rss_mb)" "$(json "$sem" rel_trans_pct)" "$(json "$sem" rel_rot_deg_per_m)" \
    "$(json "$sem" ate_rmse_m)" "$(json "$off" rel_trans_pct)"
done
echo "(10..80 m segments every 10 frames as the KITTI devkit; RTE/RRE/ATE against SemanticKITTI poses, 'off' against the official ones)"
