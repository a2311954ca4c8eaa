// Trajectory files: TUM ("t x y z qx qy qz qw") and KITTI (12 numbers of a row-major 3x4).
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace rasterslam::io
{
struct StampedPose
{
	/** Seconds; for a KITTI file without a times file, the line index. */
	double stamp = 0;
	/** Pose of the body in the world (T_world_body). */
	Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};
using Trajectory = std::vector<StampedPose>;

enum class TrajectoryFormat
{
	Auto,  //!< by the number of columns: 8 is TUM, 12 is KITTI
	Tum,
	Kitti
};

/** Reads a trajectory. Blank lines and lines starting with '#' are skipped. Throws
 *  std::runtime_error naming the file and line on a wrong column count, a non-number, a
 *  non-finite value or a rotation that is not orthonormal (|R^T R - I| > 1e-3). */
Trajectory loadTrajectory(const std::string& path, TrajectoryFormat fmt = TrajectoryFormat::Auto,
                          TrajectoryFormat* detected = nullptr);

/** Writes a file atomically (temporary name, then rename); throws naming the file. */
void saveTrajectoryTum(const std::string& path, const Trajectory& traj);
void saveTrajectoryKitti(const std::string& path, const Trajectory& traj);
/** The text those functions write. */
std::string formatTrajectoryTum(const Trajectory& traj);
std::string formatTrajectoryKitti(const Trajectory& traj);
/** One line of each (with its newline), appended to `out`: for writers that stream a long
 *  trajectory instead of holding its whole text. */
void appendTumLine(std::string& out, const StampedPose& sp);
void appendKittiLine(std::string& out, const Eigen::Isometry3d& pose);
/** The TUM file's header line, with its newline. */
inline constexpr const char* kTumHeader = "# timestamp tx ty tz qx qy qz qw\n";

/** Reads the `Tr:` line (Velodyne -> cam0) of a KITTI calib.txt as an isometry. */
Eigen::Isometry3d loadKittiCalibTr(const std::string& calibPath);

/** Reads KITTI's times.txt (one number a line). */
std::vector<double> loadKittiTimes(const std::string& path);

/** Converts KITTI cam0 poses into Velodyne-frame poses: inv(Tr) * P_i * Tr. */
Trajectory kittiCameraToVelodyne(const Trajectory& camPoses, const Eigen::Isometry3d& Tr);

/** Writes text to `path` through a temporary file in the same folder and a rename. */
void writeFileAtomically(const std::string& path, const std::string& contents);

}  // namespace rasterslam::io
