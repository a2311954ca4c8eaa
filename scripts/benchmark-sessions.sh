#!/usr/bin/env bash
# Lifelong benchmark (the lifelong-maps issue's goals): ten sessions over one simulated town
# (different routes, directions, start points, HDL-64E and VLP-16), each located in the map
# the earlier ones left (`--map-in M --map-out M --require-localization`, no pose prior), then
# a drive in another town against that map. Per session: located or not, ATE in the common
# frame (every session judged with session 1's alignment, so a wrong anchoring shows as
# metres), peak resident memory, the map's memory in the run and its size on disk.
# The world changes (the simulator's `epoch` and `traffic`): session n sees the town at epoch
# n-1 (parked cars gone or moved, walls and shop fronts built or pulled down, trees grown), with
# cars and people moving during each run; STATIC=1 drives the unchanging town instead. Each
# session's revisit truth against the earlier ones is written beside it (sN.revisits.txt).
# The pipeline is share/rasterslam/config/lifelong.yaml (CONFIG=slam: slam.yaml, whose images
# keep every height).
# LAPS=K makes every session K times longer (its route driven K times over): LAPS=4 is the
# long lifelong scenario, about 21,000 scans over the ten sessions.
# VLP16_HEIGHT=M mounts the VLP-16 of sessions 2, 4, ... M metres above the ground (a small
# robot; the HDL-64E stays at 1.73 m): a map whose sessions see the town from two heights.
# usage: scripts/benchmark-sessions.sh     (env: BUILD, WORK, STATIC, CONFIG, LAPS, VLP16_HEIGHT)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
WORK="${WORK:-$BUILD/bench-sessions}"
bin="$BUILD/bin"
# Checked before anything is removed: the simulator takes heights in (0, 10) m.
VLP16_HEIGHT="${VLP16_HEIGHT:-}"
if [ -n "$VLP16_HEIGHT" ] && ! { [[ "$VLP16_HEIGHT" =~ ^[0-9]*\.?[0-9]+$ ]] &&
  awk -v h="$VLP16_HEIGHT" 'BEGIN { exit !(h > 0 && h < 10) }'; }; then
  echo "benchmark-sessions: VLP16_HEIGHT must be a height in metres, in (0, 10)" >&2
  exit 2
fi
rm -rf "$WORK"
mkdir -p "$WORK"

yamlv() { sed -n "s/^ *$2: *\([-0-9.eE+a-z]*\).*/\1/p" "$1" | head -n1; }
# A value of a rasterslam-eval --json object by its jq path: json "$j" .ate_rmse_m (empty for null).
json() { jq -r "$2 // empty" <<<"$1"; }
CONFIG="${CONFIG:-lifelong}"
cfg="$WORK/$CONFIG.yaml"
sed -e "s#vocabulary_file: ../vocab/#vocabulary_file: $here/share/rasterslam/vocab/#" \
  "$here/share/rasterslam/config/$CONFIG.yaml" > "$cfg"
echo "config: share/rasterslam/config/$CONFIG.yaml; world: $([ "${STATIC:-0}" = 1 ] && echo static || echo "changing (session n at epoch n-1, 8 cars and 20 people moving)")$([ -n "$VLP16_HEIGHT" ] && echo "; VLP-16 $VLP16_HEIGHT m above the ground")"

# The town of rawlogs/town-loop.yaml: 3 x 2 blocks of 50 m, streets every 64 m.
town() {
  cat <<EOF
town: {blocks_x: 3, blocks_y: 2, block_size_m: 50, street_width_m: 14, sidewalk_m: 3,
       building_height_min_m: 6, building_height_max_m: 24, trees_per_100m: 4,
       poles_per_100m: 3, cars_per_100m: 5, hills: 4, max_slope: 0.06, outskirts_m: 25}
noise: {range_sigma_m: 0.02, dropout_prob: 0.02, intensity_sigma: 0.03}
EOF
}
STATIC="${STATIC:-0}"
LAPS="${LAPS:-1}"
[[ "$LAPS" =~ ^[1-9][0-9]*$ ]] || { echo "benchmark-sessions: LAPS must be a whole number >= 1" >&2; exit 2; }
# scenario N SEED LIDAR SCANS WAYPOINTS: one session's scenario file (stamps a day apart).
scenario() {
  local f="$WORK/s$1.yaml"
  {
    echo "seed: $2"
    echo "lidar: $3"
    echo "scans: $4"
    echo "rate_hz: 10"
    echo "speed_mps: 8"
    echo "start_stamp_s: $((1700000000 + 86400 * $1))"
    echo "route: {waypoints: $5, closed: true, turn_radius_m: 6}"
    if [ "$3" = vlp16 ] && [ -n "$VLP16_HEIGHT" ]; then
      echo "sensor_height_m: $VLP16_HEIGHT"
    fi
    if [ "$STATIC" != 1 ]; then
      echo "epoch: $(($1 - 1))"
      echo "traffic: {cars: 8, pedestrians: 20}"
    fi
    town
  } > "$f"
  echo "$f"
}
# Ten routes over the town, each overlapping what the earlier ones mapped (about 1.1 laps).
routes=(
  "hdl64 530 [[0,0],[128,0],[128,64],[0,64]]"
  "vlp16 530 [[0,64],[128,64],[128,0],[0,0]]"
  "hdl64 530 [[64,0],[192,0],[192,64],[64,64]]"
  "vlp16 530 [[0,0],[0,128],[64,128],[64,0]]"
  "hdl64 530 [[192,64],[192,128],[0,128],[0,64]]"
  "vlp16 530 [[128,0],[128,128],[192,128],[192,0]]"
  "hdl64 880 [[0,0],[192,0],[192,128],[0,128]]"
  "vlp16 350 [[64,64],[64,0],[0,0],[0,64]]"
  "hdl64 530 [[128,64],[0,64],[0,0],[128,0]]"
  "vlp16 530 [[64,0],[64,128],[128,128],[128,0]]"
)
map="$WORK/map"
align=""
printf '%-8s %-6s %6s %8s %9s %-9s %9s %9s %9s %10s %10s %9s\n' session lidar scans changes revisits \
  located hits ate_m peak_mb map_mem_mb map_disk_mb ms_scan
earlier=()
total_scans=0
t_sim=0
t_run=0
now() { date +%s.%N; }
for i in "${!routes[@]}"; do
  n=$((i + 1))
  read -r lidar scans wp <<<"${routes[$i]}"
  scans=$((scans * LAPS))
  total_scans=$((total_scans + scans))
  sc=$(scenario "$n" 42 "$lidar" "$scans" "$wp")
  t0=$(now)
  rev=()
  [ ${#earlier[@]} -gt 0 ] && rev=("${earlier[@]}" --revisits "$WORK/s$n.revisits.txt")
  simlog=$("$bin/rasterslam-sim" --scenario "$sc" -o "$WORK/s$n.rawlog" --compress 0 \
    --gt-tum "$WORK/s$n.tum" ${rev[@]+"${rev[@]}"} 2>&1) ||
    { printf '%s\n' "$simlog" >&2; echo "benchmark-sessions: simulating session $n failed" >&2; exit 1; }
  changes=$(sed -n 's/.*epoch [0-9]*: \([0-9]*\) changes.*/\1/p' <<<"$simlog")
  revisits=$(sed -n 's/^revisits: \([0-9]*\) of.*/\1/p' <<<"$simlog")
  earlier+=(--revisits-of "$WORK/s$n.tum")
  t1=$(now)
  out="$WORK/out$n"
  if [ "$n" = 1 ]; then
    "$bin/rasterslam" run --rawlog "$WORK/s$n.rawlog" --config "$cfg" --out "$out" --quiet --map-out "$map" >/dev/null
  else
    "$bin/rasterslam" run --rawlog "$WORK/s$n.rawlog" --config "$cfg" --out "$out" --quiet \
      --map-in "$map" --map-out "$map" --require-localization >/dev/null || true
  fi
  t2=$(now)
  t_sim=$(awk -v a="$t_sim" -v b="$t1" -v c="$t0" 'BEGIN { print a + b - c }')
  t_run=$(awk -v a="$t_run" -v b="$t2" -v c="$t1" 'BEGIN { print a + b - c }')
  # Session 1 defines the map frame: its alignment to the world is every session's.
  if [ -z "$align" ]; then
    j=$("$bin/rasterslam-eval" traj --gt "$out/groundtruth.tum" --est "$out/trajectory.tum" --json)
    align=$(json "$j" .T_gt_est)
  fi
  j=$("$bin/rasterslam-eval" traj --gt "$out/groundtruth.tum" --est "$out/trajectory.tum" --json --align "$align")
  # Located: at which scan its keyframe anchored the session.
  located=origin
  if [ "$n" != 1 ]; then
    located=$(yamlv "$out/run.yaml" localized_in_prior_map)
    [ "$located" = true ] && located="scan $(yamlv "$out/run.yaml" localized_at_scan)"
  fi
  printf '%-8s %-6s %6s %8s %9s %-9s %9s %9.3f %9.1f %10.2f %10.2f %9.2f\n' "$n" "$lidar" "$scans" \
    "${changes:-0}" "${revisits:--}" "$located" \
    "$(yamlv "$out/run.yaml" prior_map_hits)" "$(json "$j" .ate_rmse_m)" "$(yamlv "$out/run.yaml" peak_rss_mb)" \
    "$(yamlv "$out/run.yaml" map_memory_mb)" "$(du -sm "$map" | cut -f1)" \
    "$(yamlv "$out/run.yaml" ms_per_scan_median)"
  rm -f "$WORK/s$n.rawlog"
done

printf 'all sessions: %d scans; simulated and written in %.0f s, processed in %.0f s (%.1f ms a scan)\n' \
  "$total_scans" "$t_sim" "$t_run" "$(awk -v t="$t_run" -v n="$total_scans" 'BEGIN { print 1000 * t / n }')"

# Another town (another seed), driven against the map: it must never be located.
sc=$(scenario 11 7 hdl64 530 "[[0,0],[128,0],[128,64],[0,64]]")
"$bin/rasterslam-sim" --scenario "$sc" -o "$WORK/other.rawlog" --compress 0 >/dev/null 2>&1
set +e
"$bin/rasterslam" run --rawlog "$WORK/other.rawlog" --config "$cfg" --out "$WORK/other" --quiet \
  --map-in "$map" --require-localization >/dev/null 2>&1
rc=$?
set -e
echo "other town: exit $rc, located: $(yamlv "$WORK/other/run.yaml" localized_in_prior_map), hits in the map: $(yamlv "$WORK/other/run.yaml" prior_map_hits)"
rm -f "$WORK/other.rawlog"
"$bin/rasterslam" map info "$map" | head -n 6
