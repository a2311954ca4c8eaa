// Local bundle adjustment of a finished local map (paper, "Mapping", equations (3)-(4)):
// features of the keyframes are associated into tracks by their descriptors, then the
// keyframe poses and the tracked points are refined together. An observation is the 3D point
// the LiDAR measured behind a feature's pixel, in its keyframe's frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rasterslam::mapping
{
/** One keyframe of the local map as BA sees it. */
struct BaFrame
{
	const uint8_t* descriptors = nullptr;  //!< n x 32 bytes (ORB)
	const float* xyz = nullptr;  //!< n x 3, the 3D point of each feature in the keyframe's frame
	std::size_t n = 0;
	/** Initial pose in the anchor's frame. */
	Eigen::Isometry3d T_anchor_frame = Eigen::Isometry3d::Identity();
};

struct LocalBaParams
{
	int maxHamming = 64;  //!< descriptor distance for a match, bits
	float ratio = 0.9f;   //!< Lowe ratio (1 disables)
	/** Two features are the same point only if their positions, predicted with the initial
	 *  poses, are closer than this (m; 0 disables the gate). */
	double gate_m = 1.0;
	/** Noise of a feature's 3D point in its keyframe's frame (z: the highest point of a cell is
	 *  the noisy axis). */
	double sigmaXY_m = 0.1, sigmaZ_m = 0.2;
	double huber = 2.0;  //!< Huber threshold in sigmas (<= 0: plain least squares)
	int maxIterations = 20;
	/** Refine only the horizontal position and heading of the keyframes (x, y, yaw about the
	 *  anchor's vertical); height, roll and pitch stay as given. Elevation-image features
	 *  locate a point well across the ground and poorly in height (the highest point of a
	 *  cell depends on which beam reaches it), so their z cannot correct roll and pitch. */
	bool planar = false;
};

struct LocalBaResult
{
	/** False: nothing to adjust (fewer than 2 frames, no point seen twice, no frame linked to
	 *  frame 0 by 3 tracked points) or the solver failed; poses are then the initial ones. */
	bool ran = false;
	/** Refined, one per input frame; [0] is the anchor and stays identity-fixed as given. */
	std::vector<Eigen::Isometry3d> T_anchor_frame;
	/** Map points in the anchor frame: one per track (a feature seen by several keyframes is
	 *  one point), plus every feature seen once. */
	std::vector<Eigen::Vector3f> points;
	/** 32 bytes a point (of the observation in the lowest-index frame). */
	std::vector<uint8_t> descriptors;
	std::vector<uint32_t> observers;  //!< bit k set: seen by frame k (so at most 32 frames)
	/** Per frame, per feature: its index in `points`, or -1 when it was left out (its track
	 *  held two features of one frame). */
	std::vector<std::vector<int>> pointOfFeature;
	std::size_t tracks = 0;  //!< points seen by 2 or more frames
	/** Tracks dropped, with their features, for holding two features of one frame. */
	std::size_t ambiguousTracks = 0;
	/** Frames kept at their initial pose although they observe tracks: not linked to frame 0
	 *  by tracks (their pose would be free) or seeing fewer than 3 tracked points. */
	std::size_t heldFrames = 0;
	std::size_t observations = 0;  //!< residual blocks
	int iterations = 0;
	/** RMS 3D residual (m, unweighted) of the tracked observations, before and after. */
	double initialRms_m = 0, finalRms_m = 0;
	std::string message;
};

/** Local BA (paper, eqs. 3-4): jointly refines the keyframe poses (frame 0 fixed) and the
 *  points seen by several of them, minimising robust (Huber) Mahalanobis 3D point residuals.
 *  Deterministic. Throws std::invalid_argument for more than 32 frames or null pointers with
 *  n > 0. */
LocalBaResult localBundleAdjustment(const std::vector<BaFrame>& frames, const LocalBaParams& p);

}  // namespace rasterslam::mapping
