// `rasterslam map ...`: tools over a saved map.
#include <rasterslam/core/config.h>
#include <rasterslam/core/engine.h>
#include <rasterslam/io/run_outputs.h>
#include <rasterslam/map/map.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <limits>
#include <vector>

#include "cli.h"

namespace fs = std::filesystem;

namespace rasterslam::cli
{
namespace
{
const char* kMapUsage = R"(usage: rasterslam map info DIR
       rasterslam map export DIR --out DIR2
       rasterslam map merge A B --out C [--config FILE] [--overwrite] [--quiet]
       rasterslam map prune DIR (--before WHEN | --keep-per-place N [--place-radius M])
                            [--dry-run] [--config FILE]
  info DIR     sessions, local maps online and offline, keyframes, points, sizes on disk and
               the time span of the map saved in DIR (by rasterslam run --map-out)
  export DIR   writes DIR2/map.graph (keyframe pose graph, MRPT text format),
               DIR2/map.simplemap (one keyframe per local map with its points, MRPT),
               DIR2/points.pcd and points.ply (every local map's points in the map frame),
               DIR2/top.png (points and each session's trajectory from above) and
               DIR2/localmaps/NNNN.png, DIR2/keyframes-sN.tum (each session's keyframes)
  merge A B    two maps built separately become one, written to C: each keyframe of B is
               located in A with no pose prior; engine.anchor_min_agreeing (3) of them must
               agree on where B lies, else nothing is written (exit 1, "no overlap"). B's
               keyframes are moved there and optimized with A fixed; B's sessions, local maps
               and graph follow A's (ids renumbered), linked by relocalization edges.
               --config: the loop detector and optimizer to use (default: slam.yaml);
               C must not hold a map unless --overwrite (C may be A: A is then replaced)
  prune DIR    drops local maps that were offline when the map was saved, with their
               place-index entries and the keyframes no other local map holds, and writes
               the map back to DIR (atomically):
                 --before WHEN       those last updated before WHEN: a date (2026-06-01,
                                     2026-06-01T12:00:00Z, UTC) or seconds in the input's clock
                 --keep-per-place N  all but the newest N of each place: going from the
                                     newest (later session, then later stamp), a local map
                                     goes when N kept ones have their anchor within M metres
                                     of its anchor (--place-radius, default 10)
               with both, only what both drop goes; --dry-run lists and changes nothing
)";

int mapInfo(const std::string& dir)
{
	const Map map = loadMap(dir);
	std::uintmax_t disk = 0;
	std::error_code ec;
	for (const auto& e : fs::recursive_directory_iterator(dir, ec))
		if (e.is_regular_file(ec))
			disk += e.file_size(ec);
	struct SessionInfo
	{
		std::size_t keyframes = 0, localMaps = 0, online = 0;
		double first = std::numeric_limits<double>::max(),
		       last = std::numeric_limits<double>::lowest();
	};
	std::map<uint32_t, SessionInfo> sessions;
	for (const auto& [id, k] : map.keyframes)
	{
		auto& s = sessions[k->session];
		++s.keyframes;
		s.first = std::min(s.first, k->stamp);
		s.last = std::max(s.last, k->stamp);
	}
	std::size_t points = 0, online = 0, pngBytes = 0;
	for (const auto& [id, lm] : map.localMaps)
	{
		auto& s = sessions[lm->session];
		const bool on = map.onlineWhenSaved.count(id) > 0;
		++s.localMaps;
		s.online += on;
		online += on;
		const auto e = map.saved.find(id);
		points += e != map.saved.end() ? e->second.points : lm->points();
	}
	std::error_code ec2;
	for (const auto& e : fs::directory_iterator(fs::path(dir) / "localmaps", ec2))
		if (e.path().extension() == ".png")
			pngBytes += e.file_size(ec2);
	std::printf("map          : %s (%.2f MB on disk)\n", fs::path(dir).lexically_normal().c_str(),
	            disk / 1e6);
	std::printf("sessions     : %u\n", map.sessions);
	std::printf("keyframes    : %zu\n", map.keyframes.size());
	std::printf("local maps   : %zu (%zu online, %zu offline), %zu points, %.2f MB of images\n",
	            map.localMaps.size(), online, map.localMaps.size() - online, points,
	            pngBytes / 1e6);
	std::printf("local-map graph: %zu sequential, %zu loop, %zu relocalization edges\n",
	            map.graph.count(LocalMapGraph::EdgeKind::Sequential),
	            map.graph.count(LocalMapGraph::EdgeKind::Loop),
	            map.graph.count(LocalMapGraph::EdgeKind::Relocalization));
	std::printf("place index  : %s (%.2f MB)\n",
	            map.placeIndexClass.empty() ? "none" : map.placeIndexClass.c_str(),
	            map.placeIndex.size() / 1e6);
	for (const auto& [id, s] : sessions)
	{
		std::printf(
		    "  session %u: %zu keyframes, %zu local maps (%zu online), stamps %.3f .. %.3f (%.1f "
		    "s)\n",
		    id, s.keyframes, s.localMaps, s.online, s.first, s.last,
		    s.keyframes ? s.last - s.first : 0.0);
		if (const auto r = map.sessionRecords.find(id); r != map.sessionRecords.end())
			std::printf("             made %s from %s (sensor %s)\n", r->second.startedAt.c_str(),
			            r->second.input.c_str(),
			            r->second.sensor.empty() ? "-" : r->second.sensor.c_str());
	}
	return 0;
}
int mapMerge(int argc, char** argv)
{
	std::vector<std::string> dirs;
	std::string out, configPath;
	bool overwrite = false, quiet = false;
	for (int i = 2; i < argc; i++)
	{
		const std::string a = argv[i];
		auto value = [&]() -> std::string
		{
			if (i + 1 >= argc)
				usageError("map merge: " + a + " needs a value");
			return argv[++i];
		};
		if (a == "--out")
			out = value();
		else if (a == "--config")
			configPath = value();
		else if (a == "--overwrite")
			overwrite = true;
		else if (a == "--quiet")
			quiet = true;
		else if (!a.empty() && a[0] == '-')
			usageError("map merge: unknown option '" + a + "'");
		else
			dirs.push_back(a);
	}
	if (dirs.size() != 2 || out.empty())
		usageError("map merge: expected rasterslam map merge A B --out C");
	std::error_code ec;
	if (fs::exists(mapFilePath(out), ec) && !overwrite)
		throw std::runtime_error("--out " + out +
		                         " holds a map already: pass --overwrite to replace it");
	if (fs::exists(dirs[0], ec) && fs::exists(dirs[1], ec) && fs::equivalent(dirs[0], dirs[1], ec))
		throw std::runtime_error("map merge: A and B are the same map ('" + dirs[0] + "')");
	if (fs::exists(dirs[1], ec) && fs::exists(out, ec) && fs::equivalent(dirs[1], out, ec))
		throw std::runtime_error("--out " + out +
		                         " is the map being merged in (B): write to A or a new folder");
	if (configPath.empty())
		configPath = findConfig("slam.yaml");
	Engine engine(loadYamlFile(configPath), configPath);
	engine.setLogLevel(quiet ? mrpt::system::LVL_ERROR : mrpt::system::LVL_INFO);
	engine.loadMap(dirs[0]);
	const auto sessionsA = engine.mapManager()->map().sessions - 1;  // loadMap counts a new session
	const auto rep = engine.mergeMap(dirs[1]);
	io::ensureWritableDir(out);  // only now: a merge that fails leaves no folder behind
	engine.saveMap(out, {});
	const auto& t = rep.T_this_other;
	std::printf(
	    "rasterslam: merged %s (%zu local maps) into %s (%u session%s): %zu of %zu keyframes "
	    "located, %zu agree on x=%.2f y=%.2f "
	    "z=%.2f yaw=%.1f deg; optimized (chi2 %.3g -> %.3g, largest correction %.2f m)\n",
	    dirs[1].c_str(), rep.localMaps, dirs[0].c_str(), sessionsA, sessionsA == 1 ? "" : "s",
	    rep.located, rep.keyframesTried, rep.agreeing, t.x(), t.y(), t.z(), t.yaw() * 180 / M_PI,
	    rep.optimization.initialError, rep.optimization.finalError, rep.maxCorrection_m);
	std::printf("rasterslam: map of %u sessions, %zu keyframes written to %s\n", rep.sessions,
	            rep.keyframes, mapFilePath(out).c_str());
	return 0;
}
/** Seconds since the Unix epoch of a UTC date (YYYY-MM-DD[THH:MM:SS][Z]), or a number. */
double parseWhen(const std::string& v)
{
	std::tm tm{};
	int Y = 0, M = 0, D = 0, h = 0, m = 0, sec = 0;
	char tail = 0;
	const int n =
	    std::sscanf(v.c_str(), "%4d-%2d-%2dT%2d:%2d:%2d%c", &Y, &M, &D, &h, &m, &sec, &tail);
	if ((n == 3 && v.size() == 10) || n == 6 || (n == 7 && tail == 'Z'))
	{
		if (M < 1 || M > 12 || D < 1 || D > 31 || h > 23 || m > 59 || sec > 60)
			usageError("map prune: --before '" + v + "' is not a valid date");
		tm.tm_year = Y - 1900;
		tm.tm_mon = M - 1;
		tm.tm_mday = D;
		tm.tm_hour = h;
		tm.tm_min = m;
		tm.tm_sec = sec;
		return static_cast<double>(::timegm(&tm));
	}
	std::size_t used = 0;
	double x = 0;
	try
	{
		x = std::stod(v, &used);
	}
	catch (const std::exception&)
	{
		used = 0;
	}
	if (used != v.size() || !std::isfinite(x))
		usageError("map prune: --before '" + v +
		           "' is neither a date (YYYY-MM-DD[THH:MM:SS]) nor seconds");
	return x;
}

int mapPrune(int argc, char** argv)
{
	std::string dir, configPath;
	PruneOptions opts;
	bool quiet = false;
	for (int i = 2; i < argc; i++)
	{
		const std::string a = argv[i];
		auto value = [&]() -> std::string
		{
			if (i + 1 >= argc)
				usageError("map prune: " + a + " needs a value");
			return argv[++i];
		};
		if (a == "--before")
			opts.before = parseWhen(value());
		else if (a == "--keep-per-place")
		{
			const auto v = value();
			const auto n = parseIndexArg(a, v);
			if (n < 1)
				usageError("map prune: --keep-per-place must be >= 1");
			opts.keepPerPlace = n;
		}
		else if (a == "--place-radius")
		{
			const auto v = value();
			char* end = nullptr;
			opts.placeRadius_m = std::strtod(v.c_str(), &end);
			if (end == v.c_str() || *end || !(opts.placeRadius_m > 0) ||
			    !std::isfinite(opts.placeRadius_m))
				usageError("map prune: --place-radius must be a distance > 0 in metres");
		}
		else if (a == "--dry-run")
			opts.dryRun = true;
		else if (a == "--config")
			configPath = value();
		else if (a == "--quiet")
			quiet = true;
		else if (!a.empty() && a[0] == '-')
			usageError("map prune: unknown option '" + a + "'");
		else if (dir.empty())
			dir = a;
		else
			usageError("map prune: expected one folder");
	}
	if (dir.empty())
		usageError(
		    "map prune: expected rasterslam map prune DIR (--before WHEN | --keep-per-place N)");
	if (!opts.before && !opts.keepPerPlace)
		usageError("map prune: give --before WHEN or --keep-per-place N");
	if (configPath.empty())
		configPath = findConfig("slam.yaml");
	Engine engine(loadYamlFile(configPath), configPath);
	engine.setLogLevel(quiet ? mrpt::system::LVL_ERROR : mrpt::system::LVL_WARN);
	engine.loadMap(dir);
	const auto rep = engine.pruneMap(opts);
	std::string ids;
	for (const auto id : rep.dropped)
		ids += (ids.empty() ? "" : " ") + std::to_string(id);
	if (!opts.dryRun && !rep.dropped.empty())
		engine.saveMap(dir, {});
	std::printf("rasterslam: %s %zu of %zu local maps (%zu places)%s%s%s\n",
	            opts.dryRun ? "would drop" : "dropped", rep.dropped.size(), rep.localMaps,
	            rep.places, ids.empty() ? "" : ": ", ids.c_str(),
	            opts.dryRun ? ""
	                        : mrpt::format("; %zu keyframes dropped with them, %zu local maps they "
	                                       "had replaced back in the place index",
	                                       rep.keyframesDropped, rep.reindexed)
	                              .c_str());
	return 0;
}
}  // namespace

int mapCommand(int argc, char** argv)
{
	if (argc < 2 || std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help")
	{
		(argc < 2 ? std::cerr : std::cout) << kMapUsage;
		return argc < 2 ? kExitUsage : 0;
	}
	const std::string sub = argv[1];
	try
	{
		if (sub == "export")
		{
			if (argc != 5 || std::string(argv[3]) != "--out")
				usageError("map export: expected rasterslam map export DIR --out DIR2");
			// The export is a program of its own beside this one: only it loads PCL.
			const auto exe =
			    (fs::read_symlink("/proc/self/exe").parent_path() / "rasterslam-map-export")
			        .string();
			std::vector<char*> args{const_cast<char*>(exe.c_str()), argv[2], argv[3], argv[4],
			                        nullptr};
			std::fflush(stdout);
			::execv(exe.c_str(), args.data());
			throw std::runtime_error("cannot run '" + exe + "': " + std::strerror(errno));
		}
		if (sub == "merge")
			return mapMerge(argc, argv);
		if (sub == "prune")
			return mapPrune(argc, argv);
		if (sub == "info")
		{
			if (argc != 3)
				usageError("map info: expected one folder (rasterslam map info DIR)");
			return mapInfo(argv[2]);
		}
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam: error: " << e.what() << "\n";
		return kExitError;
	}
	usageError("map: unknown subcommand '" + sub + "' (info, export, merge, prune)");
}

}  // namespace rasterslam::cli
