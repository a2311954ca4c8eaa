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

struct FreeSpaceParams
{
	double cell_m = 1.0;      //!< cells of the top view compared
	double flatSpan_m = 0.3;  //!< bare ground: a cell and its 8 neighbours span less height
	double bandLow_m = 0.7;   //!< low structure: points this far above the other side's
	double bandHigh_m = 2.5;  //!< lowest point in the cell, up to this far
	/** and reaches higher than this above that point in the same cell: walls, poles, trunks
	 *  under their crowns, not people and vehicles, which move (0: any height) */
	double minTop_m = 0.0;
};

/** What contradicts an alignment of two clouds on the free space they observed. */
struct FreeSpaceCheck
{
	/** Cells where one cloud has low structure and the other has points (both ways). */
	std::size_t compared = 0;
	/** Of those, the cells that the other cloud saw as bare ground all around. */
	std::size_t conflicts = 0;
	double share() const { return compared ? double(conflicts) / double(compared) : 0.0; }
};

/** Checks `source` placed by T (source frame to target frame) on `target`: low structure of
 *  one cloud (bandLow_m-bandHigh_m above the other's lowest point in a cell: walls, poles,
 *  trunks, vehicles, at heights a vehicle's LiDAR sees at any range; with minTop_m, only what
 *  also rises higher) where the other saw bare ground all around (the cell and its eight
 *  neighbours observed, each spanning under flatSpan_m). A wrong alignment puts one place's
 *  walls and poles on the other's street; a right one conflicts only where something moved
 *  or was built. Both clouds in frames whose z axes are near the vertical; points that are
 *  not finite or lie more than 2^22 cells from the origin are left out. Throws
 *  std::invalid_argument unless cell_m is positive and finite. */
FreeSpaceCheck freeSpaceConflicts(const std::vector<Eigen::Vector3f>& source,
                                  const std::vector<Eigen::Vector3f>& target,
                                  const Eigen::Isometry3d& T, const FreeSpaceParams& params = {});

}  // namespace rasterslam::features
