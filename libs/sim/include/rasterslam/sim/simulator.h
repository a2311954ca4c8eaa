// Turns a world, a LiDAR and a route into scans with ground truth.
#pragma once

#include <mrpt/poses/CPose3D.h>
#include <rasterslam/core/sweep.h>
#include <rasterslam/core/types.h>
#include <rasterslam/sim/lidar_model.h>
#include <rasterslam/sim/route.h>
#include <rasterslam/sim/scenario.h>
#include <rasterslam/sim/traffic.h>
#include <rasterslam/sim/world.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace rasterslam::sim
{
struct SimulatorOptions
{
	NoiseParams noise;
	std::uint32_t seed = 1;
	double sensor_height_m = 1.73;
	double rate_hz = 10;
	double speed_mps = 8;
	double start_stamp_s = 1.7e9;
	/** Threads per scan; the output does not depend on it. */
	int threads = 2;
	/** Coordinates are rounded to multiples of this (0: not rounded). The default 2^-10 m
	 *  (under 1 mm, far below the range noise) zeroes the low bits of the float coordinates,
	 *  which halves the gzip-compressed rawlog and speeds up its compression. */
	double point_resolution_m = 1.0 / 1024;
	/** Motion within a sweep: each azimuth is cast from the pose of its own instant, and its
	 *  points are given in the sensor frame of that instant, as a real driver that does not
	 *  de-skew gives them. The scan's stamp and ground truth are the sweep's end. Off: every
	 *  ray leaves from the pose at the stamp (an instantaneous scan). */
	bool motion_within_sweep = false;
	/** Where the sweep starts and which way it spins (when motion_within_sweep is on). */
	SweepModel sweep;
	/** Carried by hand: on top of the route's pose the sensor sways in yaw (8 deg at 0.7 Hz),
	 *  pitch (3 deg, 1.1 Hz) and roll (3 deg, 0.9 Hz) and bobs with the steps (2 cm, 1.8 Hz),
	 *  as a function of the time since start_stamp_s. */
	bool handheld = false;
	/** A vehicle's body on its suspension: pitch, roll (degrees) and heave (m), each the sum
	 *  of three sinusoids of 0.6..2.5 Hz drawn from the seed, with these RMS values (0: a
	 *  body fixed to the route, as before). Real cars rock like this; without it a flat
	 *  ground's rings fall on the same place scan after scan, which a scan matcher reads as
	 *  standing still. */
	double body_pitch_deg = 0, body_roll_deg = 0, body_heave_m = 0;
	/** Slowing for corners: the speed on an arc of radius R is at most sqrt(this * R) (the
	 *  lateral acceleration a driver keeps to; 2..3 m/s^2 in town), reached and left braking
	 *  and speeding up at accel_mps2. 0: speed_mps everywhere, corners included. */
	double corner_accel_mps2 = 0;
	double accel_mps2 = 1.5;
	/** The carrying vehicle: its body (bonnet to boot) and its cabin (up to the roof). */
	EgoBox ego_body, ego_cabin;
};

/** Scans are instantaneous unless SimulatorOptions::motion_within_sweep is set (then every
 *  azimuth leaves from the pose of its own instant). Intensities are rounded to 1/256, as a
 * sensor's 8-bit value. Random draws are seeded per (seed, scan index, block of azimuths), so a
 * scan depends only on its inputs, not on the thread count or on the scans before it. */
class Simulator
{
   public:
	Simulator(std::shared_ptr<const World> world, LidarModel lidar, Route route,
	          SimulatorOptions opt);
	/** Builds the town (at the scenario's epoch), its traffic, the route and the LiDAR that the
	 *  scenario describes. */
	static Simulator fromScenario(const Scenario& sc);

	/** Objects moving during the run; their time is the stamp minus start_stamp_s. A mover is
	 *  drawn at the instant of each block of 64 azimuths (3 ms of a 10 Hz HDL-64E sweep), and
	 *  not when its footprint comes within 1 m of the sensor (it would drive through the
	 *  vehicle). */
	void setTraffic(Traffic t) { traffic_ = std::move(t); }
	const Traffic& traffic() const { return traffic_; }

	/** Scan k along the route, ground truth included. */
	Scan scan(std::size_t k) const;
	/** Ground truth of scan k: the sensor frame in the world. */
	mrpt::poses::CPose3D sensorPose(std::size_t k) const;
	double stamp(std::size_t k) const;
	/** A scan from any sensor pose (points in the sensor frame; groundTruth = the pose), every
	 *  ray from that pose (no motion within the sweep). */
	Scan scanFrom(const mrpt::poses::CPose3D& T_world_sensor, std::size_t index,
	              double stamp) const;
	/** The sensor's pose on the route at any time (the route's start before start_stamp_s). */
	mrpt::poses::CPose3D sensorPoseAt(double stampSec) const;

	const World& world() const { return *world_; }
	const LidarModel& lidar() const { return lidar_; }
	const Route& route() const { return route_; }
	const SimulatorOptions& options() const { return opt_; }
	/** Metres along the route t seconds after the start: speed_mps * t, or by the speed
	 *  profile when the vehicle slows for corners (SimulatorOptions::corner_accel_mps2). */
	double distanceAt(double t) const;
	/** Seconds to drive the route once. */
	double lapTime() const;

   private:
	/** The pose `s` metres along the route, `t` seconds after the start (the hand's sway
	 *  when handheld). */
	mrpt::poses::CPose3D poseAfter(double s, double t) const;
	/** Casts a sweep; column a (azimuth 2 pi a / steps) leaves from columnPose[a] at
	 *  columnStamp[a], or from T_world_sensor at stampSec when they are empty. */
	Scan cast(const mrpt::poses::CPose3D& T_world_sensor,
	          const std::vector<mrpt::poses::CPose3D>& columnPose,
	          const std::vector<double>& columnStamp, std::size_t index, double stampSec) const;
	void buildSpeedProfile();
	std::shared_ptr<const World> world_;
	LidarModel lidar_;
	Route route_;
	SimulatorOptions opt_;
	Traffic traffic_;
	/** Rays (beam-major: b * azimuthSteps + a) that meet the carrying vehicle's boxes. */
	std::vector<std::uint8_t> egoBlocked_;
	/** The speed profile, when slowing for corners: time at every profileStep_ metres. */
	std::vector<double> profileTime_;
	double profileStep_ = 0;
};

}  // namespace rasterslam::sim
