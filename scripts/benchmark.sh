#!/usr/bin/env bash
# Benchmark: runs pipeline configs on the same inputs, one after the other, and prints for
# each: ms per scan (median and 95th percentile of the whole path, and the median of every
# stage), peak memory, and accuracy (ATE; KITTI-devkit relative translation and rotation
# errors). Inputs: the KITTI sample (../shared/data/kitti00-0000-0100, against the
# SemanticKITTI and the official poses, 10..80 m segments) and the two shipped simulated
# drives (rawlogs/town-loop.yaml, HDL-64E; rawlogs/town-vlp16.yaml, VLP-16; town-sweep.yaml,
# HDL-64E sweeps taken while moving, each config also with engine.deskew; indoor-handheld.yaml,
# a VLP-16 carried through rooms, with the indoor configs instead of the given ones;
# town-kitti.yaml, a street made to look like the KITTI sample, its scans compensated for the
# motion as KITTI's odometry scans are: there GICP's and KISS-ICP's errors are set against
# their KITTI-sample errors, and the scene statistics of both are printed side by side).
#
# KISS-ICP runs beside them on every input, on the same core, scored by the same evaluator:
# it is built from the pinned sources of ../shared/anchors/kiss-icp into KISS_DIR (outside
# this tree; never part of the project's build), the rawlogs are written out as KITTI .bin
# scans for it by the kit's rawlog2bin, and the ratios of the first config to KISS-ICP are
# printed. Its ms per scan include reading the .bin scans, as ours include reading the rawlog.
# A last table puts the reading alone side by side: .bin files (kiss_runner --read-only),
# the plain rawlog (what kitti2rawlog and rasterslam-sim write by default) and a gzip one.
#
# usage: scripts/benchmark.sh [CONFIG.yaml ...]
#   default configs: share/rasterslam/config/tracking.yaml (the paper's tracking) and
#   share/rasterslam/config/gicp-baseline.yaml.  Env: BUILD (build dir), DATA, SIM_SCANS
#   (scans of the HDL-64E town drives, default 300), SIM_LIMIT (scans of the others: all), KISS=0 (leave KISS-ICP out), KISS_DIR
#   (default ~/.cache/rasterslam-bench/kiss-icp), ANCHORS (default ../shared/anchors), KISS_JEMALLOC=1
#   (KISS-ICP with jemalloc preloaded instead of glibc's malloc).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
DATA="${DATA:-$here/../shared/data/kitti00-0000-0100}"
WORK="${WORK:-$BUILD/bench}"
SIM_SCANS="${SIM_SCANS:-300}"
bin="$BUILD/bin"
ANCHORS="${ANCHORS:-$here/../shared/anchors}"
KISS_DIR="${KISS_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/rasterslam-bench/kiss-icp}"
# One core, as the goals are stated: OpenCV would otherwise spread some work over both.
PIN=""
command -v taskset >/dev/null 2>&1 && PIN="taskset -c 0"
[ $# -gt 0 ] || set -- "$here/share/rasterslam/config/tracking.yaml" "$here/share/rasterslam/config/gicp-baseline.yaml"
mkdir -p "$WORK"

# --- KISS-ICP, built outside the project's tree --------------------------------------------
kiss=""
if [ "${KISS:-1}" != 0 ]; then
  case "$(mkdir -p "$KISS_DIR" && cd "$KISS_DIR" && pwd)/" in
    "$here"/*) echo "benchmark: KISS_DIR=$KISS_DIR is inside the project's tree; choose another" >&2; exit 2 ;;
  esac
  if [ -x "$KISS_DIR/kiss_runner" ] && [ -x "$KISS_DIR/rawlog2bin" ]; then
    kiss="$KISS_DIR"
  elif [ -x "$ANCHORS/kiss-icp/build.sh" ] || [ -f "$ANCHORS/kiss-icp/build.sh" ]; then
    echo "benchmark: building KISS-ICP from $ANCHORS/kiss-icp into $KISS_DIR ..." >&2
    if sh "$ANCHORS/kiss-icp/build.sh" "$KISS_DIR" >&2; then kiss="$KISS_DIR"
    else echo "benchmark: the KISS-ICP build failed: KISS-ICP left out" >&2; fi
  else
    echo "benchmark: $ANCHORS/kiss-icp not found: KISS-ICP left out" >&2
  fi
fi

# A value of a rasterslam-eval --json object by its jq path: json "$j" .ate_rmse_m (empty for null).
json() { jq -r "$2 // empty" <<<"$1"; }
yamlv() { sed -n "s/^ *$2: *\([-0-9.eE+]*\).*/\1/p" "$1" | head -n1; }
# A generated rawlog to reuse: there, plain (what the programs write by default: the table
# says so), and newer than the scenario it came from; otherwise it is made again.
reusable() {  # reusable RAWLOG SOURCE...: newer than every source (the scenario, the simulator)
  local f="$1" s; shift
  [ -s "$f" ] && [ "$(head -c 2 "$f" | od -An -tx1 | tr -d ' ')" != 1f8b ] || return 1
  for s in "$@"; do [ "$f" -nt "$s" ] || return 1; done
}
# median of column $2 (1-based) of a CSV with a header
colmed() { awk -F, -v c="$2" 'NR>1{print $c}' "$1" | sort -g | awk '{a[NR]=$1} END{if(NR) print a[int((NR+1)/2)]; else print 0}'; }

header() {
  printf '%-20s %7s %7s | %6s %6s %6s %6s | %7s | %7s %9s %7s | %7s %7s\n' config "ms/scan" p95 read raster odom other "peak MB" "RTE %" "RRE deg/m" "ATE m" "RTE %" "ATE m"
  printf '%-20s %7s %7s | %27s | %7s | %25s | %15s\n' "" median "" "stage medians (ms)" "" "$1" "$2"
}

# A number in a fixed format, or "-" when there is none (a drive too short for its segments).
num() { if [ -n "$2" ]; then printf "$1" "$2"; else echo -; fi; }

row() {  # row NAME OUTDIR JSON1 JSON2
  local t="$2/timings.csv" y="$2/run.yaml"
  local other
  other=$(awk -F, 'NR>1{print $11+$12}' "$t" | sort -g | awk '{a[NR]=$1} END{print a[int((NR+1)/2)]}')
  printf '%-20s %7.1f %7.1f | %6.2f %6.2f %6.2f %6.2f | %7.0f | %7s %9s %7s | %7s %7s\n' "$1" \
    "$(yamlv "$y" ms_per_scan_median)" "$(yamlv "$y" ms_per_scan_p95)" \
    "$(colmed "$t" 8)" "$(colmed "$t" 9)" "$(colmed "$t" 10)" "$other" "$(yamlv "$y" peak_rss_mb)" \
    "$(num %.3f "$(json "$3" .rel_trans_pct)")" "$(num %.4f "$(json "$3" .rel_rot_deg_per_m)")" \
    "$(num %.3f "$(json "$3" .ate_rmse_m)")" \
    "${4:+$(num %.3f "$(json "$4" .rel_trans_pct)")}" "${4:+$(num %.3f "$(json "$4" .ate_rmse_m)")}"
}

kiss_row() {  # kiss_row OUTDIR JSON1 JSON2: timings.csv is scan,points,read_ms,odometry_ms,total_ms
  local t="$1/timings.csv" p95
  p95=$(awk -F, 'NR>1{print $5}' "$t" | sort -g | awk '{a[NR]=$1} END{i=int(NR*0.95+0.999); if(i<1)i=1; print a[i]}')
  printf '%-20s %7.1f %7.1f | %6.2f %6s %6.2f %6s | %7.0f | %7s %9s %7s | %7s %7s\n' "KISS-ICP" \
    "$(colmed "$t" 5)" "$p95" "$(colmed "$t" 3)" "-" "$(colmed "$t" 4)" "-" "$(awk '{printf "%.0f", $1/1024}' "$1/peak_kb")" \
    "$(num %.3f "$(json "$2" .rel_trans_pct)")" "$(num %.4f "$(json "$2" .rel_rot_deg_per_m)")" \
    "$(num %.3f "$(json "$2" .ate_rmse_m)")" \
    "${3:+$(num %.3f "$(json "$3" .rel_trans_pct)")}" "${3:+$(num %.3f "$(json "$3" .ate_rmse_m)")}"
}

# The malloc the rasterslam program was linked with (RASTERSLAM_USE_JEMALLOC, named in the
# footnote). KISS-ICP runs on glibc's malloc with the heap settings rasterslam used before it
# took jemalloc: its faster choice (KITTI: 42.5 ms a scan, 76.6 with jemalloc preloaded);
# KISS_JEMALLOC=1 preloads jemalloc for it instead.
ours_jemalloc="$(ldd "$bin/rasterslam" 2>/dev/null | awk '/libjemalloc/ && !f {print $3; f = 1}' || true)"
kiss_jemalloc=""
if [ "${KISS_JEMALLOC:-0}" = 1 ]; then
  kiss_jemalloc="${ours_jemalloc:-$(/sbin/ldconfig -p 2>/dev/null | awk '/libjemalloc\.so\.2 .*x86-64/ && !f {print $NF; f = 1}' || true)}"
  [ -n "$kiss_jemalloc" ] || { echo "benchmark: KISS_JEMALLOC=1 but no libjemalloc.so.2 found" >&2; exit 2; }
fi

run_kiss() {  # run_kiss BINDIR OUTDIR [kiss_runner options]: one thread, pinned like ours
  local velo="$1" out="$2"; shift 2
  rm -rf "$out"; mkdir -p "$out"
  if [ -n "$kiss_jemalloc" ]; then
    LD_PRELOAD="$kiss_jemalloc" \
      $PIN /usr/bin/time -f %M -o "$out/peak_kb" "$kiss/kiss_runner" --velodyne "$velo" --out "$out" --threads 1 "$@" >/dev/null
  else
    # Scan-sized blocks stay in glibc's heap (KITTI: 55.0 -> 51.5 ms with glibc's defaults).
    MALLOC_MMAP_THRESHOLD_=33554432 MALLOC_TRIM_THRESHOLD_=1073741824 \
      $PIN /usr/bin/time -f %M -o "$out/peak_kb" "$kiss/kiss_runner" --velodyne "$velo" --out "$out" --threads 1 "$@" >/dev/null
  fi
}

kiss_ratio() {  # kiss_ratio OURS_OUTDIR OURS_JSON KISS_OUTDIR KISS_JSON NAME
  local a b
  a=$(yamlv "$1/run.yaml" ms_per_scan_median); b=$(colmed "$3/timings.csv" 5)
  awk -v a="$a" -v b="$b" -v ta="$(json "$2" .rel_trans_pct)" -v tb="$(json "$4" .rel_trans_pct)" \
      -v ra="$(json "$2" .rel_rot_deg_per_m)" -v rb="$(json "$4" .rel_rot_deg_per_m)" -v n="$5" \
      'BEGIN{if (tb == "" || rb == "" || tb == 0 || rb == 0) printf "%s / KISS-ICP: time %.2f x (goal <= 0.25); no segment for relative errors\n", n, a/b;
             else printf "%s / KISS-ICP: time %.2f x (goal <= 0.25), RTE %.2f x, RRE %.2f x (goal <= 1)\n", n, a/b, ta/tb, ra/rb}'
}

rate_note() {  # speed ratio of the first config against the last
  local a b
  a=$(yamlv "$1/run.yaml" ms_per_scan_median); b=$(yamlv "$2/run.yaml" ms_per_scan_median)
  awk -v a="$a" -v b="$b" -v n1="$3" -v n2="$4" 'BEGIN{printf "%s runs %.1f times the rate of %s (median ms/scan %.1f vs %.1f)\n", n1, b/a, n2, a, b}'
}

# Relative errors on the KITTI sample (raw scans) by config, for the realism check below.
declare -A kitti_sem=()
realism() {  # realism NAME SIM_JSON: the simulated street's errors against the KITTI sample's
  local k="${kitti_sem[$1]:-}" goal=0
  [ -n "$k" ] || return 0
  # The goal is the baselines': the simulator no harder than twice the real street for scan
  # matchers. Below half the real error, the simulator lacks some of the real data's errors.
  case "$1" in gicp-baseline|KISS-ICP) goal=1 ;; esac
  awk -v n="$1" -v g="$goal" -v ts="$(json "$2" .rel_trans_pct)" -v tk="$(json "$k" .rel_trans_pct)" \
      -v rs="$(json "$2" .rel_rot_deg_per_m)" -v rk="$(json "$k" .rel_rot_deg_per_m)" \
      'BEGIN{if (ts == "" || tk == "" || tk == 0 || rk == 0) {printf "%s: no segment to compare\n", n; exit}
             ok = ts <= 2*tk && rs <= 2*rk
             low = (ts < tk/2 ? " translation" : "") (rs < rk/2 ? " rotation" : "")
             printf "%s here vs on the KITTI sample: RTE %.3f vs %.3f %% (%.2f x), RRE %.4f vs %.4f deg/m (%.2f x)%s%s\n",
               n, ts, tk, ts/tk, rs, rk, rs/rk, g ? (ok ? "; goal (at most 2 x) met" : "; goal (at most 2 x) NOT MET") : "",
               low != "" ? "; under half the real error in" low : ""}'
}

# with_grid_after_first ARRAY CONFIG...: ARRAY becomes the configs with, after the first, a
# copy of it with odometry.params.ground_model: grid (when it says plane).
with_grid_after_first() {
  local -n into="$1"; shift
  into=("$1")
  if grep -q 'ground_model: plane ' "$1"; then
    local g="$WORK/$(basename "$1" .yaml)+grid.yaml"
    sed 's/ground_model: plane /ground_model: grid  /' "$1" >"$g"; into+=("$g")
    # And with the rotation refined by ICP on the last 10 keyframes' points, keyframes only
    # (the refinement as the issue asks it reported: with and without), and the features' fit
    # refitted with a Cauchy loss: tracking-refined.yaml.
    local r="$WORK/$(basename "$1" .yaml)+grid+refine.yaml"
    sed 's/^\( *\)ground_model: plane .*/\1ground_model: grid\n\1refine: rotation\n\1refine_frames: keyframes\n\1refit_cauchy_m: 0.1/' "$1" >"$r"
    into+=("$r")
  fi
  into+=("${@:2}")
}

# --- KITTI ---------------------------------------------------------------------------
if [ -d "$DATA" ]; then
  for vc in 0 0.205; do
    rawlog="$WORK/kitti00-0000-0100-vc$vc.rawlog"
    [ -f "$rawlog" ] || "$bin/kitti2rawlog" --velodyne "$DATA/velodyne" --poses "$DATA/poses_semantickitti.txt" \
        --calib "$DATA/calib.txt" --times "$DATA/times.txt" --compress 0 --vertical-correction-deg "$vc" -o "$rawlog" >/dev/null
    echo "KITTI 00 frames 0-100 (101 HDL-64E scans, 84 m; plain rawlog; vertical angle correction $vc deg); relative errors on 10..80 m segments"
    header "vs SemanticKITTI poses" "vs official"
    outs=(); names=(); jsons=()
    kcfgs=("$@")
    # On the corrected scans: also the paper's tracking with the ground-patch alignment.
    [ "$vc" = 0 ] || with_grid_after_first kcfgs "$@"
    for cfg in "${kcfgs[@]}"; do
      name="$(basename "$cfg" .yaml)"; out="$WORK/kitti-vc$vc-$name"
      $PIN "$bin/rasterslam" run --rawlog "$rawlog" --config "$cfg" --out "$out" --quiet >/dev/null
      sem=$("$bin/rasterslam-eval" traj --gt "$DATA/poses_semantickitti.txt" --calib "$DATA/calib.txt" --est "$out/trajectory.kitti" --segments 10:80:10 --json)
      off=$("$bin/rasterslam-eval" traj --gt "$DATA/poses_official.txt" --calib "$DATA/calib.txt" --est "$out/trajectory.kitti" --segments 10:80:10 --json)
      row "$name" "$out" "$sem" "$off"
      outs+=("$out"); names+=("$name"); jsons+=("$sem")
      [ "$vc" != 0 ] || kitti_sem["$name"]="$sem"
    done
    if [ -n "$kiss" ]; then
      kout="$WORK/kitti-vc$vc-kiss"
      kopt=(); [ "$vc" = 0 ] || kopt=(--kitti-correction)
      run_kiss "$DATA/velodyne" "$kout" "${kopt[@]}"
      ksem=$("$bin/rasterslam-eval" traj --gt "$DATA/poses_semantickitti.txt" --calib "$DATA/calib.txt" --est "$kout/trajectory.kitti" --segments 10:80:10 --json)
      koff=$("$bin/rasterslam-eval" traj --gt "$DATA/poses_official.txt" --calib "$DATA/calib.txt" --est "$kout/trajectory.kitti" --segments 10:80:10 --json)
      kiss_row "$kout" "$ksem" "$koff"
      [ "$vc" != 0 ] || kitti_sem[KISS-ICP]="$ksem"
    fi
    [ ${#outs[@]} -lt 2 ] || rate_note "${outs[0]}" "${outs[-1]}" "${names[0]}" "${names[-1]}"
    [ -z "$kiss" ] || kiss_ratio "${outs[0]}" "${jsons[0]}" "$kout" "$ksem" "${names[0]}"
    [ -z "$kiss" ] || [ "${names[1]:-}" != "${names[0]}+grid" ] || kiss_ratio "${outs[1]}" "${jsons[1]}" "$kout" "$ksem" "${names[1]}"
    [ -z "$kiss" ] || [ "${names[2]:-}" != "${names[0]}+grid+refine" ] || kiss_ratio "${outs[2]}" "${jsons[2]}" "$kout" "$ksem" "${names[2]}"
    echo
  done
else
  echo "benchmark: $DATA not found: KITTI part skipped" >&2
fi

# --- Simulation --------------------------------------------------------------------------
declare -A sim_sem=()
# A config with engine.deskew on (for the drive whose sweeps are not de-skewed).
with_deskew() {  # with_deskew CONFIG OUT
  if grep -q '^engine:' "$1"; then sed 's/^engine:.*/engine:\n  deskew: constant_velocity/' "$1" >"$2"
  else { cat "$1"; printf 'engine:\n  deskew: constant_velocity\n'; } >"$2"; fi
}

for scen in town-loop town-vlp16 town-sweep indoor-handheld town-kitti; do
  segs=50:200:50 kissopt=()
  case "$scen" in
    town-loop) n="$SIM_SCANS"; sim="$WORK/town-loop-$SIM_SCANS.rawlog"; what="$SIM_SCANS HDL-64E scans" ;;
    town-vlp16) n="${SIM_LIMIT:-}"; sim="$WORK/$scen${n:+-$n}.rawlog"; what="${n:-400} VLP-16 scans" ;;
    town-sweep) n="$SIM_SCANS"; sim="$WORK/town-sweep-$SIM_SCANS.rawlog"; what="$SIM_SCANS HDL-64E scans, motion within each sweep; +deskew: engine.deskew on" ;;
    town-kitti) n="$SIM_SCANS"; sim="$WORK/town-kitti-$SIM_SCANS.rawlog"; what="$SIM_SCANS HDL-64E scans (MRPT's HDL-64 beams) of a street like the KITTI sample's, slowing for corners, scans motion-compensated as KITTI's" ;;
    indoor-handheld) n="${SIM_LIMIT:-}"; sim="$WORK/$scen${n:+-$n}.rawlog"; what="${n:-450} VLP-16 scans carried by hand through rooms; the indoor configs"
      segs=10:40:10; kissopt=(--max-range 30 --min-range 0.5) ;;
  esac
  cfgs=("$@")
  [ "$scen" != indoor-handheld ] || cfgs=("$here/share/rasterslam/config/indoor.yaml" "$here/share/rasterslam/config/gicp-indoor.yaml")
  case "$scen" in town-loop|town-vlp16|town-kitti) with_grid_after_first cfgs "$@" ;; esac
  if [ "$scen" = town-sweep ]; then
    cfgs=()
    for cfg in "$@"; do
      d="$WORK/$(basename "$cfg" .yaml)+deskew.yaml"; with_deskew "$cfg" "$d"; cfgs+=("$cfg" "$d")
    done
  fi
  reusable "$sim" "$here/rawlogs/$scen.yaml" "$bin/rasterslam-sim" ||
    "$bin/rasterslam-sim" --scenario "$here/rawlogs/$scen.yaml" ${n:+--scans "$n"} -o "$sim" >"$sim.log" 2>&1 ||
    { echo "benchmark: rasterslam-sim failed on rawlogs/$scen.yaml: $(tail -n 1 "$sim.log")" >&2; exit 1; }
  IFS=: read -r s0 s1 _ <<<"$segs"
  echo "Simulated drive (rawlogs/$scen.yaml, $what; plain rawlog); relative errors on $s0..$s1 m segments"
  header "vs simulator ground truth" ""
  outs=(); names=(); jsons=()
  for cfg in "${cfgs[@]}"; do
    name="$(basename "$cfg" .yaml)"; out="$WORK/sim-$scen-$name"
    $PIN "$bin/rasterslam" run --rawlog "$sim" --config "$cfg" --out "$out" --quiet >/dev/null
    gt=$("$bin/rasterslam-eval" traj --gt "$out/groundtruth.tum" --est "$out/trajectory.tum" --segments "$segs" --json)
    row "$name" "$out" "$gt" ""
    outs+=("$out"); names+=("$name"); jsons+=("$gt")
    # For the realism check: the KITTI sample's segment lengths (relative errors depend on them).
    [ "$scen" != town-kitti ] || sim_sem["$name"]=$("$bin/rasterslam-eval" traj --gt "$out/groundtruth.tum" --est "$out/trajectory.tum" --segments 10:80:10 --json)
  done
  if [ -n "$kiss" ]; then
    velo="$WORK/$scen-bin"
    [ -f "$velo/times.txt" ] && [ "$velo/times.txt" -nt "$sim" ] ||
      { rm -rf "$velo"; "$kiss/rawlog2bin" "$sim" "$velo" >"$WORK/rawlog2bin.log" 2>&1 ||
        { echo "benchmark: rawlog2bin failed on $sim: $(tail -n 1 "$WORK/rawlog2bin.log")" >&2; exit 1; }; }
    kout="$WORK/sim-$scen-kiss"
    run_kiss "$velo" "$kout" "${kissopt[@]}"
    kgt=$("$bin/rasterslam-eval" traj --gt "$velo/groundtruth.kitti" --est "$kout/trajectory.kitti" --segments "$segs" --json)
    kiss_row "$kout" "$kgt" ""
    [ "$scen" != town-kitti ] || sim_sem[KISS-ICP]=$("$bin/rasterslam-eval" traj --gt "$velo/groundtruth.kitti" --est "$kout/trajectory.kitti" --segments 10:80:10 --json)
  fi
  ri=0; [ "$scen" != town-sweep ] || ri=1  # there: the first config with de-skewing
  [ ${#outs[@]} -lt 2 ] || rate_note "${outs[$ri]}" "${outs[-1]}" "${names[$ri]}" "${names[-1]}"
  [ -z "$kiss" ] || kiss_ratio "${outs[$ri]}" "${jsons[$ri]}" "$kout" "$kgt" "${names[$ri]}"
  [ -z "$kiss" ] || [ "${names[1]:-}" != "${names[0]}+grid" ] || kiss_ratio "${outs[1]}" "${jsons[1]}" "$kout" "$kgt" "${names[1]}"
  [ -z "$kiss" ] || [ "${names[2]:-}" != "${names[0]}+grid+refine" ] || kiss_ratio "${outs[2]}" "${jsons[2]}" "$kout" "$kgt" "${names[2]}"
  if [ "$scen" = town-kitti ]; then
    # Is the simulated street as hard as the real one? The same programs, as they run on the
    # KITTI sample's scans (no de-skewing), within 2 x their errors there, both on 10..80 m
    # segments.
    echo "On 10..80 m segments, as on the KITTI sample:"
    for name in "${!sim_sem[@]}"; do realism "$name" "${sim_sem[$name]}"; done | sort
    if [ -d "$DATA" ]; then
      echo
      echo "Scene statistics (rasterslam-eval scene): the KITTI sample (every 5th scan), this street and the demo town (every 5th scan)"
      "$bin/rasterslam-eval" scene "$DATA/velodyne" "$sim" "$WORK/town-loop-$SIM_SCANS.rawlog" \
        --label KITTI --label town-kitti --label town-loop --every 5
    fi
  fi
  echo
done
ours_malloc="glibc's"
[ -z "$ours_jemalloc" ] || ours_malloc="jemalloc"
kiss_malloc="glibc's with scan-sized blocks kept in the heap"
[ -z "$kiss_jemalloc" ] || kiss_malloc="jemalloc (KISS_JEMALLOC=1)"
malloc_used="rasterslam $ours_malloc, KISS-ICP $kiss_malloc"
[ -n "$kiss" ] || malloc_used="rasterslam $ours_malloc"
echo "(one process per run, pinned to one core; 'other' = mapping + loop stages; peak MB = the process's RSS high-water mark;" \
  "malloc: $malloc_used)"

# --- Reading alone ---------------------------------------------------------------------------
# The same 101 KITTI scans from .bin files and from the plain rawlog (what kitti2rawlog and
# rasterslam-sim write by default) and a gzip one, read into points in one process by
# rasterslam-bench-read; KISS-ICP's runner reading the .bin files (--read-only) beside it.
if [ -d "$DATA" ]; then
  plain="$WORK/kitti00-0000-0100-vc0.rawlog" gz="$WORK/kitti00-0000-0100-gz.rawlog"
  [ -f "$gz" ] || "$bin/kitti2rawlog" --velodyne "$DATA/velodyne" --poses "$DATA/poses_semantickitti.txt" \
      --calib "$DATA/calib.txt" --times "$DATA/times.txt" --compress 1 -o "$gz" >/dev/null
  echo
  echo "Reading the KITTI sample's 101 scans into points (ms per scan, median of passes 2..5; ratio to the .bin files)"
  $PIN "$bin/rasterslam-bench-read" --bin "$DATA/velodyne" --rawlog "$plain" --rawlog "$gz" --passes 5 2>"$WORK/bench-read.log" ||
    { echo "benchmark: rasterslam-bench-read failed: $(tail -n 1 "$WORK/bench-read.log")" >&2; exit 1; }
  if [ -n "$kiss" ]; then
    rm -rf "$WORK/read-bin"; mkdir -p "$WORK/read-bin"
    $PIN "$kiss/kiss_runner" --velodyne "$DATA/velodyne" --out "$WORK/read-bin" --threads 1 --read-only >/dev/null 2>&1
    printf 'KISS-ICP reading the same .bin files into its points (kiss_runner --read-only): %.3f ms/scan\n' "$(colmed "$WORK/read-bin/timings.csv" 3)"
  fi
  echo "(goal: the default rawlog reads in at most 2 x the time of the .bin files)"
fi
