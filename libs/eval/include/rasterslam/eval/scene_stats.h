// Statistics of a LiDAR scan's scene, to compare simulated scans with real ones: how many
// points, how much of it is ground, how far, how high the rest stands, how varied the
// directions of its walls are, and how bright.
#pragma once

#include <rasterslam/core/types.h>

#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace rasterslam::eval
{
struct SceneStats
{
	/** Upper edges of the range bins (horizontal range, m); the last bin is everything beyond. */
	static constexpr std::array<double, 4> kRangeEdges{10, 20, 40, 80};
	/** Upper edges of the height bins of non-ground points (m above the ground plane). */
	static constexpr std::array<double, 4> kHeightEdges{1, 2, 4, 8};
	/** A point within this height of the ground plane (or below it) is ground. */
	static constexpr double kGroundBand_m = 0.25;

	std::size_t scans = 0;
	/** Scans left out because no ground plane was found in them (heights above the ground
	 *  cannot be told there). */
	std::size_t scansWithoutGround = 0;
	double points = 0;                    //!< a scan, mean
	double groundShare = 0;               //!< of all points
	std::array<double, 5> rangeShare{};   //!< of all points, by horizontal range
	std::array<double, 5> heightShare{};  //!< of non-ground points, by height above the ground
	/** How evenly the walls and other upright surfaces within 40 m face every horizontal
	 *  direction: the smaller over the larger eigenvalue of the structure tensor of the
	 *  bird's-eye occupancy of non-ground points (0.2 m cells). 0 = all face one way (a
	 *  straight street of plain facades: a scan matcher cannot tell where along it it is),
	 *  1 = every direction alike. */
	double isotropy = 0;
	/** Upright structure in the bird's-eye view: occupied 0.2 m cells within 40 m, a scan. */
	double structureCells = 0;
	double meanIntensity = 0;  //!< intensities as the reader gives them (0..1)
	double brightShare = 0;    //!< share of points with intensity >= 0.5
};

/** Accumulates the statistics of scans (sensor frame, z up); `finish` averages them. */
class SceneStatsAccumulator
{
   public:
	void add(const std::vector<PointXYZI>& scan);
	/** Throws std::invalid_argument when no scan with points and a ground plane was added. */
	SceneStats finish() const;

   private:
	SceneStats sum_;
	double allPoints_ = 0, nonGround_ = 0;
};

/** The statistics as aligned text lines, one column per set, with each set's label on top. */
std::string formatSceneStats(const std::vector<std::string>& labels,
                             const std::vector<SceneStats>& stats);
}  // namespace rasterslam::eval
