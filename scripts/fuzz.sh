#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) in build-fuzz with clang-14, ASan and UBSan, makes their
# seed corpora from the project's own files (fuzz/make-corpus.sh) and runs each target:
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [--runs N] [--targets fuzz_rawlog,...] [--no-build]
#                   [--keep-going]
# SECONDS_PER_TARGET defaults to 60 (none with --runs alone: --runs 1000000 is the long run).
# Fails when a target crashes, leaks, times out (15 s), allocates more than 2 GB at once or in
# all, or hits undefined behaviour; each such input is kept in build-fuzz/crashes/ and printed
# with the command that replays it. A target stops at its first finding, unless --keep-going:
# then it runs in libFuzzer's fork mode, goes on past crashes, timeouts and out-of-memory
# inputs, and the script fails at the end if any was found.
# The corpus a run grows is kept in build-fuzz/corpus/<target>/ for the next run; logs in
# build-fuzz/logs/. What each target covers: docs/fuzzing.md.
# Environment: RASTERSLAM_FUZZ_BUILD (build-fuzz), RASTERSLAM_CORPUS_BUILD (build: the GCC build
# whose programs make the seeds), JOBS (2), RASTERSLAM_FUZZ_NICE (10),
# RASTERSLAM_BUILD_LOCK (/tmp/rs-build.lock: configure and build wait for other builds),
# RASTERSLAM_FUZZ_SEED (1: the same inputs in the same order on every run; 0: libFuzzer picks).
set -euo pipefail
cd "$(dirname "$0")/.."
src="$(pwd)"

usage() {
  echo "usage: scripts/fuzz.sh [SECONDS_PER_TARGET] [--runs N] [--targets a,b] [--no-build]" >&2
  exit 2
}
secs="" runs="" build_it=1 keep_going=0
targets=(fuzz_rawlog fuzz_map_store fuzz_vocabulary fuzz_config)
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) [ $# -ge 2 ] || usage; runs="$2"; shift 2 ;;
    --targets) [ $# -ge 2 ] || usage; IFS=, read -r -a targets <<<"$2"; shift 2 ;;
    --no-build) build_it=0; shift ;;
    --keep-going) keep_going=1; shift ;;
    -h|--help) sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) [[ "$1" =~ ^[0-9]+$ ]] && [ -z "$secs" ] || usage; secs="$1"; shift ;;
  esac
done
[[ -z "$runs" || "$runs" =~ ^[0-9]+$ ]] || usage
[ -n "$secs" ] || [ -n "$runs" ] || secs=60

build="${RASTERSLAM_FUZZ_BUILD:-build-fuzz}"
mkdir -p "$build"
build="$(cd "$build" && pwd)"
corpus_build="${RASTERSLAM_CORPUS_BUILD:-build}"
serial=(nice -n 10)
if command -v flock >/dev/null 2>&1; then
  serial=(flock "${RASTERSLAM_BUILD_LOCK:-/tmp/rs-build.lock}" nice -n 10)
fi

if [ "$build_it" = 1 ]; then
  bash scripts/install-deps.sh
  need=()
  for p in clang-14 libclang-rt-14-dev; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
  done
  if [ ${#need[@]} -gt 0 ]; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO=sudo
    echo "fuzz: installing ${need[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
  fi
  # The libraries, plugins and programs get coverage counters and the sanitizers; the fuzz
  # targets add -fsanitize=fuzzer (libFuzzer's main). Debian's MRPT, OpenCV and PCL are not
  # instrumented: coverage is of the project's code.
  san="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
  t0=$(date +%s)
  CC=clang-14 CXX=clang++-14 "${serial[@]}" cmake -S . -B "$build" -G Ninja \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRASTERSLAM_FUZZ=ON -DBUILD_TESTING=OFF -DBUILD_APPS=OFF \
    -DCMAKE_C_FLAGS="$san" -DCMAKE_CXX_FLAGS="$san" \
    -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
    -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined" \
    -DCMAKE_MODULE_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null
  "${serial[@]}" cmake --build "$build" -j "${JOBS:-2}"
  echo "fuzz: built in $(($(date +%s) - t0)) s"
  # The seeds are made by the programs of the main build (GCC; clang builds of the project
  # register no MRPT classes, see fuzz/fuzz_common.h): only what they need is built there.
  t0=$(date +%s)
  [ -f "$corpus_build/build.ninja" ] || "${serial[@]}" cmake -S . -B "$corpus_build" -G Ninja \
    -DCMAKE_BUILD_TYPE=Release >/dev/null
  plugins=$(cd plugins && for d in */; do
    sed -n 's/^ *rasterslam_add_plugin(\([A-Za-z0-9_]*\).*/rasterslam_plugin_\1/p' "$d/CMakeLists.txt"
  done)
  # shellcheck disable=SC2086
  "${serial[@]}" cmake --build "$corpus_build" -j "${JOBS:-2}" --target rasterslam rasterslam-sim \
    rasterslam-vocab $plugins
  echo "fuzz: seed programs built in $(($(date +%s) - t0)) s"
fi

t0=$(date +%s)
bash fuzz/make-corpus.sh "$corpus_build" "$build/corpus-seed"
echo "fuzz: seed corpora in $(($(date +%s) - t0)) s"

mkdir -p "$build/crashes" "$build/logs"
# Inputs larger than this are cut (libFuzzer's -max_len): big inputs make slow runs.
declare -A max_len=([fuzz_rawlog]=131072 [fuzz_map_store]=131072 [fuzz_vocabulary]=65536
                    [fuzz_config]=16384)
# Leaks are checked after each input (libFuzzer); not at exit, where MRPT unloads the plugin
# modules and what their libraries' static initializers (glog, gflags) allocated looks leaked.
# A single allocation over 256 MB (an input is at most 128 kB: that is a damaged count) fails
# as under the programs' memory cap: malloc returns null (MRPT's aligned allocation then throws
# std::bad_alloc, apps/common/mrpt_aligned_malloc.cpp), operator new throws std::bad_alloc
# (fuzz/fuzz_common.cpp); the readers report either as an error. An input that needs more
# than 2 GB in all is still a finding (-rss_limit_mb).
export RASTERSLAM_FUZZ_MAX_ALLOC_MB="${RASTERSLAM_FUZZ_MAX_ALLOC_MB:-256}"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:leak_check_at_exit=0:allocator_may_return_null=1:max_allocation_size_mb=$RASTERSLAM_FUZZ_MAX_ALLOC_MB:quarantine_size_mb=64:detect_stack_use_after_return=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}"
export RASTERSLAM_MAX_MEMORY_MB=0
# The targets' scratch folders (removed at exit; one left behind by a crash stays here).
export TMPDIR="$build/tmp"
mkdir -p "$TMPDIR"
export RASTERSLAM_PLUGIN_PATH="$build/lib/rasterslam/plugins"
export RASTERSLAM_FUZZ_MAP_STORE="$build/corpus-seed/map-store"
if [ -f scripts/sanitizers/lsan.supp ]; then
  export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$src/scripts/sanitizers/lsan.supp:print_suppressions=0}"
fi

failed=()
printf 'fuzz: %s per target%s\n' "${secs:+$secs s}" "${runs:+, at most $runs runs}"
for t in "${targets[@]}"; do
  exe="$build/fuzz/$t"
  [ -x "$exe" ] || { echo "fuzz: $exe not built" >&2; exit 1; }
  mkdir -p "$build/corpus/$t"
  args=(-rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout=15 -print_final_stats=1
        -max_len="${max_len[$t]:-65536}" -artifact_prefix="$build/crashes/$t-"
        -seed="${RASTERSLAM_FUZZ_SEED:-1}")
  [ -z "$secs" ] || args+=(-max_total_time="$secs")
  [ -z "$runs" ] || args+=(-runs="$runs")
  [ ! -f "$build/corpus-seed/$t.dict" ] || args+=(-dict="$build/corpus-seed/$t.dict")
  [ "$keep_going" = 0 ] || args+=(-fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1)
  touch "$build/logs/.start-$t"
  log="$build/logs/$t.log"
  t1=$(date +%s)
  rc=0
  nice -n "${RASTERSLAM_FUZZ_NICE:-10}" "$exe" "${args[@]}" "$build/corpus/$t" \
    "$build/corpus-seed/$t" >"$log" 2>&1 || rc=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n 1)
  if [ -z "$execs" ]; then  # fork mode: the last status line
    execs=$(grep -oE '^#[0-9]+' "$log" | tail -n 1 | tr -d '#' || true)
    rate=$(grep -oE 'exec/s: [0-9]+' "$log" | tail -n 1 | cut -d' ' -f2 || true)
  fi
  cov=$(grep -oE 'cov: [0-9]+ ft: [0-9]+ corp: [0-9]+/[^ ]+' "$log" | tail -n 1 || true)
  mapfile -t found < <(find "$build/crashes" -maxdepth 1 -name "$t-*" -newer "$build/logs/.start-$t" | sort)
  ok=$([ "$rc" = 0 ] && [ ${#found[@]} = 0 ] && echo ok || echo FAILED)
  printf 'fuzz: %-16s %s in %3d s: %s runs, %s exec/s, %s\n' "$t" "$ok" "$(($(date +%s) - t1))" \
    "${execs:-?}" "${rate:-?}" "${cov:-?}"
  if [ "$ok" != ok ]; then
    failed+=("$t")
    grep -E '^(==[0-9]+== ?ERROR|SUMMARY|.*runtime error:)' "$log" | sort | uniq -c | head -n 8 |
      sed 's/^/  /' || true
    for a in "${found[@]}"; do
      echo "  reproducer: $a"
    done
    [ ${#found[@]} = 0 ] || echo "  replay: RASTERSLAM_FUZZ_MAP_STORE=$RASTERSLAM_FUZZ_MAP_STORE" \
      "RASTERSLAM_FUZZ_MAX_ALLOC_MB=$RASTERSLAM_FUZZ_MAX_ALLOC_MB ASAN_OPTIONS=$ASAN_OPTIONS $exe REPRODUCER"
    echo "  log: $log"
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: ${#failed[@]} of ${#targets[@]} targets failed: ${failed[*]}"
  exit 1
fi
echo "fuzz: ${#targets[@]} targets ran without a finding"
