#include <ceres/autodiff_cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/ordered_groups.h>
#include <ceres/problem.h>
#include <ceres/solver.h>
#include <ceres/types.h>
#include <rasterslam/features/matcher.h>
#include <rasterslam/mapping/local_ba.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace rasterslam::mapping
{
namespace
{
constexpr int kDescriptorBytes = 32;
constexpr std::size_t kMaxFrames = 32;  // observers is a 32-bit mask
// A pose needs three non-collinear points: with fewer, its rotation about them is free.
constexpr int kMinTrackedForPose = 3;
// Parameter layout of a pose: translation (x, y, z), then Eigen's quaternion storage (x, y, z, w).
constexpr int kPoseSize = 7;

using Vec3 = Eigen::Vector3d;

// Eq. (3): the observation predicted from keyframe pose (q, t) and map point X, z^ = R^T (X - t).
template <typename T>
Eigen::Matrix<T, 3, 1> predictObservation(const Eigen::Quaternion<T>& q_anchor_frame,
                                          const Eigen::Matrix<T, 3, 1>& t_anchor_frame,
                                          const Eigen::Matrix<T, 3, 1>& X_anchor)
{
	return q_anchor_frame.conjugate() * (X_anchor - t_anchor_frame);
}

// Eq. (4): e^T Omega e with Omega = diag(1/sigma^2) is the squared norm of diag(1/sigma) e.
template <typename T>
Eigen::Matrix<T, 3, 1> whiten(const Eigen::Matrix<T, 3, 1>& e, const Vec3& sqrtInformation)
{
	return sqrtInformation.cast<T>().cwiseProduct(e);
}

/** One 3D observation of a tracked point by a keyframe: residual over (t, q, X). */
struct PointObservationCost
{
	Vec3 z;  //!< the measured point, keyframe frame
	Vec3 sqrtInformation;

	template <typename T>
	bool operator()(const T* t, const T* q, const T* X, T* residual) const
	{
		const Eigen::Quaternion<T> qv(Eigen::Map<const Eigen::Quaternion<T>>{q});
		const Eigen::Matrix<T, 3, 1> tv(Eigen::Map<const Eigen::Matrix<T, 3, 1>>{t});
		const Eigen::Matrix<T, 3, 1> Xv(Eigen::Map<const Eigen::Matrix<T, 3, 1>>{X});
		Eigen::Map<Eigen::Matrix<T, 3, 1>>{residual} =
		    whiten<T>(predictObservation<T>(qv, tv, Xv) - z.cast<T>(), sqrtInformation);
		return true;
	}
};

/** The same observation with a planar pose update: the frame moves by (dx, dy) and turns by
 *  dyaw about the anchor's vertical from its initial pose (R0, t0); its height, roll and
 *  pitch stay those the tracking's ground-plane alignment gave. */
struct PlanarPointObservationCost
{
	Vec3 z;
	Vec3 sqrtInformation;
	Eigen::Matrix3d R0;
	Vec3 t0;

	template <typename T>
	bool operator()(const T* d, const T* X, T* residual) const
	{
		const T c = cos(d[2]), s = sin(d[2]);
		Eigen::Matrix<T, 3, 3> Rz;
		Rz << c, -s, T(0), s, c, T(0), T(0), T(0), T(1);
		const Eigen::Matrix<T, 3, 3> R = Rz * R0.cast<T>();
		const Eigen::Matrix<T, 3, 1> t(T(t0.x()) + d[0], T(t0.y()) + d[1], T(t0.z()));
		const Eigen::Matrix<T, 3, 1> Xv(Eigen::Map<const Eigen::Matrix<T, 3, 1>>{X});
		Eigen::Map<Eigen::Matrix<T, 3, 1>>{residual} =
		    whiten<T>(R.transpose() * (Xv - t) - z.cast<T>(), sqrtInformation);
		return true;
	}
};

/** Disjoint sets whose root is the lowest member: a track is then named by its first
 *  observation whatever order the pairs were matched in, which keeps the output ordered. */
class DisjointSets
{
   public:
	explicit DisjointSets(std::size_t n) : parent_(n)
	{
		std::iota(parent_.begin(), parent_.end(), 0);
	}
	std::size_t find(std::size_t x)
	{
		while (parent_[x] != x)
		{
			parent_[x] = parent_[parent_[x]];
			x = parent_[x];
		}
		return x;
	}
	void unite(std::size_t a, std::size_t b)
	{
		a = find(a);
		b = find(b);
		if (a == b)
			return;
		if (b < a)
			std::swap(a, b);
		parent_[b] = a;
	}

   private:
	std::vector<std::size_t> parent_;
};

struct Feature
{
	int frame = 0;
	int index = 0;
};

struct Track
{
	int point = 0;                 //!< index in the result's points
	std::vector<Feature> members;  //!< ascending frame, one per frame
};

void checkInput(const std::vector<BaFrame>& frames, const LocalBaParams& p)
{
	if (frames.size() > kMaxFrames)
		throw std::invalid_argument("localBundleAdjustment: " + std::to_string(frames.size()) +
		                            " frames, at most 32 (observers is a 32-bit mask)");
	for (std::size_t f = 0; f < frames.size(); f++)
		if (frames[f].n > 0 && (!frames[f].descriptors || !frames[f].xyz))
			throw std::invalid_argument("localBundleAdjustment: frame " + std::to_string(f) +
			                            " has n = " + std::to_string(frames[f].n) +
			                            " but a null descriptors or xyz pointer");
	if (!(p.sigmaXY_m > 0) || !(p.sigmaZ_m > 0))
		throw std::invalid_argument("localBundleAdjustment: sigmaXY_m and sigmaZ_m must be > 0");
}

Vec3 featurePoint(const BaFrame& f, int k)
{
	return Eigen::Vector3f(f.xyz + 3 * k).cast<double>();
}

/** Mutual descriptor matches of every pair of frames, gated by the positions predicted with
 *  the initial poses, joined into sets over the features of all frames. */
DisjointSets associate(const std::vector<BaFrame>& frames, const std::vector<std::size_t>& offset,
                       const LocalBaParams& p)
{
	const std::size_t nf = frames.size();
	DisjointSets sets(offset[nf]);
	features::MatchParams mp;
	mp.maxDistance = p.maxHamming;
	mp.ratio = p.ratio;
	mp.gateRadius_m = static_cast<float>(p.gate_m);
	const bool gated = p.gate_m > 0;

	std::vector<cv::Mat> desc(nf);
	std::vector<std::vector<Eigen::Vector3f>> local(nf);
	for (std::size_t f = 0; f < nf; f++)
	{
		// matchMutual only reads: wrapping the caller's buffer avoids a copy.
		desc[f] = cv::Mat(static_cast<int>(frames[f].n), kDescriptorBytes, CV_8U,
		                  const_cast<uint8_t*>(frames[f].descriptors));
		if (gated)
			for (std::size_t k = 0; k < frames[f].n; k++)
				local[f].emplace_back(frames[f].xyz + 3 * k);
	}
	std::vector<Eigen::Vector3f> predicted;
	for (std::size_t i = 0; i < nf; i++)
		for (std::size_t j = i + 1; j < nf; j++)
		{
			if (frames[i].n == 0 || frames[j].n == 0)
				continue;
			if (gated)
			{
				const Eigen::Isometry3f T_j_i =
				    (frames[j].T_anchor_frame.inverse() * frames[i].T_anchor_frame).cast<float>();
				predicted.clear();
				for (const auto& x : local[i])
					predicted.push_back(T_j_i * x);
			}
			const auto matches = features::matchMutual(
			    desc[i], desc[j], mp, gated ? &predicted : nullptr, gated ? &local[j] : nullptr);
			for (const auto& m : matches)
				sets.unite(offset[i] + m.a, offset[j] + m.b);
		}
	return sets;
}

Eigen::Isometry3d poseFromParams(const double* x)
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() = Eigen::Quaterniond(x[6], x[3], x[4], x[5]).normalized().toRotationMatrix();
	T.translation() = Vec3(x[0], x[1], x[2]);
	return T;
}

/** RMS over the tracked observations of |R^T (X - t) - z|, in metres (unwhitened). */
double rmsResidual_m(const std::vector<Track>& tracks, const std::vector<BaFrame>& frames,
                     const std::vector<double>& poses, const std::vector<double>& points)
{
	double sum = 0;
	std::size_t n = 0;
	for (std::size_t t = 0; t < tracks.size(); t++)
		for (const auto& m : tracks[t].members)
		{
			const double* x = &poses[kPoseSize * m.frame];
			const Eigen::Quaterniond q(x[6], x[3], x[4], x[5]);
			const Vec3 e = predictObservation<double>(q.normalized(), Vec3(x[0], x[1], x[2]),
			                                          Vec3(&points[3 * t])) -
			               featurePoint(frames[m.frame], m.index);
			sum += e.squaredNorm();
			n++;
		}
	return n ? std::sqrt(sum / n) : 0.0;
}

}  // namespace

LocalBaResult localBundleAdjustment(const std::vector<BaFrame>& frames, const LocalBaParams& p)
{
	checkInput(frames, p);
	const std::size_t nf = frames.size();
	LocalBaResult res;
	for (const auto& f : frames)
		res.T_anchor_frame.push_back(f.T_anchor_frame);

	std::vector<std::size_t> offset(nf + 1, 0);
	for (std::size_t f = 0; f < nf; f++)
		offset[f + 1] = offset[f] + frames[f].n;
	std::vector<Feature> featureAt(offset[nf]);
	for (std::size_t f = 0; f < nf; f++)
		for (std::size_t k = 0; k < frames[f].n; k++)
			featureAt[offset[f] + k] = {static_cast<int>(f), static_cast<int>(k)};
	DisjointSets sets = nf >= 2 ? associate(frames, offset, p) : DisjointSets(offset[nf]);

	// Sets in the order of their first feature (their root), members ascending, so frames too.
	std::vector<std::vector<Feature>> groups;
	{
		std::vector<int> groupOfRoot(offset[nf], -1);
		for (std::size_t g = 0; g < offset[nf]; g++)
		{
			const std::size_t r = sets.find(g);
			if (groupOfRoot[r] < 0)
			{
				groupOfRoot[r] = static_cast<int>(groups.size());
				groups.emplace_back();
			}
			groups[groupOfRoot[r]].push_back(featureAt[g]);
		}
	}

	res.pointOfFeature.resize(nf);
	for (std::size_t f = 0; f < nf; f++)
		res.pointOfFeature[f].assign(frames[f].n, -1);
	std::vector<Track> tracks;
	std::vector<Feature> singles;
	std::vector<int> singlePoint;
	for (const auto& g : groups)
	{
		bool ambiguous = false;
		for (std::size_t k = 1; k < g.size(); k++)
			ambiguous |= g[k].frame == g[k - 1].frame;
		if (ambiguous)
		{
			res.ambiguousTracks++;
			continue;
		}
		const int point = static_cast<int>(res.points.size());
		uint32_t observers = 0;
		for (const auto& m : g)
		{
			observers |= 1u << m.frame;
			res.pointOfFeature[m.frame][m.index] = point;
		}
		res.observers.push_back(observers);
		const uint8_t* d = frames[g[0].frame].descriptors + kDescriptorBytes * g[0].index;
		res.descriptors.insert(res.descriptors.end(), d, d + kDescriptorBytes);
		res.points.emplace_back(Eigen::Vector3f::Zero());
		if (g.size() >= 2)
			tracks.push_back({point, g});
		else
		{
			singles.push_back(g[0]);
			singlePoint.push_back(point);
		}
	}
	res.tracks = tracks.size();

	std::vector<double> poses(kPoseSize * nf);
	for (std::size_t f = 0; f < nf; f++)
	{
		const Eigen::Quaterniond q(frames[f].T_anchor_frame.linear());
		const Vec3 t = frames[f].T_anchor_frame.translation();
		double* x = &poses[kPoseSize * f];
		x[0] = t.x(), x[1] = t.y(), x[2] = t.z();
		x[3] = q.x(), x[4] = q.y(), x[5] = q.z(), x[6] = q.w();
	}
	// A point starts at the mean of its observations mapped by the initial poses.
	std::vector<double> points(3 * tracks.size());
	auto initialPoints = [&]()
	{
		for (std::size_t t = 0; t < tracks.size(); t++)
		{
			Vec3 sum = Vec3::Zero();
			for (const auto& m : tracks[t].members)
				sum += frames[m.frame].T_anchor_frame * featurePoint(frames[m.frame], m.index);
			Eigen::Map<Vec3> X(&points[3 * t]);
			X = sum / static_cast<double>(tracks[t].members.size());
		}
	};
	initialPoints();

	// Only frames linked to frame 0 through tracks have a defined pose in its frame; the others
	// would float freely together, so they keep their initial pose.
	DisjointSets linked(nf);
	std::vector<int> trackedObs(nf, 0);
	for (const auto& t : tracks)
		for (const auto& m : t.members)
		{
			linked.unite(t.members[0].frame, m.frame);
			trackedObs[m.frame]++;
		}
	std::vector<char> freeFrame(nf, 0);
	int freeFrames = 0;
	for (std::size_t f = 1; f < nf; f++)
	{
		freeFrame[f] = linked.find(f) == linked.find(0) && trackedObs[f] >= kMinTrackedForPose;
		freeFrames += freeFrame[f];
		if (!freeFrame[f] && trackedObs[f] > 0)
			res.heldFrames++;
	}

	res.initialRms_m = res.finalRms_m = rmsResidual_m(tracks, frames, poses, points);
	auto finishPoints = [&]()
	{
		for (std::size_t t = 0; t < tracks.size(); t++)
			res.points[tracks[t].point] = Vec3(&points[3 * t]).cast<float>();
		for (std::size_t s = 0; s < singles.size(); s++)
			res.points[singlePoint[s]] = (res.T_anchor_frame[singles[s].frame] *
			                              featurePoint(frames[singles[s].frame], singles[s].index))
			                                 .cast<float>();
	};
	if (tracks.empty() || freeFrames == 0)
	{
		res.message = nf < 2           ? "fewer than 2 frames"
		              : tracks.empty() ? "no point seen by two frames"
		                               : "no frame linked to frame 0 by 3 or more tracked points";
		finishPoints();
		return res;
	}

	// The problem shares one loss and one manifold among its blocks, so it must not own them.
	ceres::Problem::Options po;
	po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
	po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
	ceres::Problem problem(po);
	ceres::EigenQuaternionManifold quaternionManifold;
	// Huber's threshold applies to the whitened residual, so it is in sigmas.
	std::unique_ptr<ceres::LossFunction> loss;
	if (p.huber > 0)
		loss = std::make_unique<ceres::HuberLoss>(p.huber);
	auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
	std::vector<double> deltas(3 * nf, 0.0);  // planar: (dx, dy, dyaw) of each frame
	for (std::size_t f = 0; f < nf && p.planar; f++)
	{
		problem.AddParameterBlock(&deltas[3 * f], 3);
		if (!freeFrame[f])
			problem.SetParameterBlockConstant(&deltas[3 * f]);
		ordering->AddElementToGroup(&deltas[3 * f], 1);
	}
	for (std::size_t f = 0; f < nf && !p.planar; f++)
	{
		double* x = &poses[kPoseSize * f];
		problem.AddParameterBlock(x, 3);
		problem.AddParameterBlock(x + 3, 4, &quaternionManifold);
		if (!freeFrame[f])
		{
			problem.SetParameterBlockConstant(x);
			problem.SetParameterBlockConstant(x + 3);
		}
		ordering->AddElementToGroup(x, 1);
		ordering->AddElementToGroup(x + 3, 1);
	}
	const Vec3 sqrtInformation(1.0 / p.sigmaXY_m, 1.0 / p.sigmaXY_m, 1.0 / p.sigmaZ_m);
	for (std::size_t t = 0; t < tracks.size(); t++)
	{
		ordering->AddElementToGroup(&points[3 * t], 0);  // points first: Schur eliminates them
		for (const auto& m : tracks[t].members)
		{
			if (p.planar)
			{
				const auto& T0 = frames[m.frame].T_anchor_frame;
				auto* cost = new ceres::AutoDiffCostFunction<PlanarPointObservationCost, 3, 3, 3>(
				    new PlanarPointObservationCost{featurePoint(frames[m.frame], m.index),
				                                   sqrtInformation, T0.linear(), T0.translation()});
				problem.AddResidualBlock(cost, loss.get(), &deltas[3 * m.frame], &points[3 * t]);
			}
			else
			{
				auto* cost = new ceres::AutoDiffCostFunction<PointObservationCost, 3, 3, 4, 3>(
				    new PointObservationCost{featurePoint(frames[m.frame], m.index),
				                             sqrtInformation});
				double* x = &poses[kPoseSize * m.frame];
				problem.AddResidualBlock(cost, loss.get(), x, x + 3, &points[3 * t]);
			}
			res.observations++;
		}
	}

	ceres::Solver::Options so;
	// The reduced camera system is at most 31 poses (186 unknowns): dense beats sparse there.
	so.linear_solver_type = ceres::DENSE_SCHUR;
	so.linear_solver_ordering = ordering;
	so.max_num_iterations = std::max(0, p.maxIterations);
	so.num_threads = 1;
	so.logging_type = ceres::SILENT;
	so.minimizer_progress_to_stdout = false;
	ceres::Solver::Summary summary;
	ceres::Solve(so, &problem, &summary);
	res.iterations =
	    std::max(0, static_cast<int>(summary.iterations.size()) - 1);  // [0] is the start

	std::ostringstream msg;
	if (!summary.IsSolutionUsable())
	{
		msg << "solver failed, initial poses kept: " << summary.message;
		res.message = msg.str();
		initialPoints();
		finishPoints();
		return res;
	}
	res.ran = true;
	for (std::size_t f = 0; f < nf && p.planar; f++)
	{
		// The planar update written back as a full pose.
		const double* d = &deltas[3 * f];
		const auto& T0 = frames[f].T_anchor_frame;
		const Eigen::Quaterniond q(Eigen::AngleAxisd(d[2], Vec3::UnitZ()) *
		                           Eigen::Quaterniond(T0.linear()));
		double* x = &poses[kPoseSize * f];
		x[0] = T0.translation().x() + d[0], x[1] = T0.translation().y() + d[1],
		x[2] = T0.translation().z();
		x[3] = q.x(), x[4] = q.y(), x[5] = q.z(), x[6] = q.w();
	}
	for (std::size_t f = 1; f < nf; f++)
		if (freeFrame[f])
			res.T_anchor_frame[f] = poseFromParams(&poses[kPoseSize * f]);
	res.finalRms_m = rmsResidual_m(tracks, frames, poses, points);
	finishPoints();
	msg << res.tracks << " tracks, " << res.observations << " observations, " << res.iterations
	    << " iterations, rms " << res.initialRms_m << " -> " << res.finalRms_m << " m ("
	    << ceres::TerminationTypeToString(summary.termination_type) << ")";
	if (res.heldFrames)
		msg << ", " << res.heldFrames << " frames held";
	if (res.ambiguousTracks)
		msg << ", " << res.ambiguousTracks << " ambiguous tracks dropped";
	res.message = msg.str();
	return res;
}

}  // namespace rasterslam::mapping
