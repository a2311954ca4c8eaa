// BowLoopDetector's declaration, shared by its source files (not a public header).
#pragma once

#include <mrpt/core/initializer.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/stl_serialization.h>
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
#include <optional>

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

namespace rasterslam::bow_loop
{
/** Keyframes of a map loaded with --map-in get ids past this offset: they are not nodes of
 *  the running session's graph. */
constexpr uint64_t kPriorMapNodeOffset = uint64_t(1) << 40;
}  // namespace rasterslam::bow_loop
