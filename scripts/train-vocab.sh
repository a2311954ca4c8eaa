#!/usr/bin/env bash
# Trains the local-map vocabulary of lifelong.yaml
# (share/rasterslam/vocab/elevation-localmaps-3m-k10l4.vocab): the words of the images that
# lifelong.yaml indexes and queries, local-map images made of the 3 m band above the ground
# that its rasterizer keeps (max_height_m 3, 3 m grey 255), where the scan vocabulary
# (elevation-k10l4.vocab, slam.yaml's) was trained on single scans' images of every height.
# Images: the local-map images of 60 simulated towns (town-loop.yaml's generator, seeds
# 2000-2059, which no benchmark or test uses; rasterslam-bench-places --local-maps
# --save-images, made as the map manager makes them), then the real geometry of the KITTI
# sample (its 5 local-map images and its 101 scan images, these rasterized so too;
# KITTI data: CC BY-NC-SA 3.0), the real data the scan vocabulary was trained on too.
# 10 branches, 4 levels, 3,000 ORB features an image (as the map manager's images), seed 1:
# the same images in the same order give the same file.
# MAX_HEIGHT=0 trains on images of every height instead (8 m grey 255, the default).
# usage: scripts/train-vocab.sh OUT.vocab     (env: BUILD, DATA = the KITTI sample folder,
#        MAX_HEIGHT, default 3)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
DATA="${DATA:-$here/../shared/data/kitti00-0000-0100}"
bin="$BUILD/bin"
MAX_HEIGHT="${MAX_HEIGHT:-3}"
out="${1:?usage: scripts/train-vocab.sh OUT.vocab}"
for t in rasterslam-bench-places rasterslam-vocab kitti2rawlog rasterslam; do
  [ -x "$bin/$t" ] || { echo "train-vocab: $bin/$t not built" >&2; exit 1; }
done
[ -d "$DATA/velodyne" ] || { echo "train-vocab: $DATA/velodyne: no such folder" >&2; exit 1; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/maps" "$work/scans"
# The places' images of 60 towns, then of the KITTI street (one query each: the tool needs
# them; its figures are not used).
"$bin/rasterslam-bench-places" --scenario "$here/rawlogs/town-loop.yaml" \
  --vocabulary "$here/share/rasterslam/vocab/elevation-k10l4.vocab" --towns 60 --seed 2000 \
  --max-height "$MAX_HEIGHT" --queries 1 --local-maps --kitti "$DATA" --kitti-queries 1 --save-images "$work/maps" >/dev/null
# Its scans' images, as tracking.yaml rasterizes them with lifelong.yaml's band.
grey_max=$MAX_HEIGHT
[ "$MAX_HEIGHT" != 0 ] || grey_max=8
sed -e "s/^\(    projection: .*\)/    max_height_m: $MAX_HEIGHT\n\1/" \
  -e "s/^    grey_max_m: *[0-9.]*/    grey_max_m: $grey_max/" \
  "$here/share/rasterslam/config/tracking.yaml" >"$work/scans.yaml"
# The edit must have landed (tracking.yaml's layout may change): once each, with the values.
for key in "max_height_m: $MAX_HEIGHT" "grey_max_m: $grey_max"; do
  [ "$(grep -cE "^    $key( |$)" "$work/scans.yaml")" = 1 ] || {
    echo "train-vocab: could not set '$key' in the rasterizer section of" \
      "$here/share/rasterslam/config/tracking.yaml (its layout changed?)" >&2
    exit 1
  }
done
"$bin/kitti2rawlog" --velodyne "$DATA/velodyne" --poses "$DATA/poses_semantickitti.txt" \
  --calib "$DATA/calib.txt" --times "$DATA/times.txt" --external -o "$work/kitti.rawlog" >/dev/null
"$bin/rasterslam" run --rawlog "$work/kitti.rawlog" --out "$work/run" --config "$work/scans.yaml" \
  --save-images --quiet >/dev/null
mv "$work/run/images/"*.png "$work/scans/"
"$bin/rasterslam-vocab" train --images "$work/maps" --images "$work/scans" --features 3000 --seed 1 -o "$out"
