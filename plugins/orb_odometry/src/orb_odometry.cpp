// The paper's laser pose estimation: ORB features on the elevation image, matched against the
// last keyframe, RANSAC, back-projection to 3D and the closed-form rigid fit of equation (2);
// point-to-plane ICP on the points when the features fail.
#include <mrpt/core/initializer.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/features/icp.h>
#include <rasterslam/features/matcher.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/features/rigid_ransac.h>
#include <rasterslam/map/registration.h>
#include <rasterslam/raster/elevation_image.h>
#include <rasterslam/raster/ground_grid.h>

#include <Eigen/Dense>
#include <chrono>
#include <cmath>
#include <deque>
#include <memory>

namespace rasterslam
{
class OrbOdometry : public Odometry
{
	DEFINE_MRPT_OBJECT(OrbOdometry, rasterslam)

   public:
	OdometryResult process(const Scan& scan, const RasterFrame* raster) override;

   protected:
	void initializeImpl(ParamReader& p) override;

   private:
	struct Frame
	{
		std::vector<cv::KeyPoint> kps;
		cv::Mat desc;
		std::vector<Eigen::Vector3f> pts;
		bool groundValid = false;  //!< the rasterizer's ground plane n.p + d = 0
		Eigen::Vector3d groundN = Eigen::Vector3d::UnitZ();
		double groundD = 0;
		raster::GroundGrid grid;  //!< ground_model: grid
	};
	/** T_ref_cur with z, roll and pitch from the ground planes of both frames; none when
	 *  either has no plane or the correction is refused. `prior` (the motion model's
	 *  T_ref_cur), when given, decides a large correction: see the definition. */
	std::optional<Eigen::Isometry3d> alignPlanes(const Eigen::Isometry3d& T_ref_cur,
	                                             const Frame& ref, const Frame& cur,
	                                             const Eigen::Isometry3d* prior) const;
	/** The same, then (ground_model: grid) the same patches of ground matched. */
	Eigen::Isometry3d alignGround(const Eigen::Isometry3d& T_ref_cur, const Frame& ref,
	                              const Frame& cur, const Eigen::Isometry3d* prior) const;
	void extract(const Scan& scan, const RasterFrame& raster, Frame& f);
	/** Features of `cur` matched to those of `ref` and fitted by RANSAC; `minInliers` (at
	 *  least 3) stands in for min_inliers when given. */
	features::RigidResult track(const Frame& ref, const Frame& cur, const Eigen::Isometry3d& prior,
	                            bool gated, std::size_t seed, int minInliers = -1);
	Keyframe::Ptr keyframeOf(const Frame& f) const;
	using Cloud = std::vector<Eigen::Vector3f>;
	/** Every fallback_stride-th point of the scan within the fallback's range. */
	void sampleInto(const Scan& scan, Cloud& out) const;
	struct Recovery
	{
		Eigen::Isometry3d T_prev_curr;
		Eigen::Matrix<double, 6, 6> information;  //!< x y z yaw pitch roll (MRPT's order)
	};
	/** Lost by the features: registers the scan's points on the previous scan's
	 *  (point-to-plane ICP from each start; the converged one with the most overlap). None
	 *  when none converges,
	 *  overlaps too little, or the geometry leaves some motion free; when it leaves one
	 *  only, `weak` (when given) receives the registration, for the features to confirm. */
	std::optional<Recovery> fallback(const Cloud& cur, const std::vector<Eigen::Isometry3d>& starts,
	                                 std::string& why,
	                                 std::optional<Recovery>* weak = nullptr) const;
	/** Whether a registration leaves one motion weakly pinned and no more: the second
	 *  smallest eigenvalue of its normal matrix, scaled as its constraint, reaches
	 *  fallback_min_constraint (flat ground leaves three: x, y and yaw). */
	bool oneWeakDirection(const features::IcpResult& icp, const Cloud& cur) const;

	features::OrbParams orbParams_;
	features::MatchParams match_;
	features::RansacParams ransac_;
	/** refit_z_weight, refit_cauchy_m: the RANSAC fit refitted on its inliers with the
	 *  features' heights weighed less and a Cauchy loss (both off by default). */
	features::RobustRefitParams refit_;
	int kfMinFrames_ = 5, kfMinShared_ = 100, kfMaxFrames_ = 20;
	int weakInliers_ = 30;
	double maxStep_m_ = 5.0, sigma_m_ = 0.1;
	bool constantVelocity_ = true;
	bool alignGround_ = true;
	double groundMaxCorrection_deg_ = 2.0;
	bool groundMotionCheck_ = false;  //!< ground_motion_check
	/** ground_model: plane (the two RANSAC planes made parallel) or grid (then the ground
	 *  heights of the same patches matched, see raster/ground_grid.h). */
	bool groundGrid_ = false;
	raster::GroundGridParams gridParams_;
	bool fallback_ = true;  //!< lost_fallback: icp
	int fallbackStride_ = 4;
	features::IcpParams icp_;
	double fallbackMinOverlap_ = 0.4, fallbackMaxRange_m_ = 60.0, fallbackMinConstraint_ = 0.02;
	/** fallback_confirm_inliers: a registration below fallback_min_constraint is taken when
	 *  this many features, matched around where it puts them, fit a pose within
	 *  ransac_threshold_m and kConfirmDeg of it (0: never). */
	int fallbackConfirmInliers_ = 12;
	static constexpr double kConfirmDeg = 1.0;
	Cloud prevCloud_;  //!< sample of the previous scan (fallback on; empty: none)
	Cloud sample_;     //!< this scan's (a buffer kept between scans)
	/** refine: after the features' estimate, ICP of the scan's points on the keyframe's;
	 *  its rotation (Rotation) or its whole pose (Pose) replaces the estimate's. */
	enum class Refine
	{
		None,
		Rotation,
		Pose
	};
	Refine refine_ = Refine::None;
	features::IcpParams refineIcp_;
	/** refine_keyframes: the refinement's target holds the points of this many keyframes, the
	 *  current one and those before it, each put in the current keyframe's frame by the
	 *  odometry (a local map): one keyframe alone lets its errors chain into a drift (handheld
	 *  walk: ATE 0.099 m with 1, 0.034 m with 10; plugin README, "Refinement"). */
	int refineKeyframes_ = 10;
	/** refine_frames: keyframes (only the frames that become keyframes are refined: the others
	 *  are not built upon, so their errors do not chain) or all. */
	bool refineAll_ = true;
	double refineMinOverlap_ = 0.2;  //!< refine_min_overlap (VLP-16: 0.4 refused every one)
	std::deque<Cloud> refineMap_;  //!< per keyframe, oldest first, in the current keyframe's frame
	std::unique_ptr<features::IcpTarget> kfTarget_;  //!< refineMap_'s points (refine on)
	/** A frame since the keyframe was lost and kept no keyframe (too few features): the
	 *  pose chain to the next keyframe rests on its guess, so the local map restarts there. */
	bool guessSinceKf_ = false;
	/** A new keyframe at `T_old_new` from the previous one (nullptr: the chain is broken, the
	 *  local map restarts), whose points are `pts`: the refinement's target made anew. */
	void advanceRefineMap(const Eigen::Isometry3d* T_old_new, const Cloud& pts);

	std::unique_ptr<features::OrbExtractor> orb_;
	std::unique_ptr<Frame> kf_;
	std::shared_ptr<Frame> prev_;  //!< the previous frame, when it is not the keyframe
	Eigen::Isometry3d T_kf_prev_ = Eigen::Isometry3d::Identity();
	Eigen::Isometry3d velocity_ = Eigen::Isometry3d::Identity();
	int sinceKf_ = 0;
};
}  // namespace rasterslam

using namespace rasterslam;

IMPLEMENTS_MRPT_OBJECT(OrbOdometry, Odometry, rasterslam)

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_plugin_orb_odometry)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::OrbOdometry));
}

void OrbOdometry::initializeImpl(ParamReader& p)
{
	features::OrbParams o;
	o.numFeatures = p.getInt("num_features", 2000);
	o.gridCols = p.getInt("grid_cols", o.gridCols);
	o.gridRows = p.getInt("grid_rows", o.gridRows);
	o.fastThreshold = p.getInt("fast_threshold", o.fastThreshold);
	o.minFastThreshold = p.getInt("min_fast_threshold", o.minFastThreshold);
	o.levels = p.getInt("scale_levels", o.levels);
	const double scaleFactor = p.getDouble("scale_factor", o.scaleFactor);
	o.patchSize = p.getInt("patch_size", o.patchSize);
	o.edgeThreshold = o.patchSize;
	match_.maxDistance = p.getInt("max_hamming", 64);
	match_.ratio = static_cast<float>(p.getDouble("ratio", 1.0));
	match_.gateRadius_m = static_cast<float>(p.getDouble("gate_m", 3.0));
	ransac_.inlierThreshold_m = p.getDouble("ransac_threshold_m", 0.3);
	ransac_.maxIterations = p.getInt("ransac_max_iterations", 300);
	ransac_.confidence = p.getDouble("ransac_confidence", 0.999);
	ransac_.minInliers = p.getInt("min_inliers", 20);
	ransac_.refinements = p.getInt("refinements", 3);
	refit_ = features::RobustRefitParams();
	refit_.zWeight = p.getDouble("refit_z_weight", refit_.zWeight);
	refit_.cauchy_m = p.getDouble("refit_cauchy_m", refit_.cauchy_m);
	kfMinFrames_ = p.getInt("keyframe_min_frames", kfMinFrames_);
	kfMinShared_ = p.getInt("keyframe_min_shared", kfMinShared_);
	kfMaxFrames_ = p.getInt("keyframe_max_frames", kfMaxFrames_);
	weakInliers_ = p.getInt("weak_inliers", weakInliers_);
	maxStep_m_ = p.getDouble("max_step_m", maxStep_m_);
	sigma_m_ = p.getDouble("point_sigma_m", sigma_m_);
	constantVelocity_ = p.getBool("constant_velocity", constantVelocity_);
	alignGround_ = p.getBool("align_ground", alignGround_);
	groundMaxCorrection_deg_ = p.getDouble("ground_max_correction_deg", groundMaxCorrection_deg_);
	groundMotionCheck_ = p.getBool("ground_motion_check", groundMotionCheck_);
	groundGrid_ = p.getChoice("ground_model", "plane", {"plane", "grid"}) == "grid";
	gridParams_ = raster::GroundGridParams();
	gridParams_.cell_m = p.getDouble("ground_cell_m", gridParams_.cell_m);
	gridParams_.radius_m = p.getDouble("ground_radius_m", gridParams_.radius_m);
	gridParams_.stride = p.getInt("ground_stride", gridParams_.stride);
	p.requireRange(gridParams_.cell_m, 0.05, 20, "ground_cell_m");
	p.requireRange(gridParams_.radius_m, 1, 500, "ground_radius_m");
	p.requireRange(gridParams_.stride, 1, 1000, "ground_stride");
	p.require(gridParams_.radius_m / gridParams_.cell_m <= 2000, gridParams_.radius_m,
	          "ground_radius_m", "must be at most 2000 cells (ground_cell_m) from the sensor");
	fallback_ = p.getChoice("lost_fallback", "icp", {"icp", "none"}) == "icp";
	const auto refine = p.getChoice("refine", "none", {"none", "rotation", "pose"});
	refine_ =
	    refine == "none" ? Refine::None : (refine == "rotation" ? Refine::Rotation : Refine::Pose);
	fallbackStride_ = p.getInt("fallback_stride", fallbackStride_);
	icp_ = features::IcpParams();
	icp_.voxel_m = p.getDouble("fallback_voxel_m", icp_.voxel_m);
	icp_.maxCorrespondence_m =
	    p.getDouble("fallback_max_correspondence_m", icp_.maxCorrespondence_m);
	icp_.inlier_m = p.getDouble("fallback_inlier_m", icp_.inlier_m);
	icp_.lever_m = p.getDouble("icp_lever_m", icp_.lever_m);
	p.requireAtLeast(icp_.lever_m, 0, "icp_lever_m");
	fallbackMinOverlap_ = p.getDouble("fallback_min_overlap", fallbackMinOverlap_);
	fallbackMaxRange_m_ = p.getDouble("fallback_max_range_m", fallbackMaxRange_m_);
	fallbackMinConstraint_ = p.getDouble("fallback_min_constraint", fallbackMinConstraint_);
	fallbackConfirmInliers_ = p.getInt("fallback_confirm_inliers", fallbackConfirmInliers_);
	p.require(fallbackConfirmInliers_ == 0 ||
	              (fallbackConfirmInliers_ >= 3 && fallbackConfirmInliers_ <= 100000),
	          fallbackConfirmInliers_, "fallback_confirm_inliers",
	          "must be 0 (off) or in [3, 100000]");
	p.requireRange(fallbackStride_, 1, 1000, "fallback_stride");
	p.requireRange(icp_.voxel_m, 0.01, 100, "fallback_voxel_m");
	p.requirePositive(icp_.maxCorrespondence_m, "fallback_max_correspondence_m");
	p.requirePositive(icp_.inlier_m, "fallback_inlier_m");
	p.requireRange(fallbackMinOverlap_, 0, 1, "fallback_min_overlap");
	p.requirePositive(fallbackMaxRange_m_, "fallback_max_range_m");
	p.requireRange(fallbackMinConstraint_, 0, 1, "fallback_min_constraint");
	refineIcp_ = icp_;
	refineIcp_.voxel_m = p.getDouble("refine_voxel_m", 0.8);
	p.requireRange(refineIcp_.voxel_m, 0.01, 100, "refine_voxel_m");
	refineKeyframes_ = p.getInt("refine_keyframes", 10);
	p.requireRange(refineKeyframes_, 1, 50, "refine_keyframes");
	refineAll_ = p.getChoice("refine_frames", "all", {"all", "keyframes"}) == "all";
	refineMinOverlap_ = p.getDouble("refine_min_overlap", 0.2);
	p.requireRange(refineMinOverlap_, 0, 1, "refine_min_overlap");
	refineMap_.clear();
	kfTarget_.reset();
	guessSinceKf_ = false;
	prevCloud_.clear();
	// Upper bounds far beyond use (an elevation image has about 250,000 pixels; OpenCV's ORB
	// defaults to 8 levels): larger values only overflow counts or exhaust memory.
	p.requireRange(o.numFeatures, 1, features::kMaxFeatures, "num_features");
	p.requireRange(o.gridCols, 1, 256, "grid_cols");
	p.requireRange(o.gridRows, 1, 256, "grid_rows");
	p.requireRange(o.fastThreshold, 1, 255, "fast_threshold");  // grey-level difference
	p.require(o.minFastThreshold >= 1 && o.minFastThreshold <= o.fastThreshold, o.minFastThreshold,
	          "min_fast_threshold",
	          "must be in [1, fast_threshold (" + std::to_string(o.fastThreshold) + ")]");
	p.requireRange(o.levels, 1, 32, "scale_levels");
	p.require(scaleFactor > 1 && scaleFactor <= 2, scaleFactor, "scale_factor",
	          "must be in (1, 2]");
	// The smallest pyramid level must keep an image to find corners in.
	p.require(std::pow(scaleFactor, o.levels - 1) <= 32, scaleFactor, "scale_factor",
	          "to the power scale_levels - 1 (" + std::to_string(o.levels - 1) +
	              ") must be at most 32: the smallest pyramid level would be too small");
	o.scaleFactor = static_cast<float>(scaleFactor);
	p.requireRange(o.patchSize, 2, 255, "patch_size");          // OpenCV's ORB needs 2
	p.requireRange(match_.maxDistance, 0, 256, "max_hamming");  // ORB: 256-bit descriptors
	p.require(match_.ratio > 0 && match_.ratio <= 1, match_.ratio, "ratio",
	          "must be in (0, 1] (1 disables the test)");
	p.requireAtLeast(match_.gateRadius_m, 0, "gate_m");
	p.requirePositive(ransac_.inlierThreshold_m, "ransac_threshold_m");
	p.requirePositive(ransac_.maxIterations, "ransac_max_iterations");
	p.require(ransac_.confidence > 0 && ransac_.confidence < 1, ransac_.confidence,
	          "ransac_confidence", "must be in (0, 1)");
	p.requireAtLeast(ransac_.minInliers, 3, "min_inliers");  // a rigid fit takes 3 points
	p.requireAtLeast(ransac_.refinements, 0, "refinements");
	p.requireRange(refit_.zWeight, 0.001, 1, "refit_z_weight");
	p.requireRange(refit_.cauchy_m, 0, 10, "refit_cauchy_m");
	p.requirePositive(kfMinFrames_, "keyframe_min_frames");
	p.requireAtLeast(kfMinShared_, 0, "keyframe_min_shared");
	p.requirePositive(kfMaxFrames_, "keyframe_max_frames");
	p.requireAtLeast(weakInliers_, 0, "weak_inliers");
	p.requirePositive(maxStep_m_, "max_step_m");
	p.requirePositive(sigma_m_, "point_sigma_m");
	p.requireRange(groundMaxCorrection_deg_, 0, 180, "ground_max_correction_deg");
	orbParams_ = o;
	orb_ = std::make_unique<features::OrbExtractor>(o);
	kf_.reset();
	prev_.reset();
	T_kf_prev_.setIdentity();
	velocity_.setIdentity();
	sinceKf_ = 0;
}

void OrbOdometry::extract(const Scan& scan, const RasterFrame& raster, Frame& f)
{
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb_->extract(raster.image.asCvMatRef(), kps, desc);
	f.kps.clear();
	f.pts.clear();
	std::vector<int> keep;
	for (int i = 0; i < static_cast<int>(kps.size()); i++)
	{
		const int32_t idx = raster::pointAtPixel(raster, kps[i].pt.x, kps[i].pt.y, 1);
		if (idx < 0)
			continue;
		const auto& q = scan.points[static_cast<std::size_t>(idx)];
		f.kps.push_back(kps[i]);
		f.pts.emplace_back(q.x, q.y, q.z);
		keep.push_back(i);
	}
	f.groundValid = raster.groundValid;
	f.groundN =
	    Eigen::Vector3d(raster.groundNormal[0], raster.groundNormal[1], raster.groundNormal[2]);
	f.groundD = raster.groundD;
	if (alignGround_ && groundGrid_ && raster.groundValid)
	{
		raster::Plane pl;
		pl.n =
		    Eigen::Vector3f(raster.groundNormal[0], raster.groundNormal[1], raster.groundNormal[2]);
		pl.d = raster.groundD;
		pl.valid = true;
		f.grid.build(scan.points, pl, gridParams_);
	}
	f.desc.create(static_cast<int>(keep.size()), 32, CV_8U);
	for (int r = 0; r < static_cast<int>(keep.size()); r++)
		desc.row(keep[r]).copyTo(f.desc.row(r));
}

features::RigidResult OrbOdometry::track(const Frame& ref, const Frame& cur,
                                         const Eigen::Isometry3d& prior, bool gated,
                                         std::size_t seed, int minInliers)
{
	// Keyframe points predicted into the current frame, for the gate.
	std::vector<Eigen::Vector3f> predicted;
	features::MatchParams mp = match_;
	if (gated)
	{
		const Eigen::Isometry3f inv = prior.inverse().cast<float>();
		predicted.reserve(ref.pts.size());
		for (const auto& q : ref.pts)
			predicted.push_back(inv * q);
	}
	else
		mp.gateRadius_m = 0;
	const auto matches = features::matchMutual(cur.desc, ref.desc, mp, gated ? &cur.pts : nullptr,
	                                           gated ? &predicted : nullptr);
	std::vector<Eigen::Vector3f> p, q;
	p.reserve(matches.size());
	q.reserve(matches.size());
	for (const auto& m : matches)
	{
		p.push_back(cur.pts[m.a]);
		q.push_back(ref.pts[m.b]);
	}
	features::RansacParams rp = ransac_;
	if (minInliers >= 3)
		rp.minInliers = minInliers;
	auto r = features::ransacRigid(p, q, rp, static_cast<uint32_t>(seed * 2 + (gated ? 0 : 1)));
	if (refit_.zWeight != 1.0 || refit_.cauchy_m > 0)
		features::refitRobust(p, q, refit_, rp, r);
	// Express inlier indices in the current frame's feature numbering.
	for (auto& i : r.inliers)
		i = matches[i].a;
	return r;
}

std::optional<Eigen::Isometry3d> OrbOdometry::alignPlanes(const Eigen::Isometry3d& T,
                                                          const Frame& ref, const Frame& cur,
                                                          const Eigen::Isometry3d* prior) const
{
	if (!ref.groundValid || !cur.groundValid)
		return std::nullopt;
	auto aligned = raster::alignGroundPlanes(T, ref.groundN, ref.groundD, cur.groundN, cur.groundD,
	                                         groundMaxCorrection_deg_);
	// A large correction is either a change of slope between the scans (the planes are not
	// the same ground: keep the features' tilt) or the features' tilt being wrong (few
	// inliers, most of them far: a VLP-16 in a turn measured 3.4 deg of roll in one step).
	// The motion model tells them apart: when the planes agree with it, they are right.
	if (!aligned && prior)
	{
		double fromPrior = 0;
		raster::alignGroundPlanes(*prior, ref.groundN, ref.groundD, cur.groundN, cur.groundD, 180,
		                          &fromPrior);
		if (fromPrior <= groundMaxCorrection_deg_)
			aligned = raster::alignGroundPlanes(T, ref.groundN, ref.groundD, cur.groundN,
			                                    cur.groundD, 180);
	}
	return aligned;
}

Eigen::Isometry3d OrbOdometry::alignGround(const Eigen::Isometry3d& T, const Frame& ref,
                                           const Frame& cur, const Eigen::Isometry3d* prior) const
{
	// x, y and yaw from the features, z, roll and pitch from the two ground planes.
	if (!ref.groundValid || !cur.groundValid)
		return T;
	const auto aligned = alignPlanes(T, ref, cur, prior);
	const Eigen::Isometry3d start = aligned ? *aligned : T;  // none: a slope change
	if (!groundGrid_)
		return start;
	// The planes are the best planes through each scan's own surroundings; the same patches
	// of ground seen from both scans decide what is left (a change of slope or camber).
	raster::GroundAlignParams gp;
	gp.maxCorrection_deg = groundMaxCorrection_deg_;
	const auto g = raster::alignGroundGrids(start, ref.grid, cur.grid, gp);
	return g.ok ? g.T : start;
}

Keyframe::Ptr OrbOdometry::keyframeOf(const Frame& f) const
{
	auto k = std::make_shared<Keyframe>();
	const std::size_t n = f.kps.size();
	k->u.resize(n);
	k->v.resize(n);
	k->angle.resize(n);
	k->response.resize(n);
	k->octave.resize(n);
	k->xyz.resize(3 * n);
	k->descriptors.resize(32 * n);
	for (std::size_t i = 0; i < n; i++)
	{
		k->u[i] = f.kps[i].pt.x;
		k->v[i] = f.kps[i].pt.y;
		k->angle[i] = f.kps[i].angle;
		k->response[i] = f.kps[i].response;
		k->octave[i] = static_cast<uint8_t>(f.kps[i].octave);
		for (int c = 0; c < 3; c++)
			k->xyz[3 * i + c] = f.pts[i][c];
		std::memcpy(&k->descriptors[32 * i], f.desc.ptr<uint8_t>(static_cast<int>(i)), 32);
	}
	k->groundValid = f.groundValid;
	for (int c = 0; c < 3; c++)
		k->groundN[c] = static_cast<float>(f.groundN[c]);
	k->groundD = static_cast<float>(f.groundD);
	return k;
}

void OrbOdometry::sampleInto(const Scan& scan, Cloud& c) const
{
	// Filled in place: the two buffers (this scan's, the previous one's) keep their capacity,
	// so a run allocates them once instead of a block of a new size every scan (which the
	// heap does not give back).
	c.clear();
	const double r2max = fallbackMaxRange_m_ * fallbackMaxRange_m_;
	for (std::size_t i = 0; i < scan.points.size(); i += static_cast<std::size_t>(fallbackStride_))
	{
		const auto& q = scan.points[i];
		const double r2 = double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z;
		if (r2 >= 1.0 && r2 <= r2max)  // false for NaN
			c.emplace_back(q.x, q.y, q.z);
	}
}

std::optional<OrbOdometry::Recovery> OrbOdometry::fallback(
    const Cloud& cur, const std::vector<Eigen::Isometry3d>& starts, std::string& why,
    std::optional<Recovery>* weak) const
{
	if (prevCloud_.empty())
	{
		why = "no previous scan";
		return std::nullopt;
	}
	std::optional<features::IcpResult> best;
	int iterations = 0;
	const features::IcpTarget target(prevCloud_, icp_);  // once for every start
	for (const auto& start : starts)
	{
		auto icp = features::icpPointToPlane(cur, target, start, icp_);
		if (icp.sourcePoints < 100)
		{
			why = "too few points (" + std::to_string(icp.sourcePoints) + ")";
			return std::nullopt;
		}
		iterations = std::max(iterations, icp.iterations);
		if (icp.converged && (!best || icp.overlap > best->overlap))
			best = std::move(icp);
	}
	if (!best)
	{
		why = "ICP did not converge in " + std::to_string(iterations) + " iterations from " +
		      std::to_string(starts.size()) + " start(s)";
		return std::nullopt;
	}
	const auto& icp = *best;
	// Overlap: the share of the scan's points near the previous scan's planes. Constraint:
	// a plane pins the motion along its normal only, so ground alone leaves x, y and yaw
	// free, and a corridor its length.
	if (icp.overlap < fallbackMinOverlap_)
	{
		why = "overlap " + std::to_string(icp.overlap) + " below fallback_min_overlap";
		return std::nullopt;
	}
	const bool pinned = icp.constraint >= fallbackMinConstraint_;
	if (!pinned && (!weak || !oneWeakDirection(icp, cur)))
	{
		why = "degenerate geometry (constraint " + std::to_string(icp.constraint) +
		      " below fallback_min_constraint)";
		return std::nullopt;
	}
	Recovery rec;
	rec.T_prev_curr = icp.T;
	// Information of the step: H / sigma^2, reordered to MRPT's (x y z yaw pitch roll) from
	// (x y z rx ry rz).
	Eigen::Matrix<double, 6, 6> S = Eigen::Matrix<double, 6, 6>::Zero();
	const int order[6] = {0, 1, 2, 5, 4, 3};
	for (int a = 0; a < 6; a++)
		S(a, order[a]) = 1.0;
	rec.information = S * icp.H * S.transpose() / (sigma_m_ * sigma_m_);
	why = "overlap " + std::to_string(icp.overlap) + ", constraint " +
	      std::to_string(icp.constraint) + ", " + std::to_string(icp.iterations) + " iterations";
	if (!pinned)
	{
		*weak = rec;
		why = "overlap " + std::to_string(icp.overlap) + ", constraint " +
		      std::to_string(icp.constraint) + " below fallback_min_constraint";
		return std::nullopt;
	}
	return rec;
}

bool OrbOdometry::oneWeakDirection(const features::IcpResult& icp, const Cloud& cur) const
{
	// The normal matrix scaled as the ICP's constraint is (rotation at the lever, per matched
	// point): its second smallest eigenvalue must reach the bound the smallest misses.
	double lever = icp_.lever_m;
	if (!(lever > 0))
	{
		double r2 = 0;
		for (const auto& q : cur)
			r2 += q.cast<double>().squaredNorm();
		lever = std::sqrt(r2 / static_cast<double>(std::max<std::size_t>(cur.size(), 1)));
	}
	if (icp.matched == 0 || !(lever > 0))
		return false;
	Eigen::Matrix<double, 6, 1> D;
	D << 1, 1, 1, 1 / lever, 1 / lever, 1 / lever;
	const Eigen::Matrix<double, 6, 6> Hs =
	    D.asDiagonal() * icp.H * D.asDiagonal() / static_cast<double>(icp.matched);
	const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(Hs);
	return es.info() == Eigen::Success && es.eigenvalues()(1) >= fallbackMinConstraint_;
}

void OrbOdometry::advanceRefineMap(const Eigen::Isometry3d* T_old_new, const Cloud& pts)
{
	if (!T_old_new)
		refineMap_.clear();
	else
	{
		const Eigen::Isometry3f T_new_old = T_old_new->inverse().cast<float>();
		for (auto& c : refineMap_)
			for (auto& q : c)
				q = T_new_old * q;
	}
	refineMap_.push_back(features::voxelDownsample(pts, refineIcp_.voxel_m));
	while (static_cast<int>(refineMap_.size()) > refineKeyframes_)
		refineMap_.pop_front();
	Cloud all;
	std::size_t n = 0;
	for (const auto& c : refineMap_)
		n += c.size();
	all.reserve(n);
	for (const auto& c : refineMap_)
		all.insert(all.end(), c.begin(), c.end());
	kfTarget_ = std::make_unique<features::IcpTarget>(all, refineIcp_);
}

OdometryResult OrbOdometry::process(const Scan& scan, const RasterFrame* raster)
{
	if (!raster)
		throw std::runtime_error(
		    "rasterslam::OrbOdometry needs elevation images: configure a rasterizer (e.g. "
		    "rasterslam::ElevationRasterizer)");
	OdometryResult r;
	auto cur = std::make_unique<Frame>();
	extract(scan, *raster, *cur);

	if (!kf_)
	{
		r.status = TrackingStatus::Initializing;
		r.keyframe = true;
		r.keyframeData = keyframeOf(*cur);
		r.T_kf_curr = mrpt::poses::CPose3D();
		kf_ = std::move(cur);
		T_kf_prev_.setIdentity();
		sinceKf_ = 0;
		if (fallback_ || refine_ != Refine::None)
			sampleInto(scan, prevCloud_);
		if (refine_ != Refine::None)
			advanceRefineMap(nullptr, prevCloud_);
		return r;
	}

	const Eigen::Isometry3d prior =
	    T_kf_prev_ * (constantVelocity_ ? velocity_ : Eigen::Isometry3d::Identity());
	auto est = track(*kf_, *cur, prior, true, scan.index);
	if (!est.ok)
		est = track(*kf_, *cur, prior, false, scan.index);  // the gate may have been wrong
	bool bridged = false;
	if ((!est.ok || static_cast<int>(est.inliers.size()) < weakInliers_) && prev_)
	{
		// The keyframe may be too far behind: bridge through the previous frame, and keep
		// whichever estimate more matches agree with.
		auto viaPrev = track(*prev_, *cur, velocity_, true, scan.index + 7919);
		if (viaPrev.ok && viaPrev.inliers.size() > (est.ok ? est.inliers.size() : 0))
		{
			r.message = "tracked through the previous frame (" +
			            std::to_string(est.ok ? est.inliers.size() : 0) +
			            " inliers against the keyframe, " + std::to_string(viaPrev.inliers.size()) +
			            " against the previous frame)";
			// Roll and pitch from the previous frame's ground plane, itself aligned on the
			// keyframe's: the chain of planes stays unbroken. Left to the features, every
			// bridged frame (the next keyframe) carried their tilt into the trajectory: a
			// VLP-16 on flat ground drifted -2.7 deg per 100 m in pitch, now -0.15. The
			// planes only, not the grid (a grid step is one more relative measurement, and
			// the VLP-16's sparse grid is biased), and the rotation only: the planes' height
			// as well made the de-skewed town-sweep drive worse (ATE 0.24 -> 0.35 m; 0.22 m
			// with the features' translation kept). Plugin README, "Ground alignment".
			if (alignGround_)
				if (const auto a = alignPlanes(viaPrev.T, *prev_, *cur, &velocity_))
					viaPrev.T.linear() = a->linear();
			viaPrev.T = T_kf_prev_ * viaPrev.T;
			est = std::move(viaPrev);
			bridged = true;
		}
	}
	Eigen::Isometry3d T_kf_curr = prior;
	bool ok = est.ok;
	if (ok)
	{
		const Eigen::Isometry3d step = T_kf_prev_.inverse() * est.T;
		if (step.translation().norm() > maxStep_m_)
		{
			ok = false;
			r.message = "rejected a step of " + std::to_string(step.translation().norm()) + " m";
		}
	}
	else
		r.message = "only " + std::to_string(est.inliers.size()) + " inliers among " +
		            std::to_string(cur->kps.size()) + " features";
	// The scan's point sample, kept for the next scan's fallback.
	Cloud& curSample = sample_;
	curSample.clear();
	if (fallback_ || refine_ != Refine::None)
		sampleInto(scan, curSample);
	bool recovered = false;
	std::optional<Recovery> recovery;
	if (!ok && fallback_)
	{
		// The features failed (a featureless street, a fast turn): register the points.
		std::string why;
		// From the constant-velocity prior, and from the features' best (too weak) fit: at a
		// low scan rate the prior misses a turn by tens of degrees.
		// And straight on: after a turn the prior would turn on.
		Eigen::Isometry3d straight = Eigen::Isometry3d::Identity();
		straight.translation() = velocity_.translation();
		std::vector<Eigen::Isometry3d> starts{velocity_, straight};
		if (est.inliers.size() >= 6)
			starts.push_back(T_kf_prev_.inverse() * est.T);
		std::optional<Recovery> weak;
		recovery = fallback(curSample, starts, why, fallbackConfirmInliers_ > 0 ? &weak : nullptr);
		if (!recovery && weak && weak->T_prev_curr.translation().norm() <= maxStep_m_)
		{
			// The points leave one motion weakly pinned (a street seen from low down, a
			// corner): their registration stands when the features, matched around where it
			// puts them, agree with it. An HDL-64E 0.8 m up lost two scans of a corner this
			// way, both registered within 6 cm and 0.1 deg; of 27 wrong registrations among
			// 3,000 (most of them the points sliding along a street) none was confirmed
			// (plugin README, "When the features fail").
			const Eigen::Isometry3d guess = T_kf_prev_ * weak->T_prev_curr;
			const auto check =
			    track(*kf_, *cur, guess, true, scan.index + 104729, fallbackConfirmInliers_);
			const Eigen::Isometry3d diff = guess.inverse() * check.T;
			if (check.ok && diff.translation().norm() <= ransac_.inlierThreshold_m &&
			    Eigen::AngleAxisd(diff.linear()).angle() <= kConfirmDeg * M_PI / 180)
			{
				recovery = std::move(weak);
				est.inliers = check.inliers;  // reported as the scan's inliers
				why += ", confirmed by " + std::to_string(check.inliers.size()) + " features";
			}
			else
				why += ", not confirmed by the features (" + std::to_string(check.inliers.size()) +
				       " inliers)";
		}
		const auto* step = recovery ? &recovery->T_prev_curr : nullptr;
		if (step && step->translation().norm() <= maxStep_m_)
		{
			est.T = T_kf_prev_ * *step;
			ok = recovered = true;
			bridged = true;  // no ground alignment; the frame becomes the reference
			r.message = r.message + "; recovered by ICP (" + why + ")";
		}
		else
			r.message +=
			    "; ICP fallback failed (" +
			    (step ? "a step of " + std::to_string(step->translation().norm()) + " m" : why) +
			    ")";
	}

	++sinceKf_;
	// Paper: a keyframe when at least 5 frames have passed and at least 100 points are shared
	// with it. A weak track that goes on too long, or a lost one, also starts a new keyframe
	// so that tracking has a fresh reference.
	// A bridged match says the keyframe can no longer be tracked: this frame takes over. A
	// frame with too few features never becomes the reference (the next scan would have
	// nothing to match): the old keyframe and previous frame stay.
	const bool usable = static_cast<int>(cur->kps.size()) >= ransac_.minInliers;
	const bool becomesKeyframe =
	    usable && ((sinceKf_ >= kfMinFrames_ && !bridged &&
	                (ok ? static_cast<int>(est.inliers.size()) : 0) >= kfMinShared_) ||
	               sinceKf_ >= kfMaxFrames_ || !ok || bridged);
	if (ok)
	{
		// The motion-model check (see alignPlanes) only with ground_motion_check: on a VLP-16
		// drive it removes 3.4 deg roll steps (town, grid: RRE 0.0096 -> 0.0051 deg/m), but on
		// the de-skewed town-sweep drive the ATE went 0.22 -> 0.39 m (tests/test_orb_odometry.cpp,
		// Deskew; the one frame it corrects there is right, the rest is another realisation of
		// the open path's drift).
		// The motion model even when constant_velocity does not start the search from it.
		const Eigen::Isometry3d motion = T_kf_prev_ * velocity_;
		T_kf_curr = alignGround_ && !bridged
		                ? alignGround(est.T, *kf_, *cur, groundMotionCheck_ ? &motion : nullptr)
		                : est.T;
		// Bridged frames too (their estimate is still relative to the keyframe): on the
		// handheld walk 204 of 450 frames are bridged, and left unrefined their features' tilt
		// (up to 5 deg a step) made most of the error (RTE 5.7 % -> 0.88 % with them).
		if (refine_ != Refine::None && !recovered && kfTarget_ && (refineAll_ || becomesKeyframe))
		{
			const auto icp =
			    features::icpPointToPlane(curSample, *kfTarget_, T_kf_curr, refineIcp_);
			if (icp.converged && icp.overlap >= refineMinOverlap_ &&
			    icp.constraint >= fallbackMinConstraint_)
			{
				if (refine_ == Refine::Rotation)
					T_kf_curr.linear() = icp.T.linear();
				else
					T_kf_curr = icp.T;
			}
		}
		r.status = TrackingStatus::Ok;
		r.inliers = est.inliers.size();
		if (recovered)
		{
			r.information = mrpt::math::CMatrixDouble66(recovery->information);
			MRPT_LOG_INFO_STREAM("scan " << scan.index << ": " << r.message);
		}
		else
			r.information = mrpt::math::CMatrixDouble66(
			    features::pointToPointInformation(cur->pts, est.inliers, sigma_m_));
	}
	else
	{
		r.status = TrackingStatus::Lost;
		r.information.setIdentity();
		r.information *= 1e-2;  // a guess: trust it little
	}
	r.T_kf_curr = toPose(T_kf_curr);
	const Eigen::Isometry3d T_prev_curr = T_kf_prev_.inverse() * T_kf_curr;
	r.T_prev_curr = toPose(T_prev_curr);
	if (ok)
		velocity_ = T_prev_curr;

	r.keyframe = becomesKeyframe;  // decided above, before the refinement
	std::swap(prevCloud_, sample_);
	if (!usable)
	{
		// Keep tracking against the keyframe; the prior stands in for this frame, and the
		// previous frame no longer matches T_kf_prev_: no bridge through it.
		T_kf_prev_ = T_kf_curr;
		prev_.reset();
		guessSinceKf_ = guessSinceKf_ || !ok;
		return r;
	}
	if (r.keyframe)
	{
		// A lost frame's pose is a guess: the local map does not go on through it.
		if (refine_ != Refine::None)
			advanceRefineMap(ok && !guessSinceKf_ ? &T_kf_curr : nullptr, prevCloud_);
		guessSinceKf_ = false;
		r.keyframeData = keyframeOf(*cur);
		kf_ = std::move(cur);
		prev_.reset();
		T_kf_prev_.setIdentity();
		sinceKf_ = 0;
	}
	else
	{
		prev_ = std::move(cur);
		T_kf_prev_ = T_kf_curr;
	}
	return r;
}
