// rasterslam-sim: writes a simulated LiDAR rawlog (with ground truth) from a scenario file.
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/registerAllClasses.h>
#include <rasterslam/cli/app.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/rawlog_writer.h>
#include <rasterslam/io/trajectory_io.h>
#include <rasterslam/sim/cloud_world.h>
#include <rasterslam/sim/revisits.h>
#include <rasterslam/sim/simulator.h>

#include <cctype>
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
	// --kitti: scans rendered from a real KITTI drive
	std::string kitti, kittiPoses, at;
	double every_m = 5;
	std::vector<double> across{0, 3, -3, 6, -6};
	bool sameOnly = false;
	std::optional<long long> scans, seed;
	std::optional<std::string> lidar;
	std::optional<double> sensorHeight_m;
	int compress = 0;
	// revisit truth against earlier sessions
	std::vector<std::string> revisitsOf;
	std::string revisits;
	double revisitRadius_m = 5;
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

/** Query poses along a recorded route: every `every_m` metres, each lateral offset, facing
 *  the route's way and (unless sameOnly) the other way. The offset is along the vehicle's y
 *  axis (left), level: the height and tilt stay those of the route pose. */
rasterslam::io::Trajectory revisitPoses(const rasterslam::io::Trajectory& route, const Args& a)
{
	rasterslam::io::Trajectory out;
	double travelled = 0, next = 0;
	for (std::size_t i = 0; i < route.size(); i++)
	{
		if (i > 0)
			travelled += (route[i].pose.translation() - route[i - 1].pose.translation()).norm();
		if (travelled + 1e-9 < next)
			continue;
		next = travelled + a.every_m;
		for (const int dir : {1, -1})
		{
			if (dir < 0 && a.sameOnly)
				continue;
			for (const double d : a.across)
			{
				Eigen::Isometry3d T = route[i].pose;
				T.translate(Eigen::Vector3d(0, d, 0));
				if (dir < 0)
					T.rotate(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()));
				rasterslam::io::StampedPose sp;
				sp.stamp = 1000.0 + 0.1 * static_cast<double>(out.size());
				sp.pose = T;
				out.push_back(sp);
			}
		}
	}
	return out;
}

/** --kitti: renders scans at other poses from the registered real scans of a KITTI folder. */
int runKitti(const Args& args)
{
	using namespace rasterslam;
	const std::string D = args.kitti;
	const std::string posesFile =
	    args.kittiPoses.empty() ? D + "/poses_semantickitti.txt" : args.kittiPoses;
	checkWritable(args.out);
	if (!args.gtTum.empty())
		checkWritable(args.gtTum);
	const auto bins = io::listKittiBins(D + "/velodyne");
	const auto route = io::kittiCameraToVelodyne(io::loadTrajectory(posesFile),
	                                             io::loadKittiCalibTr(D + "/calib.txt"));
	if (route.size() < bins.size())
		throw std::runtime_error(posesFile + ": " + std::to_string(route.size()) + " poses for " +
		                         std::to_string(bins.size()) + " scans in " + D + "/velodyne");
	const auto t0 = std::chrono::steady_clock::now();
	sim::CloudWorld world;
	std::vector<PointXYZI> first;
	for (std::size_t i = 0; i < bins.size(); i++)
	{
		auto pts = io::loadKittiBin(bins[i]);
		world.add(pts, route[i].pose);
		if (i == 0)
			first = std::move(pts);
	}
	const auto lidar = sim::LidarModel::fromRingOrderedScan("kitti-hdl64", first, 2083, 2.5, 120);
	io::Trajectory queries;
	if (!args.at.empty())
		queries = io::loadTrajectory(args.at);
	else
		queries = revisitPoses(io::Trajectory(route.begin(), route.begin() + bins.size()), args);
	if (queries.empty())
		throw std::runtime_error("no poses to render");
	const double tWorld =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
	std::cerr << "rasterslam-sim: " << D << ": " << bins.size() << " scans merged into "
	          << world.size() << " voxels, " << lidar.beamCount() << " beams measured; rendering "
	          << queries.size() << " scans\n";
	io::RawlogWriter writer(args.out, args.compress);
	std::size_t totalPoints = 0;
	const auto tStart = std::chrono::steady_clock::now();
	for (std::size_t k = 0; k < queries.size(); k++)
	{
		Scan scan;
		scan.index = k;
		scan.stamp = queries[k].stamp;
		scan.sensorLabel = "LIDAR";
		scan.points = world.render(queries[k].pose, lidar);
		scan.groundTruth =
		    mrpt::poses::CPose3D(mrpt::math::CMatrixDouble44(queries[k].pose.matrix()));
		totalPoints += scan.points.size();
		writer.writeScan(scan);
	}
	writer.close();
	if (!args.gtTum.empty())
		io::saveTrajectoryTum(args.gtTum, queries);
	const double elapsed =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - tStart).count();
	std::printf(
	    "wrote %s: %zu scans, %.0f points/scan; cloud %.2f s; %.1f s rendering and "
	    "writing: %.1f scans/s\n",
	    args.out.c_str(), queries.size(),
	    static_cast<double>(totalPoints) / static_cast<double>(queries.size()), tWorld, elapsed,
	    static_cast<double>(queries.size()) / elapsed);
	if (!args.gtTum.empty())
		std::printf("ground truth: %s\n", args.gtTum.c_str());
	return 0;
}

int run(const Args& args)
{
	if (!args.kitti.empty())
		return runKitti(args);
	using namespace rasterslam;
	sim::Scenario sc = sim::loadScenario(args.scenario);
	if (args.scans)
		sc.scans = static_cast<std::size_t>(*args.scans);
	if (args.seed)
		sc.seed = static_cast<std::uint32_t>(*args.seed);
	if (args.lidar)
		sc.lidar = *args.lidar;
	if (args.sensorHeight_m)
		sc.sensor_height_m = *args.sensorHeight_m;
	sim::validateScenario(sc);
	checkWritable(args.out);
	if (!args.gtTum.empty())
		checkWritable(args.gtTum);
	std::vector<io::Trajectory> earlier;
	std::vector<std::string> earlierNames;
	if (!args.revisits.empty())
	{
		checkWritable(args.revisits);
		for (const auto& f : args.revisitsOf)
		{
			earlier.push_back(io::loadTrajectory(f));
			std::string name = std::filesystem::path(f).stem().string();
			for (char& ch : name)
				if (std::isspace(static_cast<unsigned char>(ch)))
					ch = '_';
			earlierNames.push_back(name.empty() ? "session" : name);
		}
	}

	const auto t0 = std::chrono::steady_clock::now();
	const sim::Simulator simulator = sim::Simulator::fromScenario(sc);
	const double tWorld =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
	std::cerr << "rasterslam-sim: " << sc.source << ": " << simulator.world().shapes().size()
	          << " shapes, route " << simulator.route().length() << " m (" << simulator.lapTime()
	          << " s a lap), " << sc.scans << " " << sc.lidar << " scans at " << sc.rate_hz
	          << " Hz, seed " << sc.seed << "\n";
	if (sc.changes.epoch > 0)
		std::cerr << "  epoch " << sc.changes.epoch << ": " << simulator.world().changes().size()
		          << " changes since epoch 0 (parked cars, walls, facades, furniture), vegetation "
		             "grown\n";
	if (!simulator.traffic().empty())
		std::cerr << "  moving: " << sc.traffic.cars << " cars, " << sc.traffic.pedestrians
		          << " people\n";

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
	std::size_t nRevisits = 0;
	if (!args.revisits.empty())
	{
		const auto rv = sim::findRevisits(gt, earlier, args.revisitRadius_m);
		io::writeFileAtomically(args.revisits,
		                        sim::formatRevisits(rv, earlierNames, args.revisitRadius_m));
		nRevisits = rv.size();
	}

	const auto bytes = std::filesystem::file_size(args.out);
	std::printf(
	    "wrote %s: %zu scans, %.0f points/scan, %.1f MB; world %.2f s; %.1f s simulating and "
	    "writing: %.1f scans/s\n",
	    args.out.c_str(), sc.scans, static_cast<double>(totalPoints) / sc.scans, bytes / 1e6,
	    tWorld, elapsed, sc.scans / elapsed);
	if (!args.gtTum.empty())
		std::printf("ground truth: %s\n", args.gtTum.c_str());
	if (!args.revisits.empty())
		std::printf("revisits: %zu of %zu scans within %.1f m of %zu earlier session(s): %s\n",
		            nRevisits, sc.scans, args.revisitRadius_m, earlier.size(),
		            args.revisits.c_str());
	return 0;
}
}  // namespace

int main(int argc, char** argv)
{
	Args args;
	CLI::App app(kDescription, "rasterslam-sim");
	cli::configure(app);
	auto* scenario =
	    app.add_option("--scenario", args.scenario, "scenario YAML (keys: rawlogs/README.md)")
	        ->check(CLI::ExistingFile.description(""))
	        ->type_name("FILE");
	auto* kitti =
	    app.add_option("--kitti", args.kitti,
	                   "instead of a scenario: a KITTI folder (velodyne/, calib.txt, poses) whose "
	                   "registered scans are merged into one cloud, rendered at other poses")
	        ->check(CLI::ExistingDirectory.description(""))
	        ->type_name("DIR")
	        ->excludes(scenario);
	scenario->excludes(kitti);
	app.add_option("--kitti-poses", args.kittiPoses,
	               "--kitti: cam0 poses of the scans (default DIR/poses_semantickitti.txt)")
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE")
	    ->needs(kitti);
	auto* at = app.add_option("--at", args.at,
	                          "--kitti: render at these Velodyne-frame poses (TUM or KITTI file) "
	                          "instead of the revisit grid")
	               ->check(CLI::ExistingFile.description(""))
	               ->type_name("FILE")
	               ->needs(kitti);
	app.add_option("--every", args.every_m,
	               "--kitti revisit grid: a pose every M metres of the route (default 5)")
	    ->check(CLI::Range(0.1, 1e6).description(""))
	    ->type_name("M")
	    ->needs(kitti)
	    ->excludes(at);
	app.add_option("--across", args.across,
	               "--kitti revisit grid: lateral offsets in metres, left positive (default "
	               "0,3,-3,6,-6)")
	    ->delimiter(',')
	    ->type_name("LIST")
	    ->needs(kitti)
	    ->excludes(at);
	app.add_flag("--same-direction", args.sameOnly,
	             "--kitti revisit grid: only the route's direction (default: both)")
	    ->needs(kitti)
	    ->excludes(at);
	app.add_option("-o,--out", args.out, "output rawlog")->required()->type_name("FILE");
	app.add_option("--scans", args.scans, "override the scenario's scan count (1 or more)")
	    ->check(CLI::Range(1LL, 100000000LL).description(""))
	    ->type_name("N");
	app.add_option("--seed", args.seed, "override the scenario's seed (0 to 2^32 - 1)")
	    ->check(CLI::Range(0LL, 0xFFFFFFFFLL).description(""))
	    ->type_name("S");
	app.add_option("--lidar", args.lidar, "override the LiDAR model: hdl64 | hdl64e | vlp16")
	    ->check(CLI::IsMember({"hdl64", "hdl64e", "vlp16"}).description(""))
	    ->type_name("NAME");
	app.add_option("--sensor-height", args.sensorHeight_m,
	               "override the scenario's sensor height above the ground (m, in (0, 10))")
	    ->check(cli::numberIn(0, 10, "a height in metres", cli::Ends::Open))
	    ->type_name("M");
	app.add_option("--compress", args.compress,
	               "gzip level 0..9 (default 0: a plain file, which reads ~25x faster than gzip; "
	               "1..9 for smaller files)")
	    ->check(CLI::Range(0, 9).description(""))
	    ->type_name("L");
	app.add_option("--gt-tum", args.gtTum,
	               "also write the ground truth as TUM (t x y z qx qy qz qw)")
	    ->type_name("FILE");
	auto* revisitsOf =
	    app.add_option("--revisits-of", args.revisitsOf,
	                   "ground truth (TUM or KITTI) of an earlier session in the same world; "
	                   "repeat for several")
	        ->check(CLI::ExistingFile.description(""))
	        ->type_name("FILE")
	        ->excludes(kitti);
	auto* revisits =
	    app.add_option("--revisits", args.revisits,
	                   "write which scans revisit the earlier sessions' places: scan, stamp, "
	                   "session, its nearest scan there, distance, heading difference")
	        ->type_name("FILE")
	        ->needs(revisitsOf);
	revisitsOf->needs(revisits);
	app.add_option("--revisit-radius", args.revisitRadius_m,
	               "--revisits: a scan revisits a place within this distance (default 5 m)")
	    ->check(CLI::Range(0.01, 1e6).description(""))
	    ->type_name("M")
	    ->needs(revisits);
	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;
	if (args.scenario.empty() && args.kitti.empty())
		cli::usageError("rasterslam-sim", "give --scenario FILE or --kitti DIR");
	if (!args.kitti.empty() && (args.scans || args.seed || args.lidar || args.sensorHeight_m))
		cli::usageError("rasterslam-sim",
		                "--scans, --seed, --lidar and --sensor-height belong to --scenario: "
		                "--kitti renders the measured HDL-64E at the poses of --at or of the "
		                "revisit grid");

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
