// The vehicle's path: a polyline through waypoints with circular arcs at the corners.
#pragma once

#include <mrpt/poses/CPose3D.h>
#include <rasterslam/sim/world.h>

#include <Eigen/Core>
#include <vector>

namespace rasterslam::sim
{
struct PlanarPose
{
	double x = 0, y = 0, yaw = 0;
};

/** Drives the straight segments between waypoints and turns on arcs tangent to both
 *  segments (radius turnRadius_m, shrunk where segments are too short for it), so heading is
 *  continuous. A closed route starts halfway along its first segment and wraps around; an
 *  open one starts at the first waypoint and stops at the last. */
class Route
{
   public:
	Route() = default;
	Route(const std::vector<Eigen::Vector2d>& waypoints, bool closed, double turnRadius_m);

	/** A rectangle along the street centre lines around blocks_x x blocks_y blocks from the
	 *  town's south-west corner, counter-clockwise. */
	static std::vector<Eigen::Vector2d> blockLoop(const TownParams& town, int blocks_x,
	                                              int blocks_y);
	/** Two loops around the two south-western blocks joined through their common street
	 *  (needs blocks_x >= 2): the middle street is driven twice in the same direction. */
	static std::vector<Eigen::Vector2d> figureEight(const TownParams& town);
	/** Through every room of the indoor world, room centre to room centre through the doors,
	 *  row by row (a serpentine). It ends beside the first room only with an even rooms_y (or
	 *  one column): only then may the route be closed (the scenario checks it). */
	static std::vector<Eigen::Vector2d> roomTour(const IndoorParams& indoor);

	/** Pose after driving s metres from the start. Throws std::logic_error on an empty route. */
	PlanarPose at(double s) const;
	/** |curvature| (1/m) at s metres from the start: 0 on a segment, 1/R on an arc. */
	double curvatureAt(double s) const;
	double length() const { return length_; }
	bool closed() const { return closed_; }
	bool empty() const { return pieces_.empty(); }

   private:
	struct Piece
	{
		double s0;  //!< arc length at the piece's start
		double len;
		Eigen::Vector2d p0;  //!< start point
		double yaw0;         //!< heading at the start
		double curvature;    //!< 0 for a segment, +-1/R for a left/right arc
	};
	/** The piece at s, with s wrapped around a closed route or clamped to an open one.
	 *  Throws std::logic_error on an empty route. */
	const Piece& pieceAt(double& s) const;
	std::vector<Piece> pieces_;
	double length_ = 0;
	bool closed_ = true;
};

/** Pose of a sensor mounted `height_m` above the ground on a vehicle at (x, y) heading `yaw`,
 *  with the vehicle's z axis along the ground normal (pitch and roll follow the slope). Frame:
 *  x forward, y left, z up. */
mrpt::poses::CPose3D sensorPoseOnGround(const GroundModel& ground, const PlanarPose& p,
                                        double height_m);

}  // namespace rasterslam::sim
