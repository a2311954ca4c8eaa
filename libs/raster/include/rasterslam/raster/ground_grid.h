// The ground around a scan as a grid of heights, and the alignment of two scans' ground
// surfaces (height, roll and pitch) patch by patch.
//
// Aligning the two scans' RANSAC planes (alignGroundPlanes) assumes both scans stand on one
// and the same plane. On a road whose slope or camber changes, each scan's plane is the best
// plane through its own neighbourhood, and forcing them parallel sets every scan's roll and
// pitch to the first scan's: the estimate drifts by the road's own change of slope. Comparing
// the heights of the same patches of ground, seen from both scans, does not assume a plane.
#pragma once

#include <rasterslam/core/types.h>
#include <rasterslam/raster/ground_plane.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

namespace rasterslam::raster
{
struct GroundGridParams
{
	double cell_m = 1.0;      //!< cell size
	double radius_m = 20.0;   //!< cells whose centre lies farther (horizontally) are not kept
	double minRange_m = 2.5;  //!< nearer points (the carrying vehicle) are not used
	/** A point is ground when it lies within this of the scan's ground plane. */
	double band_m = 0.3;
	int minPoints = 3;  //!< fewer ground points: the cell is unknown
	/** A cell whose ground points spread more than this in height (a kerb, a car's sill,
	 *  grass) is unknown. */
	double maxSpread_m = 0.15;
	int stride = 1;  //!< every n-th point of the scan is looked at
};

/** Heights of the ground in a square grid centred on the sensor (the scan's own frame). */
class GroundGrid
{
   public:
	/** One known cell: the mean of its ground points. */
	struct Sample
	{
		Eigen::Vector3f mean;
		int count = 0;
	};

	/** Builds the grid from the points of a scan and its ground plane (which decides what is
	 *  ground and gives the slope inside a cell). An invalid plane gives an empty grid. */
	void build(const std::vector<PointXYZI>& pts, const Plane& plane,
	           const GroundGridParams& p = {});
	void clear();
	bool empty() const { return samples_.empty(); }
	const std::vector<Sample>& samples() const { return samples_; }
	/** Height of the ground at (x, y): interpolated between the centre heights of the four
	 *  cells around it when all are known, else from the cell that holds it (its points' mean
	 *  height moved along the plane's slope). nullopt where that cell is unknown. */
	std::optional<float> heightAt(float x, float y) const;

   private:
	int half_ = 0;  //!< cells from the centre to the border
	float cell_ = 1, inv_ = 1;
	float gx_ = 0, gy_ = 0;       //!< dz/dx and dz/dy of the plane
	std::vector<int32_t> index_;  //!< (2 half + 1)^2 cells: into samples_, -1 unknown
	std::vector<float> centre_;   //!< each cell's height at its centre (NaN unknown)
	std::vector<Sample> samples_;
};

struct GroundAlignParams
{
	int iterations = 5;
	double huber_m = 0.05;       //!< residuals beyond this weigh less
	double maxResidual_m = 0.4;  //!< beyond this a pair is not used (a parked car moved)
	int minCells = 40;           //!< fewer pairs: no alignment
	/** The cells must spread at least this (standard deviation, m) along the two axes of
	 *  the ground, or roll or pitch would be free. */
	double minSpread_m = 2.0;
	double maxCorrection_deg = 2.0;  //!< a larger change of roll and pitch is refused
};
// The ground heights must be true: a vertical-angle offset of the beams (KITTI's 0.205 deg)
// makes the ground read lower in proportion to its range, which two scans see at different
// ranges; correct the scans first (engine.vertical_correction_deg).

struct GroundAlignResult
{
	bool ok = false;
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	int used = 0;               //!< pairs of cells in the last iteration
	double rms_m = 0;           //!< their height residual after the alignment
	double correction_deg = 0;  //!< roll and pitch change applied
	const char* why = "";       //!< when not ok
};

/** Moves T_ref_cur (the current scan's pose in the reference scan's frame) in height, roll
 *  and pitch, x, y and yaw kept, until the current scan's ground cells lie on the reference
 *  scan's ground: Gauss-Newton on the height differences of the same patches, Huber weights.
 *  Not ok (T unchanged) when too few cells overlap, they do not spread over the ground, or
 *  the correction exceeds maxCorrection_deg. */
GroundAlignResult alignGroundGrids(const Eigen::Isometry3d& T_ref_cur, const GroundGrid& ref,
                                   const GroundGrid& cur, const GroundAlignParams& p = {});

}  // namespace rasterslam::raster
