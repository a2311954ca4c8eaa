// RANSAC ground-plane detection (paper, "Laser Pose Estimation": the rings a multi-beam LiDAR
// draws on the ground become outliers once projected, so the ground is removed first).
#pragma once

#include <rasterslam/core/types.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

namespace rasterslam::raster
{
struct GroundParams
{
	/** Only points below this height (sensor frame, m) and within this horizontal range are
	 *  candidates: the ground near the vehicle. */
	double candidateMaxZ_m = -1.0;
	double candidateMaxRange_m = 30.0;
	/** A sensor mounted lower than candidateMaxZ_m assumes (a small robot), or points in a
	 *  vehicle frame whose origin is on the ground, put the ground above that bound. When
	 *  under 10 % of the scan's points 2.5 to candidateMaxRange_m away lie below the bound (a
	 *  ground there holds far more) and the top of their lowest dense layer of heights (0.2 m
	 *  bins; the lowest holding 30 % of the fullest one's points) lies above it, the bound is
	 *  raised to this much above that top, at most to 1 m above the origin, and candidates
	 *  nearer than 2.5 m (the vehicle's own returns) are left out. A layer whose top lies
	 *  more than 1 m above the origin (a ceiling) raises nothing. Otherwise nothing changes.
	 *  0: the bound fixed. */
	double layerMargin_m = 0.3;
	/** The plane is fitted on at most this many candidates (an even subsample). */
	int maxCandidates = 1500;
	int iterations = 60;
	/** Inlier distance to the plane, m. */
	double inlierThreshold_m = 0.15;
	/** Reject hypotheses whose normal is tilted more than this from the sensor's z axis. */
	double maxTilt_deg = 20.0;
};

/** A plane n.p + d = 0 with n a unit vector pointing up: n.p + d is the height above it. */
struct Plane
{
	Eigen::Vector3f n = Eigen::Vector3f::UnitZ();
	float d = 0;
	bool valid = false;
	int inliers = 0;  //!< among the candidates
	float height(const PointXYZI& p) const { return n.x() * p.x + n.y() * p.y + n.z() * p.z + d; }
};

/** Fits the ground plane by RANSAC on a subsample of candidate points, then refines it by
 *  least squares on the inliers. Deterministic for a given seed. Returns valid=false when
 *  there are fewer than 3 candidates or no hypothesis passes the tilt check. */
Plane fitGroundPlane(const std::vector<PointXYZI>& pts, const GroundParams& p, uint32_t seed);

/** Height, roll and pitch of a pose from two ground planes. Features on an elevation image
 *  fix x, y and yaw well and the other three poorly; the ground planes of both scans fix those
 *  (as LeGO-LOAM's two-step fit does). T_ref_cur (the current scan's pose in the reference
 *  scan's frame) is turned by the smallest rotation that maps the current ground normal onto
 *  the reference's, then moved along the normal until both planes coincide. Planes as in
 *  Plane (n.p + d = 0, n unit and up), each in its scan's frame. Returns nullopt when that
 *  rotation exceeds maxCorrection_deg (a change of slope between the two places, or a wrong
 *  estimate); `correction_deg`, when given, receives its angle either way. */
std::optional<Eigen::Isometry3d> alignGroundPlanes(const Eigen::Isometry3d& T_ref_cur,
                                                   const Eigen::Vector3d& nRef, double dRef,
                                                   const Eigen::Vector3d& nCur, double dCur,
                                                   double maxCorrection_deg,
                                                   double* correction_deg = nullptr);

}  // namespace rasterslam::raster
