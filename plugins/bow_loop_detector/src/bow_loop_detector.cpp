// Loop closure over a bag-of-words database of local-map images (paper, "BOW Database" and
// "Loop Closure"): keyframes are grouped into local maps; a finished local map's points are
// rasterized into one image whose ORB words enter the database; every new keyframe queries
// it, and candidates are verified by matching against the keyframes of the local map.
#include <mrpt/core/initializer.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/serialization/stl_serialization.h>
#include <unistd.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/bow/vocabulary.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/features/matcher.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/features/rigid_ransac.h>
#include <rasterslam/raster/elevation_image.h>

#include <Eigen/Dense>
#include <filesystem>
#include <memory>

namespace rasterslam
{
class BowLoopDetector : public LoopDetector
{
	DEFINE_MRPT_OBJECT(BowLoopDetector, rasterslam)

   public:
	std::vector<LoopConstraint> detect(
		const KeyframeInfo& kf, const Scan& scan, const RasterFrame* raster) override;
	void saveMap(const std::string& dir, const mrpt::graphs::CNetworkOfPoses3DInf& graph) override;
	void loadMap(const std::string& dir) override;
	RelocalizationResult relocalize(const Scan& scan, const RasterFrame& raster) override;
	void transformKeyframes(const mrpt::poses::CPose3D& C) override;

   protected:
	void initializeImpl(ParamReader& p) override;

   private:
	struct KeyframeData
	{
		mrpt::graphs::TNodeID node = 0;
		double stamp = 0;
		mrpt::poses::CPose3D pose;
		cv::Mat desc;  //!< N x 32
		std::vector<Eigen::Vector3f> pts;  //!< feature points, keyframe frame
		std::vector<PointXYZI> cloud;  //!< non-ground points behind the image, keyframe frame
		Keyframe::Ptr data;  //!< as the odometry gave it (saved with the map)
	};
	struct LocalMap
	{
		std::vector<std::size_t> keyframes;  //!< indices into kfs_
		double newestStamp = 0;
		std::vector<bow::Descriptor> desc;  //!< of its image, kept for online training
		std::optional<bow::Database::EntryId> entry;
		mrpt::img::CImage image;  //!< the rasterized local map
	};
	/** Best verified match of features (desc, pts) against the keyframes of a local map. */
	features::RigidResult verify(
		const cv::Mat& desc, const std::vector<Eigen::Vector3f>& pts, const LocalMap& lm,
		uint32_t seed, std::size_t& bestKf) const;
	void finishMap();
	/** Logs a candidate decision; a verified, acceptable one that beats the best so far
	 *  becomes the keyframe's loop constraint. */
	void considerLoop(
		const LoopDecision& d, const features::RigidResult& fit, std::size_t candidateKf,
		const KeyframeData& query, bool acceptable, std::optional<LoopConstraint>& best,
		std::size_t& bestDecision);
	/** The paper's two baselines: candidates are the keyframes, or the local maps, near the
	 *  current pose estimate; each is verified by feature matching. */
	void searchByDistance(const KeyframeData& kd, std::vector<LoopConstraint>& out);
	enum class Search
	{
		Bow,
		Keyframes,
		LocalMaps
	};
	Search search_ = Search::Bow;
	double searchRadius_m_ = 15.0;
	void trainOnline();
	std::vector<bow::Descriptor> descriptorsOf(const cv::Mat& m) const;

	// parameters
	std::string vocabularyFile_;
	int onlineMinMaps_ = 8, onlineBranching_ = 8, onlineLevels_ = 3;
	int keyframesPerMap_ = 5;
	raster::RasterParams mapRaster_;
	features::OrbParams mapOrb_;
	double excludeRecent_s_ = 30, minScore_ = 0.3;
	int maxCandidates_ = 5, maxResults_ = 20;
	features::MatchParams match_;
	features::RansacParams ransac_;
	double pointSigma_m_ = 0.2;

	// state
	std::shared_ptr<bow::Vocabulary> vocab_;
	bool online_ = true;
	std::size_t trainedOn_ = 0;  //!< local maps the online vocabulary was trained on
	bow::Database db_;
	std::vector<KeyframeData> kfs_;
	std::vector<LocalMap> maps_;
	std::map<bow::Database::EntryId, std::size_t> entryMap_;
	std::vector<std::size_t> open_;  //!< keyframes of the map being built
	std::optional<bow::BowVector> prevBow_;
	std::unique_ptr<features::OrbExtractor> orb_;
};
}  // namespace rasterslam

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

namespace
{
constexpr uint32_t kMapMagic = 0x504d5352;	// "RSMP"
constexpr uint8_t kMapVersion = 0;
constexpr uint64_t kPriorMapNodeOffset = uint64_t(1) << 40;
std::string mapFile(const std::string& dir) { return (std::filesystem::path(dir) / "map.rsmap").string(); }
}  // namespace

void BowLoopDetector::saveMap(const std::string& dir, const mrpt::graphs::CNetworkOfPoses3DInf& graph)
{
	finishMap();  // even a one-scan run leaves a usable map
	if (maps_.empty()) throw std::runtime_error("no keyframe was made: there is no map to save");
	if (!vocab_)
	{
		if (maps_.size() < 2)
			throw std::runtime_error(
				"the online vocabulary needs at least 2 local maps and this run made " +
				std::to_string(maps_.size()) + ": give loop_detector.params.vocabulary_file");
		trainOnline();
	}
	for (std::size_t i = 0; i < maps_.size(); i++)
		if (!maps_[i].entry)
		{
			bow::BowVector b;
			vocab_->transform(maps_[i].desc, b);
			maps_[i].entry = db_.add(b);
			entryMap_[*maps_[i].entry] = i;
		}
	// Keyframe poses as optimized.
	for (auto& k : kfs_)
		if (const auto it = graph.nodes.find(k.node); it != graph.nodes.end()) k.pose = it->second;

	std::filesystem::create_directories(dir);
	const auto path = mapFile(dir);
	const auto tmp = path + ".tmp-" + std::to_string(::getpid());
	{
		mrpt::io::CFileGZOutputStream f;
		if (!f.open(tmp, 1)) throw std::runtime_error("cannot write map '" + path + "'");
		auto a = mrpt::serialization::archiveFrom(f);
		a << kMapMagic << kMapVersion << *vocab_ << db_;
		a << static_cast<uint64_t>(kfs_.size());
		for (const auto& k : kfs_)
		{
			Keyframe kf = k.data ? *k.data : Keyframe();
			kf.id = k.node >= kPriorMapNodeOffset ? k.node - kPriorMapNodeOffset : k.node;
			kf.descriptors.assign(k.desc.datastart, k.desc.dataend);
			kf.xyz.clear();
			for (const auto& q : k.pts) kf.xyz.insert(kf.xyz.end(), {q.x(), q.y(), q.z()});
			kf.stamp = k.stamp;
			kf.pose = k.pose;
			a << kf;
		}
		a << static_cast<uint64_t>(maps_.size());
		for (const auto& m : maps_)
		{
			std::vector<uint64_t> kidx(m.keyframes.begin(), m.keyframes.end());
			a << kidx << m.newestStamp << static_cast<int64_t>(m.entry ? int64_t(*m.entry) : -1) << m.image;
		}
	}
	std::filesystem::rename(tmp, path);
	// The local-map images, for a look: a fresh folder replaces the old one whole.
	const auto imgDir = std::filesystem::path(dir) / "localmaps";
	const auto tmpDir = std::filesystem::path(dir) / (".localmaps.tmp-" + std::to_string(::getpid()));
	std::filesystem::remove_all(tmpDir);
	std::filesystem::create_directories(tmpDir);
	for (std::size_t i = 0; i < maps_.size(); i++)
		if (!maps_[i].image.saveToFile((tmpDir / mrpt::format("%04zu.png", i)).string()))
			throw std::runtime_error("cannot write '" + (imgDir / mrpt::format("%04zu.png", i)).string() + "'");
	std::filesystem::remove_all(imgDir);
	std::filesystem::rename(tmpDir, imgDir);
	MRPT_LOG_INFO_FMT("map saved to %s: %zu keyframes, %zu local maps", path.c_str(), kfs_.size(), maps_.size());
}

void BowLoopDetector::loadMap(const std::string& dir)
{
	const auto path = mapFile(dir);
	std::error_code ec;
	if (!std::filesystem::exists(path, ec)) throw std::runtime_error("map '" + path + "' does not exist");
	try
	{
		mrpt::io::CFileGZInputStream f(path);
		auto a = mrpt::serialization::archiveFrom(f);
		uint32_t magic = 0;
		uint8_t version = 0;
		a >> magic >> version;
		if (magic != kMapMagic) throw std::runtime_error("not a rasterslam map");
		if (version != kMapVersion) throw std::runtime_error("unknown map version " + std::to_string(version));
		auto v = std::make_shared<bow::Vocabulary>();
		a >> *v >> db_;
		vocab_ = v;
		uint64_t nk = 0;
		a >> nk;
		kfs_.clear();
		for (uint64_t i = 0; i < nk; i++)
		{
			auto kf = std::make_shared<Keyframe>();
			a >> *kf;
			KeyframeData kd;
			// Nodes of an earlier session are not nodes of this run's graph: give them ids
			// that cannot collide with the new ones.
			kd.node = kPriorMapNodeOffset + kf->id;
			kd.stamp = kf->stamp;
			kd.pose = kf->pose;
			kd.desc.create(static_cast<int>(kf->size()), 32, CV_8U);
			for (std::size_t j = 0; j < kf->size(); j++)
			{
				std::memcpy(kd.desc.ptr<uint8_t>(static_cast<int>(j)), &kf->descriptors[32 * j], 32);
				kd.pts.emplace_back(kf->xyz[3 * j], kf->xyz[3 * j + 1], kf->xyz[3 * j + 2]);
			}
			kf->descriptors.clear();
			kf->xyz.clear();
			kd.data = kf;
			kfs_.push_back(std::move(kd));
		}
		uint64_t nm = 0;
		a >> nm;
		maps_.clear();
		entryMap_.clear();
		for (uint64_t i = 0; i < nm; i++)
		{
			LocalMap m;
			std::vector<uint64_t> kidx;
			int64_t entry = -1;
			a >> kidx >> m.newestStamp >> entry >> m.image;
			for (const auto k : kidx)
			{
				if (k >= kfs_.size()) throw std::runtime_error("local map refers to a missing keyframe");
				m.keyframes.push_back(static_cast<std::size_t>(k));
			}
			if (entry >= 0)
			{
				if (!db_.contains(static_cast<bow::Database::EntryId>(entry)))
					throw std::runtime_error("local map refers to a missing database entry");
				m.entry = static_cast<bow::Database::EntryId>(entry);
				entryMap_[*m.entry] = maps_.size();
			}
			maps_.push_back(std::move(m));
		}
	}
	catch (const std::exception& e)
	{
		std::string what = e.what();
		if (const auto pos = what.find("Message:"); pos != std::string::npos)
			what = what.substr(pos + 9, what.find('\n', pos) - pos - 9);
		throw std::runtime_error("cannot read map '" + path + "': " + what);
	}
	open_.clear();
	prevBow_.reset();
	online_ = false;  // the map's vocabulary stays
}

RelocalizationResult BowLoopDetector::relocalize(const Scan& scan, const RasterFrame& raster)
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
	cv::Mat desc(0, 32, CV_8U);
	std::vector<Eigen::Vector3f> pts;
	for (int i = 0; i < static_cast<int>(kps.size()); i++)
	{
		const int32_t idx = raster::pointAtPixel(raster, kps[i].pt.x, kps[i].pt.y, 1);
		if (idx < 0) continue;
		const auto& q = scan.points[static_cast<std::size_t>(idx)];
		pts.emplace_back(q.x, q.y, q.z);
		desc.push_back(all.row(i));
	}
	if (pts.size() < static_cast<std::size_t>(ransac_.minInliers))
	{
		res.reason = "features";
		return res;
	}
	bow::BowVector q;
	vocab_->transform(descriptorsOf(desc), q);
	const auto results = db_.query(q, static_cast<std::size_t>(maxCandidates_ + 1));
	if (results.empty())
	{
		res.reason = "candidates";
		return res;
	}
	res.reason = "inliers";
	for (const auto& r : results)
	{
		const auto mi = entryMap_.at(r.entry);
		std::size_t kfIdx = 0;
		const auto fit = verify(desc, pts, maps_[mi], static_cast<uint32_t>(scan.index * 17 + 3), kfIdx);
		if (fit.ok && fit.inliers.size() > res.inliers)
		{
			res.found = true;
			res.reason = "ok";
			res.localMap = mi;
			res.keyframe = kfs_[kfIdx].node;
			res.keyframeStamp = kfs_[kfIdx].stamp;
			res.score = r.score;
			res.inliers = fit.inliers.size();
			res.keyframePose = kfs_[kfIdx].pose;
			res.pose = kfs_[kfIdx].pose + toPose(fit.T);
		}
		else if (!res.found)
		{
			res.score = std::max(res.score, r.score);
			res.inliers = std::max(res.inliers, fit.inliers.size());
		}
	}
	return res;
}

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

void BowLoopDetector::transformKeyframes(const mrpt::poses::CPose3D& C)
{
	for (auto& k : kfs_)
		if (k.node < kPriorMapNodeOffset) k.pose = C + k.pose;  // this session's keyframes only
}
