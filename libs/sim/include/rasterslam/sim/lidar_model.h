// Geometry of a spinning multi-beam LiDAR.
#pragma once

#include <string>
#include <vector>

namespace rasterslam::sim
{
/** Beams at fixed elevations swept over a full turn in equal azimuth steps. */
class LidarModel
{
   public:
	LidarModel(std::string name, std::vector<double> elevationsDeg, int azimuthSteps,
	           double minRange_m, double maxRange_m);

	/** Velodyne HDL-64E: 64 beams from -24.8 to +2.0 deg, 2083 steps a turn (0.1728 deg),
	 *  1..120 m. The real sensor's beams are not evenly spaced (two laser blocks with
	 *  different pitches); here they are, which keeps the span and count right. */
	static LidarModel hdl64();
	/** Velodyne VLP-16: 16 beams -15..+15 deg every 2 deg, 1800 steps (0.2 deg), 1..100 m. */
	static LidarModel vlp16();
	/** "hdl64" or "vlp16"; throws std::invalid_argument listing both otherwise. */
	static LidarModel byName(const std::string& name);

	const std::string& name() const { return name_; }
	/** Ascending, degrees. */
	const std::vector<double>& elevationsDeg() const { return elevationsDeg_; }
	int beamCount() const { return static_cast<int>(elevationsDeg_.size()); }
	int azimuthSteps() const { return azimuthSteps_; }
	double azimuthStepDeg() const { return 360.0 / azimuthSteps_; }
	double minRange_m() const { return minRange_; }
	double maxRange_m() const { return maxRange_; }
	int raysPerScan() const { return beamCount() * azimuthSteps_; }

   private:
	std::string name_;
	std::vector<double> elevationsDeg_;
	int azimuthSteps_;
	double minRange_, maxRange_;
};

}  // namespace rasterslam::sim
