#!/usr/bin/env bash
# Loop-closure benchmark (the paper's Tables 2 and 3 on simulated drives that revisit their
# start): for the BOW database of local-map images (pre-trained and online vocabulary) and
# the paper's two search baselines (nearest keyframes; nearest local maps), precision and
# recall at the detector's decisions (4 m, 30 s), F1 max over the score threshold, time per
# keyframe query, and ATE after pose-graph optimization against odometry alone. Then BOW
# query times for 100, 1,000 and 10,000 database entries.
# usage: scripts/benchmark-loops.sh      (env: BUILD)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
WORK="${WORK:-$BUILD/bench-loops}"
bin="$BUILD/bin"
vocab="$here/share/rasterslam/vocab/elevation-k10l4.vocab"
mkdir -p "$WORK"

# A value of a rasterslam-eval --json object by its jq path: json "$j" .ate_rmse_m (empty for null).
json() { jq -r "$2 // empty" <<<"$1"; }
variant() {  # variant NAME SEARCH VOCAB -> config file
  local cfg="$WORK/$1.yaml"
  sed -e "s#vocabulary_file: ../vocab/elevation-k10l4.vocab#vocabulary_file: \"$3\"#" \
      -e "s#    exclude_recent_s: 30 #    search: $2\n    exclude_recent_s: 30 #" \
      "$here/share/rasterslam/config/slam.yaml" > "$cfg"
  echo "$cfg"
}

for scen in town-vlp16 town-loop; do
  rawlog="$WORK/$scen.rawlog"
  [ -f "$rawlog" ] || "$bin/rasterslam-sim" --scenario "$here/rawlogs/$scen.yaml" -o "$rawlog" >/dev/null 2>&1
  "$bin/rasterslam" run --rawlog "$rawlog" --config "$here/share/rasterslam/config/tracking.yaml" --out "$WORK/$scen-odometry" --quiet >/dev/null
  odo=$("$bin/rasterslam-eval" traj --gt "$WORK/$scen-odometry/groundtruth.tum" --est "$WORK/$scen-odometry/trajectory.tum" --json)
  odo_ate=$(json "$odo" .ate_rmse_m)
  echo "$scen ($(grep -c . "$WORK/$scen-odometry/trajectory.tum") scans): odometry only, ATE $(printf '%.3f' "$odo_ate") m"
  printf '  %-22s %5s %5s %6s %6s %6s | %9s %9s | %7s %6s\n' method queries pos precision recall "F1max" "ms/query" "max ms" "ATE m" "/odo"
  for v in "bow:bow:$vocab" "bow-online:bow:" "keyframes:keyframes:$vocab" "localmaps:localmaps:$vocab"; do
    IFS=: read -r name search voc <<<"$v"
    out="$WORK/$scen-$name"
    "$bin/rasterslam" run --rawlog "$rawlog" --config "$(variant "$scen-$name" "$search" "$voc")" --out "$out" --quiet >/dev/null
    l=$("$bin/rasterslam-eval" loops --loops "$out/loops.txt" --gt "$out/groundtruth.tum" --json)
    t=$("$bin/rasterslam-eval" traj --gt "$out/groundtruth.tum" --est "$out/trajectory.tum" --json)
    ms=$(awk -F, 'NR>1 && $6==1 {s+=$12; n++; if($12>m)m=$12} END{printf "%.2f %.2f", (n?s/n:0), m}' "$out/timings.csv")
    ate=$(json "$t" .ate_rmse_m)
    printf '  %-22s %5s %5s %6.3f %6.3f %6.3f | %9s %9s | %7.3f %6.2f\n' "$name" "$(json "$l" .queries)" "$(json "$l" .positives)" \
      "$(json "$l" .detector.precision)" "$(json "$l" .detector.recall)" "$(json "$l" .f1_max.f1)" ${ms} "$ate" "$(awk -v a="$ate" -v b="$odo_ate" 'BEGIN{print a/b}')"
  done
  echo
done
echo "BOW query time (synthetic bags on the shipped vocabulary):"
"$bin/rasterslam-vocab" bench --vocab "$vocab" --entries 100,1000,10000
