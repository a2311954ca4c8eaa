// The graph-SLAM engine: runs the configured plugins over a scan source and owns the pose graph.
#pragma once

#include <mrpt/graphs/CNetworkOfPoses.h>
#include <mrpt/system/COutputLogger.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/core/scan_log.h>
#include <rasterslam/core/scan_source.h>
#include <rasterslam/core/sweep.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace rasterslam
{
struct RunOptions
{
	/** Only scans with first <= index <= last (input indices, 0-based). */
	std::optional<std::size_t> first, last;
	/** Play scans at their time stamps (scaled by `rate`) instead of as fast as possible. */
	bool realtime = false;
	double rate = 1.0;
	/** With realtime: a scan whose processing could only start a whole period (the step from
	 *  the previous stamp) after its due time is skipped (counted in RunResult::droppedLate). */
	bool dropLate = false;
	/** Locate the run in the loop detector's loaded map (--map-in): every keyframe is
	 *  relocalized until one is found, then all poses move into the map's frame. */
	bool relocalizeFirstScan = false;
	/** Called after every processed scan. */
	std::function<void(const ScanRecord&, double progress)> onScan;
	/** Keep RunResult::scans in an unnamed temporary file (ScanLog::spooled) in `scanSpoolDir`
	 *  (empty: $TMPDIR, else /tmp) rather than in memory: a lifelong run then holds nothing a
	 *  scan. When no such file can be made the records stay in memory, with a warning. */
	bool spoolScans = false;
	std::string scanSpoolDir;
	/** When set, the loop detector's decisions are handed over after every keyframe that made
	 *  some, on the back end's thread and with the map unlocked, and those left at the end
	 *  once more, instead of being kept in RunResult::loopDecisions: a lifelong run keeps
	 *  none of them in memory (rasterslam run writes them to a temporary file). */
	std::function<void(std::vector<LoopDecision>&&)> onLoopDecisions;
	/** Called with every rasterized image (e.g. to save it), when a rasterizer is set. */
	std::function<void(const Scan&, const RasterFrame&)> onRaster;
	/** When set and non-zero (e.g. a signal handler stored the signal's number), the run
	 *  stops before the next scan and finishes as after the last one: the back end, the final
	 *  optimization and every pose for the scans processed. */
	const std::atomic<int>* stop = nullptr;
};

struct RunResult
{
	/** Every processed scan's record (in a temporary file with RunOptions::spoolScans; if
	 *  writing it failed, scans.error() says why and `error` says so too). */
	ScanLog scans;
	/** Pose of every processed scan in the map frame (keyframe pose + T_kf_scan). */
	std::vector<mrpt::poses::CPose3D> poses;
	mrpt::graphs::CNetworkOfPoses3DInf graph;
	std::size_t keyframes = 0, lost = 0, late = 0, loopEdges = 0, skippedBadScans = 0;
	std::size_t droppedLate = 0;       //!< scans skipped by RunOptions::dropLate
	std::size_t stampsOutOfOrder = 0;  //!< scans whose stamp did not increase
	std::size_t odometryEdges = 0;     //!< edges from the input's own odometry
	std::size_t relocalized = 0, relocalizationFailures = 0;
	std::size_t loopsToPriorMap = 0;    //!< loops found to a --map-in map's keyframes
	std::size_t priorMapLoopEdges = 0;  //!< of those, made graph edges (after the anchoring)
	/** --map-in: whether the session was located (anchored) in the prior map, and how many
	 *  relocalization hits in earlier sessions it had. */
	bool localized = false;
	std::size_t anchorHits = 0;
	/** The scan (its index in the input) whose keyframe anchored the session. */
	std::optional<std::size_t> localizedAtScan;
	std::size_t localMaps = 0;          //!< local maps finished in this run
	std::size_t localBaRuns = 0;        //!< local maps refined by local BA
	std::size_t localMapsReplaced = 0;  //!< replaced on a revisit, their place-index entry dropped
	std::size_t onlineOptimizations = 0;      //!< pose-graph optimizations during the run
	double onlineOptimization_ms = 0;         //!< their total time
	std::size_t onlineOptimizationNodes = 0;  //!< nodes they had, summed (moving and fixed)
	double memoryTrim_ms = 0;                 //!< time spent returning freed heap to the system
	std::size_t corruptedLoops =
	    0;  //!< loop edges replaced by wrong ones (engine.test_corrupt_loops)
	/** Edges that may be outliers (loop, relocalization), for the robust loss. */
	EdgeSet uncertainEdges;
	OptimizerResult optimizer;  //!< the final optimization
	/** CPU time of the tracking and of the back end (mapping, loop closing, online
	 *  optimization), s; in real-time mode each is its own thread. */
	double cpuTracking_s = 0, cpuBackend_s = 0;
	/** What the loop detector examined (empty without one, and when
	 *  RunOptions::onLoopDecisions took them); loopDecisionsMade counts them either way. */
	std::vector<LoopDecision> loopDecisions;
	std::size_t loopDecisionsMade = 0;
	/** Accepted loops whose candidate the polar contexts alone ranked (LoopDecision::byContext). */
	std::size_t loopsByContext = 0;
	/** Empty if the input ended normally; else where and why it stopped early. */
	std::string stopReason;
	/** The value RunOptions::stop held when it stopped the run; 0 when it did not. */
	int stoppedBy = 0;
	/** Non-empty when the run stopped on bad input (outputs are still valid up to there). */
	std::string error;
	double wall_s = 0;
};

/** What Engine::mergeMap() found and did. */
struct MergeReport
{
	std::size_t localMaps = 0;       //!< local maps of the map merged in
	std::size_t keyframesTried = 0;  //!< its keyframes, each located with the points it saw
	std::size_t located = 0;         //!< of those, found in the loaded map
	/** Local maps none of whose keyframes was found, located whole (all their points), and
	 *  of those the ones found. */
	std::size_t localMapsWhole = 0, locatedWhole = 0;
	std::size_t agreeing = 0;  //!< of all the hits, agreeing on where the other map lies (linked)
	/** The other map's frame in the loaded one's, from the agreeing hits (before the
	 *  optimization). */
	mrpt::poses::CPose3D T_this_other;
	OptimizerResult optimization;
	uint32_t sessions = 0;  //!< sessions of the merged map
	std::size_t keyframes = 0;
	/** Largest move the optimization gave a keyframe of the other map, m. */
	double maxCorrection_m = 0;
};

/** What `map prune` drops: local maps not online when the map was saved that are older than
 *  `before` (their last update's stamp, the input's clock), and/or not among the newest
 *  `keepPerPlace` of their place (local maps whose anchors lie within `placeRadius_m`);
 *  with both, only those both rules drop. */
struct PruneOptions
{
	std::optional<double> before;
	std::optional<std::size_t> keepPerPlace;
	double placeRadius_m = 10;
	bool dryRun = false;  //!< report, change nothing
};
struct PruneReport
{
	std::size_t localMaps = 0;
	std::size_t places = 0;  //!< local maps with no kept one within the radius (a rough count)
	std::vector<uint64_t> dropped;  //!< local maps
	std::size_t keyframesDropped = 0;
	/** Kept local maps put back into the place index (a dropped one had replaced them). */
	std::size_t reindexed = 0;
};

/** Top-level config sections: plugins, rasterizer, odometry, map_manager, loop_detector,
 *  optimizer, engine. Each role section is {class: ns::Name, params: {...}}; odometry is
 *  required, the others are optional. Unknown sections or keys throw ConfigError. */
class Engine : public mrpt::system::COutputLogger
{
   public:
	Engine(const mrpt::containers::yaml& config, const std::string& configSource);

	RunResult run(ScanSource& source, const RunOptions& opts);

	/** Sets the logging level of the engine and of every plugin it created. */
	void setLogLevel(mrpt::system::VerbosityLevel level);

	Rasterizer::Ptr rasterizer() const { return rasterizer_; }
	LoopDetector::Ptr loopDetector() const { return loopDetector_; }
	MapManager::Ptr mapManager() const { return mapManager_; }
	/** The map manager's polar context of a scan, when the loop detector relocalizes by it
	 *  (LoopDetector::usesScanContexts); empty otherwise: what relocalizeScan() is given. */
	PlaceContext scanContext(const Scan& scan, const RasterFrame& raster) const;

	/** Loads a saved map (--map-in): the map manager reads it, the loop detector restores
	 *  its place index from it. Needs a map_manager. */
	void loadMap(const std::string& dir);
	/** Adds a map built separately (saved in `dir`) to the loaded one: each of its
	 *  keyframes is located in the loaded map with no pose prior (with the points it saw in its
	 *  local map); at least engine.anchor_min_agreeing of them must agree on where the other map
	 * lies (else it throws: no overlap). The other map's keyframes are moved there, tied by their
	 * relative poses and the agreeing hits, and optimized with the loaded map fixed. Save with
	 *  saveMap(dir, {}). Needs a map_manager, a loop_detector and an optimizer. */
	MergeReport mergeMap(const std::string& dir);
	/** Drops local maps of the loaded map (`map prune`) with their place-index entries and
	 *  the keyframes no local map holds any more. Throws when every local map would go. */
	PruneReport pruneMap(const PruneOptions& opts);
	/** Saves the map with the poses of `graph` (optimized) and the place index. */
	void saveMap(const std::string& dir, const mrpt::graphs::CNetworkOfPoses3DInf& graph);

	/** The whole configuration with every parameter in force (defaults filled in). */
	const mrpt::containers::yaml& configInForce() const { return inForce_; }

   private:
	// The stages of run(), in the order the data flows (engine.cpp).
	struct RunState;
	using Clock = std::chrono::steady_clock;
	/** The next scan within --first/--last, or none at the end of the input. */
	std::optional<Scan> readScan(RunState& s);
	/** The input's own odometry (wheels, visual) composed since the last keyframe. */
	void addInputOdometry(RunState& s, const Scan& scan);
	/** False for a scan to drop (non-finite points, too few points); sets the error when
	 *  such a scan ends the run. */
	bool admitScan(RunState& s, Scan& scan);
	/** The scan's record; the session's record on the first scan. */
	ScanRecord beginScan(RunState& s, const Scan& scan);
	/** Time stamps must increase: a warning (or the error that ends the run, with
	 *  engine.stamp_order: error) naming the scan when one goes back or stands still. */
	bool stampInOrder(RunState& s, const Scan& scan);
	/** --realtime: waits for the scan's time (from the first scan's) and counts it late when
	 *  past it; false for a scan to drop (RunOptions::dropLate, a whole period late). */
	bool pace(RunState& s, const Scan& scan, ScanRecord& rec);
	/** engine.deskew: the scan's points moved into the sensor frame at the sweep's end, with
	 *  the motion of the last tracked step (its time counts as rasterizing). */
	void deskew(RunState& s, Scan& scan, ScanRecord& rec);
	/** The elevation image (null without a rasterizer). */
	const RasterFrame* rasterize(RunState& s, const Scan& scan, ScanRecord& rec);
	/** Odometry: the scan's pose from the last keyframe's (as the back end has it now). */
	OdometryResult track(RunState& s, const Scan& scan, const RasterFrame* raster, ScanRecord& rec);
	/** A session in a prior map: one more hit towards anchoring it. */
	void seekAnchor(RunState& s, const Scan& scan, const RasterFrame& raster, ScanRecord& rec);
	/** Moves the session into the prior map's frame; the relocalization edge that ties it. */
	std::optional<LoopConstraint> anchor(RunState& s);
	/** Tracking lost: the scan located in the map with no prior, and the edge when the
	 *  keyframe it matched is in this run's graph. */
	std::optional<LoopConstraint> relocalizeAfterLoss(RunState& s, const Scan& scan,
	                                                  const RasterFrame& raster, ScanRecord& rec);
	/** A graph node with its odometry (and relocalization) edges, handed to the back end. */
	void addKeyframe(RunState& s, const Scan& scan, const RasterFrame* raster,
	                 const OdometryResult& odo, std::optional<LoopConstraint> relocEdge,
	                 ScanRecord& rec);
	/** The scan's pose relative to its keyframe, its timings, and the progress callback. */
	void recordScan(RunState& s, ScanRecord& rec, Clock::time_point tScan);
	/** Finishes the back end, optimizes the whole graph and computes every scan's pose. */
	void finishRun(RunState& s);

	/** Two anchorings agree: their difference `d` (where the vehicle is) is within
	 *  engine.anchor_agree_m and anchor_agree_deg. */
	bool anchorsAgree(const mrpt::poses::CPose3D& d) const;
	mrpt::graphs::CNetworkOfPoses3DInf::edge_t rawlogOdometryEdge(
	    const mrpt::poses::CPose3DPDFGaussian& odo) const;
	Plugin::Ptr makeRole(const mrpt::containers::yaml& cfg, const std::string& section,
	                     const mrpt::rtti::TRuntimeClassId* role, bool required);

	std::string source_;
	mrpt::containers::yaml inForce_ = mrpt::containers::yaml::Map();
	Rasterizer::Ptr rasterizer_;
	Odometry::Ptr odometry_;
	MapManager::Ptr mapManager_;
	LoopDetector::Ptr loopDetector_;
	Optimizer::Ptr optimizer_;
	// engine parameters
	bool skipBadScans_ = false;
	int minPoints_ = 100;
	bool optimizeAtEnd_ = true;
	bool useRawlogOdometry_ = false;
	bool relocalizeOnLoss_ = true;
	bool dropNonFinite_ = false;
	double rawlogOdoSigma_m_ = 0.05, rawlogOdoSigma_deg_ = 0.5;
	bool optimizeOnline_ = true;
	int optimizeEveryKeyframes_ = 10;
	bool optimizeOnlineWindow_ = true;
	double testCorruptLoops_ = 0;
	int anchorMinAgreeing_ = 3;
	double anchorAgree_m_ = 2.0, anchorAgree_deg_ = 5.0;
	bool anchorEveryScan_ = true;
	double anchorHitSpacing_s_ = 1.0;
	bool stampOrderError_ = false;
	double realtimeMaxWait_s_ = 5.0;
	bool deskew_ = false;
	/** engine.deskew: planar: the last step's translation and yaw only (its roll and pitch
	 *  over a sweep are mostly the estimate's noise, which de-skewing would put into the
	 *  ground). */
	bool deskewPlanar_ = false;
	/** engine.vertical_correction_deg: every scan's beams raised by this (0: as read). */
	double verticalCorrection_deg_ = 0;
	SweepModel sweep_;
	double sweepPeriod_s_ = 0;  //!< 0: the time between scans
};

/** Resident set size high-water mark of this process, MB (from /proc/self/status). */
double peakRssMb();
/** Resident set size of this process now, MB. */
double currentRssMb();

std::string rasterslamVersion();

}  // namespace rasterslam
