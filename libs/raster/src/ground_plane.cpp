#include <rasterslam/raster/ground_plane.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
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

/** Where a scan's ground candidates end when its ground lies above the fixed bound. */
struct RaisedBound
{
	double maxZ_m = 0;
	/** Candidates nearer than this horizontally are left out (the vehicle's own returns,
	 *  which the raised bound would otherwise admit). */
	double minRange_m = 0;
};

/** The raised bound of candidates, or nullopt when the fixed one stands. Over an even sample
 *  (every 3rd to 61st point, a prime stride: 16,000 to 49,000 points of a cloud of up to a
 *  million) of the points 2.5 m (past the vehicle) to candidateMaxRange_m away horizontally
 *  and within 20 m of the frame's origin in height: when under 10 % of them lie below
 *  candidateMaxZ_m (a ground there holds far more: about half of a KITTI scan's), the bound
 *  becomes the top of the lowest 0.2 m layer of heights holding at least 30 % of the points
 *  of the fullest one, plus layerMargin_m, at most 1 m above the origin, when that top lies
 *  above the fixed bound and not above 1 m (higher, the layer is a ceiling). */
std::optional<RaisedBound> raisedBound(const std::vector<PointXYZI>& pts, const GroundParams& prm)
{
	constexpr double kBin_m = 0.2, kLow_m = -20, kHigh_m = 20, kNear_m = 2.5, kCap_m = 1.0;
	constexpr int kBins = static_cast<int>((kHigh_m - kLow_m) / kBin_m);
	std::array<uint32_t, kBins> count{};
	const float r2Max = static_cast<float>(prm.candidateMaxRange_m * prm.candidateMaxRange_m),
	            r2Min = static_cast<float>(kNear_m * kNear_m);
	// A prime stride, so that a cloud whose points are interleaved ring by ring (one of each
	// of 16 to 128 rings at every azimuth) is sampled on every ring: every 7th point of a
	// KITTI scan's 120,000.
	std::size_t stride = 1;
	for (const std::size_t s : {3, 7, 13, 31, 61})
		if (pts.size() / 16384 >= s)
			stride = s;
	uint32_t inRange = 0, below = 0;
	for (std::size_t i = 0; i < pts.size(); i += stride)
	{
		const auto& p = pts[i];
		const float r2 = p.x * p.x + p.y * p.y;
		if (!(r2 >= r2Min && r2 < r2Max && p.z >= kLow_m && p.z < kHigh_m))
			continue;  // also NaN and inf
		inRange++;
		below += p.z < prm.candidateMaxZ_m;
		const int b = std::min(kBins - 1, static_cast<int>((p.z - kLow_m) / kBin_m));
		count[static_cast<std::size_t>(b)]++;
	}
	if (inRange == 0 || 10 * below >= inRange)
		return std::nullopt;
	const uint32_t most = *std::max_element(count.begin(), count.end());
	for (int b = 0; b < kBins; b++)
		if (10 * count[static_cast<std::size_t>(b)] >= 3 * most)
		{
			// Only a layer that reaches above the bound raises it (a sensor at 1.2-1.4 m, whose
			// layer tops out just below, keeps its candidates), and only one below the cap: a
			// layer higher up is a ceiling or a roof, not the ground (nor is what lies under it).
			const double top = kLow_m + (b + 1) * kBin_m;
			if (top <= prm.candidateMaxZ_m || top > kCap_m + 1e-9)
				return std::nullopt;
			return RaisedBound{std::min(kCap_m, top + prm.layerMargin_m), kNear_m};
		}
	return std::nullopt;
}
}  // namespace

Plane fitGroundPlane(const std::vector<PointXYZI>& pts, const GroundParams& prm, uint32_t seed)
{
	std::vector<Eigen::Vector3f> cand;
	const double r2 = prm.candidateMaxRange_m * prm.candidateMaxRange_m;
	double maxZ = prm.candidateMaxZ_m, minR2 = 0;
	if (prm.layerMargin_m > 0)
		if (const auto raised = raisedBound(pts, prm))
		{
			maxZ = raised->maxZ_m;
			minR2 = raised->minRange_m * raised->minRange_m;
		}
	for (const auto& p : pts)
		if (const double pr2 = double(p.x) * p.x + double(p.y) * p.y;
		    p.z < maxZ && pr2 < r2 && pr2 >= minR2)
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
