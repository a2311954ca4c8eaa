#include <mrpt/poses/CPose3D.h>
#include <mrpt/poses/CPose3DQuat.h>
#include <mrpt/tfest/se3.h>
#include <rasterslam/features/rigid_ransac.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>

namespace rasterslam::features
{
bool fitRigid(const std::vector<Eigen::Vector3f>& p, const std::vector<Eigen::Vector3f>& q,
              const std::vector<int>& idx, Eigen::Isometry3d& T)
{
	if (idx.size() < 3)
		return false;
	// MRPT's closed form (Horn): "this" = T (+) "other".
	std::vector<mrpt::math::TPoint3D> thisPts, otherPts;
	thisPts.reserve(idx.size());
	otherPts.reserve(idx.size());
	for (int i : idx)
	{
		thisPts.emplace_back(q[i].x(), q[i].y(), q[i].z());
		otherPts.emplace_back(p[i].x(), p[i].y(), p[i].z());
	}
	mrpt::poses::CPose3DQuat pq;
	double scale = 1;
	if (!mrpt::tfest::se3_l2(thisPts, otherPts, pq, scale, true))
		return false;
	const auto M = mrpt::poses::CPose3D(pq).getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>();
	for (int r = 0; r < 4; r++)
		for (int c = 0; c < 4; c++)
			T.matrix()(r, c) = M(r, c);
	return T.matrix().allFinite();
}

namespace
{
std::vector<int> selectInliers(const std::vector<Eigen::Vector3f>& p,
                               const std::vector<Eigen::Vector3f>& q, const Eigen::Isometry3d& T,
                               double thr, double* sse = nullptr)
{
	const Eigen::Matrix3f R = T.linear().cast<float>();
	const Eigen::Vector3f t = T.translation().cast<float>();
	const float thr2 = static_cast<float>(thr * thr);
	std::vector<int> in;
	double s = 0;
	for (int i = 0; i < static_cast<int>(p.size()); i++)
	{
		const float e2 = (R * p[i] + t - q[i]).squaredNorm();
		if (e2 < thr2)
		{
			in.push_back(i);
			s += e2;
		}
	}
	if (sse)
		*sse = s;
	return in;
}
}  // namespace

RigidResult ransacRigid(const std::vector<Eigen::Vector3f>& p,
                        const std::vector<Eigen::Vector3f>& q, const RansacParams& prm,
                        uint32_t seed)
{
	RigidResult best;
	const int n = static_cast<int>(p.size());
	if (n < 3 || static_cast<int>(q.size()) != n)
		return best;
	std::mt19937 rng(seed);
	std::uniform_int_distribution<int> pick(0, n - 1);
	int needed = prm.maxIterations;
	for (int it = 0; it < needed && it < prm.maxIterations; it++)
	{
		best.iterations = it + 1;
		const int a = pick(rng), b = pick(rng), c = pick(rng);
		if (a == b || b == c || a == c)
			continue;
		// Skip near-collinear samples: they leave a rotation about their line undetermined.
		const float area = (p[b] - p[a]).cross(p[c] - p[a]).norm();
		if (area < 0.5f)
			continue;
		// Matched pairs must keep their distances under a rigid motion.
		const float thr = static_cast<float>(2 * prm.inlierThreshold_m);
		if (std::abs((p[b] - p[a]).norm() - (q[b] - q[a]).norm()) > thr ||
		    std::abs((p[c] - p[a]).norm() - (q[c] - q[a]).norm()) > thr ||
		    std::abs((p[c] - p[b]).norm() - (q[c] - q[b]).norm()) > thr)
			continue;
		Eigen::Isometry3d T;
		if (!fitRigid(p, q, {a, b, c}, T))
			continue;
		auto in = selectInliers(p, q, T, prm.inlierThreshold_m);
		if (in.size() > best.inliers.size())
		{
			best.inliers = std::move(in);
			best.T = T;
			// Adaptive count: enough samples to draw one all-inlier triple with `confidence`.
			const double w = static_cast<double>(best.inliers.size()) / n;
			const double w3 = w * w * w;
			if (w3 > 1e-9 && w3 < 1.0)
				needed =
				    static_cast<int>(std::ceil(std::log(1 - prm.confidence) / std::log(1 - w3)));
			else if (w3 >= 1.0)
				needed = 0;
		}
	}
	if (static_cast<int>(best.inliers.size()) < std::max(3, prm.minInliers))
		return best;
	double sse = 0;
	for (int r = 0; r < prm.refinements; r++)
	{
		Eigen::Isometry3d T;
		if (!fitRigid(p, q, best.inliers, T))
			break;
		auto in = selectInliers(p, q, T, prm.inlierThreshold_m, &sse);
		if (in.size() < 3)
			break;
		best.T = T;
		best.inliers = std::move(in);
	}
	selectInliers(p, q, best.T, prm.inlierThreshold_m, &sse);
	best.rmse_m = best.inliers.empty() ? 0 : std::sqrt(sse / best.inliers.size());
	best.ok = static_cast<int>(best.inliers.size()) >= prm.minInliers;
	return best;
}

bool refitRobust(const std::vector<Eigen::Vector3f>& p, const std::vector<Eigen::Vector3f>& q,
                 const RobustRefitParams& refit, const RansacParams& prm, RigidResult& r)
{
	if (!r.ok || r.inliers.size() < 6 || p.size() != q.size())
		return false;
	const double sz = std::sqrt(std::max(refit.zWeight, 0.0));
	const double c2 = refit.cauchy_m * refit.cauchy_m;
	// The loss minimised, over the inliers the refit starts from.
	const auto cost = [&](const Eigen::Isometry3d& T)
	{
		double c = 0;
		for (int i : r.inliers)
		{
			Eigen::Vector3d e = T * p[i].cast<double>() - q[i].cast<double>();
			e.z() *= sz;
			c += c2 > 0 ? c2 * std::log1p(e.squaredNorm() / c2) : e.squaredNorm();
		}
		return c;
	};
	Eigen::Isometry3d T = r.T;
	for (int it = 0; it < std::max(1, refit.iterations); it++)
	{
		// Residual e = T p - q, weighed as (ex, ey, sz ez); a small motion (t, w) applied on
		// the left moves T p = a by t + w x a: d e / d(t, w) = [I, -[a]x].
		Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
		Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
		for (int i : r.inliers)
		{
			const Eigen::Vector3d a = T * p[i].cast<double>();
			Eigen::Vector3d e = a - q[i].cast<double>();
			e.z() *= sz;
			const double w = c2 > 0 ? 1.0 / (1.0 + e.squaredNorm() / c2) : 1.0;
			Eigen::Matrix<double, 3, 6> J;
			J.leftCols<3>().setIdentity();
			J.rightCols<3>() << 0, a.z(), -a.y(), -a.z(), 0, a.x(), a.y(), -a.x(), 0;
			J.row(2) *= sz;
			H.noalias() += w * J.transpose() * J;
			g.noalias() += w * J.transpose() * e;
		}
		const Eigen::Matrix<double, 6, 1> d = H.ldlt().solve(-g);
		if (!d.allFinite())
			return false;
		Eigen::Isometry3d dT = Eigen::Isometry3d::Identity();
		const Eigen::Vector3d w = d.tail<3>();
		if (w.norm() > 0)
			dT.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
		dT.translation() = d.head<3>();
		T = dT * T;
		if (d.head<3>().norm() < 1e-6 && w.norm() < 1e-8)
			break;
	}
	// A step that made the loss worse (a nearly singular system solves to a large finite
	// step), or a fit that would keep too few inliers, leaves RANSAC's fit as it was.
	if (!T.matrix().allFinite() || !(cost(T) <= cost(r.T) * (1 + 1e-9) + 1e-12))
		return false;
	double sse = 0;
	auto inliers = selectInliers(p, q, T, prm.inlierThreshold_m, &sse);
	if (static_cast<int>(inliers.size()) < std::max(3, prm.minInliers))
		return false;
	r.T = T;
	r.inliers = std::move(inliers);
	r.rmse_m = std::sqrt(sse / r.inliers.size());
	return true;
}

Eigen::Matrix<double, 6, 6> pointToPointInformation(const std::vector<Eigen::Vector3f>& pts,
                                                    const std::vector<int>& idx, double sigma_m)
{
	// Residual r = R p + t - q; d r / d(t, w) = [I, -[p]x] with w a small rotation vector
	// (roll about x, pitch about y, yaw about z).
	Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
	for (int i : idx)
	{
		const Eigen::Vector3d p = pts[i].cast<double>();
		Eigen::Matrix<double, 3, 6> J;
		J.leftCols<3>().setIdentity();
		J.rightCols<3>() << 0, p.z(), -p.y(), -p.z(), 0, p.x(), p.y(), -p.x(), 0;
		H += J.transpose() * J;
	}
	H /= sigma_m * sigma_m;
	// Reorder (x y z wx wy wz) -> MRPT's (x y z yaw pitch roll) = (x y z wz wy wx).
	const int perm[6] = {0, 1, 2, 5, 4, 3};
	Eigen::Matrix<double, 6, 6> I;
	for (int r = 0; r < 6; r++)
		for (int c = 0; c < 6; c++)
			I(r, c) = H(perm[r], perm[c]);
	return I;
}

}  // namespace rasterslam::features
