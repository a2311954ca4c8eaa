// kitti2rawlog: converts a KITTI odometry sequence (velodyne/*.bin, poses, calib, times) into
// an MRPT rawlog with one CObservationPointCloud (XYZI) a scan and its ground truth.
#include <mrpt/maps/CPointsMapXYZI.h>
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/registerAllClasses.h>
#include <rasterslam/cli/app.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/core/sweep.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/rawlog_writer.h>
#include <rasterslam/io/trajectory_io.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>

namespace fs = std::filesystem;
using namespace rasterslam;

namespace
{
const char* kDescription =
    "kitti2rawlog: convert a KITTI odometry sequence into an MRPT rawlog, from a folder of scans "
    "(--velodyne DIR, with --poses FILE --calib FILE and --times FILE when at hand) or from a "
    "KITTI layout (--sequence DIR).";

const char* kFooter =
    "Examples:\n"
    "kitti2rawlog --sequence dataset/sequences/00 -o kitti00.rawlog\n"
    "kitti2rawlog --velodyne DIR --poses P --calib C --times T -o OUT.rawlog --last 99\n"
    "\n"
    "Each scan becomes a CObservationPointCloud (label LIDAR, XYZI, sensorPose identity) and, "
    "with poses, a CObservationRobotPose (label GROUND_TRUTH) with the same time stamp holding "
    "the Velodyne-frame pose inv(Tr) * P_i * Tr.";

}  // namespace

int main(int argc, char** argv)
{
	std::string velodyne, sequence, out, posesFile, calibFile, timesFile;
	std::optional<std::size_t> first, last;
	bool external = false;
	int compress = 0;
	double verticalCorrection_deg = 0;

	CLI::App app(kDescription, "kitti2rawlog");
	cli::configure(app);
	app.footer(std::string(kFooter) + "\n\n" + cli::exitCodesFooter());
	const auto existingFile = CLI::ExistingFile.description("");
	const auto existingDir = CLI::ExistingDirectory.description("");
	app.add_option("-o,--out", out, "rawlog to write (written to a temporary name, then renamed)")
	    ->required()
	    ->type_name("FILE");
	app.add_option("--poses", posesFile,
	               "ground truth, KITTI format (cam0 frame); needs --calib (given, or found by "
	               "--sequence)")
	    ->check(existingFile)
	    ->type_name("FILE");
	app.add_option("--calib", calibFile,
	               "calib.txt; its Tr line turns cam0 poses into Velodyne-frame poses")
	    ->check(existingFile)
	    ->type_name("FILE");
	app.add_option("--times", timesFile, "times.txt (seconds); without it scans are 0.1 s apart")
	    ->check(existingFile)
	    ->type_name("FILE");
	cli::addIndex(app, "--first", first,
	              "first scan to convert (position in the sorted list, default 0)");
	cli::addIndex(app, "--last", last, "last scan to convert (inclusive, default: the last)");
	CLI::Option* externalOpt =
	    app.add_flag("--external", external,
	                 "write a small rawlog that references the .bin files (MRPT external "
	                 "storage, absolute paths) instead of embedding the points");
	app.add_option("--compress", compress,
	               "gzip level 0..9 (default 0: a plain file, which reads ~25x faster than gzip; "
	               "1..9 for smaller files)")
	    ->check(CLI::Range(0, 9).description(""))
	    ->type_name("L");
	app.add_option("--vertical-correction-deg", verticalCorrection_deg,
	               "raise every point's elevation by D degrees, D in [-5, 5] (rotation about the "
	               "horizontal axis across its azimuth): the known HDL-64 calibration error of "
	               "the KITTI scans is 0.205 deg (default 0: points as recorded; not with "
	               "--external)")
	    ->check(cli::numberIn(-5, 5, "a number of degrees"))
	    ->excludes(externalOpt)
	    ->type_name("D");
	// Exactly one of the two says where the scans are.
	CLI::App* input = app.add_option_group("input", "where the scans are");
	input
	    ->add_option("--velodyne", velodyne,
	                 "folder of KITTI .bin scans (sorted by name; scan i is line i of the poses "
	                 "and times files)")
	    ->check(existingDir)
	    ->type_name("DIR");
	input
	    ->add_option("--sequence", sequence,
	                 "KITTI layout: DIR/velodyne, DIR/times.txt, DIR/calib.txt, and poses from "
	                 "DIR/poses.txt or DIR/../../poses/<name of DIR>.txt when present")
	    ->check(existingDir)
	    ->type_name("DIR");
	input->require_option(1);
	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;

	if (!sequence.empty())
	{
		velodyne = (fs::path(sequence) / "velodyne").string();
		auto ifExists = [](const fs::path& p)
		{ return fs::exists(p) ? p.string() : std::string(); };
		if (timesFile.empty())
			timesFile = ifExists(fs::path(sequence) / "times.txt");
		if (calibFile.empty())
			calibFile = ifExists(fs::path(sequence) / "calib.txt");
		if (posesFile.empty())
			posesFile = ifExists(fs::path(sequence) / "poses.txt");
		if (posesFile.empty())
		{
			const auto seqName = fs::path(sequence).lexically_normal().filename().string();
			posesFile = ifExists(fs::path(sequence) / ".." / ".." / "poses" / (seqName + ".txt"));
		}
	}
	// Not a CLI11 needs(): with --sequence, --poses and --calib may come from the folder.
	if (!posesFile.empty() && calibFile.empty())
		cli::usageError(
		    "kitti2rawlog",
		    "--poses needs --calib: KITTI poses are in the cam0 frame, and Tr turns them "
		    "into Velodyne-frame poses");

	try
	{
		mrpt::obs::registerAllClasses_mrpt_obs();
		mrpt::maps::registerAllClasses_mrpt_maps();
		const auto bins = io::listKittiBins(velodyne);
		const std::size_t i0 = first.value_or(0);
		const std::size_t i1 = std::min(last.value_or(bins.size() - 1), bins.size() - 1);
		if (i0 > i1)
			throw std::runtime_error("--first " + std::to_string(i0) + " is past the last scan (" +
			                         std::to_string(bins.size() - 1) + ") or --last");

		std::vector<double> times;
		if (!timesFile.empty())
		{
			times = io::loadKittiTimes(timesFile);
			if (times.size() < bins.size())
				throw std::runtime_error(
				    "times file '" + timesFile + "' has " + std::to_string(times.size()) +
				    " lines for " + std::to_string(bins.size()) + " scans in '" + velodyne + "'");
		}
		io::Trajectory gt;
		if (!posesFile.empty())
		{
			gt = io::kittiCameraToVelodyne(
			    io::loadTrajectory(posesFile, io::TrajectoryFormat::Kitti),
			    io::loadKittiCalibTr(calibFile));
			if (gt.size() < bins.size())
				throw std::runtime_error(
				    "poses file '" + posesFile + "' has " + std::to_string(gt.size()) +
				    " poses for " + std::to_string(bins.size()) + " scans in '" + velodyne + "'");
		}

		io::RawlogWriter writer(out, compress);
		const auto t0 = std::chrono::steady_clock::now();
		for (std::size_t i = i0; i <= i1; i++)
		{
			Scan scan;
			scan.index = i;
			scan.stamp = times.empty() ? 0.1 * static_cast<double>(i) : times[i];
			scan.sensorLabel = "LIDAR";
			if (!gt.empty())
				scan.groundTruth = toPose(gt[i].pose);
			if (!external)
			{
				scan.points = io::loadKittiBin(bins[i]);
				if (verticalCorrection_deg != 0)
					correctElevation(scan.points, verticalCorrection_deg);
				writer.writeScan(scan);
			}
			else
			{
				mrpt::obs::CObservationPointCloud obs;
				obs.timestamp = mrpt::Clock::fromDouble(scan.stamp);
				obs.sensorLabel = scan.sensorLabel;
				obs.pointcloud = mrpt::maps::CPointsMapXYZI::Create();
				obs.setAsExternalStorage(
				    fs::absolute(bins[i]).lexically_normal().string(),
				    mrpt::obs::CObservationPointCloud::ExternalStorageFormat::KittiBinFile);
				writer.write(obs);
				if (scan.groundTruth)
				{
					mrpt::obs::CObservationRobotPose g;
					g.timestamp = obs.timestamp;
					g.sensorLabel = "GROUND_TRUTH";
					g.pose.mean = *scan.groundTruth;
					g.pose.cov.setZero();
					writer.write(g);
				}
			}
			if (isatty(2))
				std::fprintf(stderr, "\rkitti2rawlog: %zu/%zu scans", i - i0 + 1, i1 - i0 + 1);
		}
		writer.close();
		const double s =
		    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
		if (isatty(2))
			std::fprintf(stderr, "\n");
		std::printf("kitti2rawlog: wrote %zu scans%s (%s) to %s in %.1f s\n", i1 - i0 + 1,
		            gt.empty() ? "" : " with ground truth",
		            external ? "external .bin references" : "embedded points", out.c_str(), s);
	}
	catch (const std::exception& e)
	{
		std::cerr << "kitti2rawlog: error: " << e.what() << "\n";
		return 1;
	}
	return 0;
}
