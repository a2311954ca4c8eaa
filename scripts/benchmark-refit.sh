#!/usr/bin/env bash
# The weighting of the odometry's inliers (the tracking issue's causes): the features' RANSAC
# fit as it was (least squares on the inliers) against the same refitted with a Cauchy loss
# (odometry.params.refit_cauchy_m: 0.1, as tracking-refined.yaml ships it), side by side in one
# command, for tracking-refined.yaml and for tracking.yaml: relative errors, ATE and ms a scan
# on the KITTI sample (0.205 deg beam correction, 10..80 m segments) and on eight simulated
# drives of three scenarios and several seeds (50..200 m segments).
# usage: scripts/benchmark-refit.sh     (env: BUILD, WORK, DATA)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
WORK="${WORK:-$BUILD/bench-refit}"
DATA="${DATA:-$here/../shared/data/kitti00-0000-0100}"
bin="$BUILD/bin"
cfgdir="$here/share/rasterslam/config"
for p in rasterslam rasterslam-eval rasterslam-sim kitti2rawlog; do
  [ -x "$bin/$p" ] || { echo "benchmark-refit: $bin/$p not built (make build)" >&2; exit 1; }
done
command -v jq >/dev/null || { echo "benchmark-refit: jq not found (scripts/install-deps.sh)" >&2; exit 1; }
mkdir -p "$WORK"
cd "$WORK"

# Drives: NAME SCENARIO SEED SCANS
drives=("town-kitti rawlogs/town-kitti.yaml 0 150"
        "town-kitti-s2 rawlogs/town-kitti.yaml 2 300"
        "town-loop rawlogs/town-loop.yaml 0 560"
        "town-loop-s2 rawlogs/town-loop.yaml 2 400"
        "town-loop-s3 rawlogs/town-loop.yaml 3 400"
        "town-vlp16 rawlogs/town-vlp16.yaml 0 400"
        "town-vlp16-s2 rawlogs/town-vlp16.yaml 2 400"
        "town-vlp16-s3 rawlogs/town-vlp16.yaml 3 400")
for d in "${drives[@]}"; do
  read -r name scen seed scans <<<"$d"
  args=(--scenario "$here/$scen" --scans "$scans" -o "$name.rawlog" --compress 0)
  [ "$seed" = 0 ] || args+=(--seed "$seed")
  [ -f "$name.rawlog" ] || "$bin/rasterslam-sim" "${args[@]}" >/dev/null 2>&1 ||
    { echo "benchmark-refit: rasterslam-sim $scen failed" >&2; exit 1; }
done
kitti=""
if [ -d "$DATA/velodyne" ]; then
  kitti=kitti-vc0.205
  [ -f "$kitti.rawlog" ] || "$bin/kitti2rawlog" --velodyne "$DATA/velodyne" --poses "$DATA/poses_semantickitti.txt" \
    --calib "$DATA/calib.txt" --times "$DATA/times.txt" --compress 0 --vertical-correction-deg 0.205 \
    -o "$kitti.rawlog" >/dev/null
else
  echo "benchmark-refit: $DATA not found: the KITTI row is left out" >&2
fi

# variant BASE CAUCHY -> config: BASE with odometry.params.refit_cauchy_m set (or added)
variant() {
  local out="$(basename "$1" .yaml)-c$2.yaml"
  if grep -q "refit_cauchy_m:" "$cfgdir/$1"; then
    sed "s/refit_cauchy_m: [0-9.]*/refit_cauchy_m: $2/" "$cfgdir/$1" > "$out"
  else
    # under the odometry's params: (not another role's, should the odometry have none)
    awk -v c="$2" '/^[a-z_]+:/ {o = ($1 == "odometry:")} {print}
      o && /^  params:/ {print "    refit_cauchy_m: " c; o = 0; done = 1}
      END {exit !done}' "$cfgdir/$1" > "$out" ||
      { echo "benchmark-refit: $1 has no odometry params to add refit_cauchy_m to" >&2; exit 1; }
  fi
  grep -Eq "^    refit_cauchy_m: ${2//./\\.}( |$)" "$out" ||
    { echo "benchmark-refit: could not set refit_cauchy_m: $2 in $out" >&2; exit 1; }
  echo "$out"
}
# score NAME CONFIG SEGMENTS: "RTE RRE ATE MS"
score() {
  local out="run-$1-$(basename "$2" .yaml)"
  rm -rf "$out"
  "$bin/rasterslam" run --rawlog "$1.rawlog" --config "$2" --out "$out" --quiet >/dev/null 2>&1 ||
    { echo "benchmark-refit: rasterslam run $1 with $2 failed" >&2; exit 1; }
  "$bin/rasterslam-eval" traj --gt "$out/groundtruth.tum" --est "$out/trajectory.tum" --segments "$3" --json |
    jq -r --arg ms "$(sed -n 's/^ *ms_per_scan_median: *//p' "$out/run.yaml")" \
      'if .rel_trans_pct == null then error("no segments") else "\(.rel_trans_pct) \(.rel_rot_deg_per_m) \(.ate_rmse_m) \($ms)" end'
}
for base in tracking-refined.yaml tracking.yaml; do
  off=$(variant "$base" 0); on=$(variant "$base" 0.1)
  echo
  echo "$base: refit_cauchy_m 0 (least squares) -> 0.1; RTE %, RRE deg/m, ATE m, ms a scan (median)"
  printf '  %-16s %17s %19s %17s %15s\n' drive "RTE %" "RRE deg/m" "ATE m" "ms"
  names=()
  [ -z "$kitti" ] || names+=("$kitti")
  for d in "${drives[@]}"; do names+=("${d%% *}"); done
  sum0=0; sum1=0; better=0
  for n in "${names[@]}"; do
    seg=50:200:50; [ "$n" = "$kitti" ] && seg=10:80:10
    # (assigned first: a failed run must stop the script, not read as zeros)
    s0=$(score "$n" "$off" "$seg") && s1=$(score "$n" "$on" "$seg") || exit 1
    read -r t0 r0 a0 m0 <<<"$s0"
    read -r t1 r1 a1 m1 <<<"$s1"
    printf '  %-16s %7.3f -> %-7.3f %8.4f -> %-8.4f %7.3f -> %-7.3f %5.1f -> %-5.1f\n' "$n" "$t0" "$t1" "$r0" "$r1" "$a0" "$a1" "$m0" "$m1"
    if [ "$n" != "$kitti" ]; then
      sum0=$(awk -v a="$sum0" -v b="$t0" 'BEGIN {print a + b}'); sum1=$(awk -v a="$sum1" -v b="$t1" 'BEGIN {print a + b}')
      better=$(awk -v n="$better" -v a="$t0" -v b="$t1" 'BEGIN {print n + (b < a)}')
    fi
  done
  printf '  simulated drives: RTE lower on %d of %d, summed %.3f -> %.3f %%\n' "$better" "${#drives[@]}" "$sum0" "$sum1"
done
