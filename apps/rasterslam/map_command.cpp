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
struct MergeArgs
{
	std::string a, b, out, configPath;
	bool overwrite = false, quiet = false, verbose = false;
};

int mapMerge(const MergeArgs& args)
{
	const std::vector<std::string> dirs{args.a, args.b};
	const std::string& out = args.out;
	const bool overwrite = args.overwrite, quiet = args.quiet;
	std::string configPath = args.configPath;
	std::error_code ec;
	if (fs::exists(dirs[0], ec) && fs::exists(dirs[1], ec) && fs::equivalent(dirs[0], dirs[1], ec))
		throw std::runtime_error("map merge: A and B are the same map ('" + dirs[0] + "')");
	if (fs::exists(dirs[1], ec) && fs::exists(out, ec) && fs::equivalent(dirs[1], out, ec))
		throw std::runtime_error("--out " + out +
		                         " is the map being merged in (B): write to A or a new folder");
	configPath = resolveConfig(configPath, "slam");
	Engine engine(loadYamlFile(configPath), configPath);
	engine.setLogLevel(args.verbose ? mrpt::system::LVL_DEBUG
	                                : (quiet ? mrpt::system::LVL_ERROR : mrpt::system::LVL_INFO));
	// The output is written (A itself when --out is A), the inputs only read.
	std::vector<std::unique_ptr<MapUseLock>> locks;
	const auto lock = [&](const std::string& dir, MapUseLock::Mode mode)
	{
		if (std::error_code e; fs::is_directory(dir, e))
			locks.push_back(std::make_unique<MapUseLock>(dir, mode, "rasterslam map merge"));
	};
	const bool outIsA =
	    fs::exists(out, ec) && fs::exists(dirs[0], ec) && fs::equivalent(out, dirs[0], ec);
	lock(out, MapUseLock::Mode::Write);
	if (!outIsA)
		lock(dirs[0], MapUseLock::Mode::Read);
	lock(dirs[1], MapUseLock::Mode::Read);
	const bool outLocked = fs::is_directory(out, ec);
	// Under the lock: no other writer can save a map there meanwhile.
	if (fs::exists(mapFilePath(out), ec) && !overwrite)
		throw std::runtime_error("--out " + out +
		                         " holds a map already: pass --overwrite to replace it");
	engine.loadMap(dirs[0]);
	const auto sessionsA = engine.mapManager()->map().sessions - 1;  // loadMap counts a new session
	const auto rep = engine.mergeMap(dirs[1]);
	io::ensureWritableDir(out);  // only now: a merge that fails leaves no folder behind
	if (!outLocked)
		lock(out, MapUseLock::Mode::Write);
	engine.saveMap(out, {});
	const auto& t = rep.T_this_other;
	const std::string whole = rep.localMapsWhole == 0
	                              ? ""
	                              : " and " + std::to_string(rep.locatedWhole) + " of " +
	                                    std::to_string(rep.localMapsWhole) + " local maps whole";
	std::printf(
	    "rasterslam: merged %s (%zu local maps) into %s (%u session%s): %zu of %zu keyframes "
	    "located%s, %zu agree on x=%.2f y=%.2f "
	    "z=%.2f yaw=%.1f deg; optimized (chi2 %.3g -> %.3g, largest correction %.2f m)\n",
	    dirs[1].c_str(), rep.localMaps, dirs[0].c_str(), sessionsA, sessionsA == 1 ? "" : "s",
	    rep.located, rep.keyframesTried, whole.c_str(), rep.agreeing, t.x(), t.y(), t.z(),
	    t.yaw() * 180 / M_PI, rep.optimization.initialError, rep.optimization.finalError,
	    rep.maxCorrection_m);
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
			usageError("rasterslam map prune", "--before '" + v + "' is not a valid date");
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
		usageError("rasterslam map prune",
		           "--before '" + v + "' is neither a date (YYYY-MM-DD[THH:MM:SS]) nor seconds");
	return x;
}

struct PruneArgs
{
	std::string dir, before, configPath;
	std::size_t keepPerPlace = 0;
	double placeRadius_m = 10;
	bool dryRun = false, quiet = false;
};

int mapPrune(const PruneArgs& args)
{
	const std::string& dir = args.dir;
	std::string configPath = args.configPath;
	const bool quiet = args.quiet;
	PruneOptions opts;
	if (!args.before.empty())
		opts.before = parseWhen(args.before);
	if (args.keepPerPlace > 0)
		opts.keepPerPlace = args.keepPerPlace;
	opts.placeRadius_m = args.placeRadius_m;
	opts.dryRun = args.dryRun;
	configPath = resolveConfig(configPath, "slam");
	Engine engine(loadYamlFile(configPath), configPath);
	engine.setLogLevel(quiet ? mrpt::system::LVL_ERROR : mrpt::system::LVL_WARN);
	std::unique_ptr<MapUseLock> lock;
	if (std::error_code ec; fs::is_directory(dir, ec))
		lock = std::make_unique<MapUseLock>(
		    dir, opts.dryRun ? MapUseLock::Mode::Read : MapUseLock::Mode::Write,
		    "rasterslam map prune");
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

int mapExport(const std::string& dir, const std::string& out)
{
	// The export is a program of its own beside this one: only it loads PCL.
	const auto exe =
	    (fs::read_symlink("/proc/self/exe").parent_path() / "rasterslam-map-export").string();
	std::vector<std::string> strs{exe, dir, "--out", out};
	std::vector<char*> args;
	for (auto& a : strs)
		args.push_back(a.data());
	args.push_back(nullptr);
	std::fflush(stdout);
	::execv(exe.c_str(), args.data());
	throw std::runtime_error("cannot run '" + exe + "': " + std::strerror(errno));
}

/** Runs a map tool: errors while running are exit 1 with the message. */
template <typename F>
int guarded(F&& f)
{
	try
	{
		return f();
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam: error: " << e.what() << "\n";
		return kExitError;
	}
}
}  // namespace

std::vector<Command> addMapCommands(CLI::App& app)
{
	CLI::App* map = subcommand(app, "map", "tools over a map saved by rasterslam run --map-out");
	map->require_subcommand(1);
	std::vector<Command> cmds;

	auto infoDir = std::make_shared<std::string>();
	auto* info = subcommand(
	    *map, "info", "sessions, local maps, keyframes, points, sizes and time span of a map");
	info->add_option("DIR", *infoDir, "map folder")->required();
	cmds.push_back({info, [infoDir] { return guarded([&] { return mapInfo(*infoDir); }); }});

	auto ex = std::make_shared<std::pair<std::string, std::string>>();
	auto* exp = subcommand(
	    *map, "export", "write a saved map for MRPT's tools, PCL and viewers",
	    "Writes DIR2/map.graph (keyframe pose "
	    "graph, MRPT text format), DIR2/map.simplemap (one keyframe per local map with its "
	    "points), DIR2/points.pcd and points.ply (every local map's points in the map frame), "
	    "DIR2/top.png (points and each session's trajectory from above), DIR2/localmaps/NNNN.png "
	    "and DIR2/keyframes-sN.tum (each session's keyframes)");
	exp->add_option("DIR", ex->first, "map folder")->required();
	exp->add_option("--out", ex->second, "output folder")->required()->type_name("DIR2");
	cmds.push_back(
	    {exp, [ex] { return guarded([&] { return mapExport(ex->first, ex->second); }); }});

	auto m = std::make_shared<MergeArgs>();
	auto* merge = subcommand(
	    *map, "merge", "merge two maps built separately into one",
	    "Two maps built separately become one, written to C: each keyframe of B is located in A "
	    "with no pose prior (a local map none of whose keyframes is found: all its points); "
	    "engine.anchor_min_agreeing (3) of these hits must agree on where B lies, "
	    "else nothing is written (exit 1, \"no overlap\"). B's keyframes are moved there and "
	    "optimized with A fixed; B's sessions, local maps and graph follow A's (ids renumbered), "
	    "linked by relocalization edges");
	merge->add_option("A", m->a, "the map B is merged into")->required();
	merge->add_option("B", m->b, "the map merged in")->required();
	merge->add_option("--out", m->out, "output folder (may be A: A is then replaced)")
	    ->required()
	    ->type_name("C");
	merge
	    ->add_option("--config", m->configPath,
	                 configHelp("slam") + "; its loop detector and optimizer are used")
	    ->type_name("FILE|NAME");
	merge->add_flag("--overwrite", m->overwrite, "let --out replace a map already there");
	auto* mq = merge->add_flag("--quiet", m->quiet, "only errors and the final summary");
	merge
	    ->add_flag("--verbose", m->verbose,
	               "debug logging: each keyframe of B located or not, and why (free space, "
	               "inliers)")
	    ->excludes(mq);
	cmds.push_back({merge, [m] { return guarded([&] { return mapMerge(*m); }); }});

	auto p = std::make_shared<PruneArgs>();
	auto* prune = subcommand(
	    *map, "prune", "drop old local maps, by date or by place",
	    "Drops local maps that were offline when the map was saved, with their place-index "
	    "entries and the keyframes no other local map holds, and writes the map back to DIR "
	    "(atomically); with both --before and --keep-per-place only what both drop goes.");
	prune->add_option("DIR", p->dir, "map folder")->required();
	auto* before = prune->add_option(
	    "--before", p->before,
	    "drop those last updated before WHEN: a date (2026-06-01, 2026-06-01T12:00:00Z, UTC) "
	    "or seconds in the input's clock");
	before->type_name("WHEN");
	auto* keep =
	    prune
	        ->add_option("--keep-per-place", p->keepPerPlace,
	                     "drop all but the newest N of each place: going from the newest (later "
	                     "session, then later stamp), a local map goes when N kept ones have "
	                     "their anchor within --place-radius of its anchor")
	        ->check(unnamed(CLI::Range(std::size_t{1}, std::size_t{1000000})))
	        ->type_name("N");
	prune->add_option("--place-radius", p->placeRadius_m, "the radius of a place (m)")
	    ->check(unnamed(CLI::PositiveNumber))
	    ->needs(keep)
	    ->type_name("M")
	    ->capture_default_str();
	prune->add_flag("--dry-run", p->dryRun, "list what would go and change nothing");
	prune->add_option("--config", p->configPath, configHelp("slam"))->type_name("FILE|NAME");
	prune->add_flag("--quiet", p->quiet, "only errors and the final summary");
	cmds.push_back({prune, [p, before, keep]
	                {
		                if (before->count() == 0 && keep->count() == 0)
			                usageError("rasterslam map prune",
			                           "give --before WHEN or --keep-per-place N");
		                if (!p->before.empty())
			                parseWhen(p->before);  // a usage error before the map is loaded
		                return guarded([&] { return mapPrune(*p); });
	                }});
	return cmds;
}

}  // namespace rasterslam::cli
