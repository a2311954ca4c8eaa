#include <mrpt/core/format.h>
#include <mrpt/poses/CPose3DQuat.h>
#include <rasterslam/io/run_outputs.h>
#include <rasterslam/io/trajectory_io.h>
#include <unistd.h>

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
		throw std::runtime_error(
			"output folder '" + dir + "' cannot be created" + (ec ? ": " + ec.message() : ""));
	const auto probe = fs::path(dir) / (".rasterslam-write-test-" + std::to_string(::getpid()));
	{
		std::ofstream f(probe);
		if (!f || !(f << "x") || !f.flush())
			throw std::runtime_error("output folder '" + dir + "' is not writable");
	}
	fs::remove(probe, ec);
}

void writeRunOutputs(const std::string& dir, const RunResult& res, const mrpt::containers::yaml& runInfo)
{
	ensureWritableDir(dir);
	const fs::path d(dir);

	Trajectory est, gt;
	bool allGt = !res.scans.empty();
	for (std::size_t i = 0; i < res.scans.size(); i++)
	{
		est.push_back({res.scans[i].stamp, toIsometry(res.poses[i])});
		if (res.scans[i].groundTruth) gt.push_back({res.scans[i].stamp, toIsometry(*res.scans[i].groundTruth)});
		else
			allGt = false;
	}
	saveTrajectoryTum((d / "trajectory.tum").string(), est);
	saveTrajectoryKitti((d / "trajectory.kitti").string(), est);
	if (allGt)
	{
		saveTrajectoryTum((d / "groundtruth.tum").string(), gt);
		saveTrajectoryKitti((d / "groundtruth.kitti").string(), gt);
	}

	std::string csv =
		"index,stamp,points,status,inliers,keyframe,late,read_ms,rasterize_ms,odometry_ms,"
		"mapping_ms,loop_ms,total_ms\n";
	for (const auto& r : res.scans)
		csv += mrpt::format(
			"%zu,%.6f,%zu,%s,%zu,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f\n", r.index, r.stamp,
			r.numPoints, toString(r.status), r.inliers, r.keyframe ? 1 : 0, r.late ? 1 : 0,
			r.ms.read, r.ms.rasterize, r.ms.odometry, r.ms.mapping, r.ms.loop, r.ms.total);
	writeFileAtomically((d / "timings.csv").string(), csv);

	if (!res.loopDecisions.empty())
	{
		std::string txt =
			"# query_stamp candidate_stamp score inliers verified accepted reason x y z qx qy qz qw\n";
		for (const auto& l : res.loopDecisions)
		{
			const auto q = mrpt::poses::CPose3DQuat(l.T_candidate_query);
			txt += mrpt::format(
				"%.6f %.6f %.6f %zu %d %d %s %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", l.queryStamp,
				l.candidateStamp, l.score, l.inliers, l.verified ? 1 : 0, l.accepted ? 1 : 0,
				l.reason.empty() ? "-" : l.reason.c_str(), q.x(), q.y(), q.z(), q.quat().x(),
				q.quat().y(), q.quat().z(), q.quat().r());
		}
		writeFileAtomically((d / "loops.txt").string(), txt);
	}
	{
		const auto tmp = (d / (".pose_graph.graph.tmp-" + std::to_string(::getpid()))).string();
		res.graph.saveToTextFile(tmp);
		fs::rename(tmp, d / "pose_graph.graph");
	}

	std::stringstream ss;
	runInfo.printAsYAML(ss);
	writeFileAtomically((d / "run.yaml").string(), ss.str());
}

}  // namespace rasterslam::io
