// `rasterslam relocalize`: locate every scan of a rawlog in a saved map, with no pose prior.
#include <mrpt/core/format.h>
#include <mrpt/poses/CPose3DQuat.h>
#include <rasterslam/core/config.h>
#include <rasterslam/core/engine.h>
#include <rasterslam/io/rawlog_source.h>
#include <rasterslam/io/run_outputs.h>
#include <rasterslam/io/trajectory_io.h>

#include <filesystem>
#include <iostream>
#include <map>

#include "cli.h"

namespace fs = std::filesystem;

namespace rasterslam::cli
{
namespace
{
struct RelocalizeArgs
{
	std::string mapDir, rawlog, outDir, configPath;
	std::optional<std::size_t> first, last;
	bool quiet = false, verbose = false;
};
int relocalizeCommand(const RelocalizeArgs& args);
}  // namespace

Command addRelocalizeCommand(CLI::App& app)
{
	auto a = std::make_shared<RelocalizeArgs>();
	CLI::App* sub = subcommand(
	    app, "relocalize", "locate every scan of a rawlog in a saved map, with no pose prior",
	    "Writes DIR2/relocalization.txt: a line a scan with stamp, status, reason (ok, "
	    "surface: aligned on the surfaces, then verified on the features within that alignment's "
	    "gate, with loop_detector.relocalization_surface_search, "
	    "features, candidates, score, inliers, ground, free-space: the fit's walls and poles "
	    "stand where the other side saw bare ground), the map's local map and keyframe ids, "
	    "the keyframe's stamp, the BOW score normalized by what the scan's two halves score "
	    "against each other (candidates under the loop detector's min_score are not "
	    "verified), inliers, and the pose x y z qx qy qz qw in the map frame.");
	sub->add_option("--map", a->mapDir, "map saved by rasterslam run --map-out")
	    ->required()
	    ->type_name("DIR");
	sub->add_option("--rawlog", a->rawlog, "MRPT rawlog with 3D scans")
	    ->required()
	    ->type_name("FILE");
	sub->add_option("--out", a->outDir, "output folder for relocalization.txt")
	    ->required()
	    ->type_name("DIR2");
	sub->add_option("--config", a->configPath, configHelp("slam"))->type_name("FILE|NAME");
	addIndex(*sub, "--first", a->first, "skip scans before input index N (0-based)");
	addIndex(*sub, "--last", a->last, "stop after input index N (inclusive)");
	auto* q = sub->add_flag("--quiet", a->quiet, "only errors and the final summary");
	sub->add_flag("--verbose", a->verbose, "debug logging")->excludes(q);
	return {sub, [a]
	        {
		        if (a->first && a->last && *a->first > *a->last)
			        usageError("rasterslam relocalize", "--first is after --last");
		        return relocalizeCommand(*a);
	        }};
}

namespace
{
int relocalizeCommand(const RelocalizeArgs& args)
{
	std::string configPath = args.configPath;
	const std::string &mapDir = args.mapDir, &rawlog = args.rawlog, &outDir = args.outDir;
	const auto &first = args.first, &last = args.last;
	const auto level = args.verbose
	                       ? mrpt::system::LVL_DEBUG
	                       : (args.quiet ? mrpt::system::LVL_ERROR : mrpt::system::LVL_INFO);
	try
	{
		io::ensureWritableDir(outDir);
		configPath = resolveConfig(configPath, "slam");
		Engine engine(loadYamlFile(configPath), configPath);
		engine.setLogLevel(level);
		if (!engine.rasterizer() || !engine.loopDetector() || !engine.mapManager())
			throw ConfigError(
			    configPath +
			    ": relocalize needs a rasterizer, a map_manager and a loop_detector section");
		std::unique_ptr<MapUseLock> lock;
		if (std::error_code ec; fs::is_directory(mapDir, ec))
			lock = std::make_unique<MapUseLock>(mapDir, MapUseLock::Mode::Read,
			                                    "rasterslam relocalize");
		engine.loadMap(mapDir);
		const Map& map = engine.mapManager()->map();
		PoseView poses;
		poses.prior = &map.priorPoses;
		io::RawlogSource src(rawlog);
		std::string txt =
		    "# stamp status reason local_map keyframe keyframe_stamp score inliers x y z qx qy qz "
		    "qw\n";
		std::size_t n = 0, found = 0;
		std::map<std::string, std::size_t> missed;  // scans not placed, by reason
		RasterFrame raster;
		while (auto scan = src.next())
		{
			if (first && scan->index < *first)
				continue;
			if (last && scan->index > *last)
				break;
			engine.rasterizer()->rasterize(*scan, raster);
			// By the map manager's polar context of the scan too, when the loop detector ranks
			// by it (loop_detector.polar_relocalization), as a session relocalizes.
			const auto r = engine.loopDetector()->relocalizeScan(
			    *scan, raster, engine.scanContext(*scan, raster), map, poses);
			const mrpt::poses::CPose3DQuat q(r.pose);
			txt += mrpt::format(
			    "%.6f %s %s %llu %llu %.6f %.6f %zu %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n",
			    scan->stamp, r.found ? "found" : "not_found", r.reason.c_str(),
			    static_cast<unsigned long long>(r.localMap),
			    static_cast<unsigned long long>(r.keyframe), r.keyframeStamp, r.score, r.inliers,
			    q.x(), q.y(), q.z(), q.quat().x(), q.quat().y(), q.quat().z(), q.quat().r());
			++n;
			found += r.found;
			if (!r.found)
				++missed[r.reason];
		}
		io::writeFileAtomically((fs::path(outDir) / "relocalization.txt").string(), txt);
		std::string why;
		for (const auto& [reason, count] : missed)
			why += (why.empty() ? " (not placed: " : ", ") + std::to_string(count) + " " + reason;
		if (!why.empty())
			why += ")";
		std::printf("rasterslam: relocalized %zu of %zu scans%s; results in %s\n", found, n,
		            why.c_str(),
		            (fs::path(outDir) / "relocalization.txt").lexically_normal().c_str());
		if (!src.stopReason().empty())
		{
			std::cerr << "rasterslam: error: the input stopped early: " << src.stopReason() << "\n";
			return kExitError;
		}
		return n > 0 ? 0 : kExitError;
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam: error: " << e.what() << "\n";
		return kExitError;
	}
}

}  // namespace

}  // namespace rasterslam::cli
