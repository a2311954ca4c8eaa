// Loop closure over a bag-of-words database of local-map images (paper, "BOW Database" and
// "Loop Closure"): the map manager hands over each finished local map's image words; every
// new keyframe queries the database, and candidates are verified by matching the keyframe's
// features against the candidate local map's points (after its local BA).
#include "bow_loop_detector.h"

#include <mrpt/io/CMemoryStream.h>
#include <rasterslam/map/registration.h>

using namespace rasterslam;

IMPLEMENTS_MRPT_OBJECT(BowLoopDetector, LoopDetector, rasterslam)

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_plugin_bow_loop_detector)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::BowLoopDetector));
}

void BowLoopDetector::initializeImpl(ParamReader& p)
{
	vocabularyFile_ = p.getPath("vocabulary_file", "");
	const auto search = p.getChoice("search", "bow", {"bow", "keyframes", "localmaps"});
	search_ = search == "bow" ? Search::Bow
	                          : (search == "keyframes" ? Search::Keyframes : Search::LocalMaps);
	searchRadius_m_ = p.getDouble("search_radius_m", searchRadius_m_);
	onlineMinMaps_ = p.getInt("online_min_maps", onlineMinMaps_);
	onlineBranching_ = p.getInt("online_branching", onlineBranching_);
	onlineLevels_ = p.getInt("online_levels", onlineLevels_);
	queryOrb_.numFeatures = p.getInt("query_features", 3000);
	queryOrb_.levels = 3;
	excludeRecent_s_ = p.getDouble("exclude_recent_s", excludeRecent_s_);
	minScore_ = p.getDouble("min_score", minScore_);
	polarFusion_ = p.getBool("polar_fusion", false);
	polarParams_ = places::PolarParams();
	polarParams_.ringCandidates = p.getInt("polar_candidates", polarParams_.ringCandidates);
	polarParams_.shiftCandidates = p.getInt("polar_shift_candidates", polarParams_.shiftCandidates);
	polarResults_ = p.getInt("polar_results", 50);
	fuseK_ = p.getDouble("fuse_k", 10);
	polarMaxDistance_ = p.getDouble("polar_max_distance", 0);
	polarRelocalization_ = p.getBool("polar_relocalization", polarRelocalization_);
	p.requireAtLeast(polarParams_.ringCandidates, 1, "polar_candidates");
	p.requireRange(polarParams_.shiftCandidates, 1, 720, "polar_shift_candidates");
	p.requireAtLeast(polarResults_, 1, "polar_results");
	p.requireRange(fuseK_, 0, 1000, "fuse_k");
	p.requireRange(polarMaxDistance_, 0, 1, "polar_max_distance");
	maxCandidates_ = p.getInt("max_candidates", maxCandidates_);
	match_.maxDistance = p.getInt("max_hamming", 64);
	match_.ratio = static_cast<float>(p.getDouble("ratio", 0.9));
	ransac_.inlierThreshold_m = p.getDouble("ransac_threshold_m", 0.4);
	ransac_.minInliers = p.getInt("min_inliers", 25);
	ransac_.maxIterations = p.getInt("ransac_max_iterations", 1000);
	relocMinInliers_ = p.getInt("relocalization_min_inliers", relocMinInliers_);
	relocMaxConflicts_ = p.getDouble("relocalization_max_conflicts", relocMaxConflicts_);
	groundMaxTilt_deg_ = p.getDouble("relocalization_max_tilt_deg", groundMaxTilt_deg_);
	pointSigma_m_ = p.getDouble("point_sigma_m", pointSigma_m_);
	canonicalYaw_ = p.getBool("canonical_yaw", canonicalYaw_);
	queryTurns_ = p.getInt("query_turns", queryTurns_);
	queryTurnWeight_ = p.getDouble("query_turn_weight", queryTurnWeight_);
	directLevels_ = p.getInt("direct_index_levels_up", directLevels_);
	stopAtInliers_ = p.getInt("stop_at_inliers", stopAtInliers_);
	guidedRadius_m_ = p.getDouble("guided_radius_m", guidedRadius_m_);
	guidedGate_m_ = p.getDouble("guided_gate_m", guidedGate_m_);
	guidedGate_deg_ = p.getDouble("guided_gate_deg", guidedGate_deg_);
	guidedMinInliers_ = p.getInt("guided_min_inliers", guidedMinInliers_);
	guidedMaxCandidates_ = p.getInt("guided_max_candidates", guidedMaxCandidates_);
	followLoop_m_ = p.getDouble("follow_loop_m", followLoop_m_);
	icpRefine_ = p.getBool("icp_refine", icpRefine_);
	icp_.voxel_m = p.getDouble("icp_voxel_m", 0.8);
	icpRange_m_ = p.getDouble("icp_range_m", icpRange_m_);
	icp_.maxCorrespondence_m = p.getDouble("icp_max_distance_m", 1.0);
	icp_.maxIterations = p.getInt("icp_max_iterations", 30);
	icpMaxCorrection_m_ = p.getDouble("icp_max_correction_m", icpMaxCorrection_m_);
	icpMaxCorrection_deg_ = p.getDouble("icp_max_correction_deg", icpMaxCorrection_deg_);
	surfaceSearch_ = p.getBool("relocalization_surface_search", surfaceSearch_);
	surfaceSearchCandidates_ = p.getInt("surface_search_candidates", surfaceSearchCandidates_);
	surfaceSearchMinOverlap_ = p.getDouble("surface_search_min_overlap", surfaceSearchMinOverlap_);
	surfaceSearchInlierRatio_ =
	    p.getDouble("surface_search_inlier_ratio", surfaceSearchInlierRatio_);
	surfaceSearchMinInliers_ = p.getInt("surface_search_min_inliers", surfaceSearchMinInliers_);
	surfaceSearchMinAgreeing_ = p.getInt("surface_search_min_agreeing", surfaceSearchMinAgreeing_);
	surfaceSearchMaxConflicts_ =
	    p.getDouble("surface_search_max_conflicts", surfaceSearchMaxConflicts_);
	freeSpace_ = features::FreeSpaceParams();
	freeSpace_.minTop_m = p.getDouble("free_space_min_top_m", 2.5);
	planar_.yawStep_deg = p.getDouble("surface_search_yaw_step_deg", planar_.yawStep_deg);
	planar_.range_m = icpRange_m_;
	planar_.hypotheses = p.getInt("surface_search_hypotheses", planar_.hypotheses);
	p.requirePositive(searchRadius_m_, "search_radius_m");
	p.requireAtLeast(onlineMinMaps_, 2, "online_min_maps");
	p.requireAtLeast(onlineBranching_, 2, "online_branching");
	p.requireAtLeast(onlineLevels_, 1, "online_levels");
	p.requireRange(queryOrb_.numFeatures, 1, features::kMaxFeatures, "query_features");
	p.requireAtLeast(excludeRecent_s_, 0, "exclude_recent_s");
	p.requireAtLeast(minScore_, 0, "min_score");  // normalized: may exceed 1
	p.requireAtLeast(maxCandidates_, 1, "max_candidates");
	p.requireAtLeast(stopAtInliers_, 0, "stop_at_inliers");     // 0: verify every candidate
	p.requireRange(match_.maxDistance, 0, 256, "max_hamming");  // ORB: 256-bit descriptors
	p.require(match_.ratio > 0 && match_.ratio <= 1, match_.ratio, "ratio",
	          "must be in (0, 1] (1 disables the test)");
	p.requirePositive(ransac_.inlierThreshold_m, "ransac_threshold_m");
	p.requireAtLeast(ransac_.minInliers, 3, "min_inliers");  // a rigid fit takes 3 points
	p.requireAtLeast(ransac_.maxIterations, 1, "ransac_max_iterations");
	p.requireAtLeast(relocMinInliers_, 3, "relocalization_min_inliers");
	p.requireRange(relocMaxConflicts_, 0, 1, "relocalization_max_conflicts");
	p.requireRange(groundMaxTilt_deg_, 0, 180, "relocalization_max_tilt_deg");
	p.requirePositive(pointSigma_m_, "point_sigma_m");
	p.requireRange(directLevels_, 0, 8, "direct_index_levels_up");
	p.requireRange(queryTurns_, 1, 16, "query_turns");
	p.requireRange(queryTurnWeight_, 0, 1, "query_turn_weight");
	if (queryTurns_ > 1 && canonicalYaw_)
		p.reject("query_turns", "and canonical_yaw both turn the query's image: use one");
	p.requireAtLeast(guidedRadius_m_, 0, "guided_radius_m");  // 0: off
	p.requirePositive(guidedGate_m_, "guided_gate_m");
	p.requireRange(guidedGate_deg_, 0, 180, "guided_gate_deg");
	p.requireAtLeast(guidedMinInliers_, 3, "guided_min_inliers");
	p.requireAtLeast(guidedMaxCandidates_, 1, "guided_max_candidates");
	p.requireAtLeast(followLoop_m_, 0, "follow_loop_m");  // 0: off
	p.requireRange(icp_.voxel_m, 0.05, 5.0, "icp_voxel_m");
	p.requireRange(icpRange_m_, 1.0, 150.0, "icp_range_m");
	p.requirePositive(icp_.maxCorrespondence_m, "icp_max_distance_m");
	p.requireRange(icp_.maxIterations, 1, 1000, "icp_max_iterations");
	p.requirePositive(icpMaxCorrection_m_, "icp_max_correction_m");
	p.requireRange(icpMaxCorrection_deg_, 0, 180, "icp_max_correction_deg");
	if (surfaceSearch_ && !icpRefine_)
		p.reject("relocalization_surface_search", "needs icp_refine (the query's surface)");
	p.requireAtLeast(surfaceSearchCandidates_, 1, "surface_search_candidates");
	p.requireRange(surfaceSearchMinOverlap_, 0, 1, "surface_search_min_overlap");
	p.requireAtLeast(surfaceSearchInlierRatio_, 1, "surface_search_inlier_ratio");
	p.requireAtLeast(surfaceSearchMinInliers_, 3, "surface_search_min_inliers");
	p.requireAtLeast(surfaceSearchMinAgreeing_, 0, "surface_search_min_agreeing");
	p.requireRange(surfaceSearchMaxConflicts_, 0, 1, "surface_search_max_conflicts");
	p.requireRange(freeSpace_.minTop_m, 0, 100, "free_space_min_top_m");
	p.requireRange(planar_.yawStep_deg, 0.1, 90, "surface_search_yaw_step_deg");
	p.requireRange(planar_.hypotheses, 1, 64, "surface_search_hypotheses");

	orb_ = std::make_unique<features::OrbExtractor>(queryOrb_);
	vocab_.reset();
	online_ = vocabularyFile_.empty();
	if (!online_)
	{
		std::error_code ec;
		if (!std::filesystem::exists(vocabularyFile_, ec))
			p.reject("vocabulary_file", "'" + vocabularyFile_ + "' does not exist");
		try
		{
			vocab_ = bow::loadVocabularyFile(vocabularyFile_);
		}
		catch (const std::exception& e)
		{
			p.reject("vocabulary_file", e.what());
		}
		if (!vocab_ || vocab_->empty())
			p.reject("vocabulary_file", "'" + vocabularyFile_ + "' holds no vocabulary");
	}
	db_ = bow::Database();
	entryMap_.clear();
	polar_.reset();
	polarMap_.clear();
	trainingImages_.clear();
	prevBow_.reset();
	lastLoop_.reset();
	retiring_.clear();
	trainedOn_ = 0;
	decisions_.clear();
}

std::vector<bow::Descriptor> BowLoopDetector::descriptorsOf(const cv::Mat& m) const
{
	return bow::toDescriptors(m.ptr<uint8_t>(0), static_cast<std::size_t>(m.rows));
}

LocalMap::ConstPtr BowLoopDetector::candidate(const Map& map, uint64_t localMap)
{
	try
	{
		return map.data(localMap);
	}
	catch (const std::exception& e)
	{
		MRPT_LOG_THROTTLE_WARN_STREAM(5.0, "local map " << localMap << " skipped: " << e.what());
		return nullptr;
	}
}

void BowLoopDetector::addEntry(uint64_t localMap, const std::vector<bow::Descriptor>& desc)
{
	bow::BowVector b;
	vocab_->transform(desc, b);
	entryMap_[db_.add(b)] = localMap;
}

void BowLoopDetector::trainOnline()
{
	std::vector<std::vector<bow::Descriptor>> images;
	for (const auto& [id, d] : trainingImages_)
		images.push_back(d);
	auto v = std::make_shared<bow::Vocabulary>();
	bow::TrainParams tp;
	tp.branching = onlineBranching_;
	tp.levels = onlineLevels_;
	v->train(images, tp);
	vocab_ = v;
	trainedOn_ = trainingImages_.size();
	prevBow_.reset();  // in the old words: no measure of a score in the new ones
	// New words: every entry is indexed again.
	db_ = bow::Database();
	entryMap_.clear();
	for (const auto& [id, d] : trainingImages_)
		addEntry(id, d);
	MRPT_LOG_INFO_FMT("online vocabulary trained on %zu local-map images: %zu words",
	                  trainingImages_.size(), vocab_->words());
}

void BowLoopDetector::index(const LocalMap& lm, const std::vector<uint8_t>& imageDescriptors)
{
	auto desc = bow::toDescriptors(imageDescriptors.data(), imageDescriptors.size() / 32);
	if (online_)
	{
		trainingImages_[lm.id] = desc;
		if (static_cast<int>(trainingImages_.size()) >= onlineMinMaps_ &&
		    trainingImages_.size() >= 2 * trainedOn_)
		{
			trainOnline();
			indexContexts(lm);
			return;
		}
	}
	if (vocab_)
		addEntry(lm.id, desc);
	indexContexts(lm);
}

namespace
{
cv::Mat descriptorMat(const std::vector<uint8_t>& bytes)
{
	// A view, not a copy: the bytes outlive the matching.
	return cv::Mat(static_cast<int>(bytes.size() / 32), 32, CV_8U,
	               const_cast<uint8_t*>(bytes.data()));
}
}  // namespace

std::vector<uint32_t> BowLoopDetector::groupsOf(const cv::Mat& desc) const
{
	std::vector<uint32_t> g(static_cast<std::size_t>(desc.rows), 0);
	if (!vocab_ || desc.rows == 0)
		return g;
	bow::BowVector b;
	bow::FeatureVector fv;
	vocab_->transform(descriptorsOf(desc), b, &fv, directLevels_);
	for (const auto& [node, features] : fv)
		for (const auto i : features)
			g[i] = node;
	return g;
}

uint32_t BowLoopDetector::loopKeyframes(const LocalMap& lm, const Map& map,
                                        const KeyframeInfo& kf) const
{
	// An earlier session's clock is another clock (its stamps may overlap this one's), so its
	// places always count.
	if (lm.session + 1 < map.sessions)
		return kAllKeyframes;
	const double before = kf.stamp - excludeRecent_s_;
	if (lm.updatedStamp <= before)
		return kAllKeyframes;
	uint32_t mask = 0;
	for (std::size_t k = 0; k < lm.keyframes.size() && k < 32; k++)
	{
		const auto it = map.keyframes.find(lm.keyframes[k]);
		if (it != map.keyframes.end() && it->second->stamp <= before)
			mask |= 1u << k;
	}
	return mask;
}

cv::Mat BowLoopDetector::candidateRows(const LocalMap& lm, uint32_t keyframes,
                                       std::vector<int>& rows)
{
	static_assert(LocalMap::kMaxKeyframes <= 32, "a keyframe mask is 32 bits");
	rows.clear();
	const std::size_t nk = lm.keyframes.size();
	const uint32_t every = nk >= 32 ? kAllKeyframes : (1u << nk) - 1;
	if ((keyframes & every) == every)
		return descriptorMat(lm.descriptors);
	cv::Mat cand(0, 32, CV_8U);
	for (std::size_t i = 0; i < lm.points(); i++)
		if (lm.observers[i] & keyframes)
		{
			rows.push_back(static_cast<int>(i));
			cand.push_back(cv::Mat(1, 32, CV_8U, const_cast<uint8_t*>(&lm.descriptors[32 * i])));
		}
	return cand;
}

features::RigidResult BowLoopDetector::verify(const Query& q, const LocalMap& lm, uint32_t seed,
                                              uint32_t keyframes, int minInliers) const
{
	features::RigidResult fit;
	const std::size_t n = lm.points();
	if (n == 0 || q.desc.rows == 0 || keyframes == 0)
		return fit;
	std::vector<int> rows;  // local-map point of each candidate row
	const cv::Mat cand = candidateRows(lm, keyframes, rows);
	const auto matches =
	    directLevels_ > 0 && q.groups.size() == static_cast<std::size_t>(q.desc.rows)
	        ? features::matchMutualGrouped(q.desc, cand, match_, q.groups, groupsOf(cand))
	        : features::matchMutual(q.desc, cand, match_);
	std::vector<Eigen::Vector3f> p, m;
	for (const auto& mt : matches)
	{
		const int i = rows.empty() ? mt.b : rows[static_cast<std::size_t>(mt.b)];
		p.push_back(q.pts[static_cast<std::size_t>(mt.a)]);
		m.emplace_back(lm.xyz[3 * i], lm.xyz[3 * i + 1], lm.xyz[3 * i + 2]);
	}
	auto params = ransac_;
	if (minInliers > 0)
		params.minInliers = minInliers;
	fit = features::ransacRigid(p, m, params, seed);
	for (auto& i : fit.inliers)
		i = matches[static_cast<std::size_t>(i)].a;  // as query feature indices
	return fit;
}

std::size_t BowLoopDetector::agreeingMatches(const Query& q, const LocalMap& lm,
                                             const Eigen::Isometry3d& T, double within_m) const
{
	if (lm.points() == 0 || q.desc.rows == 0)
		return 0;
	const auto matches = features::matchMutual(q.desc, descriptorMat(lm.descriptors), match_);
	const Eigen::Isometry3f Tf = T.cast<float>();
	const auto w2 = static_cast<float>(within_m * within_m);
	std::size_t n = 0;
	for (const auto& mt : matches)
	{
		const auto i = static_cast<std::size_t>(mt.b);
		const Eigen::Vector3f m(lm.xyz[3 * i], lm.xyz[3 * i + 1], lm.xyz[3 * i + 2]);
		n += (Tf * q.pts[static_cast<std::size_t>(mt.a)] - m).squaredNorm() <= w2;
	}
	return n;
}

uint64_t BowLoopDetector::nearestKeyframe(const LocalMap& lm,
                                          const Eigen::Isometry3d& T_anchor_pose,
                                          const PoseView& poses, uint32_t keyframes)
{
	const auto anchor = poses.at(lm.anchor());
	uint64_t best = lm.anchor();
	double bestD = std::numeric_limits<double>::max();
	for (std::size_t i = 0; i < lm.keyframes.size(); i++)
	{
		if (keyframes != kAllKeyframes && (i >= 32 || !(keyframes & (1u << i))))
			continue;
		const auto k = lm.keyframes[i];
		const auto T_anchor_kf = poses.at(k) - anchor;
		const double d = (Eigen::Vector3d(T_anchor_kf.x(), T_anchor_kf.y(), T_anchor_kf.z()) -
		                  T_anchor_pose.translation())
		                     .norm();
		if (d < bestD)
		{
			bestD = d;
			best = k;
		}
	}
	return best;
}

void BowLoopDetector::consider(LoopDecision d, const features::RigidResult& fit, const LocalMap& lm,
                               const Query& q, const KeyframeInfo& kf, const Map& map,
                               const PoseView& poses, bool acceptable,
                               std::optional<LoopConstraint>& best, std::size_t& bestDecision,
                               uint32_t keyframes)
{
	d.candidateMap = lm.id;
	d.inliers = fit.inliers.size();
	d.verified = fit.ok;
	uint64_t kfId = lm.anchor();
	mrpt::poses::CPose3D T_kf_query;
	if (!fit.inliers.empty())
	{
		// The fit is in the anchor's frame; loops.txt and the edge use the local map's keyframe
		// nearest to the query.
		kfId = nearestKeyframe(lm, fit.T, poses, keyframes);
		const auto T_anchor_kf = poses.at(kfId) - poses.at(lm.anchor());
		T_kf_query = (mrpt::poses::CPose3D() - T_anchor_kf) + toPose(fit.T);
		d.T_candidate_query = T_kf_query;
		d.candidateStamp = map.keyframes.at(kfId)->stamp;
	}
	if (d.verified && acceptable && (!best || d.inliers > best->inliers))
	{
		LoopConstraint c;
		c.from = kfId;
		c.to = kf.node;
		c.T_from_to = T_kf_query;
		c.information = mrpt::math::CMatrixDouble66(
		    features::pointToPointInformation(q.pts, fit.inliers, pointSigma_m_));
		c.score = d.score;
		c.inliers = d.inliers;
		c.localMap = lm.id;
		best = c;
		bestDecision = decisions_.size();
	}
	decisions_.push_back(d);
}

BowLoopDetector::Query BowLoopDetector::queryOf(const Keyframe& k) const
{
	Query q;
	const std::size_t n = k.size();
	q.desc = descriptorMat(k.descriptors);
	for (std::size_t i = 0; i < n; i++)
		q.pts.emplace_back(k.xyz[3 * i], k.xyz[3 * i + 1], k.xyz[3 * i + 2]);
	if (directLevels_ > 0 && vocab_ && n > 0)
		q.groups = groupsOf(q.desc);
	q.groundValid = k.groundValid;
	q.groundN = Eigen::Vector3d(k.groundN[0], k.groundN[1], k.groundN[2]);
	q.groundD = k.groundD;
	return q;
}

std::vector<LoopConstraint> BowLoopDetector::searchEarlierSessions(const KeyframeInfo& kf,
                                                                   const Map& map,
                                                                   const PoseView& poses)
{
	if (!kf.data || !kf.inMapFrame || map.sessions < 2 || guidedRadius_m_ <= 0)
		return {};
	if (kf.data->size() > 0)
	{
		if (auto g = guidedSearch(queryOf(*kf.data), kf, map, poses))
			return {*g};
		return {};
	}
	// The keyframe's features were released when its local map was finished (all but the
	// open map's, in a session that drove a while before it was anchored): the local maps it
	// anchors stand for it, their points in its frame, with its ground plane and their
	// surfaces. Without this, only the last few keyframes before the anchoring were
	// searched, and the way to it hung from one edge (1.6 m off at the start of a session
	// that drove 240 m before it was located).
	std::vector<LoopConstraint> out;
	for (const auto id : map.localMapsOf(kf.node))
	{
		const auto& stub = map.localMaps.at(id);
		if (stub->anchor() != kf.node || stub->session + 1 != map.sessions)
			continue;
		const auto lm = candidate(map, id);  // offline: read from the store
		if (!lm || lm->points() == 0)
			continue;
		Query q;
		q.desc = cv::Mat(static_cast<int>(lm->points()), 32, CV_8U,
		                 const_cast<uint8_t*>(lm->descriptors.data()))
		             .clone();
		q.pts.reserve(lm->points());
		for (std::size_t i = 0; i < lm->points(); i++)
			q.pts.emplace_back(lm->xyz[3 * i], lm->xyz[3 * i + 1], lm->xyz[3 * i + 2]);
		q.groundValid = kf.data->groundValid;
		q.groundN = Eigen::Vector3d(kf.data->groundN[0], kf.data->groundN[1], kf.data->groundN[2]);
		q.groundD = kf.data->groundD;
		if (icpRefine_ && lm->surfacePoints() > 0)
			q.surface = [lm] { return surfaceOf(*lm); };
		if (auto g = guidedSearch(q, kf, map, poses))
			out.push_back(*g);
	}
	return out;
}

std::vector<LoopConstraint> BowLoopDetector::detect(const KeyframeInfo& kf, const Map& map,
                                                    const PoseView& poses)
{
	if (!kf.data)
		throw std::runtime_error(
		    "rasterslam::BowLoopDetector needs keyframes with features: use an odometry that "
		    "provides them (e.g. "
		    "rasterslam::OrbOdometry)");
	std::vector<LoopConstraint> out;
	const std::size_t decisionsBefore = decisions_.size();
	Query q = queryOf(*kf.data);
	const std::size_t n = kf.data->size();

	if (!retiring_.empty())
		retire(map.sessions - 1, kf.stamp);
	std::optional<LoopConstraint> best;
	std::size_t bestDecision = 0;
	if (search_ != Search::Bow)
		searchByDistance(q, kf, map, poses, best, bestDecision);
	else if (vocab_ && n > 0)
	{
		// Query the database with the words of the image of the local map being built, when
		// the map manager makes one (place_query_keyframes): image against image, as the
		// database holds; else with this keyframe's words.
		bow::BowVector b;
		const bool imageQuery = kf.placeQuery && !kf.placeQuery->empty();
		std::vector<bow::Descriptor> imageDesc;
		if (imageQuery)
		{
			imageDesc = bow::toDescriptors(kf.placeQuery->data(), kf.placeQuery->size() / 32);
			vocab_->transform(imageDesc, b);
		}
		else if (canonicalYaw_ && kf.scan && kf.raster)
			b = canonicalWords(*kf.scan, *kf.raster);
		else
			vocab_->transform(descriptorsOf(q.desc), b);
		// query_turns: the keyframe's image turned too. An image query is turned by the map
		// manager that makes it (its place_query_turns), with the extractor of its images.
		const bool turned = queryTurns_ > 1 && !imageQuery && kf.scan && kf.raster;
		const bool imageTurned = imageQuery && kf.placeQueryTurns && !kf.placeQueryTurns->empty();
		// DBoW2 normalizes by the score against the previous keyframe: what a "good" match
		// looks like here and now. The first keyframe (of a run, after a loss, or after the
		// online vocabulary was trained again) has none: it is normalized as a relocalization
		// query is, by its own halves (a raw score against min_score refused a session's
		// first keyframe even at 41 inliers).
		if (kf.afterLoss || kf.locatedAt)
			prevBow_.reset();  // after a loss (relocalized or not) the previous keyframe is
			                   // not known to be near this one
		// What the keyframe's own halves score: the scale of its turned images, and the
		// normalizer of a keyframe with no previous one; computed once if either needs it.
		const double own = db_.size() > 0 && (turned || (!imageQuery && !prevBow_))
		                       ? selfScore(descriptorsOf(q.desc))
		                       : 0;
		// An image query shares most of its keyframes with the previous one, whose score says
		// nothing of a place: it is normalized by its own halves.
		const double imageSelf = db_.size() > 0 && imageQuery ? selfScore(imageDesc) : 0;
		// polar_fusion: the place query's context ranks the places too.
		const bool fuse = canFuse(kf.placeQueryContext);
		const auto n =
		    static_cast<std::size_t>(fuse ? std::max(maxResults_, polarResults_) : maxResults_);
		const auto results = db_.size() == 0 ? std::vector<bow::Database::Result>{}
		                     : turned ? queryWithTurns(b, own, turnedViews(*kf.scan, *kf.raster), n)
		                     : imageTurned
		                         ? queryWithTurns(b, imageSelf, viewsOf(*kf.placeQueryTurns), n)
		                         : db_.query(b, n);
		const double norm = results.empty() ? 0
		                    : imageQuery    ? imageSelf
		                    : prevBow_      ? bow::Vocabulary::score(b, *prevBow_)
		                                    : own;
		std::vector<Candidate> candidates;
		if (fuse)
		{
			const auto& qc = *kf.placeQueryContext;
			candidates =
			    fusedCandidates(results, {contextOf(qc.rings, qc.sectors, qc.cells.data())});
		}
		else
			for (const auto& r : results)
				candidates.push_back({entryMap_.at(r.entry), r.score, -1, false});
		int examined = 0;
		for (auto& r : candidates)
		{
			const auto it = map.localMaps.find(r.localMap);
			if (it == map.localMaps.end())
				continue;  // not in this map (cannot happen unless removed)
			// Recent places of this session are no loops: only the keyframes older than
			// exclude_recent_s are matched (and linked to).
			const uint32_t keyframes = loopKeyframes(*it->second, map, kf);
			if (keyframes == 0)
				continue;
			if (examined++ >= maxCandidates_)
				break;
			// An offline local map is read from the store for the verification.
			const auto data = candidate(map, it->first);
			if (!data)
				continue;
			const auto& lm = *data;
			LoopDecision d;
			d.queryStamp = kf.stamp;
			scoreOf(r, b);  // ranked by its context only: its words' score is needed now
			d.score = norm > 1e-6 ? r.rawScore / norm : 0;
			d.byContext = r.byContext;
			const auto fit = verify(q, lm, static_cast<uint32_t>(kf.node * 31 + lm.id), keyframes);
			// polar_max_distance: a place whose context is this close needs no words' score.
			const bool closeContext = polarMaxDistance_ > 0 && r.polarDistance >= 0 &&
			                          r.polarDistance <= polarMaxDistance_;
			const bool acceptable = d.score >= minScore_ || closeContext;
			d.reason = !fit.ok ? "inliers" : (acceptable ? "ok" : "score");
			MRPT_LOG_DEBUG_FMT("candidate %llu: score %.3f, polar distance %.3f, %zu inliers%s",
			                   static_cast<unsigned long long>(lm.id), d.score, r.polarDistance,
			                   fit.inliers.size(), fit.ok ? "" : " (refused)");
			consider(d, fit, lm, q, kf, map, poses, acceptable, best, bestDecision, keyframes);
			// A loop this strong is taken as it is: the candidates ranked below it are not
			// verified (most fail, at the cost of a full descriptor match each).
			if (stopAtInliers_ > 0 && best &&
			    best->inliers >= static_cast<std::size_t>(stopAtInliers_))
				break;
		}
		if (imageQuery)
			prevBow_.reset();  // the words of an image, not of a keyframe
		else
			prevBow_ = b;
	}
	// A keyframe after a loss is not linked to the last loop's by the odometry.
	if (kf.afterLoss || kf.locatedAt)
		lastLoop_.reset();
	// Following the last loop: the place it closed on continues where the odometry went.
	std::optional<LoopConstraint> followed;
	if (!best && n > 0 && search_ == Search::Bow)
		if (const auto at = followedPose(kf, map, poses))
			followed = guidedSearch(q, kf, map, poses, &*at);
	// An anchored session also looks for the earlier sessions where it is, unless the BOW
	// search found one of them.
	const bool bestEarlier = best && map.localMaps.count(best->localMap) &&
	                         map.localMaps.at(best->localMap)->session + 1 < map.sessions;
	if (kf.inMapFrame && map.sessions > 1 && guidedRadius_m_ > 0 && !bestEarlier && n > 0)
		if (auto g = guidedSearch(q, kf, map, poses))
			out.push_back(*g);
	// Refined on the surfaces (the scan made into a surface only for a loop found).
	if (best)
		refineLoop(*best, decisions_[bestDecision], q, kf, map, poses);
	if (followed)
		best = followed;  // refined and logged by guidedSearch
	else if (best)
	{
		decisions_[bestDecision].accepted = true;
		MRPT_LOG_INFO_FMT(
		    "loop: keyframe %llu (t=%.2f) -> keyframe %llu in local map %llu, score %.2f, %zu "
		    "inliers",
		    static_cast<unsigned long long>(best->to), kf.stamp,
		    static_cast<unsigned long long>(best->from),
		    static_cast<unsigned long long>(best->localMap), best->score, best->inliers);
	}
	if (best)
	{
		out.push_back(*best);
		// Followed by the next keyframes when it is to this session's place.
		const auto it = map.localMaps.find(best->localMap);
		if (it != map.localMaps.end() && it->second->session + 1 == map.sessions)
			lastLoop_ = LastLoop{best->from, best->to,
			                     followed && lastLoop_ ? lastLoop_->verifiedQuery : best->to,
			                     toIsometry(best->T_from_to), it->second->session};
	}
	// Every query leaves a line, so that recall counts the keyframes that found nothing.
	if (decisions_.size() == decisionsBefore)
	{
		LoopDecision none;
		none.queryStamp = kf.stamp;
		none.reason = "none";
		decisions_.push_back(none);
	}
	return out;
}

namespace
{
/** What savePlaceIndex() writes: version, vocabulary, database, entry -> local map; from
 *  version 1 the polar contexts' dimensions and each context (local map, cells in steps of
 *  LocalMap::kContextStep_m). */
struct PlaceIndexContents
{
	std::shared_ptr<bow::Vocabulary> vocab = std::make_shared<bow::Vocabulary>();
	bow::Database db;
	std::map<bow::Database::EntryId, uint64_t> entries;
	uint16_t rings = 0, sectors = 0;
	std::vector<std::pair<uint64_t, std::vector<uint8_t>>> contexts;
};
PlaceIndexContents readPlaceIndex(const std::vector<uint8_t>& bytes)
{
	mrpt::io::CMemoryStream buf;
	buf.assignMemoryNotOwn(bytes.data(), bytes.size());
	auto a = mrpt::serialization::archiveFrom(buf);
	uint8_t version = 0;
	a >> version;
	if (version > 1)
		throw std::runtime_error("unknown place index version " + std::to_string(version));
	PlaceIndexContents c;
	a >> *c.vocab >> c.db;
	uint64_t n = 0;
	a >> n;
	for (uint64_t i = 0; i < n; i++)
	{
		uint32_t e = 0;
		uint64_t lm = 0;
		a >> e >> lm;
		c.entries[e] = lm;
	}
	if (version >= 1)
	{
		a >> c.rings >> c.sectors >> n;
		const std::size_t cells = std::size_t{c.rings} * c.sectors;
		if (n > 0 && cells == 0)
			throw std::runtime_error("the place index has polar contexts of no cells");
		if (n > bytes.size() / (12 + cells))  // each takes 12 + cells bytes: a damaged count
			throw std::runtime_error("the place index claims " + std::to_string(n) +
			                         " polar contexts in " + std::to_string(bytes.size()) +
			                         " bytes");
		c.contexts.resize(n);
		for (auto& [lm, v] : c.contexts)
		{
			a >> lm >> v;
			if (v.size() != cells)
				throw std::runtime_error("a polar context of the place index has " +
				                         std::to_string(v.size()) + " cells, not " +
				                         std::to_string(cells));
		}
	}
	return c;
}
}  // namespace

std::optional<std::set<uint64_t>> BowLoopDetector::indexedIn(const Map& map) const
{
	if (map.placeIndex.empty() || map.placeIndexClass != GetRuntimeClass()->className)
		return std::nullopt;
	std::set<uint64_t> out;
	for (const auto& [e, lm] : readPlaceIndex(map.placeIndex).entries)
		out.insert(lm);
	return out;
}

bool BowLoopDetector::indexes(uint64_t localMap) const
{
	for (const auto& [e, lm] : entryMap_)
		if (lm == localMap)
			return true;
	return false;
}

bool BowLoopDetector::forget(uint64_t localMap)
{
	bool found = false;
	for (auto it = entryMap_.begin(); it != entryMap_.end();)
		if (it->second == localMap)
		{
			db_.remove(it->first);
			it = entryMap_.erase(it);
			found = true;
		}
		else
			++it;
	if (polar_ && forgetContexts(localMap))
		found = true;
	return trainingImages_.erase(localMap) > 0 || found;
}

void BowLoopDetector::replaced(uint64_t older, const LocalMap& newer)
{
	retiring_[older] = {newer.session, newer.updatedStamp};
}

void BowLoopDetector::retire(uint32_t session, double stamp)
{
	for (auto it = retiring_.begin(); it != retiring_.end();)
		if (it->second.first != session || it->second.second <= stamp - excludeRecent_s_)
		{
			forget(it->first);
			it = retiring_.erase(it);
		}
		else
			++it;
}

std::vector<uint8_t> BowLoopDetector::savePlaceIndex()
{
	// In the next session every local map is a candidate: the replaced ones go now.
	retire(std::numeric_limits<uint32_t>::max(), 0);
	if (!vocab_)
	{
		if (trainingImages_.size() < 2)
			throw std::runtime_error(
			    "the online vocabulary needs at least 2 local maps and this run made " +
			    std::to_string(trainingImages_.size()) +
			    ": give loop_detector.params.vocabulary_file");
		trainOnline();
	}
	mrpt::io::CMemoryStream buf;
	auto a = mrpt::serialization::archiveFrom(buf);
	const uint8_t version = 1;
	a << version << *vocab_ << db_ << static_cast<uint64_t>(entryMap_.size());
	for (const auto& [e, lm] : entryMap_)
		a << static_cast<uint32_t>(e) << lm;
	const auto rings = static_cast<uint16_t>(polar_ ? polar_->params().rings : 0),
	           sectors = static_cast<uint16_t>(polar_ ? polar_->params().sectors : 0);
	a << rings << sectors << static_cast<uint64_t>(polarMap_.size());
	for (const auto& [id, lm] : polarMap_)
		a << lm << places::quantizedCells(*polar_->context(id), LocalMap::kContextStep_m);
	const auto* p = static_cast<const uint8_t*>(buf.getRawBufferData());
	return std::vector<uint8_t>(p, p + buf.getTotalBytesCount());
}

void BowLoopDetector::loadPlaceIndex(const Map& map)
{
	const std::string mine = GetRuntimeClass()->className;
	if (map.placeIndex.empty())
		throw std::runtime_error(
		    "the map has no place index (it was saved without a loop detector)");
	if (map.placeIndexClass != mine)
		throw std::runtime_error("the map's place index was written by " + map.placeIndexClass +
		                         ", not " + mine);
	auto c = readPlaceIndex(map.placeIndex);
	for (const auto& [e, lm] : c.entries)
	{
		if (!c.db.contains(e))
			throw std::runtime_error("the place index refers to a missing database entry");
		if (!map.localMaps.count(lm))
			throw std::runtime_error("the place index refers to a missing local map");
	}
	if (c.entries.size() != c.db.size())
		throw std::runtime_error("the place index has " + std::to_string(c.db.size()) +
		                         " entries and " + std::to_string(c.entries.size()) +
		                         " of them name a local map");
	for (const auto& [lm, cells] : c.contexts)
		if (!map.localMaps.count(lm))
			throw std::runtime_error("the place index has a polar context of a missing local map");
	vocab_ = c.vocab;
	db_ = std::move(c.db);
	entryMap_ = std::move(c.entries);
	polar_.reset();
	polarMap_.clear();
	if (!c.contexts.empty())
	{
		auto p = polarParams_;
		p.rings = c.rings;
		p.sectors = c.sectors;
		polar_ = std::make_unique<places::PolarIndex>(p);
		for (const auto& [lm, cells] : c.contexts)
			polarMap_[polar_->add(places::polarContextOfCells(c.rings, c.sectors, cells.data(),
			                                                  LocalMap::kContextStep_m))] = lm;
	}
	trainingImages_.clear();
	prevBow_.reset();
	lastLoop_.reset();
	online_ = false;  // the map's vocabulary stays
}
