// A registration of two point clouds that needs neither a pose prior nor descriptors: both are
// reduced to a top view of their upright structure (cells whose points span a height: walls,
// trunks, poles, vehicles; not the ground), and the source's view, turned through every yaw
// step, is correlated with the target's over every shift (by DFT). The best (x, y, yaw) peaks
// are hypotheses for ICP to refine. Made for revisits seen from far along the road, whose
// ORB descriptors no longer match (the objects are seen from 15-30 m farther) while the
// layout of the street is the same.
#pragma once

#include <Eigen/Geometry>
#include <vector>

namespace rasterslam::features
{
struct PlanarSearchParams
{
	double cell_m = 1.0;         //!< top-view cell
	double minSpan_m = 1.0;      //!< a cell is structure when its points span this much height
	double yawStep_deg = 2.0;    //!< turns tried: 0, step, 2 step, ... up to 360
	double range_m = 50.0;       //!< source points farther than this are left out
	int hypotheses = 8;          //!< best distinct peaks returned
	double distinct_m = 3.0;     //!< peaks closer than this and distinct_deg are one
	double distinct_deg = 10.0;  //!< (the best of them is kept)
};

struct PlanarHypothesis
{
	/** The source's pose in the target's frame: x, y and yaw; z 0, no roll or pitch. */
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	/** Structure cells of the turned source that land on structure of the target (smoothed
	 *  over a cell), over the smaller of the turned source's occupied cells and the target's
	 *  structure cells: 0..1. */
	double score = 0;
};

/** The best distinct (x, y, yaw) alignments of `source` on `target`, best first. Both clouds
 *  are in frames whose z axes are near the vertical (a sensor on a vehicle). Empty when either
 *  cloud has no structure cell. */
std::vector<PlanarHypothesis> planarSearch(const std::vector<Eigen::Vector3f>& source,
                                           const std::vector<Eigen::Vector3f>& target,
                                           const PlanarSearchParams& params = {});

}  // namespace rasterslam::features
