// `rasterslam export`: the scans of a rawlog and their ground truth as files other tools read
// (KITTI .bin, PCD or PLY; KITTI poses and times, TUM).
#include <mrpt/core/format.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/io/rawlog_source.h>
#include <rasterslam/io/run_outputs.h>
#include <rasterslam/io/trajectory_io.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>

#include "cli.h"

namespace fs = std::filesystem;

namespace rasterslam::cli
{
namespace
{
struct ExportArgs
{
	std::string rawlog, outDir, format = "bin", sensor;
	std::optional<std::size_t> first, last;
	bool overwrite = false, quiet = false;
};

/** The binary body of one scan: float32 x y z intensity records, little-endian (the host's
 *  order, checked at compile time). */
std::string pointRecords(const std::vector<PointXYZI>& pts)
{
	static_assert(sizeof(PointXYZI) == 16, "PointXYZI must be four packed float32");
	static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "export writes little-endian");
	return std::string(reinterpret_cast<const char*>(pts.data()), pts.size() * sizeof(PointXYZI));
}

std::string scanFile(const std::vector<PointXYZI>& pts, const std::string& format)
{
	const std::string body = pointRecords(pts);
	if (format == "pcd")
		return mrpt::format(
		           "# .PCD v0.7 - Point Cloud Data file format (written by rasterslam export)\n"
		           "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\n"
		           "COUNT 1 1 1 1\nWIDTH %zu\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %zu\n"
		           "DATA binary\n",
		           pts.size(), pts.size()) +
		       body;
	if (format == "ply")
		return mrpt::format(
		           "ply\nformat binary_little_endian 1.0\ncomment written by rasterslam export\n"
		           "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"
		           "property float intensity\nend_header\n",
		           pts.size()) +
		       body;
	return body;  // KITTI .bin: the records alone
}

void writeBinaryAtomically(const fs::path& path, const std::string& data)
{
	const fs::path tmp = path.parent_path() / ("." + path.filename().string() + ".tmp");
	{
		std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
		f.write(data.data(), static_cast<std::streamsize>(data.size()));
		f.close();
		if (!f)
		{
			std::error_code ec;
			fs::remove(tmp, ec);
			throw std::runtime_error("cannot write '" + path.string() + "'");
		}
	}
	fs::rename(tmp, path);
}

int exportCommand(const ExportArgs& a)
{
	const fs::path out(a.outDir), scansDir = out / "velodyne";
	try
	{
		std::error_code ec;
		if (fs::exists(scansDir, ec) && !fs::is_empty(scansDir, ec) && !a.overwrite)
			throw std::runtime_error(scansDir.string() +
			                         " holds files already: pass --overwrite to replace them");
		io::ensureWritableDir(a.outDir);
		if (a.overwrite && fs::exists(scansDir, ec))
			fs::remove_all(scansDir);
		fs::create_directories(scansDir);
		io::RawlogSourceOptions so;
		so.sensorLabel = a.sensor;
		io::RawlogSource src(a.rawlog, so);

		io::Trajectory gt;
		std::vector<double> stamps;
		std::size_t written = 0, points = 0;
		bool allGroundTruth = true;
		while (auto scan = src.next())
		{
			if (a.first && scan->index < *a.first)
				continue;
			if (a.last && scan->index > *a.last)
				break;
			// Files are numbered from 0 in the order written, as KITTI's are.
			const auto name = mrpt::format("%06zu.%s", written, a.format.c_str());
			writeBinaryAtomically(scansDir / name, scanFile(scan->points, a.format));
			stamps.push_back(scan->stamp);
			if (scan->groundTruth)
				gt.push_back({scan->stamp, io::toIsometry(*scan->groundTruth)});
			else
				allGroundTruth = false;
			points += scan->points.size();
			++written;
			if (!a.quiet && written % 100 == 0)
				std::fprintf(stderr, "[rasterslam] exported %zu scans\n", written);
		}
		if (written == 0)
			throw std::runtime_error(a.rawlog + ": no 3D scans" +
			                         (a.sensor.empty() ? "" : " with label '" + a.sensor + "'") +
			                         " in the range asked for");
		// times.txt: seconds since the first exported scan (KITTI's convention); the absolute
		// stamps are in groundtruth.tum and export.yaml.
		std::string times;
		for (const double t : stamps)
			times += mrpt::format("%.9f\n", t - stamps.front());
		io::writeFileAtomically((out / "times.txt").string(), times);
		if (allGroundTruth)
		{
			// The points are in the vehicle frame and so are these poses: Tr is the identity.
			io::saveTrajectoryKitti((out / "poses.txt").string(), gt);
			io::saveTrajectoryTum((out / "groundtruth.tum").string(), gt);
			io::writeFileAtomically((out / "calib.txt").string(), "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n");
		}
		io::writeFileAtomically(
		    (out / "export.yaml").string(),
		    mrpt::format("# rasterslam export of %s\nrawlog: %s\nformat: %s\nscans: %zu\n"
		                 "points: %zu\nfirst_input_index: %zu\nfirst_stamp: %.9f\n"
		                 "sensor: '%s'\nframe: vehicle (each observation's sensorPose applied)\n"
		                 "ground_truth: %s\n",
		                 a.rawlog.c_str(), fs::absolute(a.rawlog).c_str(), a.format.c_str(),
		                 written, points, a.first.value_or(0), stamps.front(), a.sensor.c_str(),
		                 allGroundTruth ? "poses.txt (KITTI, Tr identity), groundtruth.tum"
		                                : "none (not every scan has it)"));
		std::printf("rasterslam: exported %zu scans (%zu points) as %s to %s%s\n", written, points,
		            a.format.c_str(), scansDir.lexically_normal().c_str(),
		            allGroundTruth ? ", ground truth in poses.txt and groundtruth.tum" : "");
		if (!src.stopReason().empty())
		{
			std::cerr << "rasterslam: error: the input stopped early, the export covers the "
			          << written << " scans before: " << src.stopReason() << "\n";
			return kExitError;
		}
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam: error: " << e.what() << "\n";
		return kExitError;
	}
	return 0;
}
}  // namespace

Command addExportCommand(CLI::App& app)
{
	auto a = std::make_shared<ExportArgs>();
	CLI::App* sub = subcommand(
	    app, "export", "write the scans of a rawlog and their ground truth for other tools",
	    "Writes DIR/velodyne/NNNNNN.{bin,pcd,ply} (float32 x y z intensity in the vehicle frame, "
	    "numbered from 0), DIR/times.txt (seconds since the first scan), DIR/export.yaml and, "
	    "when every scan has ground truth, DIR/poses.txt with DIR/calib.txt (KITTI; Tr is the "
	    "identity, the poses being those of the vehicle frame) and DIR/groundtruth.tum. "
	    "kitti2rawlog --sequence DIR reads the bin export back.");
	sub->add_option("--rawlog", a->rawlog, "MRPT rawlog with 3D scans")
	    ->required()
	    ->type_name("FILE");
	sub->add_option("--out", a->outDir, "output folder")->required()->type_name("DIR");
	sub->add_option("--format", a->format,
	                "bin (KITTI), pcd (PCL, binary) or ply (binary little-endian)")
	    ->check(CLI::IsMember({"bin", "pcd", "ply"}))
	    ->capture_default_str();
	addIndex(*sub, "--first", a->first, "skip scans before input index N (0-based)");
	addIndex(*sub, "--last", a->last, "stop after input index N (inclusive)");
	sub->add_option("--sensor", a->sensor, "only scans with this sensor label")->type_name("LABEL");
	sub->add_flag("--overwrite", a->overwrite, "replace scans already in DIR/velodyne");
	sub->add_flag("--quiet", a->quiet, "no progress lines");
	return {sub, [a]
	        {
		        if (a->first && a->last && *a->first > *a->last)
			        usageError("rasterslam export", "--first is after --last");
		        return exportCommand(*a);
	        }};
}

}  // namespace rasterslam::cli
