#!/usr/bin/env bash
# The plugin SDK end to end (CTest: Sdk.OutOfTreePluginAgainstInstalledPackage):
#  1. installs the build tree into a fresh temporary prefix P and checks the CMake package
#     (P/<libdir>/cmake/rasterslam) and that the installed programs load P's libraries;
#  2. configures, builds (-j2) and installs examples/plugin-template against P alone
#     (find_package(rasterslam) through CMAKE_PREFIX_PATH=P);
#  3. runs P/bin/rasterslam list-plugins (the example class, from P's plugin folder),
#     P/bin/rasterslam run with no --config (the default config from P/share/rasterslam) and
#     with the example's config on a small simulated rawlog, and checks
#     that the example rasterizer was created from the config and rasterized every scan, and
#     that the ORB odometry tracked on its images.
# Everything goes into one temporary folder under --work-dir, removed on exit (also on a
# failure or SIGINT/SIGTERM); folders left by a run that was killed outright (SIGKILL, e.g. a
# CTest timeout) are removed by the next run.
set -euo pipefail

usage()
{
	echo "usage: $0 --cmake CMAKE --generator GEN --cxx CXX --build-dir DIR --source-dir DIR" \
		"--work-dir DIR --plugin-subdir lib/rasterslam/plugins --cmake-subdir lib/cmake/rasterslam" >&2
	exit 2
}
CMAKE="" GENERATOR="" CXX="" BUILD="" SRC="" WORK="" PLUGIN_SUBDIR="" CMAKE_SUBDIR=""
while [ $# -gt 0 ]; do
	[ $# -ge 2 ] || usage
	case "$1" in
		--cmake) CMAKE=$2 ;;
		--generator) GENERATOR=$2 ;;
		--cxx) CXX=$2 ;;
		--build-dir) BUILD=$2 ;;
		--source-dir) SRC=$2 ;;
		--work-dir) WORK=$2 ;;
		--plugin-subdir) PLUGIN_SUBDIR=$2 ;;
		--cmake-subdir) CMAKE_SUBDIR=$2 ;;
		*) usage ;;
	esac
	shift 2
done
for v in CMAKE GENERATOR CXX BUILD SRC WORK PLUGIN_SUBDIR CMAKE_SUBDIR; do
	[ -n "${!v}" ] || usage
done

NAME=flat_ground_rasterizer
CLASS=example::FlatGroundRasterizer
EXAMPLE="$SRC/examples/plugin-template"
CONFIG="$EXAMPLE/config/flat-ground.yaml"
SCANS=40

fail()
{
	echo "sdk test: FAIL: $*" >&2
	exit 1
}
# Runs a step with its standard output in a log and its standard error in <log>.err (apart:
# the programs' progress on stderr would cut into the lines checked); on failure prints the
# ends of both and fails.
step()
{
	local what=$1 log=$2
	shift 2
	if ! "$@" >"$log" 2>"$log.err"; then
		echo "--- end of $log:" >&2
		tail -n 30 "$log" >&2
		echo "--- end of $log.err:" >&2
		tail -n 30 "$log.err" >&2
		fail "$what failed: $*"
	fi
}

# Only the temporary prefix may provide rasterslam, its plugins and its configs.
unset RASTERSLAM_PLUGIN_PATH RASTERSLAM_SHARE_DIR LD_LIBRARY_PATH CMAKE_PREFIX_PATH rasterslam_DIR

mkdir -p "$WORK"
WORK=$(cd "$WORK" && pwd -P)
for d in "$WORK"/sdk.*.*; do
	[ -d "$d" ] || continue
	pid=${d#"$WORK"/sdk.}
	pid=${pid%%.*}
	if ! kill -0 "$pid" 2>/dev/null; then
		rm -rf "$d"
	fi
done
T=$(mktemp -d "$WORK/sdk.$$.XXXXXX")
cleanup()
{
	rm -rf "$T"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
P="$T/prefix"
LIBDIR="$P/${CMAKE_SUBDIR%/cmake/rasterslam}"
t0=$SECONDS

# 1. The installed package.
step "cmake --install $BUILD --prefix $P" "$T/install.log" "$CMAKE" --install "$BUILD" --prefix "$P"
PKG="$P/$CMAKE_SUBDIR"
for f in rasterslamConfig.cmake rasterslamConfigVersion.cmake rasterslamTargets.cmake \
	RasterslamPlugin.cmake; do
	[ -f "$PKG/$f" ] || fail "$PKG/$f was not installed"
done
for lib in core map io raster features bow places mapping eval sim; do
	grep -q "^add_library(rasterslam::$lib SHARED IMPORTED)" "$PKG/rasterslamTargets.cmake" ||
		fail "$PKG/rasterslamTargets.cmake: no imported target rasterslam::$lib"
done
for f in include/rasterslam/core/plugin.h include/rasterslam/core/config.h bin/rasterslam \
	bin/rasterslam-sim; do
	[ -e "$P/$f" ] || fail "$P/$f was not installed"
done
compgen -G "$P/share/rasterslam/config/*.yaml" >/dev/null ||
	fail "$P/share/rasterslam/config/ holds no config (*.yaml)"
# The installed programs load the installed libraries (RUNPATH $ORIGIN/../lib), not the build's.
ldd "$P/bin/rasterslam" >"$T/ldd.txt" || fail "ldd $P/bin/rasterslam failed"
if grep -q "not found" "$T/ldd.txt"; then
	fail "$P/bin/rasterslam: libraries not found: $(grep 'not found' "$T/ldd.txt" | tr -s ' \t\n' ' ')"
fi
nlibs=0
while read -r so _ path _; do
	[ "$(dirname "$(realpath "$path")")" = "$LIBDIR" ] ||
		fail "$P/bin/rasterslam loads $so from $path, not from $LIBDIR"
	nlibs=$((nlibs + 1))
done < <(grep "librasterslam_" "$T/ldd.txt")
[ "$nlibs" -gt 0 ] || fail "$P/bin/rasterslam: ldd lists no librasterslam_* library"

# 2. The example plugin, built against the installed package only.
step "configuring $EXAMPLE against $P" "$T/configure.log" \
	"$CMAKE" -S "$EXAMPLE" -B "$T/example" -G "$GENERATOR" -DCMAKE_CXX_COMPILER="$CXX" \
	-DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$P" -DCMAKE_FIND_PACKAGE_NO_PACKAGE_REGISTRY=ON
found=$(sed -n 's/^rasterslam_DIR:PATH=//p' "$T/example/CMakeCache.txt")
[ "$found" = "$PKG" ] ||
	fail "$EXAMPLE: find_package(rasterslam) used '$found', not the installed $PKG"
step "building $EXAMPLE" "$T/build.log" "$CMAKE" --build "$T/example" -j2
step "installing the example plugin into $P" "$T/install-example.log" \
	"$CMAKE" --install "$T/example" --prefix "$P"
MODULE="$P/$PLUGIN_SUBDIR/librasterslam_plugin_$NAME.so"
[ -f "$MODULE" ] || fail "$MODULE was not installed by rasterslam_add_plugin"

# 3. The installed programs find the plugin in their prefix and use it.
step "$P/bin/rasterslam list-plugins" "$T/list.txt" "$P/bin/rasterslam" list-plugins
listed=$(awk -v c="$CLASS" '$1 == "rasterizer" && $2 == c { print $3 }' "$T/list.txt")
[ "$listed" = "$MODULE" ] || {
	cat "$T/list.txt" >&2
	fail "rasterslam list-plugins: expected rasterizer $CLASS from $MODULE, got '${listed}'"
}

step "simulating $SCANS scans" "$T/sim.log" "$P/bin/rasterslam-sim" \
	--scenario "$SRC/rawlogs/town-vlp16.yaml" -o "$T/sim.rawlog" --scans "$SCANS"
# With no --config the installed program runs the default shipped config, from its prefix.
step "rasterslam run with the default config" "$T/run-default.log" "$P/bin/rasterslam" run \
	--rawlog "$T/sim.rawlog" --out "$T/out-default" --last 2
used=$(awk '/^input:/ { i = 1; next } i && /^  config:/ { print $2; exit }' "$T/out-default/run.yaml")
case "$used" in
	"$P/share/rasterslam/config/"*.yaml) [ -f "$used" ] || fail "$used: no such file" ;;
	*) fail "$T/out-default/run.yaml: the default config is '$used', not one of $P/share/rasterslam/config" ;;
esac

step "rasterslam run with $CONFIG" "$T/run.log" "$P/bin/rasterslam" run --rawlog "$T/sim.rawlog" \
	--out "$T/out" --config "$CONFIG" --verbose
RUN="$T/out/run.yaml"
[ -f "$RUN" ] || fail "$RUN was not written"
# The class in force for the rasterizer role, and a parameter read from the example config.
cls=$(awk '/^  rasterizer:/ { r = 1; next } r && /^    class:/ { print $2; exit }' "$RUN")
[ "$cls" = "$CLASS" ] || fail "$RUN: config.rasterizer.class is '$cls', expected $CLASS"
grep -q "^      ground_percentile: 5$" "$RUN" ||
	fail "$RUN: no rasterizer parameter ground_percentile: 5 in force"
# Every scan went through the plugin (its debug line, logged as the rasterizer role).
n=$(grep -c "|DEBUG|rasterizer\] scan [0-9]*: ground z=" "$T/run.log" || true)
[ "$n" -eq "$SCANS" ] || fail "$T/run.log: the example rasterizer logged $n scans, expected $SCANS"
lines=$(grep -cv "^#" "$T/out/trajectory.tum" || true)
[ "$lines" -eq "$SCANS" ] || fail "$T/out/trajectory.tum: $lines poses, expected $SCANS"
# The odometry tracked on the plugin's images: no scan lost, the trajectory close to the truth
# (0.07 m ATE when written; the elevation rasterizer's is of the same order).
lost=$(awk -F, 'NR > 1 && $4 == "lost"' "$T/out/timings.csv" | wc -l)
[ "$lost" -eq 0 ] || fail "$T/out/timings.csv: $lost scans lost on the example's images"
ate=$(awk '/^  ate_rmse_m:/ { print $2 }' "$RUN")
[ -n "$ate" ] || fail "$RUN: no summary.ate_rmse_m"
awk -v a="$ate" 'BEGIN { exit !(a < 0.5) }' || fail "$RUN: ATE $ate m, expected below 0.5 m"

echo "sdk test: OK in $((SECONDS - t0)) s: $CLASS built against $PKG, installed as $MODULE," \
	"used for $SCANS scans (ATE $ate m)"
