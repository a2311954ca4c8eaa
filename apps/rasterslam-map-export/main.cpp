// rasterslam-map-export: `rasterslam map export` in a program of its own, so that only it
// loads PCL (and VTK behind it): the SLAM runs keep their memory and start-up time.
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/registerAllClasses.h>

#include <cstdio>
#include <iostream>
#include <string>

namespace rasterslam::cli
{
void exportMap(const std::string& dir, const std::string& outDir);
}

int main(int argc, char** argv)
{
	if (argc != 4 || std::string(argv[2]) != "--out")
	{
		std::cerr << "usage: rasterslam map export DIR --out DIR2   (or rasterslam-map-export DIR "
		             "--out DIR2)\n";
		return 2;
	}
	mrpt::maps::registerAllClasses_mrpt_maps();
	mrpt::obs::registerAllClasses_mrpt_obs();
	try
	{
		rasterslam::cli::exportMap(argv[1], argv[3]);
		return 0;
	}
	catch (const std::exception& e)
	{
		std::string what = e.what();
		if (const auto pos = what.find("Call stack"); pos != std::string::npos)
			what.resize(pos);
		std::cerr << "rasterslam: error: " << what << "\n";
		return 1;
	}
}
