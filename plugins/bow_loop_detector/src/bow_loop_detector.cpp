// Loop closure over a bag-of-words database of local-map images (paper, "BOW Database" and
// "Loop Closure"): keyframes are grouped into local maps; a finished local map's points are
// rasterized into one image whose ORB words enter the database; every new keyframe queries
// it, and candidates are verified by matching against the keyframes of the local map.
#include "bow_loop_detector.h"

using namespace rasterslam;


IMPLEMENTS_MRPT_OBJECT(BowLoopDetector, LoopDetector, rasterslam)

MRPT_INITIALIZER(register_rasterslam_plugin_bow_loop_detector)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::BowLoopDetector));
}

void BowLoopDetector::initializeImpl(ParamReader& p)
{
	vocabularyFile_ = p.getPath("vocabulary_file", "");
	const auto search = p.getChoice("search", "bow", {"bow", "keyframes", "localmaps"});
	search_ = search == "bow" ? Search::Bow : (search == "keyframes" ? Search::Keyframes : Search::LocalMaps);
	searchRadius_m_ = p.getDouble("search_radius_m", searchRadius_m_);
	onlineMinMaps_ = p.getInt("online_min_maps", onlineMinMaps_);
	onlineBranching_ = p.getInt("online_branching", onlineBranching_);
	onlineLevels_ = p.getInt("online_levels", onlineLevels_);
	keyframesPerMap_ = p.getInt("keyframes_per_map", keyframesPerMap_);
	mapRaster_.resolution_m = p.getDouble("map_resolution_m", 0.2);
	mapRaster_.maxRange_m = p.getDouble("map_extent_m", 60.0);
	mapRaster_.minRange_m = 0;
	mapRaster_.removeGround = false;  // the keyframe clouds hold no ground already
	mapRaster_.belowGround_m = 1e6;
	mapOrb_.numFeatures = p.getInt("map_features", 3000);
	mapOrb_.levels = 3;
	excludeRecent_s_ = p.getDouble("exclude_recent_s", excludeRecent_s_);
	minScore_ = p.getDouble("min_score", minScore_);
	maxCandidates_ = p.getInt("max_candidates", maxCandidates_);
	match_.maxDistance = p.getInt("max_hamming", 64);
	match_.ratio = static_cast<float>(p.getDouble("ratio", 0.9));
	ransac_.inlierThreshold_m = p.getDouble("ransac_threshold_m", 0.4);
	ransac_.minInliers = p.getInt("min_inliers", 25);
	ransac_.maxIterations = p.getInt("ransac_max_iterations", 1000);
	pointSigma_m_ = p.getDouble("point_sigma_m", pointSigma_m_);
	if (keyframesPerMap_ < 1) throw ConfigError(p.context() + ".keyframes_per_map: must be >= 1");
	if (onlineMinMaps_ < 2) throw ConfigError(p.context() + ".online_min_maps: must be >= 2");
	if (maxCandidates_ < 1) throw ConfigError(p.context() + ".max_candidates: must be >= 1");

	orb_ = std::make_unique<features::OrbExtractor>(mapOrb_);
	vocab_.reset();
	online_ = vocabularyFile_.empty();
	if (!online_)
	{
		std::error_code ec;
		if (!std::filesystem::exists(vocabularyFile_, ec))
			throw ConfigError(p.context() + ".vocabulary_file: '" + vocabularyFile_ + "' does not exist");
		mrpt::io::CFileGZInputStream f(vocabularyFile_);
		auto obj = mrpt::serialization::archiveFrom(f).ReadObject();
		vocab_ = std::dynamic_pointer_cast<bow::Vocabulary>(obj);
		if (!vocab_ || vocab_->empty())
			throw ConfigError(p.context() + ".vocabulary_file: '" + vocabularyFile_ + "' holds no vocabulary");
	}
	db_ = bow::Database();
	kfs_.clear();
	maps_.clear();
	entryMap_.clear();
	open_.clear();
	prevBow_.reset();
	trainedOn_ = 0;
	decisions_.clear();
}

std::vector<bow::Descriptor> BowLoopDetector::descriptorsOf(const cv::Mat& m) const
{
	return bow::toDescriptors(m.ptr<uint8_t>(0), static_cast<std::size_t>(m.rows));
}

void BowLoopDetector::trainOnline()
{
	std::vector<std::vector<bow::Descriptor>> images;
	for (const auto& m : maps_) images.push_back(m.desc);
	auto v = std::make_shared<bow::Vocabulary>();
	bow::TrainParams tp;
	tp.branching = onlineBranching_;
	tp.levels = onlineLevels_;
	v->train(images, tp);
	vocab_ = v;
	trainedOn_ = maps_.size();
	// New words: every entry is indexed again.
	db_ = bow::Database();
	entryMap_.clear();
	for (std::size_t i = 0; i < maps_.size(); i++)
	{
		bow::BowVector b;
		vocab_->transform(maps_[i].desc, b);
		maps_[i].entry = db_.add(b);
		entryMap_[*maps_[i].entry] = i;
	}
	MRPT_LOG_INFO_FMT("online vocabulary trained on %zu local-map images: %zu words", maps_.size(), vocab_->words());
}

void BowLoopDetector::finishMap()
{
	if (open_.empty()) return;
	LocalMap lm;
	lm.keyframes = open_;
	open_.clear();
	// The local map's points in the frame of its first keyframe, rasterized into one image.
	const auto& first = kfs_[lm.keyframes.front()];
	std::vector<PointXYZI> pts;
	for (const auto k : lm.keyframes)
	{
		const auto& kd = kfs_[k];
		lm.newestStamp = std::max(lm.newestStamp, kd.stamp);
		const mrpt::poses::CPose3D T = kd.pose - first.pose;
		for (const auto& q : kd.cloud)
		{
			double x, y, z;
			T.composePoint(q.x, q.y, q.z, x, y, z);
			pts.push_back({float(x), float(y), float(z), q.intensity});
		}
	}
	// The clouds were only needed for this image: free them (memory must not grow with the
	// points of every keyframe ever made).
	for (const auto k : lm.keyframes)
	{
		kfs_[k].cloud.clear();
		kfs_[k].cloud.shrink_to_fit();
	}
	RasterFrame img;
	raster::rasterizeElevation(pts, raster::Plane(), mapRaster_, img);
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb_->extract(img.image.asCvMatRef(), kps, desc);
	lm.desc = descriptorsOf(desc);
	lm.image = img.image;
	maps_.push_back(std::move(lm));
	if (online_)
	{
		if (static_cast<int>(maps_.size()) >= onlineMinMaps_ && maps_.size() >= 2 * trainedOn_)
		{
			trainOnline();
			return;
		}
	}
	if (vocab_)
	{
		bow::BowVector b;
		vocab_->transform(maps_.back().desc, b);
		maps_.back().entry = db_.add(b);
		entryMap_[*maps_.back().entry] = maps_.size() - 1;
		// Only the online vocabulary's retraining needs the descriptors again.
		if (!online_)
		{
			maps_.back().desc.clear();
			maps_.back().desc.shrink_to_fit();
		}
	}
}

std::vector<LoopConstraint> BowLoopDetector::detect(const KeyframeInfo& kf, const Scan& scan, const RasterFrame* raster)
{
	if (!kf.data)
		throw std::runtime_error(
			"rasterslam::BowLoopDetector needs keyframes with features: use an odometry that provides them (e.g. rasterslam::OrbOdometry)");
	std::vector<LoopConstraint> out;
	const std::size_t decisionsBefore = decisions_.size();
	KeyframeData kd;
	kd.node = kf.node;
	kd.stamp = kf.stamp;
	kd.pose = kf.pose;
	const std::size_t n = kf.data->size();
	kd.desc.create(static_cast<int>(n), 32, CV_8U);
	for (std::size_t i = 0; i < n; i++)
	{
		std::memcpy(kd.desc.ptr<uint8_t>(static_cast<int>(i)), &kf.data->descriptors[32 * i], 32);
		kd.pts.emplace_back(kf.data->xyz[3 * i], kf.data->xyz[3 * i + 1], kf.data->xyz[3 * i + 2]);
	}
	// Keep the keyframe's other feature fields; descriptors and points live in desc/pts once.
	kd.data = std::make_shared<Keyframe>(*kf.data);
	kd.data->descriptors.clear();
	kd.data->descriptors.shrink_to_fit();
	kd.data->xyz.clear();
	kd.data->xyz.shrink_to_fit();
	if (raster)
		for (const auto idx : raster->pixelToPoint)
			if (idx >= 0) kd.cloud.push_back(scan.points[static_cast<std::size_t>(idx)]);

	if (search_ != Search::Bow)
	{
		searchByDistance(kd, out);
	}
	// Query the database with this keyframe's words.
	else if (vocab_ && db_.size() > 0 && n > 0)
	{
		bow::BowVector q;
		vocab_->transform(descriptorsOf(kd.desc), q);
		// DBoW2 normalizes by the score against the previous keyframe: what a "good" match
		// looks like here and now.
		const double norm = prevBow_ ? bow::Vocabulary::score(q, *prevBow_) : 1.0;
		const auto results = db_.query(q, static_cast<std::size_t>(maxResults_));
		int examined = 0;
		std::optional<LoopConstraint> best;
		std::size_t bestDecision = 0;
		for (const auto& r : results)
		{
			const auto mi = entryMap_.at(r.entry);
			const auto& lm = maps_[mi];
			if (lm.newestStamp > kf.stamp - excludeRecent_s_) continue;	 // recent: not a loop
			if (examined++ >= maxCandidates_) break;
			LoopDecision d;
			d.queryStamp = kf.stamp;
			d.candidateMap = mi;
			d.score = norm > 1e-6 ? r.score / norm : 0;
			// Verify against every keyframe of the candidate map; keep the best.
			std::size_t bestKf = 0;
			const auto bestFit = verify(kd.desc, kd.pts, lm, static_cast<uint32_t>(kf.node * 31), bestKf);
			d.inliers = bestFit.inliers.size();
			d.verified = bestFit.ok;
			if (!bestFit.inliers.empty())
			{
				d.candidateStamp = kfs_[bestKf].stamp;
				d.T_candidate_query = toPose(bestFit.T);
			}
			d.reason = !d.verified ? "inliers" : (d.score < minScore_ ? "score" : "ok");
			considerLoop(d, bestFit, bestKf, kd, d.score >= minScore_, best, bestDecision);
		}
		if (best)
		{
			decisions_[bestDecision].accepted = true;
			out.push_back(*best);
			MRPT_LOG_INFO_FMT(
				"loop: keyframe %u (t=%.2f) -> keyframe %u, score %.2f, %zu inliers", static_cast<unsigned>(best->to),
				kf.stamp, static_cast<unsigned>(best->from), best->score, best->inliers);
		}
		prevBow_ = q;
	}
	else if (vocab_ && n > 0)
	{
		bow::BowVector q;
		vocab_->transform(descriptorsOf(kd.desc), q);
		prevBow_ = q;
	}

	// Every query leaves a line, so that recall counts the keyframes that found nothing.
	if (decisions_.size() == decisionsBefore)
	{
		LoopDecision none;
		none.queryStamp = kf.stamp;
		none.reason = "none";
		decisions_.push_back(none);
	}
	kfs_.push_back(std::move(kd));
	open_.push_back(kfs_.size() - 1);
	if (static_cast<int>(open_.size()) >= keyframesPerMap_) finishMap();
	return out;
}

features::RigidResult BowLoopDetector::verify(
	const cv::Mat& desc, const std::vector<Eigen::Vector3f>& pts, const LocalMap& lm, uint32_t seed,
	std::size_t& bestKf) const
{
	features::RigidResult best;
	for (const auto k : lm.keyframes)
	{
		const auto& cand = kfs_[k];
		const auto matches = features::matchMutual(desc, cand.desc, match_);
		std::vector<Eigen::Vector3f> p, q;
		for (const auto& m : matches)
		{
			p.push_back(pts[m.a]);
			q.push_back(cand.pts[m.b]);
		}
		auto fit = features::ransacRigid(p, q, ransac_, seed + static_cast<uint32_t>(k));
		if (fit.inliers.size() > best.inliers.size())
		{
			for (auto& i : fit.inliers) i = matches[i].a;
			best = std::move(fit);
			bestKf = k;
		}
	}
	return best;
}

void BowLoopDetector::considerLoop(
	const LoopDecision& d, const features::RigidResult& fit, std::size_t candidateKf,
	const KeyframeData& query, bool acceptable, std::optional<LoopConstraint>& best,
	std::size_t& bestDecision)
{
	if (d.verified && acceptable && (!best || d.inliers > best->inliers))
	{
		LoopConstraint c;
		c.from = kfs_[candidateKf].node;
		c.to = query.node;
		c.T_from_to = d.T_candidate_query;
		c.information = mrpt::math::CMatrixDouble66(
			features::pointToPointInformation(query.pts, fit.inliers, pointSigma_m_));
		c.score = d.score;
		c.inliers = d.inliers;
		best = c;
		bestDecision = decisions_.size();
	}
	decisions_.push_back(d);
}

