#include <rasterslam/raster/ground_plane.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

namespace rasterslam::raster
{
namespace
{
/** Least-squares plane through points (smallest eigenvector of their covariance). */
Plane planeFromPoints(const std::vector<Eigen::Vector3f>& pts)
{
	Plane pl;
	if (pts.size() < 3)
		return pl;
	Eigen::Vector3d mean = Eigen::Vector3d::Zero();
	for (const auto& p : pts)
		mean += p.cast<double>();
	mean /= static_cast<double>(pts.size());
	Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
	for (const auto& p : pts)
	{
		const Eigen::Vector3d q = p.cast<double>() - mean;
		C += q * q.transpose();
	}
	Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
	Eigen::Vector3d n = es.eigenvectors().col(0);
	if (n.z() < 0)
		n = -n;
	pl.n = n.cast<float>();
	pl.d = static_cast<float>(-n.dot(mean));
	pl.valid = true;
	return pl;
}
}  // namespace

Plane fitGroundPlane(const std::vector<PointXYZI>& pts, const GroundParams& prm, uint32_t seed)
{
	std::vector<Eigen::Vector3f> cand;
	const double r2 = prm.candidateMaxRange_m * prm.candidateMaxRange_m;
	for (const auto& p : pts)
		if (p.z < prm.candidateMaxZ_m && double(p.x) * p.x + double(p.y) * p.y < r2)
			cand.emplace_back(p.x, p.y, p.z);
	if (cand.size() > static_cast<std::size_t>(prm.maxCandidates))
	{
		// An even subsample keeps the spatial spread of the candidates.
		std::vector<Eigen::Vector3f> sub;
		const double step = static_cast<double>(cand.size()) / prm.maxCandidates;
		for (int i = 0; i < prm.maxCandidates; i++)
			sub.push_back(cand[static_cast<std::size_t>(i * step)]);
		cand.swap(sub);
	}
	Plane best;
	if (cand.size() < 3)
		return best;
	const float cosTilt = static_cast<float>(std::cos(prm.maxTilt_deg * M_PI / 180.0));
	const float thr = static_cast<float>(prm.inlierThreshold_m);
	std::mt19937 rng(seed);
	std::uniform_int_distribution<std::size_t> pick(0, cand.size() - 1);
	for (int it = 0; it < prm.iterations; it++)
	{
		const auto &a = cand[pick(rng)], &b = cand[pick(rng)], &c = cand[pick(rng)];
		Eigen::Vector3f n = (b - a).cross(c - a);
		const float norm = n.norm();
		if (norm < 1e-6f)
			continue;
		n /= norm;
		if (n.z() < 0)
			n = -n;
		if (n.z() < cosTilt)
			continue;
		const float d = -n.dot(a);
		int inl = 0;
		for (const auto& p : cand)
			inl += std::abs(n.dot(p) + d) < thr;
		if (inl > best.inliers)
		{
			best.n = n;
			best.d = d;
			best.inliers = inl;
			best.valid = true;
		}
	}
	if (!best.valid)
		return best;
	std::vector<Eigen::Vector3f> in;
	for (const auto& p : cand)
		if (std::abs(best.n.dot(p) + best.d) < thr)
			in.push_back(p);
	Plane refined = planeFromPoints(in);
	if (refined.valid && refined.n.z() >= cosTilt)
	{
		refined.inliers = static_cast<int>(in.size());
		return refined;
	}
	return best;
}

std::optional<Eigen::Isometry3d> alignGroundPlanes(const Eigen::Isometry3d& T_ref_cur,
                                                   const Eigen::Vector3d& nRef, double dRef,
                                                   const Eigen::Vector3d& nCur, double dCur,
                                                   double maxCorrection_deg, double* correction_deg)
{
	const Eigen::Vector3d n1 = T_ref_cur.linear() * nCur;
	const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(n1, nRef);
	const double angle = Eigen::AngleAxisd(q).angle() * 180 / M_PI;
	if (correction_deg)
		*correction_deg = angle;
	if (angle > maxCorrection_deg)
		return std::nullopt;
	Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
	out.linear() = q.toRotationMatrix() * T_ref_cur.linear();
	const Eigen::Vector3d t = q * T_ref_cur.translation();
	// The current plane in the reference frame: nRef . x + (dCur - nRef . t) = 0.
	out.translation() = t + (dCur - dRef - nRef.dot(t)) * nRef;
	return out;
}

}  // namespace rasterslam::raster
