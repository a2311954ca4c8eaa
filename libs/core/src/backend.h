// The engine's back end (private to libs/core): mapping and loop closing for each keyframe,
// then online pose-graph optimization, on a worker thread beside the tracking (paper,
// "Mapping" and "Loop Closure"). In batch mode the tracking hands a keyframe over and waits
// for it to be done (a fixed point), so a run is deterministic; in real-time mode it never
// waits (except to relocalize, which reads the map).
#pragma once

#include <rasterslam/core/engine.h>
#include <rasterslam/core/heap.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <random>
#include <set>
#include <thread>

namespace rasterslam::detail
{
struct KeyframeJob
{
	KeyframeInfo kf;
	std::shared_ptr<const Scan> scan;
	std::shared_ptr<const RasterFrame> raster;  //!< null without a rasterizer
	std::size_t record = 0;  //!< index of the keyframe's scan in RunResult::scans
};

struct BackendSettings
{
	bool optimizeOnline = true;
	int optimizeEveryKeyframes = 10;
	/** Online optimizations move only the keyframes of online local maps (and those not
	 *  mapped yet); keyframes whose local maps all went offline hold still, so the cost
	 *  follows the online map, not the whole run. False: the whole graph every time. */
	bool optimizeOnlineWindow = true;
	double testCorruptLoops = 0;
	/** RunOptions::onLoopDecisions: the detector's decisions after every keyframe. */
	std::function<void(std::vector<LoopDecision>&&)> onLoopDecisions;
};

class Backend
{
   public:
	Backend(MapManager* mapManager, LoopDetector* loopDetector, Optimizer* optimizer,
	        const BackendSettings& s, RunResult& res, mrpt::system::COutputLogger& log,
	        bool waitForEachKeyframe);
	~Backend();
	Backend(const Backend&) = delete;
	Backend& operator=(const Backend&) = delete;

	/** Keyframe poses as they are now (each lookup locks the graph). */
	const PoseView& poses() const { return poses_; }
	/** Guards res.graph: the tracking locks it to read or add nodes and edges. */
	std::mutex& graphMutex() { return graphMutex_; }
	/** Guards the map and the place index: the tracking locks it to relocalize. */
	std::mutex& mapMutex() { return mapMutex_; }

	/** Hands a keyframe over; in batch mode returns once it is done, throwing the back end's
	 *  error if it failed. */
	void submit(KeyframeJob job);
	/** Waits for every submitted keyframe (and ends the worker), then finishes the open
	 *  local map. */
	void finish();
	/** The session is anchored in the prior map: loops to its keyframes become graph edges. */
	void setAnchored() { anchored_ = true; }
	/** Adds a prior map's keyframe to the graph as a fixed node (caller holds graphMutex). */
	void addFixedNode(mrpt::graphs::TNodeID id, const mrpt::poses::CPose3D& pose);
	/** The prior map's keyframes in the graph (caller holds graphMutex). */
	const std::set<mrpt::graphs::TNodeID>& fixedNodes() const { return fixed_; }
	/** The tracking added an uncertain edge (relocalization): optimize at the next chance. */
	void requestOptimization() { optimizationPending_ = true; }
	/** Mapping and loop ms of each keyframe's scan record, complete after finish(). */
	const std::vector<std::pair<std::size_t, StageTimes>>& timings() const { return times_; }
	/** Thread CPU time spent on back-end work, s. */
	double cpuSeconds() const { return cpu_s_; }
	/** First error of the back end, empty if none. */
	std::string error() const;

   private:
	void process(KeyframeJob& job);
	void applyMapping(const MappingUpdate& up);
	void optimizeNow();
	/** Writes new poses for some nodes; nodes made after the newest of them (the tracking
	 *  went on meanwhile) move with it. Caller holds graphMutex_. */
	void writePoses(const std::map<mrpt::graphs::TNodeID, mrpt::poses::CPose3D>& updated);
	void workerLoop();
	void returnFreedMemory();
	std::size_t kfSinceTrim_ = 0;
	bool trimHeap_ = std::string(heapAllocator()) == "glibc";
	double trimMs_ = 0;

   public:
	/** Time spent returning freed memory to the system, ms. */
	double trimMs() const { return trimMs_; }

   private:
	MapManager* mapManager_;
	LoopDetector* loopDetector_;
	Optimizer* optimizer_;
	BackendSettings s_;
	RunResult& res_;
	mrpt::system::COutputLogger& log_;
	PoseView poses_;
	std::mutex graphMutex_, mapMutex_;
	std::mt19937 corruptRng_{12345};
	std::size_t kfSinceOptimization_ = 0;
	std::atomic<bool> optimizationPending_{false};
	std::atomic<bool> anchored_{false};
	bool caughtUp_ = false;  //!< the keyframes before the anchoring were searched
	std::set<mrpt::graphs::TNodeID> fixed_;
	std::vector<std::pair<std::size_t, StageTimes>> times_;
	double cpu_s_ = 0;
	std::string error_;

	bool waitForEachKeyframe_ = true;
	std::thread worker_;
	mutable std::mutex queueMutex_;
	std::condition_variable queueCv_, idleCv_;
	std::deque<KeyframeJob> queue_;
	bool busy_ = false, stop_ = false;
};

/** CPU time of the calling thread, s. */
double threadCpuSeconds();

}  // namespace rasterslam::detail
