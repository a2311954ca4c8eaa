// Rendering scans from real geometry: the KITTI-00 sample merged into a cloud (sim::CloudWorld)
// and seen again by the HDL-64E beam pattern measured from the same scans.
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/trajectory_io.h>
#include <rasterslam/sim/cloud_world.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>

#include "test_support.h"

using namespace rasterslam;

namespace
{
/** The KITTI-00 sample: scans and SemanticKITTI poses in the Velodyne frame. */
struct KittiSample
{
	std::vector<std::vector<PointXYZI>> scans;
	std::vector<Eigen::Isometry3d> poses;
};
const KittiSample& sample()
{
	static const KittiSample s = []
	{
		KittiSample k;
		const auto D = test::sharedData("kitti00-0000-0100");
		for (const auto& b : io::listKittiBins(D + "/velodyne"))
			k.scans.push_back(io::loadKittiBin(b));
		for (const auto& p :
		     io::kittiCameraToVelodyne(io::loadTrajectory(D + "/poses_semantickitti.txt"),
		                               io::loadKittiCalibTr(D + "/calib.txt")))
			k.poses.push_back(p.pose);
		return k;
	}();
	return s;
}

/** Share of `a`'s points within `radius` of a point of `b`. */
double shareWithin(const std::vector<PointXYZI>& a, const std::vector<PointXYZI>& b, double radius)
{
	const auto key = [radius](double x, double y, double z)
	{
		const auto f = [radius](double v)
		{ return static_cast<std::int64_t>(std::floor(v / radius)) + (1 << 20); };
		return (f(x) << 42) | (f(y) << 21) | f(z);
	};
	std::unordered_map<std::int64_t, std::vector<Eigen::Vector3f>> grid;
	for (const auto& p : b)
		grid[key(p.x, p.y, p.z)].emplace_back(p.x, p.y, p.z);
	std::size_t near = 0;
	for (const auto& p : a)
	{
		const Eigen::Vector3f q(p.x, p.y, p.z);
		bool found = false;
		for (int dx = -1; dx <= 1 && !found; dx++)
			for (int dy = -1; dy <= 1 && !found; dy++)
				for (int dz = -1; dz <= 1 && !found; dz++)
				{
					const auto it =
					    grid.find(key(p.x + dx * radius, p.y + dy * radius, p.z + dz * radius));
					if (it == grid.end())
						continue;
					for (const auto& c : it->second)
						if ((c - q).norm() <= radius)
						{
							found = true;
							break;
						}
				}
		near += found;
	}
	return a.empty() ? 0 : static_cast<double>(near) / static_cast<double>(a.size());
}

sim::LidarModel kittiHdl64()
{
	return sim::LidarModel::fromRingOrderedScan("kitti-hdl64", sample().scans[0], 2083, 2.5, 120);
}
}  // namespace

TEST(CloudWorld, MeasuresTheKittiBeamPattern)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto lidar = kittiHdl64();
	// 64 lasers; two whose rings read within 0.08 degrees count as one beam.
	ASSERT_GE(lidar.beamCount(), 62);
	ASSERT_LE(lidar.beamCount(), 64);
	const auto& el = lidar.elevationsDeg();
	// The HDL-64E's span, about -24.9 to +2.0 degrees; the lowest beams read up to 1.7
	// degrees lower, seen from the one origin height all beams are given here (their lasers
	// sit lower), which places their rays through the same ground points.
	EXPECT_GT(el.front(), -27.0);
	EXPECT_LT(el.front(), -24.0);
	EXPECT_NEAR(el.back(), 2.0, 0.5);
	for (std::size_t b = 1; b < el.size(); b++)
	{
		// Spacing: about 1/3 degree in the upper block, 1/2 in the lower one.
		EXPECT_GT(el[b] - el[b - 1], 0.08) << b;
		EXPECT_LT(el[b] - el[b - 1], 0.75) << b;
	}
	// The beams' origin: about 0.2 m above the Velodyne frame's.
	EXPECT_NEAR(lidar.originHeights_m()[0], 0.2, 0.1);
	// The same pattern from another scan of the drive.
	const auto other =
	    sim::LidarModel::fromRingOrderedScan("kitti-hdl64", sample().scans[80], 2083, 2.5, 120);
	ASSERT_GE(other.beamCount(), 62);
	std::size_t same = 0;  // beams of one scan with a beam of the other within 0.25 degrees
	for (const double e : el)
		for (const double o : other.elevationsDeg())
			if (std::abs(e - o) < 0.25)
			{
				same++;
				break;
			}
	std::printf("%zu of %zu beams within 0.25 deg of a beam measured on scan 80\n", same,
	            el.size());
	EXPECT_GE(same, el.size() - 2);
	// Points sorted by range, not ring after ring: refused.
	auto shuffled = sample().scans[0];
	std::sort(shuffled.begin(), shuffled.end(),
	          [](const PointXYZI& a, const PointXYZI& b) { return a.x < b.x; });
	EXPECT_THROW(sim::LidarModel::fromRingOrderedScan("x", shuffled, 2083, 2.5, 120),
	             std::invalid_argument);
}

TEST(CloudWorld, RendersARealScanAtItsOwnPose)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto& s = sample();
	const auto lidar = kittiHdl64();
	// Leave scan 50 out: the render must come from the other scans' geometry.
	constexpr std::size_t kHeldOut = 50;
	sim::CloudWorld world;
	const auto t0 = std::chrono::steady_clock::now();
	for (std::size_t i = 0; i < s.scans.size(); i++)
		if (i != kHeldOut)
			world.add(s.scans[i], s.poses[i]);
	sim::RenderStats st;
	const auto t1 = std::chrono::steady_clock::now();
	const auto scan = world.render(s.poses[kHeldOut], lidar, &st);
	const auto t2 = std::chrono::steady_clock::now();
	const auto& real = s.scans[kHeldOut];
	const double near = shareWithin(scan, real, 0.2), covered = shareWithin(real, scan, 0.2);
	std::printf(
	    "cloud of %zu voxels built in %.1f s; render %.0f ms: %zu points (real %zu), %zu "
	    "filled, %zu dropped; %.3f of them within 0.2 m of the real scan, %.3f of the real "
	    "scan within 0.2 m of them\n",
	    world.size(), std::chrono::duration<double>(t1 - t0).count(),
	    std::chrono::duration<double, std::milli>(t2 - t1).count(), scan.size(), real.size(),
	    st.filled, st.dropped, near, covered);
	EXPECT_GT(scan.size(), real.size() * 7 / 10);
	EXPECT_LT(scan.size(), real.size() * 13 / 10);
	// README: 88 % of the rendered points lie within 0.2 m of the held-out real scan, and 91 %
	// of the real scan's points within 0.2 m of the rendered ones.
	EXPECT_GT(near, 0.8);
	EXPECT_GT(covered, 0.8);

	// The same render 1 m to the side is visibly another scan: the check can fail.
	Eigen::Isometry3d shifted = s.poses[kHeldOut];
	shifted.translate(Eigen::Vector3d(0, 1.0, 0));
	const auto moved = world.render(shifted, lidar);
	EXPECT_LT(shareWithin(moved, real, 0.2), near - 0.2);
}
