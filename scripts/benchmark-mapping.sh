#!/usr/bin/env bash
# Mapping benchmark (the map-manager issue's goals): for each simulated drive and the KITTI
# sample, tracking only against the full system (map manager, loop closure, online robust
# optimization) side by side: ms per scan, peak memory, map memory per keyframe, ATE; then
# the same with wrong loop edges injected (engine.test_corrupt_loops), local BA on against
# off (relative errors inside local maps, rasterslam-eval localmaps), and --realtime on the
# KITTI sample (late scans, tracking p95 with and without the back end).
# usage: scripts/benchmark-mapping.sh     (env: BUILD, DATA; LONG=1 adds the 10,000-scan drive)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
DATA="${DATA:-$here/../shared/data/kitti00-0000-0100}"
WORK="${WORK:-$BUILD/bench-mapping}"
bin="$BUILD/bin"
cfgdir="$here/share/rasterslam/config"
mkdir -p "$WORK"

yamlv() { sed -n "s/^ *$2: *\([-0-9.eE+]*\).*/\1/p" "$1" | head -n1; }
# A value of a rasterslam-eval --json object by its jq path: json "$j" .ate_rmse_m (empty for null).
json() { jq -r "$2 // empty" <<<"$1"; }
ate() { json "$("$bin/rasterslam-eval" traj --gt "$1/groundtruth.tum" --est "$1/${2:-trajectory.tum}" --json)" .ate_rmse_m; }
# slam.yaml with the vocabulary made absolute and sed edits applied: variant NAME [SED ...]
variant() {
  local name=$1; shift
  local cfg="$WORK/$name.yaml"
  sed -e "s#vocabulary_file: ../vocab/#vocabulary_file: $here/share/rasterslam/vocab/#" "$cfgdir/slam.yaml" > "$cfg"
  for e in "$@"; do sed -i -e "$e" "$cfg"; done
  echo "$cfg"
}
run() {  # run RAWLOG CONFIG OUT [extra args]
  local rawlog=$1 cfg=$2 out=$3; shift 3
  "$bin/rasterslam" run --rawlog "$rawlog" --config "$cfg" --out "$out" --quiet "$@" >/dev/null
}
row() {  # row LABEL OUT [ODO_ATE]
  local out=$2 a kf mm
  a=$(ate "$out")
  kf=$(yamlv "$out/run.yaml" keyframes)
  mm=$(yamlv "$out/run.yaml" map_memory_mb)
  printf '  %-26s %7.2f %7.2f %8.1f %9s %8.3f %8s %6s %6s\n' "$1" "$(yamlv "$out/run.yaml" ms_per_scan_median)" \
    "$(yamlv "$out/run.yaml" ms_per_scan_p95)" "$(yamlv "$out/run.yaml" peak_rss_mb)" \
    "$([ -n "$mm" ] && awk -v m="$mm" -v k="$kf" 'BEGIN{printf "%.1f", 1000*m/k}' || echo -)" "$a" \
    "$([ -n "${3:-}" ] && awk -v a="$a" -v o="$3" 'BEGIN{printf "%.2f", a/o}' || echo -)" \
    "$(yamlv "$out/run.yaml" loop_edges)" "$(yamlv "$out/run.yaml" local_maps)"
}

inputs=()
for scen in town-vlp16 town-loop; do
  r="$WORK/$scen.rawlog"
  [ -f "$r" ] || "$bin/rasterslam-sim" --scenario "$here/rawlogs/$scen.yaml" -o "$r" >/dev/null 2>&1
  inputs+=("$scen:$r")
done
if [ -d "$DATA" ]; then
  r="$WORK/kitti00-0000-0100.rawlog"
  [ -f "$r" ] || "$bin/kitti2rawlog" --velodyne "$DATA/velodyne" --poses "$DATA/poses_semantickitti.txt" \
      --calib "$DATA/calib.txt" --times "$DATA/times.txt" --compress 0 -o "$r" >/dev/null
  inputs+=("kitti00-0000-0100:$r")
fi
if [ "${LONG:-0}" = 1 ]; then
  r="$WORK/town-loop-10000.rawlog"
  [ -f "$r" ] || "$bin/rasterslam-sim" --scenario "$here/rawlogs/town-loop.yaml" --scans 10000 -o "$r" >/dev/null 2>&1
  inputs+=("town-loop-10000:$r")
fi

slam=$(variant slam)
wrong=$(variant wrong "s/^engine:/engine:\n  test_corrupt_loops: 0.05/")
wrong30=$(variant wrong30 "s/^engine:/engine:\n  test_corrupt_loops: 0.3/")
noloss=$(variant wrong30-noloss "s/^engine:/engine:\n  test_corrupt_loops: 0.3/" "s/loss: cauchy /loss: none /")
mm_off=$(variant mapping-ba-off "/^loop_detector:/,/^optimizer:/{/^optimizer:/!d}")
mm_on=$(variant mapping-ba-on "/^loop_detector:/,/^optimizer:/{/^optimizer:/!d}" "s/local_ba: false/local_ba: true/")

echo "== Tracking only (tracking.yaml) against the full system (slam.yaml)"
printf '  %-26s %7s %7s %8s %9s %8s %8s %6s %6s\n' run "ms/scan" p95 "peak MB" "kB/kf" "ATE m" "/track" loops maps
for in in "${inputs[@]}"; do
  name=${in%%:*}; rawlog=${in#*:}
  echo " $name"
  run "$rawlog" "$cfgdir/tracking.yaml" "$WORK/$name-track"
  odo=$(ate "$WORK/$name-track")
  row "tracking only" "$WORK/$name-track"
  run "$rawlog" "$slam" "$WORK/$name-slam"
  row "slam (final)" "$WORK/$name-slam" "$odo"
  printf '  %-26s %50s\n' "slam (online poses)" "ATE $(printf '%.3f' "$(ate "$WORK/$name-slam" trajectory_online.tum)") m"
  # Over the run: memory after 2/21 of it (lap 2 of the 21-lap drive) against the last 10 %,
  # ms per scan first against last 10 % (rasterslam-eval timings; the plot beside the run).
  n=$(($(wc -l < "$WORK/$name-slam/timings.csv") - 1))
  k=$((n * 2 / 21)); [ "$k" -ge 1 ] || k=1
  t=$("$bin/rasterslam-eval" timings "$WORK/$name-slam" --label "$name" --after-scan "$k" --json \
      --plot "$WORK/$name-slam/timings.png")
  printf '  %-26s RSS %.1f MB by scan %d, %.1f MB max in the last 10%% (x%.3f), %.2f MB/1000 scans; ms/scan %.2f first 10%%, %.2f last 10%%\n' \
    "slam over the run" "$(json "$t" '.runs[0].after_scan.rss_max_mb')" "$k" "$(json "$t" '.runs[0].rss_last_max_mb')" \
    "$(json "$t" '.runs[0].after_scan.last_ratio')" "$(json "$t" '.runs[0].rss_growth_mb_per_1000_scans')" \
    "$(json "$t" '.runs[0].total_ms.first')" "$(json "$t" '.runs[0].total_ms.last')"
  run "$rawlog" "$wrong" "$WORK/$name-wrong"
  row "5 % loops wrong ($(yamlv "$WORK/$name-wrong/run.yaml" corrupted_loops_test_hook || true))" "$WORK/$name-wrong" "$odo"
  run "$rawlog" "$wrong30" "$WORK/$name-wrong30"
  row "30 % wrong ($(yamlv "$WORK/$name-wrong30/run.yaml" corrupted_loops_test_hook || true)), cauchy" "$WORK/$name-wrong30" "$odo"
  run "$rawlog" "$noloss" "$WORK/$name-noloss"
  row "30 % wrong, no loss" "$WORK/$name-noloss" "$odo"
done

echo
echo "== Local BA: relative errors between the keyframes of each local map (map manager, no loops)"
printf '  %-20s %-7s %10s %10s %10s %10s %10s %s\n' input "BA" "trans m" "horiz m" "vert m" "rot deg" "yaw deg" "BA rms m"
for in in "${inputs[@]}"; do
  name=${in%%:*}; rawlog=${in#*:}
  [ "$name" = town-loop-10000 ] && continue
  for v in off on; do
    cfg=$mm_off; [ $v = on ] && cfg=$mm_on
    out="$WORK/$name-ba-$v"
    run "$rawlog" "$cfg" "$out" --map-out "$out/map" --overwrite
    j=$("$bin/rasterslam-eval" localmaps --map "$out/map" --gt "$out/groundtruth.tum" --json)
      printf '  %-20s %-7s %10.4f %10.4f %10.4f %10.4f %10.4f %s\n' "$name" "$v" "$(json "$j" .trans_err_mean_m)" \
      "$(json "$j" .horizontal_err_mean_m)" "$(json "$j" .vertical_err_mean_m)" "$(json "$j" .rot_err_mean_deg)" \
      "$(json "$j" .yaw_err_mean_deg)" "$([ $v = on ] && printf '%.3f -> %.3f' "$(json "$j" .ba_rms_before_m)" "$(json "$j" .ba_rms_after_m)")"
  done
done

if [ -d "$DATA" ]; then
  echo
  echo "== Two sessions on real data: the even KITTI frames make the map, the odd ones come back to it"
  for par in 0 1; do
    sub="$WORK/kitti-$par"; rm -rf "$sub"; mkdir -p "$sub/velodyne"; : > "$sub/poses.txt"; : > "$sub/times.txt"; i=0
    for f in $(ls "$DATA"/velodyne/*.bin | sort); do
      n=$((10#$(basename "$f" .bin)))
      [ $((n % 2)) = $par ] || continue
      ln -s "$f" "$sub/velodyne/$(printf %06d $i).bin"; i=$((i + 1))
      sed -n "$((n + 1))p" "$DATA/poses_semantickitti.txt" >> "$sub/poses.txt"
      sed -n "$((n + 1))p" "$DATA/times.txt" >> "$sub/times.txt"
    done
    "$bin/kitti2rawlog" --velodyne "$sub/velodyne" --poses "$sub/poses.txt" --calib "$DATA/calib.txt" \
      --times "$sub/times.txt" --compress 0 -o "$sub.rawlog" >/dev/null
  done
  rm -rf "$WORK/kitti-map"
  run "$WORK/kitti-0.rawlog" "$slam" "$WORK/kitti-s1" --map-out "$WORK/kitti-map"
  run "$WORK/kitti-1.rawlog" "$slam" "$WORK/kitti-s2" --map-in "$WORK/kitti-map" --map-out "$WORK/kitti-map"
  for f in trajectory groundtruth; do
    (echo "# timestamp tx ty tz qx qy qz qw"; grep -hv '^#' "$WORK/kitti-s1/$f.tum" "$WORK/kitti-s2/$f.tum" | sort -g) > "$WORK/kitti-both-$f.tum"
  done
  j=$("$bin/rasterslam-eval" traj --gt "$WORK/kitti-both-groundtruth.tum" --est "$WORK/kitti-both-trajectory.tum" --json)
  printf '  session 2: located %s after %s hits, %s loop edges to session 1; interleaved ATE %.3f m, consecutive frames %.3f m (mean)\n' \
    "$(sed -n 's/^ *localized_in_prior_map: *//p' "$WORK/kitti-s2/run.yaml")" "$(yamlv "$WORK/kitti-s2/run.yaml" prior_map_hits)" \
    "$(yamlv "$WORK/kitti-s2/run.yaml" prior_map_loop_edges)" "$(json "$j" .ate_rmse_m)" "$(json "$j" .rpe_trans_mean_m)"
  # The same two halves as two maps built separately, joined by `map merge`: each session's
  # keyframes in the merged map against the truth.
  rm -rf "$WORK/kitti-map-even" "$WORK/kitti-map-odd" "$WORK/kitti-merged" "$WORK/kitti-merged-x"
  run "$WORK/kitti-0.rawlog" "$slam" "$WORK/kitti-m1" --map-out "$WORK/kitti-map-even"
  run "$WORK/kitti-1.rawlog" "$slam" "$WORK/kitti-m2" --map-out "$WORK/kitti-map-odd"
  m=$("$bin/rasterslam" map merge "$WORK/kitti-map-even" "$WORK/kitti-map-odd" --out "$WORK/kitti-merged" \
      --config "$slam" --quiet | head -n1)
  "$bin/rasterslam" map export "$WORK/kitti-merged" --out "$WORK/kitti-merged-x" >/dev/null
  (echo "# timestamp tx ty tz qx qy qz qw"; grep -hv '^#' "$WORK/kitti-merged-x"/keyframes-s*.tum | sort -g) > "$WORK/kitti-merged-kf.tum"
  j=$("$bin/rasterslam-eval" traj --gt "$WORK/kitti-both-groundtruth.tum" --est "$WORK/kitti-merged-kf.tum" --json)
  printf '  map merge: %s\n  merged keyframes of both sessions: ATE %.3f m, consecutive keyframes %.3f m (mean), %s keyframes\n' \
    "${m#rasterslam: }" "$(json "$j" .ate_rmse_m)" "$(json "$j" .rpe_trans_mean_m)" "$(json "$j" .n_associated)"

  echo
  echo "== --realtime on the KITTI sample: late scans after the first, tracking p95 (ms)"
  for rate in 2 4; do
    for cfg in default slam; do
      c="$cfgdir/tracking.yaml"; [ $cfg = slam ] && c=$slam
      out="$WORK/rt-$rate-$cfg"
      run "$WORK/kitti00-0000-0100.rawlog" "$c" "$out" --realtime --rate "$rate"
      late=$(awk -F, 'NR>2 && $7==1' "$out/timings.csv" | wc -l)
      p95=$(awk -F, 'NR>1{print $8+$9+$10}' "$out/timings.csv" | sort -g | awk '{a[NR]=$1} END{print a[int(NR*0.95)]}')
      printf '  rate %s %-8s late after the first %3s   tracking p95 %6.2f ms   cpu tracking %.2f s, back end %.2f s\n' \
        "$rate" "$cfg" "$late" "$p95" "$(yamlv "$out/run.yaml" tracking_s)" "$(yamlv "$out/run.yaml" mapping_and_loop_closing_s)"
    done
  done
fi
