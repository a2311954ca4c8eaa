// BowLoopDetector's declaration, shared by its source files (not a public header).
#pragma once

#include <mrpt/core/initializer.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/stl_serialization.h>
#include <rasterslam/bow/vocabulary.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/features/icp.h>
#include <rasterslam/features/matcher.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/features/planar_search.h>
#include <rasterslam/features/rigid_ransac.h>
#include <rasterslam/places/polar_context.h>
#include <rasterslam/places/turned_views.h>
#include <rasterslam/raster/elevation_image.h>

#include <Eigen/Dense>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>

namespace rasterslam
{
/** Whether b lies within m metres and deg degrees of a (the motion a^-1 b). */
inline bool withinPose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double m, double deg)
{
	const Eigen::Isometry3d d = a.inverse() * b;
	return d.translation().norm() <= m &&
	       Eigen::AngleAxisd(d.linear()).angle() * 180.0 / M_PI <= deg;
}

/** The paper's loop closure as a query service over the map: a BOW database of local-map
 *  images (its place index), candidate search, and geometric verification of a keyframe's
 *  features against a candidate local map's points. It holds no keyframe and no map. */
class BowLoopDetector : public LoopDetector
{
	DEFINE_MRPT_OBJECT(BowLoopDetector, rasterslam)

   public:
	void index(const LocalMap& lm, const std::vector<uint8_t>& imageDescriptors) override;
	std::vector<LoopConstraint> detect(const KeyframeInfo& kf, const Map& map,
	                                   const PoseView& poses) override;
	std::vector<LoopConstraint> searchEarlierSessions(const KeyframeInfo& kf, const Map& map,
	                                                  const PoseView& poses) override;
	RelocalizationResult relocalize(const Scan& scan, const RasterFrame& raster, const Map& map,
	                                const PoseView& poses) override;
	RelocalizationResult relocalizeScan(const Scan& scan, const RasterFrame& raster,
	                                    const PlaceContext& context, const Map& map,
	                                    const PoseView& poses) override;
	bool usesScanContexts() const override { return polarFusion_ && polarRelocalization_; }
	RelocalizationResult locate(const LocalMap& query, const Map& map, const PoseView& poses,
	                            int onlyKeyframe) override;
	bool forget(uint64_t localMap) override;
	bool indexes(uint64_t localMap) const override;
	std::optional<std::set<uint64_t>> indexedIn(const Map& map) const override;
	void replaced(uint64_t older, const LocalMap& newer) override;
	std::vector<uint8_t> savePlaceIndex() override;
	void loadPlaceIndex(const Map& map) override;

   protected:
	void initializeImpl(ParamReader& p) override;

   private:
	/** Features of a query: descriptors (N x 32) and their 3D points in the query's frame. */
	struct Query
	{
		cv::Mat desc;
		std::vector<Eigen::Vector3f> pts;
		/** The query's ground plane (n . p + d = 0, its frame), when known. */
		bool groundValid = false;
		Eigen::Vector3d groundN = Eigen::Vector3d::UnitZ();
		double groundD = 0;
		/** direct_index_levels_up > 0: the vocabulary node of each feature. */
		std::vector<uint32_t> groups;
		/** icp_refine or relocalization_max_conflicts: makes the query's surface (its scan
		 *  reduced to one point a voxel, its frame), when it has one; called only once a
		 *  place is fitted. */
		std::function<std::vector<Eigen::Vector3f>()> surface;
		/** false: the surface only judges free space, it neither refines nor searches the
		 *  pose (a keyframe of a local map located alone: its surface is the whole local
		 *  map's, more than the keyframe's features stand for). */
		bool poseFromSurface = true;
		/** polar_fusion: the query's polar contexts (of the index's dimensions; a place ranks
		 *  by its best context against any of them); none: ranked by the words alone. */
		std::vector<places::PolarContext> contexts;
	};
	using TurnedView = places::TurnedView;
	/** What a place scores against itself: the BOW score of a query's even features against
	 *  its odd ones (the normalizer of a query with no previous keyframe); 0 under 40 features. */
	double selfScore(const std::vector<bow::Descriptor>& desc) const;
	/** icp_refine: a scan's points within surface range, one a voxel. */
	std::vector<Eigen::Vector3f> surfaceOf(const Scan& scan) const;
	/** A local map's surface in its anchor frame, in metres. */
	static std::vector<Eigen::Vector3f> surfaceOf(const LocalMap& lm);
	/** icp_refine: T_anchor_query refined by point-to-plane ICP of the query's surface on the
	 *  local map's. Unchanged, false, when either has none, ICP does not converge, or it would
	 *  move the pose more than icp_max_correction_m / icp_max_correction_deg (the two
	 *  disagree: the features' registration is kept). */
	bool refineOnSurface(const std::vector<Eigen::Vector3f>& surface, const LocalMap& lm,
	                     Eigen::Isometry3d& T) const;
	/** icp_refine: a loop found for keyframe kf refined on its candidate's surface (the
	 *  keyframe's scan made into a surface here, when kf has one), its height then taken from
	 *  the ground planes, and its decision line updated. */
	void refineLoop(LoopConstraint& c, LoopDecision& d, const Query& q, const KeyframeInfo& kf,
	                const Map& map, const PoseView& poses);
	/** icp_refine: local maps' surfaces prepared as ICP targets, the last few (consecutive
	 *  keyframes of a revisit close their loops on the same local maps: 7.5 -> 5.0 ms a
	 *  refinement on the town loop). Held under targetsMutex_ while aligning (a target's
	 *  normals are fitted as alignments reach them). The engine already serializes loop
	 *  closing and relocalization under its map lock; this one keeps the detector safe
	 *  without it. */
	mutable std::unique_ptr<features::IcpTargetCache> targets_;
	mutable std::mutex targetsMutex_;
	/** The ICP target of a local map's surface, from targets_ (call under targetsMutex_). */
	std::shared_ptr<const features::IcpTarget> targetOf(const LocalMap& lm) const;
	/** relocalization_surface_search: alignments T_anchor_query of the query's surface on
	 *  the local map's found with no pose prior and no descriptors: planarSearch's best
	 *  (x, y, yaw) peaks, each refined by ICP, those whose overlap (the share of the query's
	 *  points over the local map's footprint that lie on its surface; 0 when fewer than 200
	 *  of them lie over it) reaches surface_search_min_overlap, largest overlap first.
	 *  `target` is surfaceOf(lm), converted once by the caller. */
	struct SurfaceAlignment
	{
		Eigen::Isometry3d T;
		double overlap = 0;
	};
	std::vector<SurfaceAlignment> searchOnSurface(const std::vector<Eigen::Vector3f>& surface,
	                                              const LocalMap& lm,
	                                              const std::vector<Eigen::Vector3f>& target) const;
	/** The query's features matched with the local map's only within guided_gate_m of where
	 *  `predicted` (T_anchor_query) puts them, then fitted by RANSAC with guided_min_inliers
	 *  (inliers as query feature indices). */
	features::RigidResult guidedFit(const Query& q, const LocalMap& lm,
	                                const Eigen::Isometry3d& predicted, uint32_t seed,
	                                uint32_t keyframes = kAllKeyframes) const;
	/** The query's features matched with all of the local map's as verify() matches them
	 *  (mutual, ratio test: a feature that repeats does not pass), counted where pose T
	 *  (T_anchor_query) puts the two within `within_m`: evidence of T independent of the
	 *  surfaces and of any gate. */
	std::size_t agreeingMatches(const Query& q, const LocalMap& lm, const Eigen::Isometry3d& T,
	                            double within_m) const;
	bool surfaceSearch_ = false;
	int surfaceSearchCandidates_ = 2;
	double surfaceSearchMinOverlap_ = 0.2, surfaceSearchInlierRatio_ = 2.0;
	int surfaceSearchMinInliers_ = 30, surfaceSearchMinAgreeing_ = 12;
	double surfaceSearchMaxConflicts_ = 0.05;
	/** The free-space checks (surface search, relocalization_max_conflicts): tall structure only
	 *  (free_space_min_top_m, 2.5 m): people and vehicles move between sessions. */
	features::FreeSpaceParams freeSpace_;
	features::PlanarSearchParams planar_;
	bool icpRefine_ = false;
	features::IcpParams icp_;
	double icpRange_m_ = 40, icpMaxCorrection_m_ = 1.0, icpMaxCorrection_deg_ = 3.0;
	/** A keyframe's features and ground plane as a query. */
	Query queryOf(const Keyframe& k) const;
	/** The vocabulary node `directLevels_` levels above the leaves of each descriptor row. */
	std::vector<uint32_t> groupsOf(const cv::Mat& desc) const;
	int directLevels_ = 0;
	/** T_anchor_query with its height from the ground planes of the query and of keyframe
	 *  `kf` (nearest to it in the local map): unchanged when either has none; nullopt when
	 *  the registration tilts the query's plane more than groundMaxTilt_deg_ off the
	 *  keyframe's (then it is not trusted); `tilt_deg` receives that angle. */
	std::optional<Eigen::Isometry3d> groundAligned(const Query& q, const LocalMap& lm, uint64_t kf,
	                                               const Eigen::Isometry3d& T, const Map& map,
	                                               const PoseView& poses, double* tilt_deg) const;
	/** The database's best candidates for the query, each verified; the one with the most
	 *  inliers wins. `words`: the query's words when they do not come from its features
	 *  (canonical_yaw). */
	RelocalizationResult relocalizeQuery(const Query& q, uint32_t seed, const Map& map,
	                                     const PoseView& poses,
	                                     const bow::BowVector* words = nullptr,
	                                     const std::vector<TurnedView>* turns = nullptr);
	/** canonical_yaw: the words of the scan's elevation image turned to its dominant edges
	 *  (as the local-map images are with map_manager.canonical_yaw). */
	bow::BowVector canonicalWords(const Scan& scan, const RasterFrame& raster) const;
	bool canonicalYaw_ = false;
	/** query_turns > 1: the words and normalizer (selfScore) of the scan's elevation image
	 *  rasterized turned by k * 90 / query_turns degrees, k = 1..query_turns-1: a turn of 90
	 *  maps the pixel grid onto itself, so one of the images lies within 45 / query_turns
	 *  degrees of any place's grid. */
	std::vector<TurnedView> turnedViews(const Scan& scan, const RasterFrame& raster) const;
	/** The views of turned images whose descriptors (32 bytes each) another plugin made (the
	 *  map manager's placeQueryTurns). */
	std::vector<TurnedView> viewsOf(const std::vector<std::vector<uint8_t>>& descriptors) const;
	/** The database's best `n` for words `b` (normalizer `norm`) and the turned views of the
	 *  same place, each entry at its best on b's scale (bow::Database::queryViews). */
	std::vector<bow::Database::Result> queryWithTurns(const bow::BowVector& b, double norm,
	                                                  const std::vector<TurnedView>& turns,
	                                                  std::size_t n) const;
	int queryTurns_ = 1;
	double queryTurnWeight_ = 0.8;  //!< query_turn_weight
	/** Keyframes of a local map as a mask: bit k stands for lm.keyframes[k] (as in
	 *  LocalMap::observers); all bits set: every keyframe. */
	static constexpr uint32_t kAllKeyframes = ~0u;
	/** The keyframes of `lm` that may close a loop with keyframe `kf`: all of them for an
	 *  earlier session's map; in this session's, those older than exclude_recent_s. A local
	 *  map still being added to when the vehicle left it (its first keyframes old, its last
	 *  recent) is a candidate through its old keyframes, not only once its newest one is
	 *  old: a place is as old as the keyframes that saw it. */
	uint32_t loopKeyframes(const LocalMap& lm, const Map& map, const KeyframeInfo& kf) const;
	/** Matches the query against the local map's points (only those seen by the keyframes
	 *  in `keyframes`) and fits the rigid transform with RANSAC. The fit's T maps the query
	 *  frame into the local map's anchor frame; its inliers are query feature indices. */
	features::RigidResult verify(const Query& q, const LocalMap& lm, uint32_t seed,
	                             uint32_t keyframes = kAllKeyframes, int minInliers = -1) const;
	/** The local map's points seen by the keyframes in `keyframes`: their descriptors as
	 *  rows, and the point of each row (`rows` empty when every point is taken, row i then
	 *  point i). */
	static cv::Mat candidateRows(const LocalMap& lm, uint32_t keyframes, std::vector<int>& rows);
	/** The keyframe of `lm` (among those in `keyframes`) nearest to a pose given in the
	 *  anchor's frame: the one a constraint to that pose is shortest from. */
	static uint64_t nearestKeyframe(const LocalMap& lm, const Eigen::Isometry3d& T_anchor_pose,
	                                const PoseView& poses, uint32_t keyframes = kAllKeyframes);
	/** Turns a verification into a decision (logged) and keeps the best acceptable one; the
	 *  constraint's keyframe is one of `keyframes`. */
	void consider(LoopDecision d, const features::RigidResult& fit, const LocalMap& lm,
	              const Query& q, const KeyframeInfo& kf, const Map& map, const PoseView& poses,
	              bool acceptable, std::optional<LoopConstraint>& best, std::size_t& bestDecision,
	              uint32_t keyframes = kAllKeyframes);
	/** The paper's two baselines: candidates are the keyframes, or the local maps, near the
	 *  current pose estimate; each is verified by feature matching. */
	void searchByDistance(const Query& q, const KeyframeInfo& kf, const Map& map,
	                      const PoseView& poses, std::optional<LoopConstraint>& best,
	                      std::size_t& bestDecision);
	/** Once the session is anchored in a prior map (kf.inMapFrame): the earlier sessions'
	 *  local maps within guided_radius_m of the keyframe, matched with the predicted positions
	 *  as a gate; a fit with guided_min_inliers that agrees with the prediction is a loop.
	 *  With `followed` (follow_loop_m): the same search among this session's local maps old
	 *  enough to be loop candidates (their old keyframes' points only), near the keyframe's
	 *  pose `followed` as the last loop puts it, not as the odometry does. */
	std::optional<LoopConstraint> guidedSearch(const Query& q, const KeyframeInfo& kf,
	                                           const Map& map, const PoseView& poses,
	                                           const Eigen::Isometry3d* followed = nullptr);
	double guidedRadius_m_ = 10.0, guidedGate_m_ = 2.0, guidedGate_deg_ = 5.0;
	int guidedMinInliers_ = 12, guidedMaxCandidates_ = 2;
	/** follow_loop_m: a keyframe that the BOW search closes no loop for, within this many
	 *  metres of the last keyframe whose loop the BOW search verified in this session, is
	 *  searched for where the last loop (verified or followed) and the odometry since put it
	 *  (guidedSearch with `followed`); 0: off. A revisit closes its loops one keyframe after
	 *  another, and one whose candidate falls a few inliers short of min_inliers is otherwise
	 *  lost. Measured from a verified loop, so that followed loops (12 inliers, gated) cannot
	 *  carry one another on for ever. */
	double followLoop_m_ = 0;
	/** The last loop closed in this session: keyframe `from` of the earlier pass, the query
	 *  keyframe, the query in the from keyframe's frame, and the query keyframe of the last
	 *  loop the BOW search verified (itself, or the one a followed loop descends from). */
	struct LastLoop
	{
		uint64_t from = 0, query = 0, verifiedQuery = 0;
		Eigen::Isometry3d T_from_query = Eigen::Isometry3d::Identity();
		uint32_t session = 0;
	};
	std::optional<LastLoop> lastLoop_;
	/** Where the last loop (lastLoop_) and the odometry since put keyframe kf, in the map
	 *  frame; nullopt when there is none in this session, follow_loop_m is 0 or kf is
	 *  farther than it from the last verified loop's query keyframe. */
	std::optional<Eigen::Isometry3d> followedPose(const KeyframeInfo& kf, const Map& map,
	                                              const PoseView& poses) const;
	enum class Search
	{
		Bow,
		Keyframes,
		LocalMaps
	};
	Search search_ = Search::Bow;
	double searchRadius_m_ = 15.0;
	void trainOnline();
	void addEntry(uint64_t localMap, const std::vector<bow::Descriptor>& desc);
	std::vector<bow::Descriptor> descriptorsOf(const cv::Mat& m) const;
	/** A candidate local map with its points (read from the offline store when it is
	 *  offline); null, with a warning, when its file cannot be read: one damaged file costs a
	 *  candidate, not the run. */
	LocalMap::ConstPtr candidate(const Map& map, uint64_t localMap);

	/** The polar contexts of the indexed local maps (LocalMap::contextCells); with
	 *  polar_fusion, ranked beside the words when a keyframe's place query has one. Made
	 *  with the first
	 *  context's dimensions; contexts of others are not indexed (a warning). */
	bool polarFusion_ = false;
	places::PolarParams polarParams_;  //!< its ringCandidates and shiftCandidates
	int polarResults_ = 50;            //!< first places of each ranking fused
	double fuseK_ = 10;                //!< fusion: 1 / (fuse_k + rank) summed
	/** A fused candidate this close to the query's context (polar distance) is acceptable
	 *  once verified whatever its words' score; 0: the score decides alone. */
	double polarMaxDistance_ = 0;
	/** With polar_fusion, a relocalized scan's places are ranked by its own context too (a
	 *  single scan's against the local maps'); false: by its words only. Off: on the ten
	 *  sessions it brought wrong places to the verification (README, Place ranking). */
	bool polarRelocalization_ = false;
	std::unique_ptr<places::PolarIndex> polar_;
	std::map<std::size_t, uint64_t> polarMap_;  //!< context -> local map
	/** Adds the contexts of `lm` (none when it has none or the index holds others'). */
	void indexContexts(const LocalMap& lm);
	bool forgetContexts(uint64_t localMap);
	/** A candidate of the place search: its words' score (raw, 0 when not indexed by its
	 *  words) and its polar distance to the query (-1: not ranked by its context). */
	struct Candidate
	{
		uint64_t localMap = 0;
		double rawScore = 0;
		double polarDistance = -1;
		bool byContext = false;  //!< not among the words' first max_results
		/** false: ranked by its context only, rawScore not computed yet (scoreOf()). */
		bool scored = true;
	};
	/** Whether polar_fusion can rank with the query context `q`: it is on, the index holds
	 *  contexts and `q` is one of their dimensions (a throttled warning when it is not). */
	bool canFuse(const PlaceContext* q);
	/** The same for contexts of `rings` x `sectors` held as `cellCount` cells. */
	bool canFuse(uint16_t rings, uint16_t sectors, std::size_t cellCount);
	/** A context as PlaceContext and LocalMap keep them (cells in kContextStep_m steps). */
	static places::PolarContext contextOf(uint16_t rings, uint16_t sectors, const uint8_t* cells);
	/** The words' ranking `words` and the polar contexts' ranking of the query contexts
	 *  `queries` fused by reciprocal rank (places::fuseRankings, K fuse_k): each ranking's
	 *  first polar_results local maps (all of the words' first max_results). A place the
	 *  words did not rank is not scored yet (scored false). */
	std::vector<Candidate> fusedCandidates(const std::vector<bow::Database::Result>& words,
	                                       const std::vector<places::PolarContext>& queries) const;
	/** The words' raw score of a local map against the query's words `b` (0 when the
	 *  database has no entry for it), filled in once for a candidate not yet scored. */
	void scoreOf(Candidate& c, const bow::BowVector& b) const;

	// parameters
	std::string vocabularyFile_;
	int onlineMinMaps_ = 8, onlineBranching_ = 8, onlineLevels_ = 3;
	features::OrbParams queryOrb_;
	double excludeRecent_s_ = 30, minScore_ = 0.3;
	int maxCandidates_ = 5, maxResults_ = 20;  //!< max_results is not a parameter
	int stopAtInliers_ = 0;  //!< an accepted candidate with this many inliers ends the search
	features::MatchParams match_;
	features::RansacParams ransac_;
	/** Inliers a relocalization (no pose prior) needs: fewer than a loop's, because one hit
	 *  decides nothing (a session is anchored by several agreeing ones) and another sensor's
	 *  scans match a map with fewer. */
	int relocMinInliers_ = 18;
	/** relocalization_max_conflicts: a place found on the features is refused when more than
	 *  this share of its free space conflicts (freeSpace_); 1: not checked. */
	double relocMaxConflicts_ = 0.05;
	/** A relocalization whose tilt differs from the ground planes' by more than this is
	 *  refused; within it, the planes give the height. */
	double groundMaxTilt_deg_ = 5.0;
	double pointSigma_m_ = 0.2;

	// state: the place index, and the last loop closed (lastLoop_, follow_loop_m)
	std::shared_ptr<bow::Vocabulary> vocab_;
	bool online_ = true;
	std::size_t trainedOn_ = 0;  //!< local maps the online vocabulary was trained on
	bow::Database db_;
	std::map<bow::Database::EntryId, uint64_t> entryMap_;  //!< entry -> local map id
	/** Online vocabulary only: the image words of every local map, to train it again. */
	std::map<uint64_t, std::vector<bow::Descriptor>> trainingImages_;
	std::optional<bow::BowVector> prevBow_;
	/** Replaced local maps waiting to leave the database: until the newer one of their place
	 *  is older than exclude_recent_s (a candidate), they still answer for the place. Value:
	 *  the newer one's session and last update. */
	std::map<uint64_t, std::pair<uint32_t, double>> retiring_;
	void retire(uint32_t session, double stamp);
	std::unique_ptr<features::OrbExtractor> orb_;  //!< relocalization queries
};
}  // namespace rasterslam
