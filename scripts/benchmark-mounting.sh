#!/usr/bin/env bash
# Sensors mounted at other heights (README, Configuration, "Mounting height"): the simulated
# town drives (rawlogs/town-loop.yaml, 560 HDL-64E scans; rawlogs/town-vlp16.yaml, 400 VLP-16
# scans) with the sensor at its shipped 1.73 m, higher and lower (rasterslam-sim --sensor-height), run
# with slam.yaml as shipped, with slam.yaml whose ground candidates keep their fixed bound
# (ground_candidate_layer_margin_m: 0, the behaviour before the bound followed the ground),
# and with tracking.yaml alone. Prints, a row each: scans lost, ATE (m), and the loops
# accepted with their precision and recall (rasterslam-eval loops). About 2 minutes.
# usage: scripts/benchmark-mounting.sh     (env: BUILD, WORK)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
WORK="${WORK:-$BUILD/bench-mounting}"
bin="$BUILD/bin"
for p in rasterslam rasterslam-eval rasterslam-sim; do
  [ -x "$bin/$p" ] || { echo "benchmark-mounting: $bin/$p not built (make build)" >&2; exit 1; }
done
command -v jq > /dev/null || { echo "benchmark-mounting: jq not found (scripts/install-deps.sh)" >&2; exit 1; }
rm -rf "$WORK"
mkdir -p "$WORK"
cd "$WORK"
vocab="s#vocabulary_file: ../vocab/#vocabulary_file: $here/share/rasterslam/vocab/#"
sed -e "$vocab" "$here/share/rasterslam/config/slam.yaml" > slam.yaml
# The rasterizer's params with the bound fixed (slam.yaml names the class without params).
awk '{print} /class: rasterslam::ElevationRasterizer/ {print "  params:\n    ground_candidate_layer_margin_m: 0"}' \
  slam.yaml > fixed.yaml
grep -q "ground_candidate_layer_margin_m: 0" fixed.yaml ||
  { echo "benchmark-mounting: could not fix the bound in fixed.yaml" >&2; exit 1; }
cp "$here/share/rasterslam/config/tracking.yaml" tracking.yaml

# quietly CMD...: its output only if it fails
quietly() { "$@" > quiet.log 2>&1 || { cat quiet.log >&2; echo "benchmark-mounting: failed: $*" >&2; exit 1; }; }
printf "%-24s %-9s %5s %8s %6s %10s %7s\n" drive config lost "ATE m" loops precision recall
for drive in town-loop:1.73 town-loop:2.4 town-loop:0.8 town-loop:0.5 town-vlp16:1.73 town-vlp16:0.6; do
  scenario=${drive%%:*} height=${drive#*:}
  name="$scenario-$height"
  quietly "$bin/rasterslam-sim" --scenario "$here/rawlogs/$scenario.yaml" --sensor-height "$height" \
    -o "$name.rawlog" --compress 0
  for cfg in slam fixed tracking; do
    out="$name-$cfg"
    quietly "$bin/rasterslam" run --rawlog "$name.rawlog" --config "$cfg.yaml" --out "$out" --quiet
    lost=$(awk '$1 == "lost:" {print $2; exit}' "$out/run.yaml")
    ate=$("$bin/rasterslam-eval" traj --gt "$out/groundtruth.tum" --est "$out/trajectory.tum" --json |
      jq -r 'if .ate_rmse_m == null then "-" else (.ate_rmse_m * 1000 | round / 1000 | tostring) end')
    loops=- precision=- recall=-
    if [ "$cfg" != tracking ]; then
      d=$("$bin/rasterslam-eval" loops --loops "$out/loops.txt" --gt "$out/groundtruth.tum" --json | jq -c '.detector')
      loops=$(jq '.tp + .fp' <<< "$d")
      precision=$(jq -r 'if .precision == null then "-" else (.precision * 100 | round / 100 | tostring) end' <<< "$d")
      recall=$(jq -r 'if .recall == null then "-" else (.recall * 100 | round / 100 | tostring) end' <<< "$d")
    fi
    printf "%-24s %-9s %5s %8s %6s %10s %7s\n" "$scenario at $height m" "$cfg" "$lost" "$ate" "$loops" \
      "$precision" "$recall"
  done
  rm -f "$name.rawlog"
done
