// Relocalization (paper, "Re-localization"): a scan with no pose prior queries the database
// and is verified against the candidate local maps' points.
#include <rasterslam/raster/ground_plane.h>

#include "bow_loop_detector.h"

using namespace rasterslam;

RelocalizationResult BowLoopDetector::relocalize(const Scan& scan, const RasterFrame& raster,
                                                 const Map& map, const PoseView& poses)
{
	return relocalizeScan(scan, raster, PlaceContext{}, map, poses);
}

RelocalizationResult BowLoopDetector::relocalizeScan(const Scan& scan, const RasterFrame& raster,
                                                     const PlaceContext& context, const Map& map,
                                                     const PoseView& poses)
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
	q.groundValid = raster.groundValid;
	q.groundN =
	    Eigen::Vector3d(raster.groundNormal[0], raster.groundNormal[1], raster.groundNormal[2]);
	q.groundD = raster.groundD;
	if (directLevels_ > 0)
		q.groups = groupsOf(q.desc);
	if (icpRefine_ || relocMaxConflicts_ < 1)
		q.surface = [this, &scan] { return surfaceOf(scan); };
	if (polarRelocalization_ && canFuse(&context))
		q.contexts.push_back(contextOf(context.rings, context.sectors, context.cells.data()));
	if (canonicalYaw_)
	{
		const auto words = canonicalWords(scan, raster);
		return relocalizeQuery(q, static_cast<uint32_t>(scan.index * 17 + 3), map, poses, &words);
	}
	if (queryTurns_ > 1)
	{
		const auto turns = turnedViews(scan, raster);
		return relocalizeQuery(q, static_cast<uint32_t>(scan.index * 17 + 3), map, poses, nullptr,
		                       &turns);
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
	if (directLevels_ > 0)
		q.groups = groupsOf(q.desc);
	// The free-space check also for one keyframe (map merge locates each): where the
	// keyframe's features put the local map, its whole surface must not stand on the other
	// map's bare ground.
	if (icpRefine_ || relocMaxConflicts_ < 1)
		q.surface = [&query] { return surfaceOf(query); };
	q.poseFromSurface = onlyKeyframe < 0;
	// polar_fusion: the query's contexts (about the keyframe, or about each of them) rank the
	// places too, when it was made with contexts of the index's dimensions.
	const std::size_t cells = std::size_t{query.contextRings} * query.contextSectors;
	if (query.contexts() > 0 && canFuse(query.contextRings, query.contextSectors, cells))
		for (std::size_t k = 0; k < query.contexts(); k++)
			if (onlyKeyframe < 0 || k == static_cast<std::size_t>(onlyKeyframe))
				q.contexts.push_back(contextOf(query.contextRings, query.contextSectors,
				                               query.contextCells.data() + k * cells));
	return relocalizeQuery(q, static_cast<uint32_t>(query.id * 29 + 7 + onlyKeyframe), map, poses);
}

double BowLoopDetector::selfScore(const std::vector<bow::Descriptor>& desc) const
{
	// The query's two halves, even and odd features, scored against each other stand for
	// what the same place scores. Halves of a few features score by chance (two words shared
	// or none): under 40 features a query gets no normalizer, its scores read 0 and min_score
	// refuses it (40: a little over twice the default relocalization_min_inliers, 18).
	return vocab_->selfScore(desc, 40);
}

RelocalizationResult BowLoopDetector::relocalizeQuery(const Query& q, uint32_t seed, const Map& map,
                                                      const PoseView& poses,
                                                      const bow::BowVector* words,
                                                      const std::vector<TurnedView>* turns)
{
	RelocalizationResult res;
	bow::BowVector b;
	const auto desc = descriptorsOf(q.desc);
	if (words)
		b = *words;
	else
		vocab_->transform(desc, b);
	// A single query has no previous keyframe to normalize by (DBoW2 does that for loops).
	const double norm = selfScore(desc);
	// The candidates examined: the words' first max_candidates + 1, or with polar_fusion as
	// many of the words' and the contexts' rankings fused.
	const auto n = static_cast<std::size_t>(maxCandidates_ + 1);
	const bool fuse = !q.contexts.empty();
	const auto m = fuse ? std::max(n, static_cast<std::size_t>(polarResults_)) : n;
	const auto results = turns ? queryWithTurns(b, norm, *turns, m) : db_.query(b, m);
	std::vector<Candidate> candidates;
	if (fuse)
		candidates = fusedCandidates(results, q.contexts);
	else
		for (const auto& r : results)
			candidates.push_back({entryMap_.at(r.entry), r.score, -1, false});
	if (candidates.size() > n)
		candidates.resize(n);
	if (candidates.empty())
	{
		res.reason = "candidates";
		return res;
	}
	res.reason = "inliers";
	LocalMap::ConstPtr bestMap;
	Eigen::Isometry3d bestT = Eigen::Isometry3d::Identity();
	// The query's surface, made once when first needed.
	std::optional<std::vector<Eigen::Vector3f>> querySurface;
	const auto surfaceOfQuery = [&]() -> const std::vector<Eigen::Vector3f>&
	{
		if (!querySurface)
			querySurface = q.surface();
		return *querySurface;
	};
	const bool judgeFreeSpace =
	    q.surface && (relocMaxConflicts_ < 1 || getMinLoggingLevel() <= mrpt::system::LVL_DEBUG);
	// While nothing is placed, the result says how far the candidates got: refused on its
	// score (0), verified with too few inliers (1), refused on its ground or free space (2).
	// A later candidate that gets less far does not overwrite the reason.
	int reached = -1;
	const auto notPlaced =
	    [&res, &reached](const char* reason, int reach, double score, std::size_t inliers)
	{
		if (res.found)
			return;
		if (reach >= reached)
		{
			res.reason = reason;
			reached = reach;
		}
		res.score = std::max(res.score, score);
		res.inliers = std::max(res.inliers, inliers);
	};
	for (auto& r : candidates)
	{
		const auto it = map.localMaps.find(r.localMap);
		if (it == map.localMaps.end())
			continue;
		scoreOf(r, b);  // ranked by its context only: its words' score is needed now
		const double score = norm > 1e-6 ? r.rawScore / norm : 0;
		// min_score before the verification: a candidate the words do not support costs no
		// matching (scans of another town against a KITTI map: 90 % score under 0.32; true
		// places 0.44 and up on the simulated town, 1.04 and up on the KITTI street), unless
		// polar_max_distance accepts its context.
		const bool closeContext =
		    polarMaxDistance_ > 0 && r.polarDistance >= 0 && r.polarDistance <= polarMaxDistance_;
		if (score < minScore_ && !closeContext)
		{
			notPlaced("score", 0, score, 0);
			continue;
		}
		const auto data = candidate(map, it->first);  // offline: read from the store
		if (!data)
			continue;
		const auto& lm = *data;
		const auto fit =
		    verify(q, lm, static_cast<uint32_t>(seed + lm.id), kAllKeyframes, relocMinInliers_);
		// Compared with the best place taken only: a fit refused on its ground or free space
		// (res.inliers reports it) must not hide a right place of fewer inliers after it.
		if (fit.ok && fit.inliers.size() > (res.found ? res.inliers : 0))
		{
			const uint64_t kf = nearestKeyframe(lm, fit.T, poses);
			double tilt = 0;
			const auto T = groundAligned(q, lm, kf, fit.T, map, poses, &tilt);
			if (!T)
			{
				notPlaced("ground", 2, score, fit.inliers.size());
				continue;
			}
			if (judgeFreeSpace)
			{
				// A place of another town can fit as many features as a true one, but its walls
				// and poles stand where the query saw bare ground (and the other way).
				const auto free =
				    features::freeSpaceConflicts(surfaceOfQuery(), surfaceOf(lm), *T, freeSpace_);
				const bool refused = free.share() > relocMaxConflicts_;
				MRPT_LOG_DEBUG_FMT(
				    "features fit local map %llu: %zu inliers, free-space conflicts %zu of %zu "
				    "(%.3f): %s",
				    static_cast<unsigned long long>(lm.id), fit.inliers.size(), free.conflicts,
				    free.compared, free.share(), refused ? "refused" : "kept");
				if (refused)
				{
					notPlaced("free-space", 2, score, fit.inliers.size());
					continue;
				}
			}
			res.found = true;
			res.reason = "ok";
			res.localMap = lm.id;
			res.keyframe = kf;
			res.keyframeStamp = map.keyframes.at(kf)->stamp;
			res.score = score;
			res.inliers = fit.inliers.size();
			res.keyframePose = poses.at(kf);
			res.pose = poses.at(lm.anchor()) + toPose(*T);
			bestMap = data;
			bestT = *T;
		}
		else
			notPlaced("inliers", 1, score, fit.inliers.size());
	}
	if (!res.found && surfaceSearch_ && q.surface && q.poseFromSurface)
	{
		// No candidate verified on the features: far revisits (15-30 m along the road) match
		// too few descriptors, while their surfaces still overlap. The best-scored candidates
		// are aligned on the surfaces with no prior; the features, matched only near where an
		// alignment puts them, then decide.
		const auto& surface = surfaceOfQuery();
		int tried = 0;
		for (auto& r : candidates)
		{
			if (tried >= surfaceSearchCandidates_)
				break;
			scoreOf(r, b);
			const double score = norm > 1e-6 ? r.rawScore / norm : 0;
			if (score < minScore_)
				continue;  // in the fused order a lower-scored candidate may come first
			const auto it = map.localMaps.find(r.localMap);
			if (it == map.localMaps.end())
				continue;
			const auto data = candidate(map, it->first);
			if (!data)
				continue;
			tried++;
			// The surfaces of streets look alike (another simulated town's scans reach the
			// same overlaps as true places): the features decide. Matched only near where an
			// alignment puts them, they must fit a pose within the guided gate of it, and the
			// best alignment must hold surface_search_inlier_ratio times the inliers of any
			// other distinct one (a street whose parts repeat fits several).
			struct Held
			{
				Eigen::Isometry3d T;
				std::size_t inliers = 0;
			};
			std::vector<Held> held;
			const auto target = surfaceOf(*data);
			for (const auto& a : searchOnSurface(surface, *data, target))
			{
				const auto fit = guidedFit(q, *data, a.T, static_cast<uint32_t>(seed + data->id));
				const bool agrees =
				    fit.ok && withinPose(a.T, fit.T, guidedGate_m_, guidedGate_deg_);
				held.push_back({a.T, agrees ? fit.inliers.size() : 0});
			}
			std::stable_sort(held.begin(), held.end(),
			                 [](const Held& x, const Held& y) { return x.inliers > y.inliers; });
			if (held.empty() || held.front().inliers == 0)
				continue;
			std::size_t second = 0;
			for (std::size_t i = 1; i < held.size(); i++)
			{
				if (!withinPose(held.front().T, held[i].T, planar_.distinct_m,
				                planar_.distinct_deg))
					second = std::max(second, held[i].inliers);
			}
			const bool distinct =
			    held.front().inliers >= static_cast<std::size_t>(surfaceSearchMinInliers_) &&
			    static_cast<double>(held.front().inliers) >=
			        surfaceSearchInlierRatio_ * static_cast<double>(second);
			const std::size_t agreeing = agreeingMatches(q, *data, held.front().T, 1.0);
			const bool passes =
			    distinct && agreeing >= static_cast<std::size_t>(surfaceSearchMinAgreeing_);
			// Another town's street can hold as many features and as much surface as the right
			// one, but not the same free space: its walls and poles stand on the map's road.
			// Checked when the rest passes (and for the debug log).
			features::FreeSpaceCheck free;
			if (passes || getMinLoggingLevel() <= mrpt::system::LVL_DEBUG)
				free = features::freeSpaceConflicts(surface, target, held.front().T, freeSpace_);
			const bool taken = passes && free.share() <= surfaceSearchMaxConflicts_;
			MRPT_LOG_DEBUG_FMT(
			    "surface pose on local map %llu: %zu guided inliers, next %zu, %zu agreeing, "
			    "free-space conflicts %zu of %zu (%.3f): %s",
			    static_cast<unsigned long long>(data->id), held.front().inliers, second, agreeing,
			    free.conflicts, free.compared, free.share(), taken ? "taken" : "refused");
			if (!taken)
				continue;
			const auto T = std::optional<Eigen::Isometry3d>(held.front().T);
			const std::size_t inliers = held.front().inliers;
			const uint64_t kf = nearestKeyframe(*data, *T, poses);
			double tilt = 0;
			const auto g = groundAligned(q, *data, kf, *T, map, poses, &tilt);
			if (!g)
				continue;
			res.found = true;
			res.reason = "surface";
			res.localMap = data->id;
			res.keyframe = kf;
			res.keyframeStamp = map.keyframes.at(kf)->stamp;
			res.score = score;
			res.inliers = inliers;  // guided by the surface pose
			res.keyframePose = poses.at(kf);
			res.pose = poses.at(data->anchor()) + toPose(*g);
			return res;
		}
	}
	if (bestMap && q.surface && q.poseFromSurface && icpRefine_ &&
	    refineOnSurface(surfaceOfQuery(), *bestMap, bestT))
	{
		res.keyframe = nearestKeyframe(*bestMap, bestT, poses);
		// Height from the two ground planes again, as before the refinement: on the rendered
		// KITTI revisits ICP leaves the height 0.044 m off (median), the planes 0.029 m.
		double tilt = 0;
		if (const auto g = groundAligned(q, *bestMap, res.keyframe, bestT, map, poses, &tilt))
			bestT = *g;
		res.keyframeStamp = map.keyframes.at(res.keyframe)->stamp;
		res.keyframePose = poses.at(res.keyframe);
		res.pose = poses.at(bestMap->anchor()) + toPose(bestT);
	}
	return res;
}

std::optional<Eigen::Isometry3d> BowLoopDetector::groundAligned(
    const Query& q, const LocalMap& lm, uint64_t kf, const Eigen::Isometry3d& T, const Map& map,
    const PoseView& poses, double* tilt_deg) const
{
	*tilt_deg = 0;
	const auto it = map.keyframes.find(kf);
	if (!q.groundValid || it == map.keyframes.end() || !it->second->groundValid)
		return T;
	const auto& k = *it->second;
	// Both planes in the keyframe's frame: T_kf_query = T_kf_anchor * T_anchor_query.
	const Eigen::Isometry3d T_anchor_kf = toIsometry(poses.at(kf) - poses.at(lm.anchor()));
	const Eigen::Isometry3d T_kf_query = T_anchor_kf.inverse() * T;
	const Eigen::Vector3d nK(k.groundN[0], k.groundN[1], k.groundN[2]);
	const auto aligned = raster::alignGroundPlanes(T_kf_query, nK, k.groundD, q.groundN, q.groundD,
	                                               groundMaxTilt_deg_, tilt_deg);
	if (!aligned)
		return std::nullopt;
	// Height only: the ground point under the query goes onto the keyframe's plane. Roll and
	// pitch stay the registration's: at a few metres to the side (a kerb, the camber) the
	// local planes differ, and turning the pose onto them made its tilt worse (rendered KITTI
	// revisits: median tilt error 0.22 -> 0.34 deg, 154 -> 149 of 160 correct; this way 155).
	const Eigen::Vector3d g = T_kf_query * (-q.groundD * q.groundN);
	Eigen::Isometry3d out = T_kf_query;
	out.translation() -= (nK.dot(g) + k.groundD) * nK;
	return T_anchor_kf * out;
}

namespace
{
/** The ground plane a RasterFrame was made with. */
raster::Plane planeOf(const RasterFrame& raster)
{
	raster::Plane plane;
	plane.valid = raster.groundValid;
	plane.n =
	    Eigen::Vector3f(raster.groundNormal[0], raster.groundNormal[1], raster.groundNormal[2]);
	plane.d = raster.groundD;
	return plane;
}
}  // namespace

bow::BowVector BowLoopDetector::canonicalWords(const Scan& scan, const RasterFrame& raster) const
{
	const auto yaw = static_cast<float>(raster::dominantEdgeAngle(raster.image.asCvMatRef()));
	const auto plane = planeOf(raster);
	RasterFrame turned;
	raster::rasterizeElevationTurned(scan.points, plane, raster::RasterParams(), yaw, turned);
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb_->extract(turned.image.asCvMatRef(), kps, desc);
	bow::BowVector b;
	vocab_->transform(descriptorsOf(desc), b);
	return b;
}

std::vector<BowLoopDetector::TurnedView> BowLoopDetector::turnedViews(
    const Scan& scan, const RasterFrame& raster) const
{
	return places::turnedViews(scan.points, planeOf(raster), raster::RasterParams(), queryTurns_,
	                           *vocab_, *orb_);
}

std::vector<BowLoopDetector::TurnedView> BowLoopDetector::viewsOf(
    const std::vector<std::vector<uint8_t>>& descriptors) const
{
	std::vector<TurnedView> out;
	for (const auto& blob : descriptors)
	{
		const auto d = bow::toDescriptors(blob.data(), blob.size() / 32);
		TurnedView v;
		vocab_->transform(d, v.words);
		v.selfScore = vocab_->selfScore(d);
		out.push_back(std::move(v));
	}
	return out;
}

std::vector<bow::Database::Result> BowLoopDetector::queryWithTurns(
    const bow::BowVector& b, double norm, const std::vector<TurnedView>& turns, std::size_t n) const
{
	std::vector<bow::Database::View> views{{&b, norm}};
	for (const auto& [w, self] : turns)
		views.push_back({&w, self, queryTurnWeight_});
	return db_.queryViews(views, n);
}
