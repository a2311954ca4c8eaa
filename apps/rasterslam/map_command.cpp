// `rasterslam map ...`: tools over a saved map.
#include <rasterslam/map/map.h>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <vector>
#include <filesystem>
#include <iostream>
#include <limits>

#include "cli.h"

namespace fs = std::filesystem;

namespace rasterslam::cli
{
namespace
{
const char* kMapUsage = R"(usage: rasterslam map info DIR
       rasterslam map export DIR --out DIR2
  info DIR     sessions, local maps online and offline, keyframes, points, sizes on disk and
               the time span of the map saved in DIR (by rasterslam run --map-out)
  export DIR   writes DIR2/map.graph (keyframe pose graph, MRPT text format),
               DIR2/map.simplemap (one keyframe per local map with its points, MRPT),
               DIR2/points.pcd and points.ply (every local map's points in the map frame),
               DIR2/top.png (points and each session's trajectory from above) and
               DIR2/localmaps/NNNN.png
)";

int mapInfo(const std::string& dir)
{
	const Map map = loadMap(dir);
	std::uintmax_t disk = 0;
	std::error_code ec;
	for (const auto& e : fs::recursive_directory_iterator(dir, ec))
		if (e.is_regular_file(ec)) disk += e.file_size(ec);
	struct SessionInfo
	{
		std::size_t keyframes = 0, localMaps = 0, online = 0;
		double first = std::numeric_limits<double>::max(), last = std::numeric_limits<double>::lowest();
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
		++s.localMaps;
		s.online += lm->online;
		online += lm->online;
		points += lm->points();
		pngBytes += lm->imagePng.size();
	}
	std::printf("map          : %s (%.2f MB on disk)\n", fs::path(dir).lexically_normal().c_str(), disk / 1e6);
	std::printf("sessions     : %u\n", map.sessions);
	std::printf("keyframes    : %zu\n", map.keyframes.size());
	std::printf(
		"local maps   : %zu (%zu online, %zu offline), %zu points, %.2f MB of images\n", map.localMaps.size(), online,
		map.localMaps.size() - online, points, pngBytes / 1e6);
	std::printf(
		"local-map graph: %zu sequential, %zu loop, %zu relocalization edges\n",
		map.graph.count(LocalMapGraph::EdgeKind::Sequential), map.graph.count(LocalMapGraph::EdgeKind::Loop),
		map.graph.count(LocalMapGraph::EdgeKind::Relocalization));
	std::printf(
		"place index  : %s (%.2f MB)\n", map.placeIndexClass.empty() ? "none" : map.placeIndexClass.c_str(),
		map.placeIndex.size() / 1e6);
	for (const auto& [id, s] : sessions)
		std::printf(
			"  session %u: %zu keyframes, %zu local maps (%zu online), stamps %.3f .. %.3f (%.1f s)\n", id, s.keyframes,
			s.localMaps, s.online, s.first, s.last, s.keyframes ? s.last - s.first : 0.0);
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
			const auto exe = (fs::read_symlink("/proc/self/exe").parent_path() / "rasterslam-map-export").string();
			std::vector<char*> args{const_cast<char*>(exe.c_str()), argv[2], argv[3], argv[4], nullptr};
			std::fflush(stdout);
			::execv(exe.c_str(), args.data());
			throw std::runtime_error("cannot run '" + exe + "': " + std::strerror(errno));
		}
		if (sub == "info")
		{
			if (argc != 3) usageError("map info: expected one folder (rasterslam map info DIR)");
			return mapInfo(argv[2]);
		}
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam: error: " << e.what() << "\n";
		return kExitError;
	}
	usageError("map: unknown subcommand '" + sub + "' (info, export)");
}

}  // namespace rasterslam::cli
