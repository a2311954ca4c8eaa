#!/usr/bin/env bash
# The whole project and its test suite under AddressSanitizer and UndefinedBehaviorSanitizer:
# configures build-asan (GCC, -O2 -g1, -fsanitize=address,undefined), builds every
# target and runs ctest there. The tests run the programs and load the plugins of the same
# tree, all built with the sanitizers; they inherit the options below. Any report fails
# the test that caused it (abort_on_error, -fno-sanitize-recover=undefined).
#   scripts/sanitize.sh [extra ctest arguments, e.g. -R Rawlog]
# Suppressions (scripts/sanitizers/): only for reports inside Debian's libraries, each with
# its reason. Environment: RASTERSLAM_ASAN_BUILD (build-asan), JOBS (2),
# RASTERSLAM_BUILD_LOCK (/tmp/rs-build.lock: configure, build and ctest wait for other builds).
set -euo pipefail
cd "$(dirname "$0")/.."
src="$(pwd)"
build="${RASTERSLAM_ASAN_BUILD:-build-asan}"
jobs="${JOBS:-2}"
serial=(nice -n 10)
if command -v flock >/dev/null 2>&1; then
  serial=(flock "${RASTERSLAM_BUILD_LOCK:-/tmp/rs-build.lock}" nice -n 10)
fi

bash scripts/install-deps.sh

export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$src/scripts/sanitizers/lsan.supp:print_suppressions=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
# The programs cap their data memory with RLIMIT_DATA, which counts ASan's shadow mappings
# (terabytes, reserved at start): every later allocation would fail. No cap here.
export RASTERSLAM_MAX_MEMORY_MB=0

san="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"
t0=$(date +%s)
# -g1: line tables and function names, all a sanitizer's report needs; a third less compile
# time than -g (engine.cpp: 27 s against 41 s).
"${serial[@]}" cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
  -DCMAKE_C_FLAGS="$san" -DCMAKE_CXX_FLAGS="$san" -DRASTERSLAM_USE_JEMALLOC=OFF \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_MODULE_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null
# The build runs the test programs too (GoogleTest discovery), with the options above.
"${serial[@]}" cmake --build "$build" -j "$jobs"
t1=$(date +%s)
echo "sanitize: built in $((t1 - t0)) s"
rc=0
(cd "$build" && "${serial[@]}" ctest --output-on-failure -j "$jobs" "$@") || rc=$?
echo "sanitize: ctest in $(($(date +%s) - t1)) s"
exit "$rc"
