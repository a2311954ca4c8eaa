#!/usr/bin/env bash
# Interruptions, measured (the hardening issue's goals), on the simulated VLP-16 drive
# (rawlogs/town-vlp16.yaml, 400 scans, about 2 s a run):
#  1. Ctrl-C at random moments: N_INT runs (20) of `rasterslam run --map-out`, each sent SIGINT
#     at a moment drawn uniformly over a whole run (start-up, scans, optimization, saving).
#     Each must exit 130 (or 0 when it had already finished) and leave the outputs for what it
#     processed: trajectory.tum and groundtruth.tum with one line per scan that run.yaml counts,
#     run.yaml naming the signal, a map that loads when a keyframe was made, no *.tmp-* file.
#  2. Kills while saving: N_KILL runs (50) that update a map in place (--map-in M --map-out M),
#     each killed with SIGKILL at a moment drawn uniformly from the start of its save (the first
#     temporary file in the map folder) to 20 ms past the length of the final optimization and
#     save (read from an uninterrupted run's log). After
#     each kill the map must load (`rasterslam map info`) with the old session count or the new
#     one; then a whole run over it must pass and leave no *.tmp-* file anywhere in the map,
#     and no run's offline local maps in the temporary folder (the killed run's included).
# Fails on the first violation (naming the trial, its moment and the reason); at the end prints
# what the signals hit. Seeded: SEED (1) gives the same moments on every run. Do not rebuild
# the programs while it runs.
# usage: scripts/interrupt-check.sh   (env: BUILD=build, N_INT=20, N_KILL=50, SEED=1, KEEP=0)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${BUILD:-$here/build}"
bin="$BUILD/bin"
N_INT="${N_INT:-20}"
N_KILL="${N_KILL:-50}"
RANDOM="${SEED:-1}"
for p in rasterslam rasterslam-sim; do
  [ -x "$bin/$p" ] || { echo "interrupt-check: $bin/$p not built (ninja -C $BUILD)" >&2; exit 1; }
done
# Job control: background programs get SIGINT as from a terminal (a non-interactive shell
# would start them with SIGINT ignored).
set -m
work="$(mktemp -d "${TMPDIR:-/tmp}/rasterslam-interrupt.XXXXXX")"
[ "${KEEP:-0}" = 1 ] || trap 'rm -rf "$work"' EXIT
# The programs' own temporary folder (a run's offline local maps): checked for what killed
# runs leave.
export TMPDIR="$work/tmp"
mkdir -p "$TMPDIR"

fail() {
  echo "interrupt-check: FAILED: $*" >&2
  echo "  (work folder kept: $work)" >&2
  trap - EXIT
  exit 1
}
now_ms() { date +%s%3N; }
# A uniform whole number in [0, n) from bash's seeded generator (30 bits), in REPLY: drawn in
# this shell (a $(...) subshell would reseed the generator).
uniform() { REPLY=$(((RANDOM << 15 | RANDOM) % $1)); }
# Data lines of a TUM file.
lines() { [ -f "$1" ] && grep -cv '^#' "$1" || echo 0; }
yamlv() { sed -n "s/^ *$2: *\([-0-9A-Za-z_.]*\).*/\1/p" "$1" | head -n1; }
debris() { find "$@" -name '*.tmp-*' 2>/dev/null | head -n 5; }
offline_left() { find "$TMPDIR" -mindepth 1 -maxdepth 1 -name 'rasterslam-offline-*' | head -n 3; }

rawlog="$work/town-vlp16.rawlog"
"$bin/rasterslam-sim" --scenario "$here/rawlogs/town-vlp16.yaml" -o "$rawlog" >/dev/null 2>&1 ||
  fail "rasterslam-sim could not make the drive"
run=("$bin/rasterslam" run --rawlog "$rawlog")

# An uninterrupted run: its length, and when its final phase starts (the log line that
# announces the final optimization; saving follows it).
t0=$(now_ms)
"${run[@]}" --out "$work/ref" --map-out "$work/ref-map" --verbose >"$work/ref.log" 2>&1 ||
  fail "the uninterrupted run failed: $(tail -n 3 "$work/ref.log")"
total_ms=$(($(now_ms) - t0))
scans_ref=$(lines "$work/ref/trajectory.tum")
echo "interrupt-check: an uninterrupted run: $scans_ref scans in $total_ms ms"

# --- 1. Ctrl-C at random moments -----------------------------------------------------------
hit_start=0 hit_run=0 finished=0
for i in $(seq 1 "$N_INT"); do
  uniform $((total_ms + 1))
  at=$REPLY
  out="$work/int$i" map="$work/int$i-map"
  "${run[@]}" --quiet --out "$out" --map-out "$map" >"$work/int$i.log" 2>&1 &
  pid=$!
  sleep "$(printf '%d.%03d' $((at / 1000)) $((at % 1000)))"
  kill -INT "$pid" 2>/dev/null || true
  rc=0
  wait "$pid" || rc=$?
  what="trial $i (SIGINT at $at ms of $total_ms)"
  [ "$rc" = 130 ] || [ "$rc" = 0 ] || fail "$what: exit $rc: $(tail -n 3 "$work/int$i.log")"
  if [ "$rc" = 130 ] && grep -q 'interrupted by SIGINT after 0 scans; nothing to write' "$work/int$i.log"; then
    # Before the first scan (loading the config, the plugins): nothing to write, nothing left.
    [ ! -f "$out/trajectory.tum" ] || fail "$what: a trajectory after 0 scans"
    [ ! -f "$map/map.rsmap" ] || fail "$what: a map after 0 scans"
    d=$(debris "$out" "$map")
    [ -z "$d" ] || fail "$what: temporary files left: $d"
    hit_start=$((hit_start + 1))
    rm -rf "$out" "$map"
    continue
  fi
  [ -f "$out/run.yaml" ] || fail "$what: no run.yaml"
  n=$(lines "$out/trajectory.tum")
  counted=$(yamlv "$out/run.yaml" scans)
  [ "$n" = "$counted" ] || fail "$what: trajectory.tum has $n scans, run.yaml counts $counted"
  [ "$(lines "$out/groundtruth.tum")" = "$n" ] || fail "$what: groundtruth.tum has not $n lines"
  if [ "$rc" = 130 ]; then
    grep -q '^ *interrupted_by: SIGINT' "$out/run.yaml" || fail "$what: run.yaml names no SIGINT"
    grep -q 'interrupted by SIGINT after ' "$work/int$i.log" || fail "$what: no line saying so"
    hit_run=$((hit_run + 1))
  else
    finished=$((finished + 1))
    [ "$n" = "$scans_ref" ] || fail "$what: exit 0 after $n of $scans_ref scans"
  fi
  kf=$(yamlv "$out/run.yaml" keyframes)
  if [ "${kf:-0}" -gt 0 ]; then
    "$bin/rasterslam" map info "$map" >"$work/int$i-info.log" 2>&1 ||
      fail "$what: the map does not load: $(tail -n 2 "$work/int$i-info.log")"
  fi
  d=$(debris "$out" "$map")
  [ -z "$d" ] || fail "$what: temporary files left: $d"
  d=$(offline_left)
  [ -z "$d" ] || fail "$what: its offline local maps were left in the temporary folder: $d"
  rm -rf "$out" "$map"
done
echo "interrupt-check: Ctrl-C at $N_INT random moments: $hit_run during the scans or the save," \
  "$hit_start before the first scan, $finished after the last scan (exit 0, all written); every one left its outputs"

# --- 2. SIGKILL while saving an updated map ------------------------------------------------
# The window: from the final optimization to the end of the save, read from the log's time
# stamps (wall clock, as `date` gives it) on a run that updates the reference map in place.
cp -a "$work/ref-map" "$work/base-map"
cp -a "$work/base-map" "$work/m"
# Milliseconds since midnight of a "HH:MM:SS.fff..." time.
day_ms() {
  local h m s
  IFS=: read -r h m s <<<"$1"
  echo $(((10#$h * 3600 + 10#$m * 60) * 1000 + 10#${s%%.*} * 1000 + 10#$(printf '%.3s' "${s#*.}000")))
}
launch=$(day_ms "$(date +%H:%M:%S.%N)")
"${run[@]}" --out "$work/upd" --map-in "$work/m" --map-out "$work/m" --verbose >"$work/upd.log" 2>&1 ||
  fail "the uninterrupted update run failed: $(tail -n 3 "$work/upd.log")"
stamp() { sed -n "s/^\[\([0-9:.]*\)|.*$1.*/\1/p" "$work/upd.log" | tail -n 1; }
s_final=$(stamp 'optimizing the pose graph')
s_saved=$(stamp 'map saved to')
[ -n "$s_final" ] && [ -n "$s_saved" ] || fail "the update run's log has no optimization or save line"
t_final=$(($(day_ms "$s_final") - launch))
t_saved=$(($(day_ms "$s_saved") - launch))
sessions_old=$("$bin/rasterslam" map info "$work/base-map" | sed -n 's/^sessions *: *//p')
sessions_new=$("$bin/rasterslam" map info "$work/m" | sed -n 's/^sessions *: *//p')
echo "interrupt-check: an update of the map in place: final optimization at $t_final ms, map" \
  "saved at $t_saved ms; sessions $sessions_old -> $sessions_new"
window=$((t_saved - t_final + 20))
[ "$window" -lt 1000 ] || fail "the final phase takes $window ms: too long for this check"

old=0 new=0 mid=0 missed=0
for i in $(seq 1 "$N_KILL"); do
  rm -rf "$work/m" "$work/k"
  cp -a "$work/base-map" "$work/m"
  uniform "$window"
  at=$REPLY
  "${run[@]}" --quiet --out "$work/k" --map-in "$work/m" --map-out "$work/m" >"$work/kill.log" 2>&1 &
  pid=$!
  # The save has begun when its first temporary file appears (a busy loop of shell builtins:
  # the files live for milliseconds); then a uniform delay.
  seen=0
  while kill -0 "$pid" 2>/dev/null; do
    if compgen -G "$work/m/*.tmp-*" >/dev/null || compgen -G "$work/m/store/*.tmp-*" >/dev/null ||
      compgen -G "$work/m/localmaps/*.tmp-*" >/dev/null; then
      seen=1
      break
    fi
  done
  if [ "$seen" = 1 ]; then
    [ "$at" = 0 ] || sleep "$(printf '0.%03d' "$at")"
    kill -KILL "$pid" 2>/dev/null || true
  fi
  wait "$pid" 2>/dev/null || true
  [ "$seen" = 1 ] || missed=$((missed + 1))
  what="kill $i (SIGKILL $at ms after the save began)"
  [ -z "$(debris "$work/m")" ] || mid=$((mid + 1))
  "$bin/rasterslam" map info "$work/m" >"$work/info.log" 2>&1 ||
    fail "$what: the map does not load: $(tail -n 2 "$work/info.log")"
  s=$(sed -n 's/^sessions *: *//p' "$work/info.log")
  if [ "$s" = "$sessions_old" ]; then
    old=$((old + 1))
  elif [ "$s" = "$sessions_new" ]; then
    new=$((new + 1))
  else
    fail "$what: the map holds $s sessions, neither $sessions_old nor $sessions_new"
  fi
  # The next run over the map passes and leaves nothing behind.
  rm -rf "$work/k"
  "${run[@]}" --quiet --out "$work/k" --map-in "$work/m" --map-out "$work/m" >"$work/next.log" 2>&1 ||
    fail "$what: the next run over the map failed: $(tail -n 3 "$work/next.log")"
  d=$(debris "$work/m" "$work/k")
  [ -z "$d" ] || fail "$what: the next run left temporary files: $d"
  d=$(offline_left)
  [ -z "$d" ] || fail "$what: after the next run, offline local maps are left in the temporary folder: $d"
  "$bin/rasterslam" map info "$work/m" >"$work/info.log" 2>&1 ||
    fail "$what: the map after the next run does not load: $(tail -n 2 "$work/info.log")"
done
echo "interrupt-check: $N_KILL runs killed 0-$window ms after their save began ($missed ended" \
  "before a temporary file was seen): $old left the old map, $new the new one, $mid left" \
  "temporary files (all cleaned by the next run); every map loaded"
# A check that killed nothing during a save would prove nothing.
[ "$N_KILL" -lt 10 ] || [ "$missed" -lt "$N_KILL" ] || fail "no kill landed during a save"
[ "$N_KILL" -lt 10 ] || [ "$old" -gt 0 ] || fail "no kill stopped a save before it replaced the map"
echo "interrupt-check: passed"
