// A world made of real scans: registered LiDAR scans merged into a voxel cloud, from which new
// scans are rendered at any pose with a spinning LiDAR's beam pattern and occlusion. It turns
// a short real drive (with its poses) into revisits with exact truth: the street driven the
// other way, sideways, further along.
#pragma once

#include <rasterslam/core/types.h>
#include <rasterslam/sim/lidar_model.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace rasterslam::sim
{
struct CloudWorldParams
{
	/** Edge of the voxels the scans are merged into; a voxel keeps the mean of its points. */
	double voxel_m = 0.1;
	/** Points farther than this from the scan's own sensor are not merged: far returns are
	 *  sparse and their pose error is largest. */
	double maxMergeRange_m = 60;
	/** A voxel is kept when this many scans hit it: a moving car leaves a trail of voxels
	 *  that one or two scans each hit, a wall is hit by every scan that passes. */
	int minScans = 3;
};

struct RenderStats
{
	std::size_t candidates = 0;  //!< voxels within the sensor's range
	std::size_t rays = 0;        //!< beam x azimuth cells that returned a point
	std::size_t filled = 0;      //!< of those, gaps closed from their neighbours
	std::size_t dropped = 0;     //!< cells seen through a gap of a nearer surface, removed
};

/** The merged cloud, and the renderer over it. Not thread-safe while adding. */
class CloudWorld
{
   public:
	explicit CloudWorld(CloudWorldParams p = {});

	/** Merges a scan whose points are in the sensor frame, the sensor at T_world_sensor. */
	void add(const std::vector<PointXYZI>& scan, const Eigen::Isometry3d& T_world_sensor);
	/** Voxels in the cloud (those hit by minScans scans or more). */
	std::size_t size() const
	{
		finalize();
		return points_.size();
	}
	const CloudWorldParams& params() const { return p_; }

	/** A scan as `lidar` at T_world_sensor would see the cloud, points in the sensor frame.
	 *  Each map voxel is splatted over the beam x azimuth cells its footprint covers and the
	 *  nearest one wins (a z-buffer); a cell's point lies on the cell's own ray where the ray
	 *  meets the winner's surface (its plane from the neighbouring voxels; its range where no
	 *  plane is known), so the scan has the sensor's beam pattern and a road seen at a grazing
	 *  angle is not raised by the voxel's footprint. A cell whose neighbours on both sides (in
	 *  its row or its column) are much nearer looks through a gap of the sparse cloud: it is
	 *  given their range when they agree, and removed when not. */
	std::vector<PointXYZI> render(const Eigen::Isometry3d& T_world_sensor, const LidarModel& lidar,
	                              RenderStats* stats = nullptr) const;

   private:
	struct Accum
	{
		double x = 0, y = 0, z = 0, i = 0;
		std::uint32_t n = 0;
		std::uint32_t scans = 0;  //!< distinct scans that hit it
		std::uint32_t lastScan = 0;
	};
	/** Sorts the voxels into 2D columns after adds (once). */
	void finalize() const;

	CloudWorldParams p_;
	std::unordered_map<std::int64_t, Accum> voxels_;
	mutable std::vector<PointXYZI> points_;  //!< voxel means, grouped by column
	/** Surface normal at each voxel (zero where its neighbours fix no plane). */
	mutable std::vector<Eigen::Vector3f> normals_;
	/** Column key -> [begin, end) in points_. */
	mutable std::unordered_map<std::int64_t, std::pair<std::size_t, std::size_t>> columns_;
	mutable bool dirty_ = false;
	std::uint32_t added_ = 0;  //!< scans added
	static constexpr double kColumn_m = 8.0;
};

}  // namespace rasterslam::sim
