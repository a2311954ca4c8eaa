// Relocalization (paper, "Re-localization"): a scan with no pose prior queries the database
// and is verified against the candidate local maps' points.
#include "bow_loop_detector.h"

using namespace rasterslam;

RelocalizationResult BowLoopDetector::relocalize(const Scan& scan, const RasterFrame& raster,
                                                 const Map& map, const PoseView& poses)
{
	RelocalizationResult res;
	if (!vocab_ || db_.size() == 0)
	{
		res.reason = "empty-map";
		return res;
	}
	std::vector<cv::KeyPoint> kps;
	cv::Mat all;
	orb_->extract(raster.image.asCvMatRef(), kps, all);
	Query q;
	q.desc.create(0, 32, CV_8U);
	for (int i = 0; i < static_cast<int>(kps.size()); i++)
	{
		const int32_t idx = raster::pointAtPixel(raster, kps[i].pt.x, kps[i].pt.y, 1);
		if (idx < 0)
			continue;
		const auto& p = scan.points[static_cast<std::size_t>(idx)];
		q.pts.emplace_back(p.x, p.y, p.z);
		q.desc.push_back(all.row(i));
	}
	if (q.pts.size() < static_cast<std::size_t>(relocMinInliers_))
	{
		res.reason = "features";
		return res;
	}
	return relocalizeQuery(q, static_cast<uint32_t>(scan.index * 17 + 3), map, poses);
}

RelocalizationResult BowLoopDetector::locate(const LocalMap& query, const Map& map,
                                             const PoseView& poses, int onlyKeyframe)
{
	RelocalizationResult res;
	if (!vocab_ || db_.size() == 0)
	{
		res.reason = "empty-map";
		return res;
	}
	Query q;
	q.desc.create(0, 32, CV_8U);
	for (std::size_t i = 0; i < query.points(); i++)
		if (onlyKeyframe < 0 || (query.observers[i] & (1u << onlyKeyframe)))
		{
			q.pts.emplace_back(query.xyz[3 * i], query.xyz[3 * i + 1], query.xyz[3 * i + 2]);
			q.desc.push_back(
			    cv::Mat(1, 32, CV_8U, const_cast<uint8_t*>(&query.descriptors[32 * i])));
		}
	if (q.pts.size() < static_cast<std::size_t>(relocMinInliers_))
	{
		res.reason = "features";
		return res;
	}
	return relocalizeQuery(q, static_cast<uint32_t>(query.id * 29 + 7 + onlyKeyframe), map, poses);
}

RelocalizationResult BowLoopDetector::relocalizeQuery(const Query& q, uint32_t seed, const Map& map,
                                                      const PoseView& poses)
{
	RelocalizationResult res;
	bow::BowVector b;
	vocab_->transform(descriptorsOf(q.desc), b);
	const auto results = db_.query(b, static_cast<std::size_t>(maxCandidates_ + 1));
	if (results.empty())
	{
		res.reason = "candidates";
		return res;
	}
	res.reason = "inliers";
	for (const auto& r : results)
	{
		const auto it = map.localMaps.find(entryMap_.at(r.entry));
		if (it == map.localMaps.end())
			continue;
		const auto data = candidate(map, it->first);  // offline: read from the store
		if (!data)
			continue;
		const auto& lm = *data;
		const auto fit = verify(q, lm, static_cast<uint32_t>(seed + lm.id), -1, relocMinInliers_);
		if (fit.ok && fit.inliers.size() > res.inliers)
		{
			const uint64_t kf = nearestKeyframe(lm, fit.T, poses);
			res.found = true;
			res.reason = "ok";
			res.localMap = lm.id;
			res.keyframe = kf;
			res.keyframeStamp = map.keyframes.at(kf)->stamp;
			res.score = r.score;
			res.inliers = fit.inliers.size();
			res.keyframePose = poses.at(kf);
			res.pose = poses.at(lm.anchor()) + toPose(fit.T);
		}
		else if (!res.found)
		{
			res.score = std::max(res.score, r.score);
			res.inliers = std::max(res.inliers, fit.inliers.size());
		}
	}
	return res;
}
