// Guided search of earlier sessions: once a session is anchored in a prior map, its keyframe
// poses are in that map's frame, so the earlier sessions' local maps near a keyframe are
// candidates whatever the place index ranks first, and the matching can be gated by the
// predicted positions (as the odometry's is). Another sensor sees the same walls at other
// heights, and few of its features match the map's: the BOW search alone found no loop to
// the first session in a whole VLP-16 session over an HDL-64E map.
#include <algorithm>

#include "bow_loop_detector.h"

using namespace rasterslam;

features::RigidResult BowLoopDetector::guidedFit(const Query& q, const LocalMap& lm,
                                                 const Eigen::Isometry3d& predicted, uint32_t seed,
                                                 uint32_t keyframes) const
{
	const Eigen::Isometry3f pf = predicted.cast<float>();
	std::vector<Eigen::Vector3f> qInAnchor, lmPts;
	qInAnchor.reserve(q.pts.size());
	for (const auto& p : q.pts)
		qInAnchor.push_back(pf * p);
	std::vector<int> rows;
	const cv::Mat cand = candidateRows(lm, keyframes, rows);
	const std::size_t nc = static_cast<std::size_t>(cand.rows);
	lmPts.reserve(nc);
	for (std::size_t r = 0; r < nc; r++)
	{
		const std::size_t i = rows.empty() ? r : static_cast<std::size_t>(rows[r]);
		lmPts.emplace_back(lm.xyz[3 * i], lm.xyz[3 * i + 1], lm.xyz[3 * i + 2]);
	}
	features::MatchParams mp = match_;
	mp.gateRadius_m = static_cast<float>(guidedGate_m_);
	const auto matches = features::matchMutual(q.desc, cand, mp, &qInAnchor, &lmPts);
	std::vector<Eigen::Vector3f> p, m;
	for (const auto& mt : matches)
	{
		p.push_back(q.pts[static_cast<std::size_t>(mt.a)]);
		m.push_back(lmPts[static_cast<std::size_t>(mt.b)]);
	}
	auto params = ransac_;
	params.minInliers = guidedMinInliers_;
	auto fit = features::ransacRigid(p, m, params, seed);
	for (auto& i : fit.inliers)
		i = matches[static_cast<std::size_t>(i)].a;  // as query feature indices
	return fit;
}

std::optional<Eigen::Isometry3d> BowLoopDetector::followedPose(const KeyframeInfo& kf,
                                                               const Map& map,
                                                               const PoseView& poses) const
{
	if (followLoop_m_ <= 0 || !lastLoop_ || lastLoop_->session + 1 != map.sessions)
		return std::nullopt;
	const auto from = poses(lastLoop_->from);
	const auto query = poses(lastLoop_->query);
	const auto verified = poses(lastLoop_->verifiedQuery);
	if (!from || !query || !verified)
		return std::nullopt;
	if ((Eigen::Vector3d(verified->x(), verified->y(), verified->z()) -
	     Eigen::Vector3d(kf.pose.x(), kf.pose.y(), kf.pose.z()))
	        .norm() > followLoop_m_)
		return std::nullopt;
	// The odometry since the loop's keyframe: the two are this session's, drifted alike.
	const Eigen::Isometry3d moved = toIsometry(*query).inverse() * toIsometry(kf.pose);
	return toIsometry(*from) * lastLoop_->T_from_query * moved;
}

std::optional<LoopConstraint> BowLoopDetector::guidedSearch(const Query& q, const KeyframeInfo& kf,
                                                            const Map& map, const PoseView& poses,
                                                            const Eigen::Isometry3d* followed)
{
	struct Cand
	{
		double dist;
		uint64_t localMap;
		uint32_t keyframes;
	};
	std::vector<Cand> cands;
	const Eigen::Isometry3d at = followed ? *followed : toIsometry(kf.pose);
	const Eigen::Vector3d here = at.translation();
	for (const auto& [id, lm] : map.localMaps)
	{
		// Earlier sessions' (this session's are the BOW search's), or following a loop this
		// session's old enough to close one.
		const bool thisSession = lm->session + 1 >= map.sessions;
		if (thisSession != (followed != nullptr))
			continue;
		const uint32_t keyframes = followed ? loopKeyframes(*lm, map, kf) : kAllKeyframes;
		if (keyframes == 0)
			continue;
		double best = std::numeric_limits<double>::max();
		for (std::size_t k = 0; k < lm->keyframes.size(); k++)
			if (keyframes & (1u << k))
				if (const auto p = poses(lm->keyframes[k]))
					best = std::min(best, (Eigen::Vector3d(p->x(), p->y(), p->z()) - here).norm());
		if (best <= guidedRadius_m_)
			cands.push_back({best, id, keyframes});
	}
	std::stable_sort(cands.begin(), cands.end(),
	                 [](const Cand& a, const Cand& b) { return a.dist < b.dist; });
	if (cands.size() > static_cast<std::size_t>(guidedMaxCandidates_))
		cands.resize(static_cast<std::size_t>(guidedMaxCandidates_));

	std::optional<LoopConstraint> best;
	std::size_t bestDecision = 0;
	for (const auto& c : cands)
	{
		const auto data = candidate(map, c.localMap);  // offline: read from the store
		if (!data)
			continue;
		const auto& lm = *data;
		const auto anchor = poses(lm.anchor());
		if (!anchor)
			continue;
		// Where the query should be in the anchor's frame; features are paired only where
		// their predicted positions agree within the gate.
		const Eigen::Isometry3d predicted = toIsometry(*anchor).inverse() * at;
		auto fit =
		    guidedFit(q, lm, predicted, static_cast<uint32_t>(kf.node * 37 + lm.id), c.keyframes);
		LoopDecision d;
		d.queryStamp = kf.stamp;
		d.score = q.pts.empty()
		              ? 0
		              : static_cast<double>(fit.inliers.size()) / static_cast<double>(q.pts.size());
		// Height from the ground planes, as a relocalization's: another sensor's features
		// sit at other heights of the same walls (measured on a VLP-16 session in an HDL-64E
		// map: up to 0.6 m off in z without this).
		bool ground = true;
		if (fit.ok)
		{
			double tilt = 0;
			const auto aligned = groundAligned(
			    q, lm, nearestKeyframe(lm, fit.T, poses, c.keyframes), fit.T, map, poses, &tilt);
			if (aligned)
				fit.T = *aligned;
			else
				ground = false;
		}
		// The registration must agree with the prediction: the gate let only nearby pairs
		// through, but a fit on a few of them can still slide along a wall.
		const bool agrees = withinPose(predicted, fit.T, guidedGate_m_, guidedGate_deg_);
		d.reason = !fit.ok    ? "inliers"
		           : !ground  ? "ground"
		           : !agrees  ? "prior"
		           : followed ? "followed"
		                      : "guided";
		consider(d, fit, lm, q, kf, map, poses, fit.ok && ground && agrees, best, bestDecision,
		         c.keyframes);
	}
	if (best)
	{
		refineLoop(*best, decisions_[bestDecision], q, kf, map, poses);
		decisions_[bestDecision].accepted = true;
		MRPT_LOG_INFO_FMT(
		    "%s loop: keyframe %llu (t=%.2f) -> keyframe %llu of %s, local map %llu, %zu "
		    "inliers",
		    followed ? "followed" : "guided", static_cast<unsigned long long>(best->to), kf.stamp,
		    static_cast<unsigned long long>(best->from),
		    followed ? "an earlier pass" : "an earlier session",
		    static_cast<unsigned long long>(best->localMap), best->inliers);
	}
	return best;
}
