// A simulation scenario as read from a YAML file (rawlogs/*.yaml; keys in rawlogs/README.md).
#pragma once

#include <rasterslam/sim/traffic.h>
#include <rasterslam/sim/world.h>

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rasterslam::sim
{
/** A box of the carrying vehicle around the sensor (sensor frame: x forward, y left), from
 *  the ground up to height_m above it. Rays that meet it give no return, as a real driver
 *  drops its own car's returns; a zero box is none. */
struct EgoBox
{
	double front_m = 0, back_m = 0, half_width_m = 0, height_m = 0;
	bool empty() const { return !(front_m + back_m > 0 && half_width_m > 0 && height_m > 0); }
};

struct NoiseParams
{
	/** Standard deviation of the Gaussian range noise along the beam. */
	double range_sigma_m = 0.02;
	/** Probability that a return that should exist is lost. */
	double dropout_prob = 0.02;
	/** Standard deviation of the Gaussian noise on the intensity (clamped to [0,1]). */
	double intensity_sigma = 0.03;
	/** Foliage lets light in: a return from a crown or hedge comes from this far inside it
	 *  on average (an exponential depth, at most 4 times this; 0: from its surface). */
	double foliage_depth_m = 0;
	/** Dark surfaces are seen less far: a return's echo falls with reflectivity / range^2,
	 *  so a surface of reflectivity rho (the intensity of its kind) is seen up to
	 *  max_range * sqrt(rho / 0.8), the sensor's range being given for 80 %: asphalt
	 *  (0.28) to 71 m of an HDL-64E's 120. Off: everything up to the maximum range. */
	bool range_by_reflectivity = false;
};

struct RouteParams
{
	/** "block_loop", "figure_eight", "room_tour" (indoor) or "waypoints" (then `waypoints` is
	 *  used). */
	std::string pattern = "block_loop";
	/** Size of the block loop, in blocks. */
	int blocks_x = 2;
	int blocks_y = 1;
	std::vector<Eigen::Vector2d> waypoints;
	bool closed = true;
	double turn_radius_m = 6;
};

struct Scenario
{
	/** The file it came from, for messages. */
	std::string source;
	std::uint32_t seed = 1;
	/** "hdl64", "hdl64e" (the beams of MRPT's HDL-64 calibration) or "vlp16". */
	std::string lidar = "hdl64";
	std::size_t scans = 300;
	double rate_hz = 10;
	double speed_mps = 8;
	double sensor_height_m = 1.73;
	double start_stamp_s = 1.7e9;
	/** Threads casting one scan's rays. */
	int threads = 2;
	/** Point coordinates are rounded to multiples of this; 0 keeps them unrounded. */
	double point_resolution_m = 1.0 / 1024;
	/** "town" or "indoor". */
	std::string world = "town";
	IndoorParams indoor;
	/** The sensor carried by hand: it sways in yaw, pitch and roll and bobs with the steps
	 *  (see SimulatorOptions::handheld). */
	bool handheld = false;
	/** The vehicle's body rocking on its suspension (see SimulatorOptions::body_pitch_deg):
	 *  scenario key `body: {pitch_deg, roll_deg, heave_m}`. */
	double body_pitch_deg = 0, body_roll_deg = 0, body_heave_m = 0;
	/** Slowing for corners (SimulatorOptions::corner_accel_mps2, accel_mps2). */
	double corner_accel_mps2 = 0, accel_mps2 = 1.5;
	/** The carrying vehicle's boxes (SimulatorOptions::ego_body, ego_cabin): keys
	 *  `ego: {body: {front_m, back_m, half_width_m, height_m}, cabin: {...}}`. */
	EgoBox ego_body, ego_cabin;
	/** Each azimuth cast from the pose of its instant (see SimulatorOptions). */
	bool motion_within_sweep = false;
	double sweep_start_azimuth_deg = 180;
	bool sweep_clockwise = true;
	RouteParams route;
	TownParams town;
	NoiseParams noise;
	/** Cars and people moving during the run. */
	TrafficParams traffic;
	/** The world's epoch (top-level key `epoch`: the sessions before this one changed it that
	 *  many times) and the rates of change (key `changes`). */
	ChangeParams changes;
};

/** Reads a scenario. Missing keys keep their defaults; an unknown key, a value of the wrong
 *  type or out of range, or an unreadable file throws std::runtime_error naming the file and
 *  the key. */
Scenario loadScenario(const std::string& path);

/** Checks ranges (positive rates, probabilities in [0,1], ...); throws std::runtime_error
 *  naming `sc.source` and the key. loadScenario() calls it; call it again after overrides. */
void validateScenario(const Scenario& sc);

}  // namespace rasterslam::sim
