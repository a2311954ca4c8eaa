// Plugin roles. Each role is an abstract MRPT RTTI class; a plugin library derives from one,
// registers the class when it is loaded, and the engine creates it by name from the config.
#pragma once

#include <mrpt/graphs/CNetworkOfPoses.h>
#include <mrpt/img/CImage.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/rtti/CObject.h>
#include <mrpt/system/COutputLogger.h>
#include <rasterslam/core/config.h>
#include <rasterslam/core/types.h>
#include <rasterslam/map/map.h>

#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

/** The plugin ABI: the role classes below (their virtual functions, in order) and the types
 *  they pass. Raised with every change of them: PluginLoader refuses a module built for
 *  another, which would call the wrong functions. 1: the first marked (polar contexts in
 *  relocalizeScan and placeContextOf, LoopDetector::usesScanContexts). 2: bow::Database's
 *  inverted index a table by word (its size changed). 3: raster::GroundParams gained
 *  layerMargin_m (its size changed). */
#define RASTERSLAM_PLUGIN_ABI 3

/** The plugin ABI a module was built for. Defined (weak: once a module, however many of its
 *  files include this header) in every module that includes plugin.h; PluginLoader reads a
 *  module's own. */
extern "C" int rasterslam_plugin_abi();
extern "C" __attribute__((weak, visibility("default"))) int rasterslam_plugin_abi()
{
	return RASTERSLAM_PLUGIN_ABI;
}

namespace rasterslam
{
/** Base of every plugin. initialize() reads the parameter block strictly (unknown keys and
 *  wrong types throw ConfigError) through the plugin's own initializeImpl(). */
class Plugin : public mrpt::rtti::CObject, public mrpt::system::COutputLogger
{
	DEFINE_VIRTUAL_MRPT_OBJECT(Plugin)

   public:
	/** Role name as it appears in the config ("odometry", "rasterizer", ...). */
	virtual std::string role() const = 0;

	/** `params` is the role's `params:` map (may be null for all defaults); `source` names
	 *  the config file for error messages. Not virtual: plugins implement initializeImpl. */
	void initialize(const mrpt::containers::yaml& params, const std::string& source = "");
	/** Parameters in force after initialize(), defaults included. */
	const mrpt::containers::yaml& paramsInForce() const { return paramsInForce_; }

   protected:
	virtual void initializeImpl(ParamReader& params) = 0;

   private:
	mrpt::containers::yaml paramsInForce_ = mrpt::containers::yaml::Map();
};

/** An image made from a scan, with the 3D point behind each pixel for back-projection. */
struct RasterFrame
{
	/** Ground plane found in the scan, n.p + d = height above ground (n unit, up). */
	float groundNormal[3] = {0, 0, 1};
	float groundD = 0;
	bool groundValid = false;
	mrpt::img::CImage image;  //!< 8-bit greyscale
	/** Row-major, one entry a pixel: index into Scan::points, or -1 for an empty pixel. */
	std::vector<int32_t> pixelToPoint;
	/** The image shows the scan turned by this about z (radians, counter-clockwise): 0 unless
	 *  the rasterizer turns its images to a canonical orientation. */
	float imageYaw = 0;
};

class Rasterizer : public Plugin
{
	DEFINE_VIRTUAL_MRPT_OBJECT(Rasterizer)
   public:
	std::string role() const override { return "rasterizer"; }
	virtual void rasterize(const Scan& scan, RasterFrame& out) = 0;
};

enum class TrackingStatus : uint8_t
{
	Initializing,  //!< first scan: nothing to compare against yet
	Ok,
	Lost  //!< no reliable estimate; the motion is the prior and must not be trusted
};
const char* toString(TrackingStatus s);

struct OdometryResult
{
	TrackingStatus status = TrackingStatus::Initializing;
	/** Motion of the vehicle from the previous scan to this one (pose of the current scan
	 *  in the frame of the previous one). */
	mrpt::poses::CPose3D T_prev_curr;
	/** Whether this scan should become a keyframe (a node of the pose graph). */
	bool keyframe = false;
	std::size_t inliers = 0;
	/** Information matrix of T_prev_curr, order (x y z yaw pitch roll) as MRPT's 3D graphs. */
	mrpt::math::CMatrixDouble66 information = mrpt::math::CMatrixDouble66::Identity();
	/** Why, when not Ok; how, when Ok other than by the keyframe's features (bridged through
	 *  the previous frame, recovered by ICP). */
	std::string message;
	/** When `keyframe` is set, what the odometry saw there (features and 3D points); the
	 *  engine fills in the id and pose. Null for odometries without features (GICP). */
	Keyframe::Ptr keyframeData;
	/** Motion of the scan relative to the last keyframe, when the odometry tracks against
	 *  keyframes (more precise than chaining T_prev_curr); unset otherwise. */
	std::optional<mrpt::poses::CPose3D> T_kf_curr;
};

class Odometry : public Plugin
{
	DEFINE_VIRTUAL_MRPT_OBJECT(Odometry)
   public:
	std::string role() const override { return "odometry"; }
	/** `raster` is null when no rasterizer is configured. */
	virtual OdometryResult process(const Scan& scan, const RasterFrame* raster) = 0;
};

/** A place's polar context as a LocalMap keeps one (LocalMap::contextCells): rings x sectors
 *  cells, ring-major, each the height above the ground of the highest point in it in steps
 *  of LocalMap::kContextStep_m (0: empty). */
struct PlaceContext
{
	uint16_t rings = 0, sectors = 0;
	std::vector<uint8_t> cells;
	bool empty() const { return cells.empty(); }
};

/** A keyframe as the engine hands it to mapping and loop closing. */
struct KeyframeInfo
{
	mrpt::graphs::TNodeID node = 0;
	std::size_t scanIndex = 0;
	double stamp = 0;
	mrpt::poses::CPose3D pose;  //!< current estimate in the map frame
	Keyframe::Ptr data;         //!< features seen there, when the odometry provides them
	/** Tracking was lost since the previous keyframe and not recovered: the two are not
	 *  linked by a trustworthy motion (a local map must not span them). */
	bool afterLoss = false;
	/** The keyframe of the map this one was relocalized against (a graph edge joins them):
	 *  a session anchored in a prior map, or tracking found again after a loss. */
	std::optional<uint64_t> locatedAt;
	/** The pose is in the frame of the map's earlier sessions (this session is anchored in
	 *  them): a loop detector may search them near it. */
	bool inMapFrame = false;
	/** The scan that made the keyframe and its elevation image, while the engine hands the
	 *  keyframe to the mapping and the loop detector (null otherwise; not to be kept). */
	const Scan* scan = nullptr;
	const RasterFrame* raster = nullptr;
	/** The map manager's MappingUpdate::placeQuery for this keyframe, while the engine hands
	 *  it to the loop detector (null or empty otherwise; not to be kept). */
	const std::vector<uint8_t>* placeQuery = nullptr;
	/** MappingUpdate::placeQueryTurns for this keyframe, handed over as placeQuery is. */
	const std::vector<std::vector<uint8_t>>* placeQueryTurns = nullptr;
	/** MappingUpdate::placeQueryContext for this keyframe, handed over as placeQuery is. */
	const PlaceContext* placeQueryContext = nullptr;
};

/** What the mapping did with a keyframe, for the engine to apply. */
struct MappingUpdate
{
	/** A local map finished with this keyframe, and the ORB descriptors of its image (32
	 *  bytes each) for the place index; they are not kept in the map. */
	struct Finished
	{
		uint64_t localMap = 0;
		std::vector<uint8_t> imageDescriptors;
	};
	std::vector<Finished> finished;
	/** Local maps the finished one replaced (update on revisit), each with the one that
	 *  replaced it: they leave the place index, the new local map indexes their place. */
	std::vector<std::pair<uint64_t, uint64_t>> replaced;
	/** Local BA's refined poses of the finished map's keyframes in its anchor's frame (the
	 *  anchor itself not listed). The engine writes them into the pose graph. */
	uint64_t anchor = 0;
	std::vector<std::pair<uint64_t, mrpt::poses::CPose3D>> T_anchor_kf;
	/** The ORB descriptors (32 bytes each) of an image of the local map being built around
	 *  the new keyframe, made as a local-map image is, for the loop detector's query (image
	 *  against image); empty when the map manager makes none. */
	std::vector<uint8_t> placeQuery;
	/** The descriptors of the same image rasterized turned by k * 90 / N degrees (k = 1..N-1,
	 *  in that order) when the map manager turns its queries: one of the N images, placeQuery
	 *  included, lies within 45 / N degrees of any place's pixel grid. Empty when it does not. */
	std::vector<std::vector<uint8_t>> placeQueryTurns;
	/** The polar context of the same points about the new keyframe, when the map manager
	 *  makes contexts (as it makes each local map's, LocalMap::contextCells); empty when not. */
	PlaceContext placeQueryContext;
};

/** Paper, "Mapping" and "Map Management": the only writer of the map model (keyframes,
 *  local maps, the local-map graph). Poses are read from the engine's PoseView. */
class MapManager : public Plugin
{
	DEFINE_VIRTUAL_MRPT_OBJECT(MapManager)
   public:
	std::string role() const override { return "map_manager"; }
	virtual MappingUpdate addKeyframe(const KeyframeInfo& kf, const Scan& scan,
	                                  const RasterFrame* raster, const PoseView& poses) = 0;
	/** Called once at the end of a run: finish what is open. */
	virtual MappingUpdate finish(const PoseView& poses) = 0;
	/** An accepted loop between two keyframes (the engine made it a graph edge). */
	virtual void loopAccepted(uint64_t /*fromKf*/, uint64_t /*toKf*/, double /*stamp*/) {}
	virtual const Map& map() const = 0;
	/** What the engine knows of the session being made (its id is the manager's to set). */
	virtual void describeSession(const SessionRecord& /*session*/) {}
	/** What addMap() did: the other map's ids as they are in this one, and the local maps
	 *  it added with the ORB descriptors of their images, for the place index. */
	struct Added
	{
		std::map<uint64_t, uint64_t> keyframeIds, localMapIds;
		std::map<uint32_t, uint32_t> sessionIds;
		std::vector<MappingUpdate::Finished> localMaps;
	};
	/** Adds a map built separately (`map merge`): its sessions, keyframes at `poses` (this
	 *  map's frame, keyed by the other map's keyframe ids), local maps and graph, renumbered
	 *  after this map's, and a relocalization edge for each (this map's local map, the
	 *  other's) in `links`. */
	virtual Added addMap(const Map& /*other*/,
	                     const std::map<uint64_t, mrpt::poses::CPose3D>& /*poses*/,
	                     const std::vector<std::pair<uint64_t, uint64_t>>& /*links*/)
	{
		throw std::runtime_error(std::string(GetRuntimeClass()->className) + " cannot merge maps");
	}
	/** The polar context of a scan's points made as a place query's is (empty when this
	 *  manager makes no contexts), for relocalizing the scan. */
	virtual PlaceContext placeContextOf(const Scan& /*scan*/, const RasterFrame& /*raster*/) const
	{
		return {};
	}
	/** The ORB descriptors of a local map's image (32 bytes each), for the place index. */
	virtual std::vector<uint8_t> imageDescriptors(uint64_t /*localMap*/) { return {}; }
	/** Removes local maps (`map prune`) with their graph edges, and the keyframes no
	 *  remaining local map holds. Returns the keyframes removed. */
	virtual std::size_t removeLocalMaps(const std::set<uint64_t>& /*localMaps*/)
	{
		throw std::runtime_error(std::string(GetRuntimeClass()->className) +
		                         " cannot remove local maps");
	}
	/** Replaces the map with one loaded from disk; the next session continues its ids. */
	virtual void loadMap(const std::string& dir) = 0;
	/** Writes the map (open local map included) with the given poses and place index. */
	virtual void saveMap(const std::string& dir, const PoseView& poses,
	                     const std::string& placeIndexClass,
	                     const std::vector<uint8_t>& placeIndex) = 0;
};

/** A constraint found by a loop detector: pose of `to` in the frame of `from`. */
struct LoopConstraint
{
	mrpt::graphs::TNodeID from = 0, to = 0;
	mrpt::poses::CPose3D T_from_to;
	mrpt::math::CMatrixDouble66 information = mrpt::math::CMatrixDouble66::Identity();
	double score = 0;
	std::size_t inliers = 0;
	uint64_t localMap = 0;  //!< the local map it was found in
};

/** One candidate a loop detector examined, for loops.txt. */
struct LoopDecision
{
	double queryStamp = 0;
	double candidateStamp = -1;  //!< stamp of the matched keyframe's scan, -1 if none
	uint64_t candidateMap = 0;   //!< the candidate local map
	double score = 0;            //!< normalized BOW score
	std::size_t inliers = 0;
	bool verified = false;  //!< the geometric check passed
	bool accepted = false;  //!< it became a loop edge
	std::string reason;     //!< one word: ok, score, inliers, ...
	/** The candidate came from the places' polar contexts (not among what the words alone
	 *  would rank): what ranking by them adds. */
	bool byContext = false;
	mrpt::poses::CPose3D T_candidate_query;  //!< query in the matched keyframe's frame
};

/** Where a scan lies in a map, found with no pose prior. */
struct RelocalizationResult
{
	bool found = false;
	std::string reason;  //!< one word: ok, surface (no features verified it), features, ...
	uint64_t localMap = 0;
	uint64_t keyframe = 0;  //!< id of the matched keyframe (most inliers among the map's)
	double keyframeStamp = -1;
	double score = 0;
	std::size_t inliers = 0;
	mrpt::poses::CPose3D pose;          //!< of the scan, in the map frame
	mrpt::poses::CPose3D keyframePose;  //!< of the matched keyframe, in the map frame
};

/** Paper, "BOW Database" and "Loop Closure": a query service over the map. It keeps only
 *  its place index (words of the local-map images); keyframes and local maps are read from
 *  the map the engine passes. */
class LoopDetector : public Plugin
{
	DEFINE_VIRTUAL_MRPT_OBJECT(LoopDetector)
   public:
	std::string role() const override { return "loop_detector"; }
	/** A finished local map enters the place index. */
	virtual void index(const LocalMap& lm, const std::vector<uint8_t>& imageDescriptors) = 0;
	virtual std::vector<LoopConstraint> detect(const KeyframeInfo& kf, const Map& map,
	                                           const PoseView& poses) = 0;
	/** Looks for the map's earlier sessions near kf.pose only (kf.inMapFrame): for the
	 *  keyframes a session made before it was anchored, searched once it is. None by
	 *  default. */
	virtual std::vector<LoopConstraint> searchEarlierSessions(const KeyframeInfo& /*kf*/,
	                                                          const Map& /*map*/,
	                                                          const PoseView& /*poses*/)
	{
		return {};
	}
	/** Locates a scan in the map with no pose prior. */
	virtual RelocalizationResult relocalize(const Scan& scan, const RasterFrame& raster,
	                                        const Map& map, const PoseView& poses) = 0;
	/** The same with the scan's polar context as the map manager makes it
	 *  (MapManager::placeContextOf; empty when it makes none), for a detector that ranks the
	 *  places by it too; what the engine and `rasterslam relocalize` call, with the context
	 *  only when usesScanContexts(). By default the context is not used: a detector that
	 *  overrides this must not implement relocalize() by calling it back (each would call
	 *  the other). */
	virtual RelocalizationResult relocalizeScan(const Scan& scan, const RasterFrame& raster,
	                                            const PlaceContext& context, const Map& map,
	                                            const PoseView& poses)
	{
		(void)context;
		return relocalize(scan, raster, map, poses);
	}
	/** Whether relocalizeScan() ranks by the scan's polar context (the engine makes one only
	 *  then). */
	virtual bool usesScanContexts() const { return false; }
	/** Locates a local map of another map (its points, in its anchor's frame; only those its
	 *  keyframe number `onlyKeyframe` saw, when >= 0) with no pose prior; the result's pose
	 *  is that of its anchor keyframe in `map`'s frame. */
	virtual RelocalizationResult locate(const LocalMap& query, const Map& map,
	                                    const PoseView& poses, int onlyKeyframe = -1)
	{
		(void)query, (void)map, (void)poses, (void)onlyKeyframe;
		throw std::runtime_error(std::string(GetRuntimeClass()->className) +
		                         " cannot locate local maps");
	}
	/** The local maps the place index saved with `map` has entries for (a local map replaced
	 *  on a revisit has none); nullopt when this detector cannot read that index. */
	virtual std::optional<std::set<uint64_t>> indexedIn(const Map& /*map*/) const
	{
		return std::nullopt;
	}
	/** Whether the place index has an entry for the local map. */
	virtual bool indexes(uint64_t /*localMap*/) const { return false; }
	/** A local map leaves the place index now (pruned). Returns whether it was there. */
	virtual bool forget(uint64_t /*localMap*/) { return false; }
	/** A local map was replaced by a newer one of the same place (update on revisit): its
	 *  entry leaves the place index once the newer one can be found in its stead. */
	virtual void replaced(uint64_t /*older*/, const LocalMap& /*newer*/) {}
	/** The place index as bytes to save with the map, and the class name that reads them. */
	virtual std::vector<uint8_t> savePlaceIndex() = 0;
	/** Restores a place index saved with `map` (after the map manager loaded it). */
	virtual void loadPlaceIndex(const Map& map) = 0;
	/** Every candidate examined so far (since the last takeDecisions()), in order. */
	const std::vector<LoopDecision>& decisions() const { return decisions_; }
	/** Moves out the decisions made since the last call: a long run hands them on as it goes
	 *  (RunOptions::onLoopDecisions) instead of keeping every one. */
	std::vector<LoopDecision> takeDecisions()
	{
		std::vector<LoopDecision> d;
		d.swap(decisions_);
		return d;
	}

   protected:
	std::vector<LoopDecision> decisions_;
};

/** Edges (from, to) whose constraint may be wrong: loop and relocalization edges. An
 *  optimizer with a robust loss applies it to these; odometry edges are trusted. */
using EdgeSet = std::set<std::pair<mrpt::graphs::TNodeID, mrpt::graphs::TNodeID>>;

struct OptimizerResult
{
	bool ran = false;
	std::size_t iterations = 0;
	double initialError = 0, finalError = 0;  //!< sum of squared whitened residuals (chi2)
	double time_ms = 0;
	/** For each uncertain edge, the weight the robust loss gave it at the solution (1: fully
	 *  trusted, near 0: rejected). Empty when the optimizer has no robust loss. */
	std::map<std::pair<mrpt::graphs::TNodeID, mrpt::graphs::TNodeID>, double> edgeWeights;
};

class Optimizer : public Plugin
{
	DEFINE_VIRTUAL_MRPT_OBJECT(Optimizer)
   public:
	std::string role() const override { return "optimizer"; }
	/** Optimizes the node poses of `graph` in place; the root node and the nodes in `fixed`
	 *  (an earlier session's keyframes) stay where they are. `uncertain` names the edges that
	 *  may be outliers (see EdgeSet). */
	virtual OptimizerResult optimize(mrpt::graphs::CNetworkOfPoses3DInf& graph,
	                                 const EdgeSet& uncertain = {},
	                                 const std::set<mrpt::graphs::TNodeID>& fixed = {}) = 0;
};

}  // namespace rasterslam
