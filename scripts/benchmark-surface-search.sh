#!/usr/bin/env bash
# Far revisits searched on the surfaces, and what refuses wrong places (the place-recognition
# issue): the loop detector's relocalization_surface_search against slam.yaml without it, on
#  - the KITTI street mapped from its first 51 real scans, relocalizing the 160 HDL-64E scans
#    that `rasterslam-sim --kitti` renders from the whole route (every 5 m, 0/3/6 m to either
#    side, both directions): places up to 50 m beyond the mapped part, exact truth;
#  - 200 scans of each of two other simulated towns (seeds 7 and 1001 of rawlogs/town-loop.yaml)
#    against the map of the town-loop drive: every placement there is wrong.
#  - with SESSIONS=DIR (the WORK of a scripts/benchmark-sessions.sh run, which leaves its
#    scenarios there): a town that changed: the map of session 1 (epoch 0, lifelong.yaml), and
#    the first 150 scans of sessions 9 (HDL-64E) and 10 (VLP-16), 8 and 9 epochs later
#    (parked cars moved, walls built and pulled down, trees grown; cars and people moving).
# Prints each side's relocalization table (rasterslam-eval reloc), the placements in the other
# towns, seconds, peak memory, and for every alignment the surface search judged its share of
# free-space conflicts (features::freeSpaceConflicts), taken and refused apart, and of every
# place fitted on the features (relocalization_max_conflicts). Two more passes show that check
# where it matters: the features' verification made lax (relocalization_min_inliers 12 instead
# of 18, which admits wrong places), without the check (lax-unchecked) and with it (lax).
# usage: scripts/benchmark-surface-search.sh     (env: BUILD, WORK, DATA, SESSIONS)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
WORK="${WORK:-$BUILD/bench-surface-search}"
DATA="${DATA:-$here/../shared/data}"
bin="$BUILD/bin"
D="$DATA/kitti00-0000-0100"
[ -d "$D/velodyne" ] || { echo "benchmark-surface-search: $D/velodyne not found (set DATA)" >&2; exit 1; }
for p in rasterslam rasterslam-eval rasterslam-sim kitti2rawlog; do
  [ -x "$bin/$p" ] || { echo "benchmark-surface-search: $bin/$p not built (make build)" >&2; exit 1; }
done
rm -rf "$WORK"
mkdir -p "$WORK"
cd "$WORK"
vocab="s#vocabulary_file: ../vocab/#vocabulary_file: $here/share/rasterslam/vocab/#"
sed -e "$vocab" "$here/share/rasterslam/config/slam.yaml" > off.yaml
# search_on IN OUT: the config IN with the search on (the key goes under the loop detector's params)
search_on() {
  awk '{print} /class: rasterslam::BowLoopDetector/ {lp=1} lp && /^  params:/ {print "    relocalization_surface_search: true"; lp=0}' \
    "$1" > "$2"
  grep -q "relocalization_surface_search: true" "$2" || { echo "benchmark-surface-search: could not switch the search on in $2" >&2; exit 1; }
}
search_on off.yaml on.yaml
# lax IN OUT [MAXCONFLICTS]: IN with relocalization_min_inliers 12 (and the check's bound)
lax() {
  awk -v mc="${3:-}" '/relocalization_min_inliers:/ {sub(/: *[0-9]+/, ": 12")} {print}
    mc != "" && /class: rasterslam::BowLoopDetector/ {lp=1}
    lp && /^  params:/ {print "    relocalization_max_conflicts: " mc; lp=0}' "$1" > "$2"
  grep -q "relocalization_min_inliers: 12" "$2" || { echo "benchmark-surface-search: could not make $2 lax" >&2; exit 1; }
  [ -z "${3:-}" ] || grep -q "relocalization_max_conflicts: $3" "$2" ||
    { echo "benchmark-surface-search: could not set relocalization_max_conflicts in $2" >&2; exit 1; }
}
lax off.yaml lax.yaml
lax off.yaml lax-unchecked.yaml 1

# quietly CMD...: its output only if it fails
quietly() { "$@" > quiet.log 2>&1 || { cat quiet.log >&2; echo "benchmark-surface-search: failed: $*" >&2; exit 1; }; }
echo "making the maps and queries..."
quietly "$bin/kitti2rawlog" --velodyne "$D/velodyne" --poses "$D/poses_semantickitti.txt" --calib "$D/calib.txt" \
  --times "$D/times.txt" --compress 0 -o k.rawlog
quietly "$bin/rasterslam" run --rawlog k.rawlog --config off.yaml --out krun --map-out kmap --last 50 --quiet
quietly "$bin/rasterslam-sim" --kitti "$D" -o q.rawlog --gt-tum q.tum --compress 0
quietly "$bin/rasterslam-sim" --scenario "$here/rawlogs/town-loop.yaml" -o town.rawlog --compress 0
quietly "$bin/rasterslam" run --rawlog town.rawlog --config off.yaml --out town-run --map-out town-map --quiet
for s in 7 1001; do
  quietly "$bin/rasterslam-sim" --scenario "$here/rawlogs/town-loop.yaml" --seed "$s" --scans 200 -o "other$s.rawlog" --compress 0
done

# relocalize NAME MAP RAWLOG CONFIG [ARGS...]: seconds and peak memory (MB) on stdout, the log in NAME.log
relocalize() {
  local t0 t1 name=$1 map=$2 rawlog=$3 cfg=$4
  shift 4
  t0=$(date +%s.%N)
  /usr/bin/time -f "%M" -o "$name.mem" "$bin/rasterslam" relocalize --map "$map" --rawlog "$rawlog" --out "$name" \
    --config "$cfg" --verbose "$@" > "$name.log" 2>&1 ||
    { tail -5 "$name.log" >&2; echo "benchmark-surface-search: relocalize $name failed" >&2; return 1; }
  t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" -v m="$(cat "$name.mem")" 'BEGIN {printf "%.1f s, peak %.0f MB", b - a, m / 1024}'
}
# shares NAME: the free-space conflict shares of the surface search's alignments (taken,
# refused) and of the places fitted on the features (features-kept, features-refused:
# relocalization_max_conflicts).
shares() {
  { grep -o "surface pose on .*free-space conflicts [0-9]* of [0-9]* ([0-9.]*): [a-z]*" "$1.log" || true
    grep -o "features fit local map .*free-space conflicts [0-9]* of [0-9]* ([0-9.]*): [a-z]*" "$1.log" |
      sed 's/: \([a-z]*\)$/: features-\1/' || true; } |
    sed 's/.*free-space conflicts/free-space conflicts/' |
    awk '{gsub(/[():]/, ""); v[$7] = v[$7] " " $6} END {
      for (k in v) { n = split(v[k], a, " "); mn = a[1]; mx = a[1]
        for (i = 2; i <= n; i++) { if (a[i] < mn) mn = a[i]; if (a[i] > mx) mx = a[i] }
        printf "  %s: %d alignments, conflict share %.3f-%.3f\n", k, n, mn, mx } }' | sort
}
for mode in off on lax-unchecked lax; do
  echo
  case $mode in
    off|on) echo "== surface search $mode" ;;
    *) echo "== surface search off, relocalization_min_inliers 12, $mode" ;;
  esac
  # (each relocalize assigned on its own: under set -e a failure there stops the script)
  took="$(relocalize "k-$mode" kmap q.rawlog $mode.yaml)"
  echo "KITTI street, 160 rendered scans against the map of its first 51 ($took):"
  "$bin/rasterslam-eval" reloc --reloc "k-$mode/relocalization.txt" --gt q.tum --map-gt krun/groundtruth.tum \
    --map-est krun/trajectory.tum
  shares "k-$mode"
  for s in 7 1001; do
    took="$(relocalize "o$s-$mode" town-map "other$s.rawlog" $mode.yaml)"
    placed=$(grep -c " found " "o$s-$mode/relocalization.txt" || true)
    echo "town seed $s, 200 scans against the town-loop map: $placed placed (all wrong) ($took)"
    shares "o$s-$mode"
  done
done

[ -n "${SESSIONS:-}" ] || exit 0
for f in lifelong.yaml s1.yaml s9.yaml s10.yaml; do
  [ -f "$SESSIONS/$f" ] || { echo "benchmark-surface-search: $SESSIONS/$f not found (SESSIONS: a benchmark-sessions.sh WORK)" >&2; exit 1; }
done
echo
echo "== a town that changed (scenarios of $SESSIONS)"
cp "$SESSIONS/lifelong.yaml" loff.yaml
search_on loff.yaml lon.yaml
lax loff.yaml llax.yaml
lax loff.yaml llax-unchecked.yaml 1
for n in 1 9 10; do quietly "$bin/rasterslam-sim" --scenario "$SESSIONS/s$n.yaml" -o "c$n.rawlog" --gt-tum "c$n.tum" --compress 0; done
quietly "$bin/rasterslam" run --rawlog c1.rawlog --config loff.yaml --out c1run --map-out c1map --quiet
for mode in off on lax-unchecked lax; do
  for n in 9 10; do
    took=$(relocalize "c$n-$mode" c1map "c$n.rawlog" "l$mode.yaml" --last 149)
    echo "session $n's first 150 scans against session 1's map, $mode ($took):"
    "$bin/rasterslam-eval" reloc --reloc "c$n-$mode/relocalization.txt" --gt "c$n.tum" --map-gt c1run/groundtruth.tum \
      --map-est c1run/trajectory.tum | grep -E "^all|^group"
    shares "c$n-$mode"
  done
done
