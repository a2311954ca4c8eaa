#include <rasterslam/features/icp.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <nanoflann.hpp>
#include <unordered_map>

namespace rasterslam::features
{
namespace
{
struct CloudAdaptor
{
	const std::vector<Eigen::Vector3f>& pts;
	std::size_t kdtree_get_point_count() const { return pts.size(); }
	float kdtree_get_pt(std::size_t i, std::size_t d) const { return pts[i][static_cast<int>(d)]; }
	template <class B>
	bool kdtree_get_bbox(B&) const
	{
		return false;
	}
};
using KdTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>,
                                        CloudAdaptor, 3, uint32_t>;

Eigen::Matrix3d skew(const Eigen::Vector3d& v)
{
	Eigen::Matrix3d S;
	S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
	return S;
}

/** exp of a twist (translation first, rotation vector second), applied on the left. */
Eigen::Isometry3d expTwist(const Eigen::Matrix<double, 6, 1>& d)
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	const Eigen::Vector3d w = d.tail<3>();
	const double a = w.norm();
	T.linear() = a > 1e-12 ? Eigen::AngleAxisd(a, w / a).toRotationMatrix()
	                       : Eigen::Matrix3d::Identity() + skew(w);
	T.translation() = d.head<3>();
	return T;
}
}  // namespace

std::vector<Eigen::Vector3f> voxelDownsample(const std::vector<Eigen::Vector3f>& pts,
                                             double voxel_m)
{
	struct Acc
	{
		Eigen::Vector3d sum = Eigen::Vector3d::Zero();
		int n = 0;
	};
	std::unordered_map<uint64_t, Acc> cells;
	cells.reserve(pts.size() / 4 + 1);
	const double inv = 1.0 / voxel_m;
	constexpr int64_t kOffset = int64_t(1) << 20;  // cells +-1M voxels from the origin
	for (const auto& p : pts)
	{
		if (!p.allFinite())
			continue;
		int64_t c[3];
		bool inside = true;
		for (int k = 0; k < 3 && inside; k++)
		{
			const double f = std::floor(p[k] * inv) + static_cast<double>(kOffset);
			inside = f >= 0 && f < static_cast<double>(2 * kOffset);  // before the cast
			c[k] = inside ? static_cast<int64_t>(f) : 0;
		}
		if (!inside)
			continue;
		// 21 bits each, combined without shifting negative values.
		const uint64_t key = static_cast<uint64_t>(c[0]) * (uint64_t(1) << 42) +
		                     static_cast<uint64_t>(c[1]) * (uint64_t(1) << 21) +
		                     static_cast<uint64_t>(c[2]);
		auto& a = cells[key];
		a.sum += p.cast<double>();
		++a.n;
	}
	std::vector<Eigen::Vector3f> out;
	out.reserve(cells.size());
	for (const auto& [k, a] : cells)
		out.push_back((a.sum / a.n).cast<float>());
	return out;
}

IcpTargetCache::IcpTargetCache(std::size_t capacity, const IcpParams& params)
    : capacity_(std::max<std::size_t>(capacity, 1)), params_(params)
{
}

std::shared_ptr<const IcpTarget> IcpTargetCache::get(
    uint64_t key, uint64_t fingerprint, const std::function<std::vector<Eigen::Vector3f>()>& points)
{
	for (std::size_t i = 0; i < entries_.size(); i++)
		if (entries_[i].key == key && entries_[i].fingerprint == fingerprint)
		{
			std::rotate(entries_.begin(), entries_.begin() + static_cast<std::ptrdiff_t>(i),
			            entries_.begin() + static_cast<std::ptrdiff_t>(i) + 1);
			return entries_.front().target;
		}
	Entry e{key, fingerprint, std::make_shared<const IcpTarget>(points(), params_)};
	++made_;
	if (entries_.size() >= capacity_)
		entries_.pop_back();
	entries_.insert(entries_.begin(), std::move(e));
	return entries_.front().target;
}

std::vector<Eigen::Vector3f> voxelDownsample(const std::vector<PointXYZI>& pts, double voxel_m,
                                             double range_m)
{
	std::vector<Eigen::Vector3f> near;
	near.reserve(pts.size());
	const float r2 = static_cast<float>(range_m * range_m);
	for (const auto& p : pts)
		if (p.x * p.x + p.y * p.y + p.z * p.z <= r2)
			near.emplace_back(p.x, p.y, p.z);
	return voxelDownsample(near, voxel_m);
}

struct IcpTarget::Impl
{
	std::vector<Eigen::Vector3f> pts;
	CloudAdaptor adaptor{pts};
	std::unique_ptr<KdTree> tree;
	int k = 10;
	double minPlanarity = 0.7;
	/** The normal of point i (zero where its neighbourhood is not flat), fitted on first use:
	 *  an alignment reaches a part of the target only (the odometry's refinement on the KITTI
	 *  sample, a keyframe's scan on the last ten keyframes' points: 29 % of them), and fitting
	 *  every normal when the target was made cost more than the alignment. The same normals
	 *  as fitted up front. Not safe for two threads on one target. */
	const Eigen::Vector3f& normal(uint32_t i) const
	{
		if (!fitted[i])
			fit(i);
		return normals[i];
	}

   private:
	mutable std::vector<Eigen::Vector3f> normals;
	mutable std::vector<uint8_t> fitted;
	mutable std::vector<uint32_t> idx;
	mutable std::vector<float> d2;
	friend class IcpTarget;
	void fit(uint32_t i) const
	{
		fitted[i] = 1;
		// The smallest principal direction of the neighbourhood, when it is flat.
		const std::size_t n =
		    tree->knnSearch(pts[i].data(), static_cast<std::size_t>(k), idx.data(), d2.data());
		if (n < 3)
			return;
		Eigen::Vector3d mean = Eigen::Vector3d::Zero();
		for (std::size_t j = 0; j < n; j++)
			mean += pts[idx[j]].cast<double>();
		mean /= static_cast<double>(n);
		Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
		for (std::size_t j = 0; j < n; j++)
		{
			const Eigen::Vector3d e = pts[idx[j]].cast<double>() - mean;
			C += e * e.transpose();
		}
		const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
		const double sum = es.eigenvalues().sum();
		if (!(sum > 0) || 1.0 - 3.0 * es.eigenvalues()(0) / sum < minPlanarity)
			return;
		normals[i] = es.eigenvectors().col(0).cast<float>();
	}
};

IcpTarget::IcpTarget(const std::vector<Eigen::Vector3f>& in, const IcpParams& prm)
    : impl_(std::make_unique<Impl>())
{
	auto& t = *impl_;
	t.pts = voxelDownsample(in, prm.voxel_m);
	t.k = std::max(3, prm.normalNeighbours);
	t.minPlanarity = prm.minPlanarity;
	if (t.pts.size() < static_cast<std::size_t>(t.k))
		return;
	t.tree = std::make_unique<KdTree>(3, t.adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
	t.normals.assign(t.pts.size(), Eigen::Vector3f::Zero());
	t.fitted.assign(t.pts.size(), 0);
	t.idx.resize(static_cast<std::size_t>(t.k));
	t.d2.resize(static_cast<std::size_t>(t.k));
}

IcpTarget::~IcpTarget() = default;

std::size_t IcpTarget::size() const
{
	return impl_->tree ? impl_->pts.size() : 0;
}

namespace
{
/** Overlap and normal matrix of the (voxelized) source at res.T on the target. */
void assess(const std::vector<Eigen::Vector3f>& src, const IcpTarget& target, const IcpParams& prm,
            IcpResult& res)
{
	using Mat6 = Eigen::Matrix<double, 6, 6>;
	using Vec6 = Eigen::Matrix<double, 6, 1>;
	res.sourcePoints = src.size();
	res.matched = 0;
	res.H.setZero();
	res.overlap = res.constraint = 0;
	if (src.empty() || target.size() == 0)
		return;
	const auto& tgt = target.impl();
	const KdTree& tree = *tgt.tree;
	const float in2 = static_cast<float>(prm.inlier_m * prm.inlier_m);
	uint32_t nn = 0;
	float nd2 = 0;
	double r2 = 0;
	std::size_t withNormal = 0;
	for (const auto& p : src)
	{
		const Eigen::Vector3d q = res.T * p.cast<double>();
		const Eigen::Vector3f qf = q.cast<float>();
		if (tree.knnSearch(qf.data(), 1, &nn, &nd2) != 1 || nd2 > in2)
			continue;
		++res.matched;
		const Eigen::Vector3f& nf = tgt.normal(nn);
		if (nf.squaredNorm() < 0.5f)
			continue;
		const Eigen::Vector3d n = nf.cast<double>();
		Vec6 J;
		J.head<3>() = n;
		J.tail<3>() = q.cross(n);
		res.H += J * J.transpose();
		r2 += q.squaredNorm();
		++withNormal;
	}
	// The same normal matrix with rotation in metres at the lever (H is linear in the scaling).
	const double lever =
	    prm.lever_m > 0 ? prm.lever_m : std::sqrt(r2 / std::max<std::size_t>(withNormal, 1));
	Vec6 D;
	D << 1, 1, 1, 1 / lever, 1 / lever, 1 / lever;
	const Mat6 Hs = D.asDiagonal() * res.H * D.asDiagonal();
	res.overlap = static_cast<double>(res.matched) / static_cast<double>(src.size());
	if (res.matched > 0)
		res.constraint = Eigen::SelfAdjointEigenSolver<Mat6>(Hs).eigenvalues().minCoeff() /
		                 static_cast<double>(res.matched);
}
}  // namespace

IcpResult icpPointToPlane(const std::vector<Eigen::Vector3f>& sourceIn,
                          const std::vector<Eigen::Vector3f>& targetIn,
                          const Eigen::Isometry3d& initial, const IcpParams& prm)
{
	return icpPointToPlane(sourceIn, IcpTarget(targetIn, prm), initial, prm);
}

IcpResult icpPointToPlane(const std::vector<Eigen::Vector3f>& sourceIn, const IcpTarget& target,
                          const Eigen::Isometry3d& initial, const IcpParams& prm)
{
	IcpResult res;
	res.T = initial;
	const auto src = voxelDownsample(sourceIn, prm.voxel_m);
	res.sourcePoints = src.size();
	if (src.size() < 6 || target.size() == 0)
		return res;
	const auto& dst = target.impl().pts;
	const auto& tgt = target.impl();
	const KdTree& tree = *tgt.tree;

	const float maxD2 = static_cast<float>(prm.maxCorrespondence_m * prm.maxCorrespondence_m);
	using Mat6 = Eigen::Matrix<double, 6, 6>;
	using Vec6 = Eigen::Matrix<double, 6, 1>;
	uint32_t nn = 0;
	float nd2 = 0;
	constexpr int kRecent = 4;
	std::array<Eigen::Isometry3d, kRecent> recent;  // the poses before the last steps
	for (res.iterations = 0; res.iterations < prm.maxIterations; res.iterations++)
	{
		Mat6 A = Mat6::Zero();
		Vec6 b = Vec6::Zero();
		std::size_t used = 0;
		double r2 = 0;
		for (const auto& p : src)
		{
			const Eigen::Vector3d q = res.T * p.cast<double>();
			const Eigen::Vector3f qf = q.cast<float>();
			if (tree.knnSearch(qf.data(), 1, &nn, &nd2) != 1 || nd2 > maxD2)
				continue;
			const Eigen::Vector3f& nf = tgt.normal(nn);
			if (nf.squaredNorm() < 0.5f)
				continue;
			const Eigen::Vector3d n = nf.cast<double>();
			const double r = n.dot(q - dst[nn].cast<double>());
			Vec6 J;
			J.head<3>() = n;
			J.tail<3>() = q.cross(n);
			const double w = std::abs(r) <= prm.huber_m ? 1.0 : prm.huber_m / std::abs(r);
			A += w * J * J.transpose();
			b -= w * J * r;
			r2 += q.squaredNorm();
			++used;
		}
		if (used < 6)
			return res;
		// Solved along the eigenvectors of the normal matrix (rotation scaled by lever_m):
		// a direction nothing pins (x, y and yaw over flat ground) gets no update instead of
		// drifting on noise, and the constraint measure below reports it.
		const double lever =
		    prm.lever_m > 0 ? prm.lever_m : std::sqrt(r2 / static_cast<double>(used));
		Vec6 D;
		D << 1, 1, 1, 1 / lever, 1 / lever, 1 / lever;
		const Mat6 As = D.asDiagonal() * A * D.asDiagonal();
		const Eigen::SelfAdjointEigenSolver<Mat6> es(As);
		const Vec6 bs = D.asDiagonal() * b;
		Vec6 ds = Vec6::Zero();
		const double floor = 1e-3 * static_cast<double>(used);
		for (int e = 0; e < 6; e++)
			if (es.eigenvalues()(e) > floor)
				ds += es.eigenvectors().col(e) *
				      (es.eigenvectors().col(e).dot(bs) / es.eigenvalues()(e));
		const Vec6 d = D.asDiagonal() * ds;
		if (!d.allFinite())
			return res;
		recent[res.iterations % kRecent] = res.T;
		res.T = expTwist(d) * res.T;
		// Converged: the step is below the bounds, or the pose is back where it was two to
		// four steps ago. Nearest-neighbour matching can flip a few correspondences back and
		// forth at the end, and the pose then cycles through two to four poses a fraction of a
		// millimetre apart for ever (measured on the handheld walk: steps of 0.1-0.6 mm, 8 % of
		// the refinements, and the fallback of its one lost scan).
		bool cycled = false;
		for (int back = 2; back <= kRecent && back <= res.iterations + 1 && !cycled; back++)
		{
			const Eigen::Isometry3d delta =
			    recent[(res.iterations + 1 - back) % kRecent].inverse() * res.T;
			cycled = delta.translation().norm() < prm.convergedTranslation_m &&
			         Eigen::AngleAxisd(delta.linear()).angle() < prm.convergedRotation_rad;
		}
		if ((d.head<3>().norm() < prm.convergedTranslation_m &&
		     d.tail<3>().norm() < prm.convergedRotation_rad) ||
		    cycled)
		{
			res.converged = true;
			++res.iterations;
			break;
		}
	}
	// Orthonormal, whatever rounding did.
	res.T.linear() = Eigen::Quaterniond(res.T.linear()).normalized().toRotationMatrix();

	assess(src, target, prm, res);
	return res;
}

IcpResult assessAlignment(const std::vector<Eigen::Vector3f>& source, const IcpTarget& target,
                          const Eigen::Isometry3d& T, const IcpParams& params)
{
	IcpResult res;
	res.T = T;
	assess(voxelDownsample(source, params.voxel_m), target, params, res);
	return res;
}

}  // namespace rasterslam::features
