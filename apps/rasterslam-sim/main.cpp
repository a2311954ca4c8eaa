// rasterslam-sim: writes a simulated LiDAR rawlog (with ground truth) from a scenario file.
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/registerAllClasses.h>
#include <rasterslam/cli/app.h>
#include <rasterslam/io/rawlog_writer.h>
#include <rasterslam/io/trajectory_io.h>
#include <rasterslam/sim/simulator.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <future>
#include <iostream>
#include <optional>
#include <string>

namespace cli = rasterslam::cli;

namespace
{
const char* kDescription =
    "rasterslam-sim: simulates a LiDAR driving through a procedural town and writes an MRPT "
    "rawlog (CObservationPointCloud + CObservationRobotPose ground truth per scan).";

struct Args
{
	std::string scenario, out, gtTum;
	std::optional<long long> scans, seed;
	std::optional<std::string> lidar;
	int compress = 1;
};

void checkWritable(const std::string& path)
{
	// Fail before minutes of simulation, not at the final rename.
	auto dir = std::filesystem::path(path).parent_path();
	if (dir.empty())
		dir = ".";
	if (!std::filesystem::is_directory(dir))
		throw std::runtime_error(path + ": output folder " + dir.string() + " does not exist");
	if (std::filesystem::is_directory(path))
		throw std::runtime_error(path + ": is a folder");
}

int run(const Args& args)
{
	using namespace rasterslam;
	sim::Scenario sc = sim::loadScenario(args.scenario);
	if (args.scans)
		sc.scans = static_cast<std::size_t>(*args.scans);
	if (args.seed)
		sc.seed = static_cast<std::uint32_t>(*args.seed);
	if (args.lidar)
		sc.lidar = *args.lidar;
	sim::validateScenario(sc);
	checkWritable(args.out);
	if (!args.gtTum.empty())
		checkWritable(args.gtTum);

	const auto t0 = std::chrono::steady_clock::now();
	const sim::Simulator simulator = sim::Simulator::fromScenario(sc);
	const double tWorld =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
	std::cerr << "rasterslam-sim: " << sc.source << ": " << simulator.world().shapes().size()
	          << " shapes, route " << simulator.route().length() << " m ("
	          << simulator.route().length() / sc.speed_mps << " s a lap), " << sc.scans << " "
	          << sc.lidar << " scans at " << sc.rate_hz << " Hz, seed " << sc.seed << "\n";

	io::RawlogWriter writer(args.out, args.compress);
	io::Trajectory gt;
	std::size_t totalPoints = 0;
	const auto tStart = std::chrono::steady_clock::now();
	// Scan k+1 is cast while scan k is compressed and written: the writer is single-threaded.
	auto next = std::async(std::launch::async, [&] { return simulator.scan(0); });
	for (std::size_t k = 0; k < sc.scans; k++)
	{
		Scan scan = next.get();
		if (k + 1 < sc.scans)
			next = std::async(std::launch::async, [&, k] { return simulator.scan(k + 1); });
		writer.writeScan(scan);
		totalPoints += scan.points.size();
		io::StampedPose sp;
		sp.stamp = scan.stamp;
		sp.pose.matrix() =
		    scan.groundTruth->getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
		gt.push_back(sp);
		if ((k + 1) % 50 == 0 || k + 1 == sc.scans)
		{
			const double el =
			    std::chrono::duration<double>(std::chrono::steady_clock::now() - tStart).count();
			std::cerr << "  scan " << (k + 1) << "/" << sc.scans << "  " << scan.points.size()
			          << " points  " << (k + 1) / el << " scans/s\n";
		}
	}
	writer.close();
	const double elapsed =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - tStart).count();
	if (!args.gtTum.empty())
		io::saveTrajectoryTum(args.gtTum, gt);

	const auto bytes = std::filesystem::file_size(args.out);
	std::printf(
	    "wrote %s: %zu scans, %.0f points/scan, %.1f MB; world %.2f s; %.1f s simulating and "
	    "writing: %.1f scans/s\n",
	    args.out.c_str(), sc.scans, static_cast<double>(totalPoints) / sc.scans, bytes / 1e6,
	    tWorld, elapsed, sc.scans / elapsed);
	if (!args.gtTum.empty())
		std::printf("ground truth: %s\n", args.gtTum.c_str());
	return 0;
}
}  // namespace

int main(int argc, char** argv)
{
	Args args;
	CLI::App app(kDescription, "rasterslam-sim");
	cli::configure(app);
	app.add_option("--scenario", args.scenario, "scenario YAML (keys: rawlogs/README.md)")
	    ->required()
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE");
	app.add_option("-o,--out", args.out, "output rawlog")->required()->type_name("FILE");
	app.add_option("--scans", args.scans, "override the scenario's scan count (1 or more)")
	    ->check(CLI::Range(1LL, 100000000LL).description(""))
	    ->type_name("N");
	app.add_option("--seed", args.seed, "override the scenario's seed (0 to 2^32 - 1)")
	    ->check(CLI::Range(0LL, 0xFFFFFFFFLL).description(""))
	    ->type_name("S");
	app.add_option("--lidar", args.lidar, "override the LiDAR model: hdl64 | vlp16")
	    ->check(CLI::IsMember({"hdl64", "vlp16"}).description(""))
	    ->type_name("NAME");
	app.add_option("--compress", args.compress, "gzip level 0..9 (0: plain file; default 1)")
	    ->check(CLI::Range(0, 9).description(""))
	    ->type_name("L");
	app.add_option("--gt-tum", args.gtTum,
	               "also write the ground truth as TUM (t x y z qx qy qz qw)")
	    ->type_name("FILE");
	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;

	// Debian links with --as-needed: without these calls the classes are not registered.
	mrpt::maps::registerAllClasses_mrpt_maps();
	mrpt::obs::registerAllClasses_mrpt_obs();
	try
	{
		return run(args);
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-sim: error: " << e.what() << "\n";
		return cli::kExitError;
	}
}
