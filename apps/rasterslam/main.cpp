// rasterslam: the command line of the SLAM pipeline.
#include <mrpt/system/os.h>
#include <rasterslam/core/engine.h>
#include <rasterslam/core/plugin_loader.h>

#include <cstdio>
#include <iostream>

#include "cli.h"

using namespace rasterslam;

namespace
{
const char* kUsage = R"(rasterslam: lifelong 3D-LiDAR SLAM on rasterized elevation images

usage:
  rasterslam run --rawlog FILE --out DIR [--config FILE] [--first N] [--last N]
                 [--realtime [--rate R]] [--sensor LABEL] [--save-images]
                 [--map-in DIR [--require-localization]] [--map-out DIR [--overwrite]]
                 [--quiet | --verbose]
  rasterslam relocalize --map DIR --rawlog FILE --out DIR2 [--config FILE] [--first N] [--last N] [--quiet|--verbose]
  rasterslam map info DIR | export DIR --out DIR2 | merge A B --out C | prune DIR ...
                 (rasterslam map --help for the map tools)
  rasterslam list-plugins
  rasterslam --help | --version

run options:
  --rawlog FILE   MRPT rawlog (either format, gzip or plain) with 3D scans
  --out DIR       output folder: trajectory.tum, trajectory.kitti, timings.csv, run.yaml,
                  pose_graph.graph, groundtruth.{tum,kitti} when the rawlog has ground truth
  --config FILE   YAML pipeline config (default: share/rasterslam/config/default.yaml)
  --first N       skip scans before input index N (0-based)
  --last N        stop after input index N (inclusive)
  --realtime      play scans at their time stamps; the summary counts late scans
  --rate R        clock scale for --realtime (2 = twice as fast; default 1)
  --sensor LABEL  use only scans with this sensor label
  --save-images   write each scan's elevation image to DIR/images/NNNNNN.png
  --map-in DIR    start in a map saved by --map-out: the first scan is relocalized in it
                  (poses are then in that map's frame) and mapping goes on
  --map-out DIR   save the map (keyframes, local maps, their graph, the place index:
                  DIR/map.rsmap, DIR/store/, DIR/localmaps/*.png); needs a map_manager. A map already
                  there is only replaced when it is the --map-in map or with --overwrite
  --overwrite     let --map-out replace a map that is not the --map-in one
  --require-localization  with --map-in: exit 1 when the session is never located in the
                  map (a session never located is not saved into it either way)

map: info (sessions, local maps online and offline, keyframes, sizes, time span), export (for
  MRPT's tools, PCL and viewers), merge (two maps built separately), prune (old local maps).
relocalize: locate every scan of FILE in the map saved in DIR, with no pose prior; writes
  DIR2/relocalization.txt (stamp, status, reason, local map, keyframe, score, inliers, pose
  x y z qx qy qz qw in the map frame). Default config: share/rasterslam/config/slam.yaml.
  --quiet         only errors and the final summary;  --verbose: debug logging

Plugins are searched in $RASTERSLAM_PLUGIN_PATH (colon-separated), <bin>/../lib/rasterslam/
plugins, the build tree and the install prefix. Exit codes: 0 success, 1 bad input or run
failure (outputs are still written for the scans processed), 2 usage error.
)";

int listPlugins()
{
	auto& loader = PluginLoader::instance();
	try
	{
		loader.load();
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam: " << e.what() << "\n";
		return cli::kExitError;
	}
	std::printf("plugin search path:\n");
	for (const auto& d : loader.searchPath())
		std::printf("  %s\n", d.c_str());
	const auto classes = loader.registeredClasses();
	std::printf("%zu plugin classes from %zu modules:\n", classes.size(),
	            loader.loadedModules().size());
	std::printf("  %-14s %-32s %s\n", "ROLE", "CLASS", "MODULE");
	for (const auto& c : classes)
		std::printf("  %-14s %-32s %s\n", c.role.c_str(), c.className.c_str(), c.module.c_str());
	for (const auto& f : loader.failedModules())
		std::printf("not loaded: %s\n", f.c_str());
	return loader.failedModules().empty() ? 0 : cli::kExitError;
}
}  // namespace

int main(int argc, char** argv)
{
	if (argc < 2)
	{
		std::cerr << kUsage;
		return cli::kExitUsage;
	}
	const std::string cmd = argv[1];
	if (cmd == "-h" || cmd == "--help" || cmd == "help")
	{
		std::cout << kUsage;
		return 0;
	}
	if (cmd == "--version" || cmd == "version")
	{
		std::printf("rasterslam %s (%s)\n", RASTERSLAM_VERSION,
		            mrpt::system::MRPT_getVersion().c_str());
		return 0;
	}
	if (cmd == "list-plugins")
		return listPlugins();
	if (cmd == "run")
		return cli::runCommand(argc - 1, argv + 1);
	if (cmd == "relocalize")
		return cli::relocalizeCommand(argc - 1, argv + 1);
	if (cmd == "map")
		return cli::mapCommand(argc - 1, argv + 1);
	cli::usageError("unknown command '" + cmd + "'");
}
