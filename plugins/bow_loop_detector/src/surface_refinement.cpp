// A registration found on the features, refined on the surfaces (issue: "a verified loop is
// refined by ICP"). The features are the highest points of objects in the elevation image;
// seen from another side they are other points of the object, which biases the fit (about
// 0.2 m along the road on the KITTI street driven the other way). The scans' surfaces do not
// depend on the side they are seen from.
#include <mrpt/system/crc.h>

#include <chrono>

#include "bow_loop_detector.h"

using namespace rasterslam;

std::vector<Eigen::Vector3f> BowLoopDetector::surfaceOf(const Scan& scan) const
{
	return features::voxelDownsample(scan.points, icp_.voxel_m, icpRange_m_);
}

std::vector<Eigen::Vector3f> BowLoopDetector::surfaceOf(const LocalMap& lm)
{
	std::vector<Eigen::Vector3f> pts;
	pts.reserve(lm.surfacePoints());
	for (std::size_t i = 0; i < lm.surfaceCm.size(); i += 3)
		pts.emplace_back(lm.surfaceCm[i] * 0.01f, lm.surfaceCm[i + 1] * 0.01f,
		                 lm.surfaceCm[i + 2] * 0.01f);
	return pts;
}

bool BowLoopDetector::refineOnSurface(const std::vector<Eigen::Vector3f>& surface,
                                      const LocalMap& lm, Eigen::Isometry3d& T) const
{
	if (!icpRefine_ || surface.empty() || lm.surfacePoints() < 100)
		return false;
	const auto t0 = std::chrono::steady_clock::now();
	std::lock_guard<std::mutex> lock(targetsMutex_);
	if (!targets_)
		targets_ = std::make_unique<features::IcpTargetCache>(4, icp_);
	// The fingerprint covers the whole surface: a local map still being added to, or another
	// map's local map under the same id, is another target.
	const uint64_t fingerprint =
	    (static_cast<uint64_t>(lm.surfaceCm.size()) << 32) |
	    mrpt::system::compute_CRC32(reinterpret_cast<const uint8_t*>(lm.surfaceCm.data()),
	                                lm.surfaceCm.size() * sizeof(int16_t));
	const auto tgt = targets_->get(lm.id, fingerprint, [&lm] { return surfaceOf(lm); });
	const auto t1 = std::chrono::steady_clock::now();
	const auto r = features::icpPointToPlane(surface, *tgt, T, icp_);
	const auto t2 = std::chrono::steady_clock::now();
	const Eigen::Isometry3d delta = T.inverse() * r.T;
	const double moved = delta.translation().norm();
	const double turned = Eigen::AngleAxisd(delta.linear()).angle() * 180.0 / M_PI;
	const bool ok = r.converged && moved <= icpMaxCorrection_m_ && turned <= icpMaxCorrection_deg_;
	MRPT_LOG_DEBUG_FMT(
	    "surface refinement on local map %llu: %s, %d iterations, moved %.3f m %.2f deg, overlap "
	    "%.2f; %zu and %zu points, %.1f + %.1f ms",
	    static_cast<unsigned long long>(lm.id), ok ? "taken" : "refused", r.iterations, moved,
	    turned, r.overlap, surface.size(), tgt->size(),
	    std::chrono::duration<double, std::milli>(t1 - t0).count(),
	    std::chrono::duration<double, std::milli>(t2 - t1).count());
	if (ok)
		T = r.T;
	return ok;
}

void BowLoopDetector::refineLoop(LoopConstraint& c, LoopDecision& d, const Query& q,
                                 const KeyframeInfo& kf, const Map& map, const PoseView& poses)
{
	// The keyframe's scan, or the query's own surface when it has no scan (a local map).
	if (!icpRefine_ || (!kf.scan && !q.surface))
		return;
	const auto lm = candidate(map, c.localMap);
	if (!lm || lm->surfacePoints() == 0)
		return;
	const auto T_anchor_from = poses.at(c.from) - poses.at(lm->anchor());
	Eigen::Isometry3d T = toIsometry(T_anchor_from + c.T_from_to);
	if (!refineOnSurface(kf.scan ? surfaceOf(*kf.scan) : q.surface(), *lm, T))
		return;
	c.from = nearestKeyframe(*lm, T, poses, loopKeyframes(*lm, map, kf));
	double tilt = 0;
	if (const auto g = groundAligned(q, *lm, c.from, T, map, poses, &tilt))
		T = *g;
	const auto T_anchor_kf = poses.at(c.from) - poses.at(lm->anchor());
	c.T_from_to = (mrpt::poses::CPose3D() - T_anchor_kf) + toPose(T);
	d.T_candidate_query = c.T_from_to;
	d.candidateStamp = map.keyframes.at(c.from)->stamp;
}
