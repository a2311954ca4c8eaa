// The paper's two loop-search baselines: candidates by distance, verified by feature matching.
#include "bow_loop_detector.h"

using namespace rasterslam;

void BowLoopDetector::searchByDistance(const KeyframeData& kd, std::vector<LoopConstraint>& out)
{
	// Candidate sets: single keyframes, or the keyframes of a local map (its centre is its
	// keyframes' mean position), older than the exclusion window and within the radius.
	std::vector<std::pair<double, LocalMap>> cands;
	if (search_ == Search::Keyframes)
	{
		for (std::size_t k = 0; k < kfs_.size(); k++)
		{
			if (kfs_[k].stamp > kd.stamp - excludeRecent_s_) continue;
			const double d = (kfs_[k].pose.translation() - kd.pose.translation()).norm();
			if (d > searchRadius_m_) continue;
			LocalMap one;
			one.keyframes = {k};
			one.newestStamp = kfs_[k].stamp;
			cands.emplace_back(d, one);
		}
	}
	else
	{
		for (const auto& lm : maps_)
		{
			if (lm.newestStamp > kd.stamp - excludeRecent_s_) continue;
			Eigen::Vector3d c = Eigen::Vector3d::Zero();
			for (const auto k : lm.keyframes) c += Eigen::Vector3d(kfs_[k].pose.x(), kfs_[k].pose.y(), kfs_[k].pose.z());
			c /= static_cast<double>(lm.keyframes.size());
			const double d = (c - Eigen::Vector3d(kd.pose.x(), kd.pose.y(), kd.pose.z())).norm();
			if (d <= searchRadius_m_) cands.emplace_back(d, lm);
		}
	}
	std::sort(cands.begin(), cands.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
	std::optional<LoopConstraint> best;
	std::size_t bestDecision = 0;
	for (const auto& [dist, lm] : cands)
	{
		LoopDecision d;
		d.queryStamp = kd.stamp;
		std::size_t bestKf = 0;
		const auto fit = verify(kd.desc, kd.pts, lm, static_cast<uint32_t>(kd.node * 31), bestKf);
		d.inliers = fit.inliers.size();
		d.verified = fit.ok;
		// No BOW score here: the share of features that are inliers ranks the candidates.
		d.score = kd.pts.empty() ? 0 : static_cast<double>(d.inliers) / static_cast<double>(kd.pts.size());
		if (!fit.inliers.empty())
		{
			d.candidateStamp = kfs_[bestKf].stamp;
			d.T_candidate_query = toPose(fit.T);
		}
		d.reason = d.verified ? "ok" : "inliers";
		considerLoop(d, fit, bestKf, kd, true, best, bestDecision);
	}
	if (best)
	{
		decisions_[bestDecision].accepted = true;
		out.push_back(*best);
	}
}

