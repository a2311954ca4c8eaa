#include <mrpt/core/format.h>
#include <mrpt/poses/CPose3DQuat.h>
#include <rasterslam/core/config.h>
#include <rasterslam/core/scan_log.h>
#include <rasterslam/io/run_outputs.h>
#include <rasterslam/io/trajectory_io.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
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

void appendLoopLine(std::string& buf, const LoopDecision& l)
{
	const auto q = mrpt::poses::CPose3DQuat(l.T_candidate_query);
	buf += mrpt::format("%.6f %.6f %.6f %zu %d %d %s %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n",
	                    l.queryStamp, l.candidateStamp, l.score, l.inliers, l.verified ? 1 : 0,
	                    l.accepted ? 1 : 0, l.reason.empty() ? "-" : l.reason.c_str(), q.x(), q.y(),
	                    q.z(), q.quat().x(), q.quat().y(), q.quat().z(), q.quat().r());
}

LoopDecisionSpool::LoopDecisionSpool(const std::string& dir)
{
	const int fd = openUnnamedTempFile(dir, "the loop decisions");
	f_ = ::fdopen(fd, "w+");
	if (!f_)
	{
		const int e = errno;
		::close(fd);
		throw std::runtime_error("no temporary file for the loop decisions: " +
		                         std::string(std::strerror(e)));
	}
}

LoopDecisionSpool::LoopDecisionSpool(std::FILE* f) : f_(f)
{
	if (!f_)
		throw std::invalid_argument("LoopDecisionSpool: no file");
}

LoopDecisionSpool::~LoopDecisionSpool()
{
	if (f_)
		std::fclose(f_);
}

void LoopDecisionSpool::append(const std::vector<LoopDecision>& decisions)
{
	if (decisions.empty() || failed_)
		return;
	std::string buf;
	for (const auto& l : decisions)
		appendLoopLine(buf, l);
	if (std::fwrite(buf.data(), 1, buf.size(), f_) != buf.size())
	{
		failed_ = true;
		errno_ = errno;
	}
	lines_ += decisions.size();
}

std::string LoopDecisionSpool::finish()
{
	if (!failed_ && std::fflush(f_) != 0)
	{
		failed_ = true;
		errno_ = errno;
	}
	if (!failed_)
		return {};
	return "the loop decisions could not be kept in a temporary file (" +
	       std::string(errno_ != 0 ? std::strerror(errno_) : "write failed") + ")";
}

void LoopDecisionSpool::copyTo(std::string& buf, const std::function<void()>& flush) const
{
	if (failed_ || std::fflush(f_) != 0 || std::fseek(f_, 0, SEEK_SET) != 0)
		throw std::runtime_error("the loop decisions could not be kept in a temporary file (" +
		                         std::string(errno_ != 0 ? std::strerror(errno_) : "disk full?") +
		                         ")");
	char chunk[64 * 1024];
	std::size_t n = 0;
	while ((n = std::fread(chunk, 1, sizeof(chunk), f_)) > 0)
	{
		buf.append(chunk, n);
		flush();
	}
	const bool bad = std::ferror(f_) != 0;
	std::fseek(f_, 0, SEEK_END);  // appending may go on
	if (bad)
		throw std::runtime_error("the loop decisions' temporary file could not be read back");
}

void writeRunOutputs(const std::string& dir, const RunResult& res,
                     const mrpt::containers::yaml& runInfo, const LoopDecisionSpool* spooledLoops)
{
	ensureWritableDir(dir);
	const fs::path d(dir);

	// Every file is first written under a temporary name; only when all are written are they
	// renamed, so a failure (a full disk) leaves the previous run's outputs whole. Each file is
	// streamed in chunks of about 64 kB: a lifelong run's whole text (a line a scan, in five
	// files) was built in memory before, 22 MB at the end of a 10,000-scan run, its peak.
	using Producer = std::function<void(std::string & buf, const std::function<void()>& flush)>;
	std::vector<std::pair<std::string, Producer>> files;
	const auto& scans = res.scans;  // in memory, or read back from its temporary file
	// Records lost (their temporary file could not be written) or no final poses: the run
	// failed and says why in res.error (run.yaml); its per-scan files cannot be written, the
	// others (loops.txt, the pose graph, run.yaml) still are.
	const bool perScan = scans.error().empty() && res.poses.size() == scans.size();
	if (!perScan && res.error.empty())
		throw std::runtime_error(!scans.error().empty()
		                             ? scans.error()
		                             : "the run has " + std::to_string(scans.size()) +
		                                   " scan records but " + std::to_string(res.poses.size()) +
		                                   " poses; no output is written");
	bool allGt = perScan && !scans.empty();
	if (perScan)
		scans.forEach([&allGt](const ScanRecord& r)
		              { allGt = allGt && r.groundTruth.has_value(); });
	// A trajectory file, a line a scan: `poseOf(i, record)` gives scan i's pose.
	using PoseOf = std::function<Eigen::Isometry3d(std::size_t, const ScanRecord&)>;
	auto trajectory = [&](bool tum, PoseOf poseOf)
	{
		return [&scans, tum, poseOf](std::string& buf, const std::function<void()>& flush)
		{
			if (tum)
				buf += kTumHeader;
			std::size_t i = 0;
			scans.forEach(
			    [&](const ScanRecord& r)
			    {
				    if (tum)
					    appendTumLine(buf, {r.stamp, poseOf(i, r)});
				    else
					    appendKittiLine(buf, poseOf(i, r));
				    ++i;
				    flush();
			    });
		};
	};
	const auto estimated = [&res](std::size_t i, const ScanRecord&)
	{ return toIsometry(res.poses.at(i)); };
	// What a robot would have acted on: each scan's pose when it was processed.
	const auto onlinePose = [](std::size_t, const ScanRecord& r)
	{ return toIsometry(mrpt::poses::CPose3D(r.onlinePose)); };
	const auto truth = [](std::size_t, const ScanRecord& r)
	{ return toIsometry(mrpt::poses::CPose3D(*r.groundTruth)); };
	if (perScan)
	{
		files.emplace_back("trajectory.tum", trajectory(true, estimated));
		files.emplace_back("trajectory.kitti", trajectory(false, estimated));
		files.emplace_back("trajectory_online.tum", trajectory(true, onlinePose));
	}
	if (allGt)
	{
		files.emplace_back("groundtruth.tum", trajectory(true, truth));
		files.emplace_back("groundtruth.kitti", trajectory(false, truth));
	}
	if (perScan)
		files.emplace_back(
		    "timings.csv",
		    [&scans](std::string& buf, const std::function<void()>& flush)
		    {
			    buf +=
			        "index,stamp,points,status,inliers,keyframe,late,read_ms,rasterize_ms,odometry_"
			        "ms,"
			        "mapping_ms,loop_ms,total_ms,rss_mb\n";
			    scans.forEach(
			        [&](const ScanRecord& r)
			        {
				        buf += mrpt::format(
				            "%zu,%.6f,%zu,%s,%zu,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.1f\n",
				            r.index, r.stamp, r.numPoints, toString(r.status), r.inliers,
				            r.keyframe ? 1 : 0, r.late ? 1 : 0, r.ms.read, r.ms.rasterize,
				            r.ms.odometry, r.ms.mapping, r.ms.loop, r.ms.total, r.rssMb);
				        flush();
			        });
		    });
	if (!res.loopDecisions.empty() || (spooledLoops && spooledLoops->size() > 0))
		files.emplace_back(
		    "loops.txt",
		    [&res, spooledLoops](std::string& buf, const std::function<void()>& flush)
		    {
			    buf +=
			        "# query_stamp candidate_stamp score inliers verified accepted reason x y z "
			        "qx qy qz qw\n";
			    if (spooledLoops)
				    spooledLoops->copyTo(buf, flush);
			    for (const auto& l : res.loopDecisions)
			    {
				    appendLoopLine(buf, l);
				    flush();
			    }
		    });
	const std::string yaml = emitYaml(runInfo);
	files.emplace_back("run.yaml",
	                   [&yaml](std::string& buf, const std::function<void()>&) { buf += yaml; });

	const std::string suffix = ".tmp-" + std::to_string(::getpid());
	std::vector<std::string> written;
	auto cleanup = [&]
	{
		std::error_code ec;
		for (const auto& w : written)
			fs::remove(d / (w + suffix), ec);
	};
	std::string buf;
	for (const auto& [name, produce] : files)
	{
		const auto tmp = d / (name + suffix);
		std::ofstream f(tmp, std::ios::binary);
		written.push_back(name);
		bool ok = static_cast<bool>(f);
		auto write = [&]
		{
			ok = ok && f.write(buf.data(), static_cast<std::streamsize>(buf.size()));
			buf.clear();
		};
		constexpr std::size_t kChunk = 64 * 1024;
		buf.clear();
		try
		{
			if (ok)
				produce(buf,
				        [&]
				        {
					        if (buf.size() >= kChunk)
						        write();
				        });
		}
		catch (const std::exception& e)
		{
			f.close();
			cleanup();  // a producer that throws leaves no temporary behind
			throw std::runtime_error("error writing '" + (d / name).string() + "': " + e.what() +
			                         "; the previous outputs are kept");
		}
		catch (...)
		{
			f.close();
			cleanup();
			throw;
		}
		write();
		if (!ok || !f.flush())
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
	for (const auto* stale : {"groundtruth.tum", "groundtruth.kitti", "loops.txt", "trajectory.tum",
	                          "trajectory.kitti", "trajectory_online.tum", "timings.csv"})
		if (std::find(written.begin(), written.end(), stale) == written.end())
			fs::remove(d / stale, ec);
}

}  // namespace rasterslam::io
