// Geometry of a spinning multi-beam LiDAR.
#pragma once

#include <rasterslam/core/types.h>

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
	/** Velodyne HDL-64E with the beam elevations of MRPT's default HDL-64 calibration
	 *  (`VelodyneCalibration::LoadDefaultCalibration("HDL64")`, its `vert_correction`s): an
	 *  upper block of 32 beams from -8.56 to +1.96 deg (about 1/3 deg apart) and a lower block
	 *  of 32 from -24.56 to -8.77 deg (about 1/2 deg). Fewer beams reach the ground near the
	 *  vehicle than with hdl64()'s even spread, as on the real sensor; each laser sits at its
	 *  calibrated height (vert_offset_correction, 0.14-0.22 m) above the frame's origin, which
	 *  is what sensor_height_m puts above the ground. The table is kept here
	 *  because MRPT 2.5 (Debian 12) fails to load that calibration: its YAML loader reads the
	 *  embedded text as a file name. Same steps and ranges as hdl64(). */
	static LidarModel hdl64e();
	/** Velodyne VLP-16: 16 beams -15..+15 deg every 2 deg, 1800 steps (0.2 deg), 1..100 m. */
	static LidarModel vlp16();
	/** The beams of a real sensor measured from one of its scans, when the scan stores its
	 *  points ring after ring, each ring one turn (as KITTI's HDL-64E scans do; a ring ends
	 *  where the azimuth falls back by more than half a turn). The beams share one origin
	 *  height (fitted as z = h + r_xy tan(elevation) on the rings that see a spread of ranges;
	 *  a real HDL-64E's lasers sit 0.14-0.22 m above its base); a beam's elevation is the
	 *  median over its ring's points from that origin, 2.5 to 80 m away. Throws
	 *  std::invalid_argument when the scan has fewer than 4 rings. */
	static LidarModel fromRingOrderedScan(const std::string& name,
	                                      const std::vector<PointXYZI>& scan, int azimuthSteps,
	                                      double minRange_m, double maxRange_m);
	/** "hdl64", "hdl64e" or "vlp16"; throws std::invalid_argument listing them otherwise. */
	static LidarModel byName(const std::string& name);

	const std::string& name() const { return name_; }
	/** Ascending, degrees. */
	const std::vector<double>& elevationsDeg() const { return elevationsDeg_; }
	/** Height of each beam's origin in the sensor frame (same order; zeros unless measured). */
	const std::vector<double>& originHeights_m() const { return originHeights_; }
	int beamCount() const { return static_cast<int>(elevationsDeg_.size()); }
	int azimuthSteps() const { return azimuthSteps_; }
	double azimuthStepDeg() const { return 360.0 / azimuthSteps_; }
	double minRange_m() const { return minRange_; }
	double maxRange_m() const { return maxRange_; }
	int raysPerScan() const { return beamCount() * azimuthSteps_; }

   private:
	std::string name_;
	std::vector<double> elevationsDeg_;
	std::vector<double> originHeights_;
	int azimuthSteps_;
	double minRange_, maxRange_;
};

}  // namespace rasterslam::sim
