// Objects that move during a run: cars driving the town's streets, people walking its
// sidewalks or the rooms of the indoor world. A mover goes back and forth along a straight
// path at a constant speed, so where it is at any time is known exactly (the truth a test
// needs), and it is drawn into the scans at the instant each azimuth is measured.
#pragma once

#include <rasterslam/sim/world.h>

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace rasterslam::sim
{
/** Moving objects of a scenario (all zero: a static world). */
struct TrafficParams
{
	/** Cars driving the streets, in the lanes either side of the centre line (3 m from it, or
	 *  0.43 of the half street width in streets narrower than 14 m; the route drives the centre
	 *  line). */
	int cars = 0;
	/** People walking: on the sidewalks in a town, across the rooms indoors. */
	int pedestrians = 0;
	double car_speed_mps = 8;
	double walk_speed_mps = 1.4;
};

/** One mover: it starts at `a` + phase along the path a -> b, turns at the ends. */
struct Mover
{
	ObjectKind kind = ObjectKind::Car;
	Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();
	double speed_mps = 1;
	/** Distance along the back-and-forth path at time 0, in [0, 2 |b - a|). */
	double phase_m = 0;
	/** Car: body half length and half width, body and cabin heights. Person: radius, height. */
	double halfLength = 0.25, halfWidth = 0.25, height = 1.7, cabinHeight = 0;
};

/** Where a mover is: position and heading (radians, the way it is going). */
struct MoverState
{
	Eigen::Vector2d position = Eigen::Vector2d::Zero();
	double yaw = 0;
};

class Traffic
{
   public:
	Traffic() = default;
	explicit Traffic(std::vector<Mover> movers) : movers_(std::move(movers)) {}

	/** Cars on the street lines of the town (the whole length of a street, both directions),
	 *  people on the sidewalk of one side of a block. Deterministic for (params, seed)
	 *  (Simulator::fromScenario mixes the start stamp into the seed: each session its own
	 *  traffic); throws
	 *  std::invalid_argument on negative counts or speeds out of (0, 40] m/s. */
	static Traffic town(const TownParams& town, const TrafficParams& p, std::uint32_t seed);
	/** People walking across a room, 0.8 m off the lanes through the room centres (where a
	 *  handheld walk goes). */
	static Traffic indoor(const IndoorParams& indoor, const TrafficParams& p, std::uint32_t seed);

	/** Mover i at time t (seconds since the run's start; any real t). */
	MoverState state(std::size_t i, double t) const;
	/** The shapes of every mover at time t standing on `ground`, except those whose footprint
	 *  (a car's box, a person's circle) comes within `keepOut` metres of `sensor` horizontally,
	 *  and those farther than `range` from it: a mover is not drawn through the sensor (the
	 *  vehicle or the person carrying it). Appends to `out`. */
	void shapesAt(double t, const GroundModel& ground, const Eigen::Vector3d& sensor, double range,
	              double keepOut, std::vector<Shape>& out) const;

	const std::vector<Mover>& movers() const { return movers_; }
	bool empty() const { return movers_.empty(); }

   private:
	std::vector<Mover> movers_;
};

}  // namespace rasterslam::sim
