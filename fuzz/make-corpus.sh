#!/usr/bin/env bash
# Makes the seed corpora of the fuzz targets from the project's own files with the programs of
# a build tree (any build: scripts/fuzz.sh passes build-fuzz). Nothing here is committed:
# every seed is made anew.
#   fuzz/make-corpus.sh BUILD_DIR OUT_DIR
# OUT_DIR/<target>/ holds each target's seeds, OUT_DIR/<target>.dict its dictionary (when it
# has one), OUT_DIR/map-store/ the store of the seed map (RASTERSLAM_FUZZ_MAP_STORE for
# fuzz_map_store). Takes about half a minute with a sanitizer build.
set -euo pipefail
if [ $# -ne 2 ]; then
  echo "usage: $0 BUILD_DIR OUT_DIR" >&2
  exit 2
fi
src="$(cd "$(dirname "$0")/.." && pwd)"
build="$(cd "$1" && pwd)"
mkdir -p "$2"
out="$(cd "$2" && pwd)"
bin="$build/bin"
for p in rasterslam rasterslam-sim rasterslam-vocab; do
  [ -x "$bin/$p" ] || { echo "make-corpus: $bin/$p not built" >&2; exit 1; }
done

# The programs may be sanitizer builds: no leak report (that is the sanitizer suite's job) and
# no data-memory cap (RLIMIT_DATA and ASan's shadow memory do not mix).
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"
export RASTERSLAM_MAX_MEMORY_MB=0
export RASTERSLAM_PLUGIN_PATH="$build/lib/rasterslam/plugins"
work="$(mktemp -d "${TMPDIR:-/tmp}/rasterslam-corpus-XXXXXX")"
trap 'rm -rf "$work"' EXIT
log="$work/log"
run() {
  if ! "$@" >>"$log" 2>&1; then
    echo "make-corpus: failed: $*" >&2
    tail -n 30 "$log" >&2
    exit 1
  fi
}

for t in fuzz_rawlog fuzz_map_store fuzz_vocabulary fuzz_config; do
  rm -rf "${out:?}/$t"
  mkdir -p "$out/$t"
done

# --- rawlogs: the town demo's first scans (VLP-16 gzip, the start of the HDL-64E plain one)
# and small ones (a scenario of the same town keeping 0.5 % of the returns), plain and gzip:
# large seeds make slow runs (scripts/fuzz.sh caps an input at 128 kB).
sim="$bin/rasterslam-sim"
scen="$src/rawlogs/town-loop.yaml"
cat >"$work/sparse.yaml" <<'YAML'
seed: 7
lidar: vlp16
scans: 3
noise: {dropout_prob: 0.995}
YAML
run "$sim" --scenario "$work/sparse.yaml" --compress 0 -o "$out/fuzz_rawlog/sparse-3-plain.rawlog"
run "$sim" --scenario "$work/sparse.yaml" --compress 1 -o "$out/fuzz_rawlog/sparse-3-gz.rawlog"
run "$sim" --scenario "$work/sparse.yaml" --scans 1 --lidar hdl64 --compress 0 \
  -o "$out/fuzz_rawlog/sparse-1-hdl64-plain.rawlog"
run "$sim" --scenario "$scen" --scans 2 --lidar vlp16 --compress 1 -o "$out/fuzz_rawlog/town-2-vlp16-gz.rawlog"
# The whole-size plain HDL-64E scans (4 MB) would set the fuzzer's input size: the first
# 64 kB (a scan cut short) stands for them.
run "$sim" --scenario "$scen" --scans 2 --compress 0 -o "$work/town-2-plain.rawlog"
head -c 65536 "$work/town-2-plain.rawlog" >"$out/fuzz_rawlog/town-2-plain-head.rawlog"
# MRPT class names the reader dispatches on, and the archive's markers.
cat >"$out/fuzz_rawlog.dict" <<'DICT'
"CObservationPointCloud"
"CObservationVelodyneScan"
"CObservationRotatingScan"
"CObservation3DRangeScan"
"CObservationRobotPose"
"CObservationOdometry"
"CObservation2DRangeScan"
"CActionCollection"
"CActionRobotMovement2D"
"CActionRobotMovement3D"
"CSensoryFrame"
"CPointsMapXYZI"
"CPointsMapXYZIRT"
"CSimplePointsMap"
"CColouredPointsMap"
"CPose3D"
"CPose2D"
"CPose3DPDFGaussian"
"CPosePDFGaussian"
"mrpt::obs::"
"mrpt::maps::"
"mrpt::poses::"
"LIDAR"
"\x88"
"\x80"
"\xff\xff\xff\xff"
"\x00\x00\x00\x00"
DICT

# --- a small map: 30 VLP-16 scans through the whole system with an online vocabulary (the
# shipped one would make the index 600 kB) and two keyframes a local map, so that the map has
# two local maps, their graph and a place index; with polar contexts (LocalMap version 2, place
# index version 1).
run "$sim" --scenario "$scen" --scans 30 --lidar vlp16 -o "$work/town-30.rawlog"
sed -e 's|^\( *vocabulary_file:\).*|\1 ""|' \
  -e 's|^\( *\)keyframes_per_map: *[0-9]*|\1keyframes_per_map: 2\n\1place_query_keyframes: 2\n\1polar_contexts: true|' \
  "$src/share/rasterslam/config/slam.yaml" >"$work/slam-small.yaml"
run "$bin/rasterslam" run --rawlog "$work/town-30.rawlog" --config "$work/slam-small.yaml" \
  --out "$work/run" --map-out "$work/map" --save-images --quiet
# First byte: the reader (fuzz/fuzz_map_store.cpp): 0 store file, 1 store payload, 2 map index.
n=0
for f in "$work"/map/store/*.rslm; do
  { printf '\x00'; cat "$f"; } >"$out/fuzz_map_store/store-$n.bin"
  { printf '\x01'; tail -c +18 "$f"; } >"$out/fuzz_map_store/payload-$n.bin"
  n=$((n + 1))
done
# The index as written (gzip; version 4: the body's length and CRC-32 first), plain, and as
# version 3 (the same body with no length and checksum: damage in it reaches the parser).
gzip -dc "$work/map/map.rsmap" >"$work/map-plain.rsmap"
{ printf '\x02'; cat "$work/map/map.rsmap"; } >"$out/fuzz_map_store/map-gz.bin"
{ printf '\x02'; cat "$work/map-plain.rsmap"; } >"$out/fuzz_map_store/map-plain.bin"
if [ "$(head -c 5 "$work/map-plain.rsmap" | od -An -tx1 | tr -d ' ')" = "52534d5004" ]; then
  { printf '\x02RSMP\x03'; tail -c +18 "$work/map-plain.rsmap"; } >"$out/fuzz_map_store/map-v3.bin"
fi
rm -rf "$out/map-store"
cp -r "$work/map/store" "$out/map-store"

# --- vocabularies: the shipped one (gzip, 390 kB) and a small one trained on the run's
# elevation images, gzip and plain.
for v in "$src"/share/rasterslam/vocab/*.vocab; do
  cp "$v" "$out/fuzz_vocabulary/$(basename "$v")"
done
run "$bin/rasterslam-vocab" train --images "$work/run/images" -o "$work/small.vocab" \
  --branching 3 --levels 3 --features 100
cp "$work/small.vocab" "$out/fuzz_vocabulary/small-k3l3.vocab"
# Plain, and in the older form without length and checksum (the MRPT object alone, still
# read): damage in it reaches the vocabulary's own deserialization.
gzip -dc "$work/small.vocab" >"$work/small-plain.vocab" 2>/dev/null || cp "$work/small.vocab" "$work/small-plain.vocab"
cp "$work/small-plain.vocab" "$out/fuzz_vocabulary/small-k3l3-plain.vocab"
if [ "$(head -c 4 "$work/small-plain.vocab")" = "RSVB" ]; then
  tail -c +18 "$work/small-plain.vocab" >"$out/fuzz_vocabulary/small-k3l3-legacy.vocab"
fi

# --- configs: the shipped ones and the plugin template's; the dictionary holds YAML syntax,
# the sections, the plugin classes and every parameter key the sources read.
for c in "$src"/share/rasterslam/config/*.yaml "$src"/examples/plugin-template/config/*.yaml; do
  cp "$c" "$out/fuzz_config/$(basename "$c")"
done
cp "$work/slam-small.yaml" "$out/fuzz_config/slam-small.yaml"
{
  for tok in ': ' '- ' '[' ']' '{' '}' ', ' '#' '"' "'" '&a' '*a' '<<: ' '---' '...' '|' '>' \
             '!!str' '!!int' '!!float' '~' 'null' 'true' 'false' '.inf' '-.inf' '.nan' '1e308' \
             '-1' '0' '2147483648' '9223372036854775808' '0x7fffffff' '1.5'; do
    printf '"%s"\n' "$(printf '%s' "$tok" | sed -e 's/\\/\\\\/g' -e 's/"/\\"/g')"
  done
  for tok in plugins rasterizer odometry map_manager loop_detector optimizer engine class params; do
    printf '"%s"\n' "$tok"
  done
  grep -rhoE 'rasterslam::[A-Z][A-Za-z]+' "$src"/share/rasterslam/config "$src"/examples/plugin-template/config |
    sort -u | sed 's/.*/"&"/'
  grep -rhoE 'librasterslam_plugin_[a-z_]+\.so' "$src"/share/rasterslam/config | sort -u | sed 's/.*/"&"/'
  grep -rhoE 'get(Double|Int|Bool|String|Choice|Doubles|Path)\("[a-z0-9_]+"' \
    "$src"/libs "$src"/plugins "$src"/examples | sed -E 's/.*\("([a-z0-9_]+)"/"\1"/' | sort -u
} >"$out/fuzz_config.dict"

for t in fuzz_rawlog fuzz_map_store fuzz_vocabulary fuzz_config; do
  printf 'make-corpus: %-16s %3d seeds, %s\n' "$t" "$(ls "$out/$t" | wc -l)" \
    "$(du -sh "$out/$t" | cut -f1)"
done
