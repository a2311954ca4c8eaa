// Basic data types shared by every stage of the pipeline.
#pragma once

#include <mrpt/poses/CPose3D.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace rasterslam
{
/** One LiDAR return, metres in the vehicle frame; intensity as the sensor reports it. */
struct PointXYZI
{
	float x = 0, y = 0, z = 0, intensity = 0;
};

/** One 3D scan as it leaves a ScanSource. */
struct Scan
{
	/** Position of the scan in its input (0-based, counts only scans). */
	std::size_t index = 0;
	/** Time stamp, seconds (mrpt::Clock::toDouble of the observation's stamp). */
	double stamp = 0;
	/** Sensor label from the rawlog (e.g. "LIDAR"). */
	std::string sensorLabel;
	/** Points in the vehicle frame: the observation's sensorPose is already applied. */
	std::vector<PointXYZI> points;
	/** Pose of the vehicle frame in the world, when the input carries ground truth. */
	std::optional<mrpt::poses::CPose3D> groundTruth;
	/** Motion since the previous scan measured by another odometry in the input (wheel or
	 *  visual odometry: CActionRobotMovement2D/3D, CObservationOdometry), with its
	 *  covariance (all zero when the input gives none). */
	std::optional<mrpt::poses::CPose3DPDFGaussian> odometryIncrement;
};

}  // namespace rasterslam
