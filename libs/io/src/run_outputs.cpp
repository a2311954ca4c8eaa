#include <mrpt/core/format.h>
#include <mrpt/poses/CPose3DQuat.h>
#include <rasterslam/core/config.h>
#include <rasterslam/io/run_outputs.h>
#include <rasterslam/io/trajectory_io.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace rasterslam::io
{
void ensureWritableDir(const std::string& dir)
{
	std::error_code ec;
	fs::create_directories(dir, ec);
	if (!fs::is_directory(dir))
		throw std::runtime_error("output folder '" + dir + "' cannot be created" +
		                         (ec ? ": " + ec.message() : ""));
	const auto probe = fs::path(dir) / (".rasterslam-write-test-" + std::to_string(::getpid()));
	bool ok = false;
	{
		std::ofstream f(probe);
		ok = f && (f << "x") && f.flush();
	}
	fs::remove(probe, ec);
	if (!ok)
		throw std::runtime_error("output folder '" + dir + "' is not writable");
}

void writeRunOutputs(const std::string& dir, const RunResult& res,
                     const mrpt::containers::yaml& runInfo)
{
	ensureWritableDir(dir);
	const fs::path d(dir);

	// Every file is first written under a temporary name; only when all are written are they
	// renamed, so a failure (a full disk) leaves the previous run's outputs whole.
	std::vector<std::pair<std::string, std::string>> files;  // name, contents
	Trajectory est, online, gt;
	bool allGt = !res.scans.empty();
	for (std::size_t i = 0; i < res.scans.size(); i++)
	{
		est.push_back({res.scans[i].stamp, toIsometry(res.poses[i])});
		online.push_back(
		    {res.scans[i].stamp, toIsometry(mrpt::poses::CPose3D(res.scans[i].onlinePose))});
		if (res.scans[i].groundTruth)
			gt.push_back(
			    {res.scans[i].stamp, toIsometry(mrpt::poses::CPose3D(*res.scans[i].groundTruth))});
		else
			allGt = false;
	}
	files.emplace_back("trajectory.tum", formatTrajectoryTum(est));
	files.emplace_back("trajectory.kitti", formatTrajectoryKitti(est));
	// What a robot would have acted on: each scan's pose when it was processed.
	files.emplace_back("trajectory_online.tum", formatTrajectoryTum(online));
	if (allGt)
	{
		files.emplace_back("groundtruth.tum", formatTrajectoryTum(gt));
		files.emplace_back("groundtruth.kitti", formatTrajectoryKitti(gt));
	}

	std::string csv =
	    "index,stamp,points,status,inliers,keyframe,late,read_ms,rasterize_ms,odometry_ms,"
	    "mapping_ms,loop_ms,total_ms,rss_mb\n";
	for (const auto& r : res.scans)
		csv += mrpt::format("%zu,%.6f,%zu,%s,%zu,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.1f\n",
		                    r.index, r.stamp, r.numPoints, toString(r.status), r.inliers,
		                    r.keyframe ? 1 : 0, r.late ? 1 : 0, r.ms.read, r.ms.rasterize,
		                    r.ms.odometry, r.ms.mapping, r.ms.loop, r.ms.total, r.rssMb);
	files.emplace_back("timings.csv", csv);

	if (!res.loopDecisions.empty())
	{
		std::string txt =
		    "# query_stamp candidate_stamp score inliers verified accepted reason x y z qx qy qz "
		    "qw\n";
		for (const auto& l : res.loopDecisions)
		{
			const auto q = mrpt::poses::CPose3DQuat(l.T_candidate_query);
			txt +=
			    mrpt::format("%.6f %.6f %.6f %zu %d %d %s %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n",
			                 l.queryStamp, l.candidateStamp, l.score, l.inliers, l.verified ? 1 : 0,
			                 l.accepted ? 1 : 0, l.reason.empty() ? "-" : l.reason.c_str(), q.x(),
			                 q.y(), q.z(), q.quat().x(), q.quat().y(), q.quat().z(), q.quat().r());
		}
		files.emplace_back("loops.txt", txt);
	}
	{
		files.emplace_back("run.yaml", emitYaml(runInfo));
	}

	const std::string suffix = ".tmp-" + std::to_string(::getpid());
	std::vector<std::string> written;
	auto cleanup = [&]
	{
		std::error_code ec;
		for (const auto& w : written)
			fs::remove(d / (w + suffix), ec);
	};
	for (const auto& [name, contents] : files)
	{
		const auto tmp = d / (name + suffix);
		std::ofstream f(tmp, std::ios::binary);
		written.push_back(name);
		if (!f || !f.write(contents.data(), static_cast<std::streamsize>(contents.size())) ||
		    !f.flush())
		{
			cleanup();
			throw std::runtime_error("error writing '" + (d / name).string() +
			                         "' (disk full?); the previous outputs are kept");
		}
	}
	written.push_back("pose_graph.graph");
	try
	{
		res.graph.saveToTextFile((d / ("pose_graph.graph" + suffix)).string());
	}
	catch (const std::exception&)
	{
		cleanup();
		throw std::runtime_error("error writing '" + (d / "pose_graph.graph").string() +
		                         "'; the previous outputs are kept");
	}
	for (const auto& w : written)
		fs::rename(d / (w + suffix), d / w);
	// Files of an earlier run that this run does not produce would be mistaken for its own.
	std::error_code ec;
	for (const auto* stale : {"groundtruth.tum", "groundtruth.kitti", "loops.txt"})
		if (std::find(written.begin(), written.end(), stale) == written.end())
			fs::remove(d / stale, ec);
}

}  // namespace rasterslam::io
