// Rigid transform between matched 3D points: RANSAC over 3-point samples, each solved in
// closed form (paper, equation (2): minimise sum |q_i - R p_i - t|^2), then refitted on the
// inliers.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace rasterslam::features
{
struct RansacParams
{
	double inlierThreshold_m = 0.3;
	int maxIterations = 300;
	double confidence = 0.999;
	int minInliers = 20;
	/** Refit on the inliers, re-select inliers, this many times. */
	int refinements = 3;
};

struct RigidResult
{
	bool ok = false;
	/** q = T * p for the inlier pairs (T maps the first set's frame into the second's). */
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	std::vector<int> inliers;  //!< indices of the pairs
	int iterations = 0;
	double rmse_m = 0;  //!< over the inliers
};

/** Closed-form least-squares rigid fit (no scale) of q = T p over the given pairs. */
bool fitRigid(const std::vector<Eigen::Vector3f>& p, const std::vector<Eigen::Vector3f>& q,
              const std::vector<int>& idx, Eigen::Isometry3d& T);

/** RANSAC rigid fit of q_i = T p_i. The iteration count adapts to the inlier ratio found
 *  so far (never dividing by zero when a hypothesis has no inliers). Deterministic for a
 *  seed. `ok` is false when fewer than minInliers pairs agree. */
RigidResult ransacRigid(const std::vector<Eigen::Vector3f>& p,
                        const std::vector<Eigen::Vector3f>& q, const RansacParams& prm,
                        uint32_t seed);

/** How refitRobust weighs the inlier pairs of a rigid fit. */
struct RobustRefitParams
{
	/** Weight of a residual's squared z component against x's and y's (1: all alike; the z
	 *  component is scaled by its square root). The heights of
	 *  features found on an elevation image are biased: a pixel keeps the highest point a beam
	 *  reached, which changes with the range a wall or tree is seen from. */
	double zWeight = 1.0;
	/** Cauchy scale of the (weighed) residuals, m: a pair this far off counts half; 0: least
	 *  squares, every inlier alike. */
	double cauchy_m = 0.0;
	int iterations = 10;  //!< Gauss-Newton steps at most
};

/** Refits r.T on r's inlier pairs (q = T p): Gauss-Newton on SE(3) minimising the Cauchy
 *  loss of the residuals T p - q, each with its squared z component weighed by zWeight,
 *  started from r.T; then selects the inliers again (prm.inlierThreshold_m) and sets rmse_m.
 *  Nothing changes (false) when r is not ok or has fewer than 6 inliers, when the solve
 *  leaves no finite pose or a larger loss than r.T's, or when fewer than prm.minInliers
 *  inliers would remain: r stays RANSAC's fit, still ok. */
bool refitRobust(const std::vector<Eigen::Vector3f>& p, const std::vector<Eigen::Vector3f>& q,
                 const RobustRefitParams& refit, const RansacParams& prm, RigidResult& r);

/** Information matrix (6x6, MRPT order x y z yaw pitch roll) of a pose estimated from
 *  point-to-point residuals with isotropic noise sigma_m at the given points (in the frame
 *  the pose moves). */
Eigen::Matrix<double, 6, 6> pointToPointInformation(const std::vector<Eigen::Vector3f>& pts,
                                                    const std::vector<int>& idx, double sigma_m);

}  // namespace rasterslam::features
