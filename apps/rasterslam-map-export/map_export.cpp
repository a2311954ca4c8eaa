// `rasterslam map export`: a saved map in the formats other tools open. PCL writes the point
// clouds; it is kept to this one file (its headers are slow to compile).
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_types.h>
// PCL first, then MRPT (see DESIGN.md).
#include <mrpt/graphs/CNetworkOfPoses.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>
#include <rasterslam/io/trajectory_io.h>
#include <rasterslam/map/map.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace fs = std::filesystem;

namespace rasterslam::cli
{
namespace
{
/** Writes through `write(tmpPath)` then renames onto `path`. */
template <class F>
void writeAtomically(const fs::path& path, F&& write)
{
	const auto tmp = path.string() + ".tmp-" + std::to_string(::getpid());
	if (!write(tmp))
	{
		std::error_code ec;
		fs::remove(tmp, ec);
		throw std::runtime_error("cannot write '" + path.string() + "'");
	}
	fs::rename(tmp, path);
}
}  // namespace

void exportMap(const std::string& dir, const std::string& outDir)
{
	std::unique_ptr<MapUseLock> lock;
	if (std::error_code ec; std::filesystem::is_directory(dir, ec))
		lock = std::make_unique<MapUseLock>(dir, MapUseLock::Mode::Read, "rasterslam map export");
	const Map map = loadMap(dir);
	fs::create_directories(outDir);
	const fs::path out(outDir);
	auto pose = [&](uint64_t kf) { return map.priorPoses.at(kf); };

	// The keyframe pose graph: consecutive keyframes of a session, and the anchors of local
	// maps joined by a loop.
	mrpt::graphs::CNetworkOfPoses3D graph;
	std::map<uint32_t, uint64_t> lastOfSession;
	for (const auto& [id, k] : map.keyframes)
	{
		graph.nodes[id] = pose(id);
		if (const auto it = lastOfSession.find(k->session); it != lastOfSession.end())
			graph.insertEdge(it->second, id, pose(id) - pose(it->second));
		lastOfSession[k->session] = id;
	}
	for (const auto& e : map.graph.edges)
		if (e.kind != LocalMapGraph::EdgeKind::Sequential)
		{
			const auto a = map.localMaps.at(e.from)->anchor(), b = map.localMaps.at(e.to)->anchor();
			graph.insertEdge(a, b, pose(b) - pose(a));
		}
	if (!map.keyframes.empty())
		graph.root = map.keyframes.begin()->first;
	writeAtomically(out / "map.graph",
	                [&](const std::string& p)
	                {
		                graph.saveToTextFile(p);
		                return fs::exists(p);
	                });

	// One keyframe of the simple map per local map: its points seen from its anchor.
	mrpt::maps::CSimpleMap sm;
	pcl::PointCloud<pcl::PointXYZ> cloud;
	for (const auto& [id, stub] : map.localMaps)
	{
		const auto lm = map.data(id);
		const auto anchor = pose(lm->anchor());
		auto pts = mrpt::maps::CSimplePointsMap::Create();
		for (std::size_t i = 0; i < lm->points(); i++)
		{
			const float x = lm->xyz[3 * i], y = lm->xyz[3 * i + 1], z = lm->xyz[3 * i + 2];
			pts->insertPoint(x, y, z);
			double gx, gy, gz;
			anchor.composePoint(x, y, z, gx, gy, gz);
			cloud.push_back(pcl::PointXYZ(static_cast<float>(gx), static_cast<float>(gy),
			                              static_cast<float>(gz)));
		}
		auto obs = mrpt::obs::CObservationPointCloud::Create();
		obs->pointcloud = pts;
		obs->sensorLabel = "localmap-" + std::to_string(id);
		obs->timestamp = mrpt::Clock::fromDouble(lm->updatedStamp);
		auto sf = mrpt::obs::CSensoryFrame::Create();
		sf->insert(obs);
		auto pdf = mrpt::poses::CPose3DPDFGaussian::Create();
		pdf->mean = anchor;
		sm.insert(pdf, sf);
	}
	writeAtomically(out / "map.simplemap", [&](const std::string& p) { return sm.saveToFile(p); });
	cloud.width = static_cast<uint32_t>(cloud.size());
	cloud.height = 1;
	writeAtomically(out / "points.pcd",
	                [&](const std::string& p)
	                {
		                return cloud.empty() ? static_cast<bool>(std::ofstream(p) << "")
		                                     : pcl::io::savePCDFileBinary(p, cloud) == 0;
	                });
	writeAtomically(out / "points.ply", [&](const std::string& p)
	                { return pcl::io::savePLYFileBinary(p, cloud) == 0; });

	// A top view: the points in grey, each session's keyframes as a coloured line.
	double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
	auto grow = [&](double x, double y)
	{ x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y); };
	for (const auto& p : cloud)
		grow(p.x, p.y);
	for (const auto& [id, p] : map.priorPoses)
		grow(p.x(), p.y());
	const int size = 1000, margin = 20;
	const double scale = (size - 2 * margin) / std::max({x1 - x0, y1 - y0, 1.0});
	cv::Mat img(size, size, CV_8UC3, cv::Scalar(255, 255, 255));
	auto px = [&](double x, double y)
	{
		return cv::Point(margin + static_cast<int>((x - x0) * scale),
		                 size - margin - static_cast<int>((y - y0) * scale));
	};
	for (const auto& p : cloud)
		img.at<cv::Vec3b>(px(p.x, p.y)) = cv::Vec3b(170, 170, 170);
	const cv::Scalar colours[] = {
	    {200, 60, 20}, {30, 30, 220}, {40, 160, 40}, {160, 40, 160}, {20, 150, 200}};
	std::map<uint32_t, std::vector<cv::Point>> lines;
	for (const auto& [id, k] : map.keyframes)
		lines[k->session].push_back(px(pose(id).x(), pose(id).y()));
	for (const auto& [s, l] : lines)
		cv::polylines(img, l, false, colours[s % 5], 2);
	writeAtomically(out / "top.png",
	                [&](const std::string& p)
	                {
		                std::vector<uint8_t> png;
		                if (!cv::imencode(".png", img, png))
			                return false;
		                std::ofstream f(p, std::ios::binary);
		                f.write(reinterpret_cast<const char*>(png.data()),
		                        static_cast<std::streamsize>(png.size()));
		                return static_cast<bool>(f);
	                });

	// Each session's keyframes as a trajectory, for rasterslam-eval and other tools.
	std::map<uint32_t, io::Trajectory> trajectories;
	for (const auto& [id, k] : map.keyframes)
	{
		Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
		T.matrix() = pose(id).getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
		trajectories[k->session].push_back({k->stamp, T});
	}
	for (const auto& [s, t] : trajectories)
		io::saveTrajectoryTum((out / mrpt::format("keyframes-s%u.tum", s)).string(), t);

	const auto imgDir = out / "localmaps";
	fs::create_directories(imgDir);
	for (const auto& [id, stub] : map.localMaps)
	{
		const auto lm = map.data(id);
		writeAtomically(imgDir / mrpt::format("%04llu.png", static_cast<unsigned long long>(id)),
		                [&](const std::string& p)
		                {
			                std::ofstream f(p, std::ios::binary);
			                f.write(reinterpret_cast<const char*>(lm->imagePng.data()),
			                        static_cast<std::streamsize>(lm->imagePng.size()));
			                return static_cast<bool>(f);
		                });
	}
	std::printf(
	    "rasterslam: map %s exported to %s: map.graph (%zu keyframes), map.simplemap (%zu local "
	    "maps), "
	    "points.pcd and points.ply (%zu points), top.png, keyframes-s*.tum (%zu sessions), "
	    "localmaps/\n",
	    dir.c_str(), outDir.c_str(), graph.nodes.size(), sm.size(), cloud.size(),
	    trajectories.size());
}

}  // namespace rasterslam::cli
