// A spinning LiDAR's sweep: when in a turn each point was measured, and moving the points of a
// sweep taken while the sensor moved into one frame (de-skewing). A rotating sensor measures
// its points one azimuth after another over a whole period (0.1 s at 10 Hz); a driver that does
// not know the motion gives each point in the sensor frame of its own instant, so a scan taken
// at 8 m/s is smeared by 0.8 m from its first azimuth to its last, and a turn bends it.
#pragma once

#include <rasterslam/core/types.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

namespace rasterslam
{
/** Where a sweep starts and which way the sensor spins. Velodyne sensors spin clockwise seen
 *  from above (x forward, y left, z up: the azimuth decreases); KITTI's sweeps start and end
 *  behind the car (azimuth 180 deg), where the cameras are not triggered. */
struct SweepModel
{
	double startAzimuth_deg = 180;
	bool clockwise = true;

	/** The share of the sweep [0, 1) elapsed when the sensor points at azimuth `az_rad`
	 *  (atan2(y, x) of the point in the frame its scan is given in). */
	double fraction(double az_rad) const
	{
		constexpr double kTwoPi = 2 * 3.14159265358979323846;
		const double a0 = startAzimuth_deg * (kTwoPi / 360.0);
		double d = clockwise ? a0 - az_rad : az_rad - a0;
		d = std::fmod(d, kTwoPi);
		if (d < 0)
			d += kTwoPi;
		return d < kTwoPi ? d / kTwoPi : 0.0;
	}
};

/** The pose a fraction `s` of the way along `motion` (rotation angle and translation scaled by
 *  s; s may exceed 1 or be negative). A constant-velocity model over short times. */
Eigen::Isometry3d scaleMotion(const Eigen::Isometry3d& motion, double s);

/** Moves every point of a sweep into the sensor frame at its end. `T_start_end` is the sensor's
 *  motion over the whole sweep (the end's pose in the frame of the start); a point is taken to
 *  be measured at the fraction of the sweep its azimuth gives, with the motion spread evenly
 *  over the sweep. Points at the sweep's end do not move; at its start, by the whole motion. */
void deskewSweep(std::vector<PointXYZI>& points, const Eigen::Isometry3d& T_start_end,
                 const SweepModel& model);

/** Rotates every point by `deg` about the horizontal axis perpendicular to its azimuth, which
 *  raises its elevation angle by `deg` and keeps its range and azimuth: the correction of a
 *  sensor whose beams are all tilted by the same angle (KITTI's HDL-64E scans read 0.205 deg
 *  low, so the ground looks like a shallow cone around the sensor). */
void correctElevation(std::vector<PointXYZI>& points, double deg);

}  // namespace rasterslam
