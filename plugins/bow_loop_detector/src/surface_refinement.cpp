// A registration found on the features, refined on the surfaces (issue: "a verified loop is
// refined by ICP"). The features are the highest points of objects in the elevation image;
// seen from another side they are other points of the object, which biases the fit (about
// 0.2 m along the road on the KITTI street driven the other way). The scans' surfaces do not
// depend on the side they are seen from.
#include <mrpt/system/crc.h>

#include <algorithm>
#include <chrono>
#include <unordered_set>

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

std::shared_ptr<const features::IcpTarget> BowLoopDetector::targetOf(const LocalMap& lm) const
{
	if (!targets_)
		targets_ = std::make_unique<features::IcpTargetCache>(4, icp_);
	// The fingerprint covers the whole surface: a local map still being added to, or another
	// map's local map under the same id, is another target.
	const uint64_t fingerprint =
	    (static_cast<uint64_t>(lm.surfaceCm.size()) << 32) |
	    mrpt::system::compute_CRC32(reinterpret_cast<const uint8_t*>(lm.surfaceCm.data()),
	                                lm.surfaceCm.size() * sizeof(int16_t));
	return targets_->get(lm.id, fingerprint, [&lm] { return surfaceOf(lm); });
}

std::vector<BowLoopDetector::SurfaceAlignment> BowLoopDetector::searchOnSurface(
    const std::vector<Eigen::Vector3f>& surface, const LocalMap& lm,
    const std::vector<Eigen::Vector3f>& target) const
{
	std::vector<SurfaceAlignment> fits;
	if (surface.empty() || lm.surfacePoints() < 100)
		return fits;
	const auto t0 = std::chrono::steady_clock::now();
	const auto hyps = features::planarSearch(surface, target, planar_);
	const auto t1 = std::chrono::steady_clock::now();
	std::lock_guard<std::mutex> lock(targetsMutex_);
	const auto tgt = targetOf(lm);
	// From a peak of the search (a cell and a yaw step off) ICP first reaches farther, on the
	// query's surface in voxels twice as large and stopped at steps of a centimetre and 0.05
	// deg: the second stage, at the full resolution, gives the pose.
	auto coarse = icp_;
	coarse.maxCorrespondence_m = std::max(icp_.maxCorrespondence_m, 3 * planar_.cell_m);
	coarse.voxel_m = 2 * icp_.voxel_m;
	coarse.convergedTranslation_m = 0.01;
	coarse.convergedRotation_rad = 0.05 * M_PI / 180;
	const auto coarseSurface = features::voxelDownsample(surface, coarse.voxel_m);
	// The overlap is counted over the query's points that land where the local map has
	// points (its footprint, 2 m cells): a query beyond the end of the mapped street is not
	// to score less than one pulled over the map, where its own surroundings do not fit.
	const double fcell = 2.0;
	std::unordered_set<int64_t> footprint;
	// Cells packed as cx * 2^24 + cy (|cy| < 2^23: the surfaces are in centimetres in int16,
	// +-328 m, and the query's points within icp_range_m of a pose on them).
	const auto key = [fcell](double x, double y)
	{
		return static_cast<int64_t>(std::floor(x / fcell)) * (int64_t(1) << 24) +
		       static_cast<int64_t>(std::floor(y / fcell));
	};
	for (const auto& p : target)
		footprint.insert(key(p.x(), p.y()));
	const auto reduced = features::voxelDownsample(surface, icp_.voxel_m);
	// Peaks that the first stage takes to where an earlier one's went, refined to a converged
	// alignment, would end at the same alignment.
	std::vector<Eigen::Isometry3d> reached;
	int coarseIterations = 0, fineIterations = 0, refined = 0;
	for (const auto& h : hyps)
	{
		const auto r0 = features::icpPointToPlane(coarseSurface, *tgt, h.T, coarse);
		coarseIterations += r0.iterations;
		const bool again = std::any_of(reached.begin(), reached.end(),
		                               [&r0](const Eigen::Isometry3d& x)
		                               { return withinPose(x, r0.T, 0.1, 0.5); });
		if (again)
			continue;
		const auto r = features::icpPointToPlane(reduced, *tgt, r0.T, icp_);
		fineIterations += r.iterations;
		refined++;
		if (r.converged)  // else a later peak reaching the same pose is tried again
			reached.push_back(r0.T);
		std::size_t inside = 0;
		for (const auto& p : reduced)
		{
			const Eigen::Vector3d q = r.T * p.cast<double>();
			inside += footprint.count(key(q.x(), q.y()));
		}
		const double ov = r.converged && inside >= 200 ? double(r.matched) / double(inside) : 0;
		if (ov >= surfaceSearchMinOverlap_)
			fits.push_back({r.T, ov});
	}
	const auto t2 = std::chrono::steady_clock::now();
	std::sort(fits.begin(), fits.end(),
	          [](const SurfaceAlignment& a, const SurfaceAlignment& b)
	          { return a.overlap > b.overlap; });
	MRPT_LOG_DEBUG_FMT(
	    "surface search on local map %llu: %zu of %zu alignments reach the overlap, best %.3f "
	    "(%d peaks refined, any other ending where one did; %d + %d ICP iterations); %.1f + "
	    "%.1f ms",
	    static_cast<unsigned long long>(lm.id), fits.size(), hyps.size(),
	    fits.empty() ? 0.0 : fits.front().overlap, refined, coarseIterations, fineIterations,
	    std::chrono::duration<double, std::milli>(t1 - t0).count(),
	    std::chrono::duration<double, std::milli>(t2 - t1).count());
	return fits;
}

bool BowLoopDetector::refineOnSurface(const std::vector<Eigen::Vector3f>& surface,
                                      const LocalMap& lm, Eigen::Isometry3d& T) const
{
	if (!icpRefine_ || surface.empty() || lm.surfacePoints() < 100)
		return false;
	const auto t0 = std::chrono::steady_clock::now();
	std::lock_guard<std::mutex> lock(targetsMutex_);
	const auto tgt = targetOf(lm);
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
