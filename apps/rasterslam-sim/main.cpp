// rasterslam-sim: writes a simulated LiDAR rawlog (with ground truth) from a scenario file.
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/registerAllClasses.h>
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

namespace
{
const char* kUsage =
    "Usage: rasterslam-sim --scenario FILE.yaml -o OUT.rawlog [options]\n"
    "Simulates a LiDAR driving through a procedural town and writes an MRPT rawlog\n"
    "(CObservationPointCloud + CObservationRobotPose ground truth per scan).\n"
    "\n"
    "Options:\n"
    "  --scenario FILE   scenario YAML (keys: rawlogs/README.md)\n"
    "  -o, --out FILE    output rawlog\n"
    "  --scans N         override the scenario's scan count\n"
    "  --seed S          override the scenario's seed\n"
    "  --lidar NAME      override the LiDAR model: hdl64 | vlp16\n"
    "  --compress L      gzip level 0..9 (0: plain file; default 1)\n"
    "  --gt-tum FILE     also write the ground truth as TUM (t x y z qx qy qz qw)\n"
    "  -h, --help        this text\n";

struct Args
{
	std::string scenario, out, gtTum;
	std::optional<long long> scans, seed;
	std::optional<std::string> lidar;
	int compress = 1;
};

long long parseInt(const std::string& opt, const std::string& v, long long lo, long long hi)
{
	std::size_t used = 0;
	long long x = 0;
	try
	{
		x = std::stoll(v, &used);
	}
	catch (const std::exception&)
	{
		used = 0;
	}
	if (used != v.size() || v.empty() || x < lo || x > hi)
		throw std::invalid_argument(opt + ": expected an integer in [" + std::to_string(lo) + ", " +
		                            std::to_string(hi) + "], got '" + v + "'");
	return x;
}

Args parseArgs(int argc, char** argv)
{
	Args a;
	for (int i = 1; i < argc; i++)
	{
		const std::string opt = argv[i];
		if (opt == "-h" || opt == "--help")
		{
			std::cout << kUsage;
			std::exit(0);
		}
		if (i + 1 >= argc)
			throw std::invalid_argument("unknown option or missing value: " + opt);
		const std::string v = argv[++i];
		if (opt == "--scenario")
			a.scenario = v;
		else if (opt == "-o" || opt == "--out")
			a.out = v;
		else if (opt == "--scans")
			a.scans = parseInt(opt, v, 1, 100000000);
		else if (opt == "--seed")
			a.seed = parseInt(opt, v, 0, 0xFFFFFFFFll);
		else if (opt == "--lidar")
			a.lidar = v;
		else if (opt == "--compress")
			a.compress = static_cast<int>(parseInt(opt, v, 0, 9));
		else if (opt == "--gt-tum")
			a.gtTum = v;
		else
			throw std::invalid_argument("unknown option: " + opt);
	}
	if (a.scenario.empty())
		throw std::invalid_argument("--scenario is required");
	if (a.out.empty())
		throw std::invalid_argument("-o OUT.rawlog is required");
	return a;
}

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
	// Debian links with --as-needed: without these calls the classes are not registered.
	mrpt::maps::registerAllClasses_mrpt_maps();
	mrpt::obs::registerAllClasses_mrpt_obs();
	Args args;
	try
	{
		args = parseArgs(argc, argv);
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-sim: " << e.what() << "\n\n" << kUsage;
		return 2;
	}
	try
	{
		return run(args);
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-sim: error: " << e.what() << "\n";
		return 1;
	}
}
