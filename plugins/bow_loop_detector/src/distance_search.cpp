// The paper's two loop-search baselines: candidates by distance, verified by feature matching.
#include <set>

#include "bow_loop_detector.h"

using namespace rasterslam;

void BowLoopDetector::searchByDistance(const Query& q, const KeyframeInfo& kf, const Map& map,
                                       const PoseView& poses, std::optional<LoopConstraint>& best,
                                       std::size_t& bestDecision)
{
	// Candidates: single keyframes (the points of a local map that keyframe saw), or whole
	// local maps (centred on their keyframes' mean position), older than the exclusion
	// window and within the radius (a local map through its keyframes that are).
	struct Cand
	{
		double dist;
		const LocalMap* lm;
		uint32_t keyframes;  //!< the keyframes of lm verified against
	};
	std::vector<Cand> cands;
	const Eigen::Vector3d here(kf.pose.x(), kf.pose.y(), kf.pose.z());
	std::set<uint64_t> taken;  // a keyframe shared by two local maps is a candidate once
	for (const auto& [id, lm] : map.localMaps)
	{
		const uint32_t old = loopKeyframes(*lm, map, kf);
		if (old == 0)
			continue;
		if (search_ == Search::Keyframes)
		{
			for (std::size_t k = 0; k < lm->keyframes.size() && k < 32; k++)
			{
				if (!(old & (1u << k)))
					continue;
				const auto p = poses(lm->keyframes[k]);
				if (!p)
					continue;
				if (!taken.insert(lm->keyframes[k]).second)
					continue;
				const double d = (Eigen::Vector3d(p->x(), p->y(), p->z()) - here).norm();
				if (d <= searchRadius_m_)
					cands.push_back({d, lm.get(), 1u << k});
			}
		}
		else
		{
			Eigen::Vector3d c = Eigen::Vector3d::Zero();
			int n = 0;
			for (std::size_t k = 0; k < lm->keyframes.size(); k++)
				if (const auto p = poses(lm->keyframes[k]);
				    p && (old == kAllKeyframes || (k < 32 && (old & (1u << k)))))
				{
					c += Eigen::Vector3d(p->x(), p->y(), p->z());
					++n;
				}
			if (n == 0)
				continue;
			const double d = (c / n - here).norm();
			if (d <= searchRadius_m_)
				cands.push_back({d, lm.get(), old});
		}
	}
	std::stable_sort(cands.begin(), cands.end(),
	                 [](const Cand& a, const Cand& b) { return a.dist < b.dist; });
	for (const auto& c : cands)
	{
		LoopDecision d;
		d.queryStamp = kf.stamp;
		const auto data = candidate(map, c.lm->id);  // offline: read from the store
		if (!data)
			continue;
		const auto fit =
		    verify(q, *data, static_cast<uint32_t>(kf.node * 31 + c.lm->id), c.keyframes);
		// No BOW score here: the share of features that are inliers ranks the candidates.
		d.score = q.pts.empty()
		              ? 0
		              : static_cast<double>(fit.inliers.size()) / static_cast<double>(q.pts.size());
		d.reason = fit.ok ? "ok" : "inliers";
		consider(d, fit, *data, q, kf, map, poses, true, best, bestDecision, c.keyframes);
	}
}
