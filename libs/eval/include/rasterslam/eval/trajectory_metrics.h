// Trajectory error metrics: ATE after SE(3) alignment, RPE, KITTI-devkit relative errors.
#pragma once

#include <rasterslam/io/trajectory_io.h>

#include <optional>
#include <string>
#include <vector>

namespace rasterslam::eval
{
using io::Trajectory;

/** Pairs of indices (gt, est) of poses that describe the same instant. */
struct Association
{
	std::vector<std::size_t> gt, est;
};

/** By index when `byIndex` (both trajectories must then have the same length, else throws),
 *  otherwise by nearest time stamp within maxDt seconds. */
Association associate(const Trajectory& gt, const Trajectory& est, bool byIndex,
                      double maxDt = 0.02);

struct AteResult
{
	std::size_t n = 0;
	double rmse_m = 0, mean_m = 0, median_m = 0, max_m = 0;
	/** The rigid alignment applied to the estimate (Umeyama, no scale). */
	Eigen::Isometry3d T_gt_est = Eigen::Isometry3d::Identity();
};
/** Absolute trajectory error of associated poses after the best SE(3) alignment, or after a
 *  given one (`fixed`: e.g. the alignment of another session of the same map, so that
 *  sessions are judged in one common frame). */
AteResult computeAte(const Trajectory& gt, const Trajectory& est, const Association& a,
                     const std::optional<Eigen::Isometry3d>& fixed = std::nullopt);

struct RpeResult
{
	std::size_t n = 0;  //!< number of consecutive pairs
	double trans_rmse_m = 0, trans_mean_m = 0;
	double rot_rmse_deg = 0, rot_mean_deg = 0;
	/** Rotation drift by axis: the frame-to-frame rotation errors (dG^-1 dE, as rotation
	 *  vectors in the later true frame: x roll, y pitch, z yaw for a vehicle frame) added
	 *  up, in degrees per 100 m of the ground truth's path (0 when it does not move). A bias in
	 *  one axis shows here, where the per-frame RMS mixes it with noise. */
	Eigen::Vector3d rot_drift_deg_per_100m = Eigen::Vector3d::Zero();
};
/** Relative pose error between consecutive associated poses (per frame). */
RpeResult computeRpe(const Trajectory& gt, const Trajectory& est, const Association& a);

struct KittiSegmentError
{
	double length_m = 0;
	std::size_t count = 0;
	double t_err_pct = 0, r_err_deg_per_m = 0;
};
struct KittiRelativeResult
{
	std::size_t count = 0;       //!< number of segments over all lengths
	double t_err_pct = 0;        //!< mean translation error, % of segment length
	double r_err_deg_per_m = 0;  //!< mean rotation error, degrees per metre
	std::vector<KittiSegmentError> perLength;
};
/** The KITTI odometry devkit's metric: for every first frame (every `step` frames) and every
 *  segment length, the error of the relative motion to the first frame whose path distance
 *  from it reaches the length, divided by the length; averaged over all segments. */
KittiRelativeResult computeKittiRelative(const Trajectory& gt, const Trajectory& est,
                                         const Association& a, const std::vector<double>& lengths_m,
                                         std::size_t step = 10);

/** The devkit's trajectoryDistances over the associated ground-truth poses: element k is the
 *  path length from the first associated pose to the k-th (size = number of pairs). */
std::vector<double> trajectoryDistances(const Trajectory& gt, const Association& a);

/** Inverse through the full 3x3 inverse, not R^T, as the devkit's Matrix::inv: KITTI's 7-digit
 *  rotations are orthonormal only to ~1e-7, which R^T turns into visible rotation errors. */
Eigen::Isometry3d fullInverse(const Eigen::Isometry3d& T);

/** Rotation angle of a pose in radians, by the devkit's formula
 *  acos(max(min(0.5 * (trace(R) - 1), 1), -1)). */
double rotationAngle(const Eigen::Isometry3d& T);

/** "10:80:10" -> {10,20,...,80} (start:end:step, end included); a comma list "10,20,40" or
 *  one number are accepted too. Throws std::invalid_argument on a malformed spec. */
std::vector<double> parseSegmentSpec(const std::string& spec);

}  // namespace rasterslam::eval
