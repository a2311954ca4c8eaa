// Point-to-plane ICP between two point clouds (a scan against the previous one, or against a
// map): voxel reduction, normals from the neighbours, Gauss-Newton with a Huber weight, and
// how well the result is pinned down (overlap and the smallest eigenvalue of the normal
// matrix), so that a caller can refuse a degenerate alignment (flat ground, a corridor).
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "rasterslam/core/types.h"

namespace rasterslam::features
{
struct IcpParams
{
	double voxel_m = 0.4;              //!< both clouds are reduced to one point a voxel
	double maxCorrespondence_m = 1.0;  //!< farther pairs are not matched
	double inlier_m = 0.3;             //!< a point this close counts for the overlap
	double huber_m = 0.1;              //!< residuals above this are down-weighted
	int maxIterations = 30;
	int normalNeighbours = 10;  //!< points the target's normals are fitted to
	double minPlanarity = 0.7;  //!< 1 - 3 * smallest / sum of eigenvalues, else no normal
	/** Converged when a step is below both, or when the pose is back within both of where it
	 *  was two to four steps before (correspondences flipping back and forth). */
	double convergedTranslation_m = 1e-4;
	double convergedRotation_rad = 1e-5;
	/** Rotation is weighed by its effect at this distance (a street scan's scale); 0: at the
	 *  RMS distance of the points used (scale-free: indoors, where walls are 3-5 m away, a
	 *  fixed 10 m makes every rotation look weakly pinned). */
	double lever_m = 10.0;
};

struct IcpResult
{
	bool converged = false;
	int iterations = 0;
	/** The source's pose in the target's frame (maps source points onto the target). */
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	std::size_t sourcePoints = 0;  //!< after the voxel reduction
	std::size_t matched = 0;       //!< source points with a plane within inlier_m at the end
	double overlap = 0;            //!< matched / sourcePoints
	/** Normal matrix sum of [n; p x n][n; p x n]^T over the matched points, order
	 *  (x y z rx ry rz), rotation in radians. H / sigma^2 is the information of T. */
	Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
	/** Smallest eigenvalue of H with rotation scaled by lever_m, per matched point: about 0
	 *  when some motion is not pinned (ground alone: x, y, yaw), up to 1/3. */
	double constraint = 0;
};

/** The target of an alignment, prepared once (voxel reduction, k-d tree) so that several
 *  sources can be aligned on it: the scans tracked against one keyframe. A point's normal is
 *  fitted the first time an alignment reaches it and kept: one target is not to be used by
 *  two threads at once. */
class IcpTarget
{
   public:
	IcpTarget(const std::vector<Eigen::Vector3f>& pts, const IcpParams& params);
	~IcpTarget();
	IcpTarget(const IcpTarget&) = delete;
	IcpTarget& operator=(const IcpTarget&) = delete;
	std::size_t size() const;
	struct Impl;
	const Impl& impl() const { return *impl_; }

   private:
	std::unique_ptr<Impl> impl_;
};

/** The last few targets made, each under a caller's key and a fingerprint of its points:
 *  a target is made again only when no cached one has both (the loop refinement aligns the
 *  keyframes of a revisit, one after the other, on the same local maps). Not thread-safe:
 *  a caller that shares it locks around get() and the alignments on what it returns. */
class IcpTargetCache
{
   public:
	IcpTargetCache(std::size_t capacity, const IcpParams& params);
	/** The target under `key` made of `points()`, from the cache when `fingerprint` is that
	 *  of the cached one's points (else made, the least recently used dropped). */
	std::shared_ptr<const IcpTarget> get(
	    uint64_t key, uint64_t fingerprint,
	    const std::function<std::vector<Eigen::Vector3f>()>& points);
	std::size_t size() const { return entries_.size(); }
	std::size_t made() const { return made_; }  //!< targets made so far

   private:
	struct Entry
	{
		uint64_t key = 0, fingerprint = 0;
		std::shared_ptr<const IcpTarget> target;
	};
	std::size_t capacity_;
	IcpParams params_;
	std::vector<Entry> entries_;  //!< most recently used first
	std::size_t made_ = 0;
};

/** One point per occupied voxel (the mean of its points). */
std::vector<Eigen::Vector3f> voxelDownsample(const std::vector<Eigen::Vector3f>& pts,
                                             double voxel_m);
/** A scan's points within `range_m` of its origin, one point per occupied voxel: the surface
 *  a scan is registered with (loop refinement) and the one a local map keeps. */
std::vector<Eigen::Vector3f> voxelDownsample(const std::vector<PointXYZI>& pts, double voxel_m,
                                             double range_m);

/** Aligns `source` on `target` from `initial` (source pose in the target's frame). */
IcpResult icpPointToPlane(const std::vector<Eigen::Vector3f>& source,
                          const std::vector<Eigen::Vector3f>& target,
                          const Eigen::Isometry3d& initial, const IcpParams& params = {});
/** The same on a prepared target (made with the same params). */
IcpResult icpPointToPlane(const std::vector<Eigen::Vector3f>& source, const IcpTarget& target,
                          const Eigen::Isometry3d& initial, const IcpParams& params = {});

/** How well `source` at pose T lies on `target` (overlap, normal matrix, constraint), for an
 *  alignment made elsewhere (another registration's result); `converged` stays false. */
IcpResult assessAlignment(const std::vector<Eigen::Vector3f>& source, const IcpTarget& target,
                          const Eigen::Isometry3d& T, const IcpParams& params = {});

}  // namespace rasterslam::features
