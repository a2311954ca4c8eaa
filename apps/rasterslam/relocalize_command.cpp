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

#include "cli.h"

namespace fs = std::filesystem;

namespace rasterslam::cli
{
int relocalizeCommand(int argc, char** argv)
{
	std::string mapDir, rawlog, outDir, configPath;
	std::optional<std::size_t> first, last;
	auto level = mrpt::system::LVL_INFO;
	for (int i = 1; i < argc; i++)
	{
		const std::string a = argv[i];
		auto value = [&]() -> std::string
		{
			if (i + 1 >= argc)
				usageError(a + " needs a value");
			return argv[++i];
		};
		if (a == "--map")
			mapDir = value();
		else if (a == "--rawlog")
			rawlog = value();
		else if (a == "--out")
			outDir = value();
		else if (a == "--config")
			configPath = value();
		else if (a == "--first")
			first = parseIndexArg(a, value());
		else if (a == "--last")
			last = parseIndexArg(a, value());
		else if (a == "--quiet")
			level = mrpt::system::LVL_ERROR;
		else if (a == "--verbose")
			level = mrpt::system::LVL_DEBUG;
		else if (a == "-h" || a == "--help")
		{
			std::cout << "usage: rasterslam relocalize --map DIR --rawlog FILE --out DIR2 "
			             "[--config FILE] "
			             "[--first N] [--last N] [--quiet|--verbose]\n";
			return 0;
		}
		else
			usageError("relocalize: unknown option '" + a + "'");
	}
	if (mapDir.empty() || rawlog.empty() || outDir.empty())
		usageError("relocalize: --map DIR, --rawlog FILE and --out DIR2 are required");
	try
	{
		io::ensureWritableDir(outDir);
		if (configPath.empty())
			configPath = findConfig("slam.yaml");
		Engine engine(loadYamlFile(configPath), configPath);
		engine.setLogLevel(level);
		if (!engine.rasterizer() || !engine.loopDetector() || !engine.mapManager())
			throw ConfigError(
			    configPath +
			    ": relocalize needs a rasterizer, a map_manager and a loop_detector section");
		engine.loadMap(mapDir);
		const Map& map = engine.mapManager()->map();
		PoseView poses;
		poses.prior = &map.priorPoses;
		io::RawlogSource src(rawlog);
		std::string txt =
		    "# stamp status reason local_map keyframe keyframe_stamp score inliers x y z qx qy qz "
		    "qw\n";
		std::size_t n = 0, found = 0;
		RasterFrame raster;
		while (auto scan = src.next())
		{
			if (first && scan->index < *first)
				continue;
			if (last && scan->index > *last)
				break;
			engine.rasterizer()->rasterize(*scan, raster);
			const auto r = engine.loopDetector()->relocalize(*scan, raster, map, poses);
			const mrpt::poses::CPose3DQuat q(r.pose);
			txt += mrpt::format(
			    "%.6f %s %s %llu %llu %.6f %.6f %zu %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n",
			    scan->stamp, r.found ? "found" : "not_found", r.reason.c_str(),
			    static_cast<unsigned long long>(r.localMap),
			    static_cast<unsigned long long>(r.keyframe), r.keyframeStamp, r.score, r.inliers,
			    q.x(), q.y(), q.z(), q.quat().x(), q.quat().y(), q.quat().z(), q.quat().r());
			++n;
			found += r.found;
		}
		io::writeFileAtomically((fs::path(outDir) / "relocalization.txt").string(), txt);
		std::printf("rasterslam: relocalized %zu of %zu scans; results in %s\n", found, n,
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

}  // namespace rasterslam::cli
