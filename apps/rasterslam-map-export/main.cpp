// rasterslam-map-export: `rasterslam map export` in a program of its own, so that only it
// loads PCL (and VTK behind it): the SLAM runs keep their memory and start-up time.
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/registerAllClasses.h>
#include <rasterslam/cli/app.h>

#include <cstdio>
#include <iostream>
#include <string>

namespace rasterslam::cli
{
void exportMap(const std::string& dir, const std::string& outDir);
}

int main(int argc, char** argv)
{
	namespace cli = rasterslam::cli;
	std::string dir, outDir;
	CLI::App app(
	    "rasterslam-map-export: writes a saved map in the formats other tools open "
	    "(`rasterslam map export DIR --out DIR2` runs this program).",
	    "rasterslam-map-export");
	cli::configure(app);
	app.footer(
	    "DIR2 receives map.graph (the keyframe pose graph, MRPT), map.simplemap (one keyframe a "
	    "local map, MRPT), points.pcd and points.ply (all points, PCL), top.png (a top view), "
	    "keyframes-s*.tum (each session's keyframes) and localmaps/ (the local maps' images).\n\n" +
	    std::string(cli::exitCodesFooter()));
	// No ExistingDirectory on DIR: a missing map is bad input (exit 1), as for the other
	// `rasterslam map` tools.
	app.add_option("DIR", dir, "map folder (saved by rasterslam run --map-out)")
	    ->required()
	    ->type_name("");
	app.add_option("--out", outDir, "folder to write the exported files to (created if needed)")
	    ->required()
	    ->type_name("DIR2");
	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;

	mrpt::maps::registerAllClasses_mrpt_maps();
	mrpt::obs::registerAllClasses_mrpt_obs();
	try
	{
		cli::exportMap(dir, outDir);
		return cli::kExitOk;
	}
	catch (const std::exception& e)
	{
		std::string what = e.what();
		if (const auto pos = what.find("Call stack"); pos != std::string::npos)
			what.resize(pos);
		std::cerr << "rasterslam: error: " << what << "\n";
		return cli::kExitError;
	}
}
