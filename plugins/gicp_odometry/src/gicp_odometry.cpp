// Scan-to-scan Generalized-ICP odometry (Segal et al., RSS 2009) with PCL: the paper's GICP
// baseline, and the reference the paper's own tracking is measured against.
// PCL headers come before MRPT's (see DESIGN.md).
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>
// MRPT
#include <mrpt/core/initializer.h>
#include <mrpt/math/CMatrixFixed.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/features/icp.h>
#include <rasterslam/map/registration.h>

#include <chrono>
#include <cmath>

namespace rasterslam
{
class GicpOdometry : public Odometry
{
	DEFINE_MRPT_OBJECT(GicpOdometry, rasterslam)

   public:
	OdometryResult process(const Scan& scan, const RasterFrame* raster) override;

   protected:
	void initializeImpl(ParamReader& p) override;

   private:
	using Cloud = pcl::PointCloud<pcl::PointXYZ>;
	/** Exposes the covariances GICP computed for the source scan, so that they serve again
	 *  when that scan becomes the target (saves one of the two k-NN covariance passes). */
	class Gicp : public pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ>
	{
	   public:
		MatricesVectorPtr sourceCovariances() const { return input_covariances_; }
	};

	Cloud::Ptr preprocess(const Scan& scan) const;

	// parameters
	double voxel_m_ = 0.5, minRange_m_ = 2.0, maxRange_m_ = 100.0;
	double maxCorrespondence_m_ = 1.0, transformationEpsilon_ = 5e-4;
	int kCorrespondences_ = 20, maxIterations_ = 50, minPoints_ = 100, keyframeEvery_ = 1;
	double maxFitness_m2_ = 0.5;
	/** The result is also judged as the ORB odometry's fallback judges its ICP: the share of
	 *  the scan's points within 0.3 m of the previous scan's planes, and the smallest
	 *  eigenvalue per point of the point-to-plane normal matrix (0: some motion is free). */
	double minOverlap_ = 0.4, minConstraint_ = 0.02;
	features::IcpParams judge_;
	std::unique_ptr<features::IcpTarget> previousTarget_;  //!< previous_, prepared
	double infoTranslation_ = 1e4, infoRotation_ = 1e5;
	bool constantVelocity_ = true;
	// state
	Cloud::Ptr previous_;
	Gicp::MatricesVectorPtr previousCov_;  // covariances of previous_, when known
	Eigen::Matrix4f velocity_ = Eigen::Matrix4f::Identity();
	int sinceKeyframe_ = 0;
};
}  // namespace rasterslam

using namespace rasterslam;

IMPLEMENTS_MRPT_OBJECT(GicpOdometry, Odometry, rasterslam)

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_plugin_gicp)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::GicpOdometry));
}

void GicpOdometry::initializeImpl(ParamReader& p)
{
	voxel_m_ = p.getDouble("voxel_m", voxel_m_);
	minRange_m_ = p.getDouble("min_range_m", minRange_m_);
	maxRange_m_ = p.getDouble("max_range_m", maxRange_m_);
	maxCorrespondence_m_ = p.getDouble("max_correspondence_m", maxCorrespondence_m_);
	kCorrespondences_ = p.getInt("k_correspondences", kCorrespondences_);
	maxIterations_ = p.getInt("max_iterations", maxIterations_);
	transformationEpsilon_ = p.getDouble("transformation_epsilon", transformationEpsilon_);
	minPoints_ = p.getInt("min_points", minPoints_);
	maxFitness_m2_ = p.getDouble("max_fitness_m2", maxFitness_m2_);
	minOverlap_ = p.getDouble("min_overlap", minOverlap_);
	minConstraint_ = p.getDouble("min_constraint", minConstraint_);
	const double lever = p.getDouble("constraint_lever_m", features::IcpParams().lever_m);
	keyframeEvery_ = p.getInt("keyframe_every", keyframeEvery_);
	constantVelocity_ = p.getBool("constant_velocity", constantVelocity_);
	infoTranslation_ = p.getDouble("information_translation", infoTranslation_);
	infoRotation_ = p.getDouble("information_rotation", infoRotation_);
	p.requirePositive(voxel_m_, "voxel_m");
	p.requireAtLeast(minRange_m_, 0, "min_range_m");
	p.requirePositive(maxRange_m_, "max_range_m");
	p.require(minRange_m_ < maxRange_m_, minRange_m_, "min_range_m", "must be below max_range_m");
	p.requirePositive(maxCorrespondence_m_, "max_correspondence_m");
	p.requirePositive(kCorrespondences_, "k_correspondences");
	p.requirePositive(maxIterations_, "max_iterations");
	p.requirePositive(keyframeEvery_, "keyframe_every");
	p.requirePositive(minPoints_, "min_points");
	p.requireAtLeast(transformationEpsilon_, 0, "transformation_epsilon");
	p.requirePositive(maxFitness_m2_, "max_fitness_m2");
	p.requireRange(minOverlap_, 0, 1, "min_overlap");
	p.requireRange(minConstraint_, 0, 1, "min_constraint");
	p.requireAtLeast(lever, 0, "constraint_lever_m");
	judge_ = features::IcpParams();
	judge_.voxel_m = voxel_m_;
	judge_.lever_m = lever;
	p.requirePositive(infoTranslation_, "information_translation");
	p.requirePositive(infoRotation_, "information_rotation");
	previous_.reset();
	previousCov_.reset();
	previousTarget_.reset();
	velocity_.setIdentity();
	sinceKeyframe_ = 0;
}

namespace
{
std::vector<Eigen::Vector3f> points(const pcl::PointCloud<pcl::PointXYZ>& c)
{
	std::vector<Eigen::Vector3f> v;
	v.reserve(c.size());
	for (const auto& p : c.points)
		v.emplace_back(p.x, p.y, p.z);
	return v;
}
}  // namespace

GicpOdometry::Cloud::Ptr GicpOdometry::preprocess(const Scan& scan) const
{
	Cloud::Ptr raw(new Cloud);
	raw->reserve(scan.points.size());
	const double r2min = minRange_m_ * minRange_m_, r2max = maxRange_m_ * maxRange_m_;
	for (const auto& q : scan.points)
	{
		const double r2 = double(q.x) * q.x + double(q.y) * q.y + double(q.z) * q.z;
		if (r2 >= r2min && r2 <= r2max)
			raw->push_back(pcl::PointXYZ(q.x, q.y, q.z));
	}
	Cloud::Ptr out(new Cloud);
	pcl::VoxelGrid<pcl::PointXYZ> vg;
	const float leaf = static_cast<float>(voxel_m_);
	vg.setLeafSize(leaf, leaf, leaf);
	vg.setInputCloud(raw);
	vg.filter(*out);
	return out;
}

OdometryResult GicpOdometry::process(const Scan& scan, const RasterFrame* /*raster*/)
{
	OdometryResult r;
	const auto t0 = std::chrono::steady_clock::now();
	Cloud::Ptr cloud = preprocess(scan);
	const double prepMs =
	    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
	const Eigen::Matrix4f prior = constantVelocity_ ? velocity_ : Eigen::Matrix4f::Identity();

	if (!previous_)
	{
		r.status = TrackingStatus::Initializing;
		r.keyframe = true;
		previous_ = cloud;
		previousCov_.reset();
		previousTarget_ = std::make_unique<features::IcpTarget>(points(*cloud), judge_);
		sinceKeyframe_ = 0;
		return r;
	}
	Eigen::Matrix4f T = prior;
	Gicp::MatricesVectorPtr nextCov;
	if (static_cast<int>(cloud->size()) < minPoints_ ||
	    static_cast<int>(previous_->size()) < minPoints_)
	{
		r.status = TrackingStatus::Lost;
		r.message = "too few points after filtering (" + std::to_string(cloud->size()) + ")";
	}
	else
	{
		Gicp gicp;
		gicp.setMaxCorrespondenceDistance(maxCorrespondence_m_);
		gicp.setCorrespondenceRandomness(kCorrespondences_);
		gicp.setMaximumIterations(maxIterations_);
		gicp.setTransformationEpsilon(transformationEpsilon_);
		gicp.setInputSource(cloud);
		gicp.setInputTarget(previous_);
		if (previousCov_ && previousCov_->size() == previous_->size())
			gicp.setTargetCovariances(previousCov_);
		Cloud aligned;
		gicp.align(aligned, prior);
		nextCov = gicp.sourceCovariances();
		MRPT_LOG_DEBUG_FMT(
		    "scan %zu: %zu points after filtering, preprocess %.1f ms, align %.1f ms", scan.index,
		    cloud->size(), prepMs,
		    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
		            .count() -
		        prepMs);
		const double fitness = gicp.getFitnessScore(maxCorrespondence_m_);
		if (!gicp.hasConverged() || !std::isfinite(fitness) || fitness > maxFitness_m2_)
		{
			r.status = TrackingStatus::Lost;
			r.message = gicp.hasConverged()
			                ? "fitness " + std::to_string(fitness) + " m^2 above max_fitness_m2"
			                : "GICP did not converge";
		}
		else
		{
			// Judged on its points: a low fitness says little when most matched points are
			// ground (a 2 Hz drive's GICP stood still where the car moved 4 m, fitness low).
			const auto judged = features::assessAlignment(
			    points(*cloud), *previousTarget_,
			    Eigen::Isometry3d(gicp.getFinalTransformation().cast<double>()), judge_);
			if (judged.overlap < minOverlap_ || judged.constraint < minConstraint_)
			{
				r.status = TrackingStatus::Lost;
				r.message = "overlap " + std::to_string(judged.overlap) + ", constraint " +
				            std::to_string(judged.constraint) +
				            " (min_overlap, min_constraint): not pinned down";
			}
			else
			{
				T = gicp.getFinalTransformation();
				r.status = TrackingStatus::Ok;
				r.inliers = aligned.size();
			}
		}
	}
	// GICP aligns the current scan (source) onto the previous one (target): that transform is
	// the pose of the current scan in the previous scan's frame.
	r.T_prev_curr = toPose(Eigen::Isometry3d(T.cast<double>()));
	if (r.status == TrackingStatus::Ok)
		velocity_ = T;
	r.information.setZero();
	for (int i = 0; i < 3; i++)
		r.information(i, i) = infoTranslation_;
	for (int i = 3; i < 6; i++)
		r.information(i, i) = infoRotation_;
	if (r.status == TrackingStatus::Lost)
		r.information *= 1e-3;  // a guess: trust it little
	previous_ = cloud;
	previousCov_ = nextCov;
	previousTarget_ = std::make_unique<features::IcpTarget>(points(*cloud), judge_);
	if (++sinceKeyframe_ >= keyframeEvery_)
	{
		r.keyframe = true;
		sinceKeyframe_ = 0;
	}
	return r;
}
