#include "backend.h"

#include <malloc.h>

#include <chrono>
#include <ctime>

namespace rasterslam::detail
{
namespace
{
using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
}  // namespace

double threadCpuSeconds()
{
	timespec ts{};
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

Backend::Backend(MapManager* mapManager, LoopDetector* loopDetector, Optimizer* optimizer,
                 const BackendSettings& s, RunResult& res, mrpt::system::COutputLogger& log,
                 bool waitForEachKeyframe)
    : mapManager_(mapManager),
      loopDetector_(loopDetector),
      optimizer_(optimizer),
      s_(s),
      res_(res),
      log_(log),
      waitForEachKeyframe_(waitForEachKeyframe)
{
	poses_.live = [this](uint64_t id) -> const mrpt::poses::CPose3D*
	{
		// A copy taken under the lock: the optimizer may rewrite the node right after.
		thread_local mrpt::poses::CPose3D copy;
		std::lock_guard<std::mutex> lk(graphMutex_);
		const auto it = res_.graph.nodes.find(id);
		if (it == res_.graph.nodes.end())
			return nullptr;
		copy = it->second;
		return &copy;
	};
	if (mapManager_)
		poses_.prior = &mapManager_->map().priorPoses;
	worker_ = std::thread([this] { workerLoop(); });
}

Backend::~Backend()
{
	if (worker_.joinable())
	{
		{
			std::lock_guard<std::mutex> lk(queueMutex_);
			stop_ = true;
		}
		queueCv_.notify_all();
		worker_.join();
	}
}

std::string Backend::error() const
{
	std::lock_guard<std::mutex> lk(queueMutex_);
	return error_;
}

void Backend::submit(KeyframeJob job)
{
	{
		std::lock_guard<std::mutex> lk(queueMutex_);
		queue_.push_back(std::move(job));
	}
	queueCv_.notify_one();
	if (!waitForEachKeyframe_)
		return;
	std::unique_lock<std::mutex> lk(queueMutex_);
	idleCv_.wait(lk, [this] { return queue_.empty() && !busy_; });
	if (!error_.empty())
		throw std::runtime_error(error_);
}

void Backend::workerLoop()
{
	const double c0 = threadCpuSeconds();
	for (;;)
	{
		KeyframeJob job;
		{
			std::unique_lock<std::mutex> lk(queueMutex_);
			queueCv_.wait(lk, [this] { return stop_ || !queue_.empty(); });
			if (queue_.empty())
				break;
			job = std::move(queue_.front());
			queue_.pop_front();
			busy_ = true;
		}
		try
		{
			if (error().empty())
			{
				process(job);
				returnFreedMemory();  // outside the map lock: the tracking may be relocalizing
			}
		}
		catch (const std::exception& e)
		{
			std::lock_guard<std::mutex> lk(queueMutex_);
			if (error_.empty())
				error_ = e.what();
		}
		catch (...)
		{
			std::lock_guard<std::mutex> lk(queueMutex_);
			if (error_.empty())
				error_ = "unknown exception";
		}
		{
			std::lock_guard<std::mutex> lk(queueMutex_);
			busy_ = false;
		}
		idleCv_.notify_all();
	}
	cpu_s_ = threadCpuSeconds() - c0;
}

void Backend::finish()
{
	if (worker_.joinable())
	{
		{
			std::unique_lock<std::mutex> lk(queueMutex_);
			idleCv_.wait(lk, [this] { return queue_.empty() && !busy_; });
			stop_ = true;
		}
		queueCv_.notify_all();
		worker_.join();
	}
	if (!mapManager_)
		return;
	const double c0 = threadCpuSeconds();
	std::lock_guard<std::mutex> lk(mapMutex_);
	applyMapping(mapManager_->finish(poses_));
	cpu_s_ += threadCpuSeconds() - c0;
}

void Backend::writePoses(const std::map<mrpt::graphs::TNodeID, mrpt::poses::CPose3D>& updated)
{
	if (updated.empty())
		return;
	const auto newest = updated.rbegin()->first;
	auto& nodes = res_.graph.nodes;
	const mrpt::poses::CPose3D before = nodes.at(newest);
	for (const auto& [id, p] : updated)
		nodes.at(id) = p;
	// Keyframe ids grow with time: those past the newest updated one were made by the tracking
	// from its old pose; they move rigidly with it.
	const mrpt::poses::CPose3D C = updated.rbegin()->second + (mrpt::poses::CPose3D() - before);
	for (auto it = nodes.upper_bound(newest); it != nodes.end(); ++it)
		it->second = C + it->second;
}

void Backend::addFixedNode(mrpt::graphs::TNodeID id, const mrpt::poses::CPose3D& pose)
{
	res_.graph.nodes[id] = pose;
	fixed_.insert(id);
}

void Backend::applyMapping(const MappingUpdate& up)
{
	if (!up.T_anchor_kf.empty())
	{
		std::lock_guard<std::mutex> lk(graphMutex_);
		++res_.localBaRuns;
		const mrpt::poses::CPose3D anchor = res_.graph.nodes.at(up.anchor);
		std::map<mrpt::graphs::TNodeID, mrpt::poses::CPose3D> updated;
		for (const auto& [id, T] : up.T_anchor_kf)
			updated[id] = anchor + T;
		writePoses(updated);
		// The tracking edge between consecutive keyframes takes the refined motion, so a later
		// optimization keeps it.
		mrpt::graphs::TNodeID prev = up.anchor;
		for (const auto& [id, T] : up.T_anchor_kf)
		{
			const auto range = res_.graph.edges.equal_range({prev, id});
			if (range.first != range.second)
				range.first->second.mean = res_.graph.nodes.at(id) - res_.graph.nodes.at(prev);
			prev = id;
		}
	}
	for (const auto& f : up.finished)
	{
		{
			std::lock_guard<std::mutex> lk(graphMutex_);
			++res_.localMaps;
		}
		if (loopDetector_)
			// Whole (its polar contexts): online, as it was just made, unless the culling took
			// it to the store already, whence it is read.
			loopDetector_->index(*mapManager_->map().data(f.localMap), f.imageDescriptors);
	}
	if (loopDetector_)
		for (const auto& [older, newer] : up.replaced)
		{
			loopDetector_->replaced(older, *mapManager_->map().localMaps.at(newer));
			std::lock_guard<std::mutex> lk(graphMutex_);
			++res_.localMapsReplaced;
		}
}

void Backend::optimizeNow()
{
	// Keyframes that only offline local maps hold: the map they belong to has been set aside
	// (culled, or replaced on a revisit), and they anchor what is optimized now. Caller holds
	// mapMutex_.
	std::set<mrpt::graphs::TNodeID> still;
	if (s_.optimizeOnlineWindow && mapManager_)
	{
		std::set<uint64_t> online;
		for (const auto& [id, lm] : mapManager_->map().localMaps)
			(lm->online ? online : still).insert(lm->keyframes.begin(), lm->keyframes.end());
		for (const auto k : online)
			still.erase(k);
	}
	// The optimizer works on a copy (of the window), so the tracking can add keyframes
	// meanwhile.
	mrpt::graphs::CNetworkOfPoses3DInf g;
	EdgeSet uncertain;
	std::set<mrpt::graphs::TNodeID> fixed;
	{
		std::lock_guard<std::mutex> lk(graphMutex_);
		if (still.empty())
		{
			g = res_.graph;
			uncertain = res_.uncertainEdges;
			fixed = fixed_;
		}
		else
		{
			auto moves = [&](mrpt::graphs::TNodeID id)
			{ return !still.count(id) && !fixed_.count(id); };
			for (const auto& [id, p] : res_.graph.nodes)
				if (moves(id))
					g.nodes[id] = p;
			// Edges with a moving end; their other end joins the window, fixed.
			for (const auto& [ends, e] : res_.graph.edges)
			{
				const bool a = moves(ends.first), b = moves(ends.second);
				if (!a && !b)
					continue;
				for (const auto id : {ends.first, ends.second})
					if (!moves(id) && res_.graph.nodes.count(id))
					{
						g.nodes[id] = res_.graph.nodes.at(id);
						fixed.insert(id);
					}
				g.insertEdge(ends.first, ends.second, e);
				if (res_.uncertainEdges.count(ends))
					uncertain.insert(ends);
			}
			g.root = fixed.empty() ? res_.graph.root : *fixed.begin();
			if (!g.nodes.count(g.root))
				g.root = g.nodes.empty() ? 0 : g.nodes.begin()->first;
		}
	}
	if (g.nodes.empty())
		return;
	const auto r = optimizer_->optimize(g, uncertain, fixed);
	std::lock_guard<std::mutex> lk(graphMutex_);
	std::map<mrpt::graphs::TNodeID, mrpt::poses::CPose3D> updated;
	for (const auto& [id, p] : g.nodes)
		if (!fixed.count(id))
			updated[id] = p;
	writePoses(updated);
	++res_.onlineOptimizations;
	res_.onlineOptimization_ms += r.time_ms;
	res_.onlineOptimizationNodes += g.nodes.size();
}

void Backend::returnFreedMemory()
{
	// Freed heap pages go back to the system every few keyframes. Scans, images and loaded
	// candidates are blocks of 0.5-2 MB; glibc serves them from the heap once the first one
	// is freed, and the holes they leave are kept resident: without this, memory climbs by
	// some 20 MB between trims on a long run. A trim costs about a millisecond.
	// jemalloc (heapAllocator) returns its pages by itself; glibc's trim would find nothing.
	if (!trimHeap_)
		return;
	if (++kfSinceTrim_ >= 5)
	{
		kfSinceTrim_ = 0;
#ifdef __GLIBC__
		const auto t0 = Clock::now();
		::malloc_trim(0);
		trimMs_ += msSince(t0);
#endif
	}
}

void Backend::process(KeyframeJob& job)
{
	StageTimes t;
	std::unique_lock<std::mutex> mapLock(mapMutex_);
	std::vector<uint8_t> placeQuery;
	std::vector<std::vector<uint8_t>> placeQueryTurns;
	PlaceContext placeQueryContext;
	std::vector<LoopDecision> handOver;
	if (mapManager_)
	{
		const auto t0 = Clock::now();
		auto up = mapManager_->addKeyframe(job.kf, *job.scan, job.raster.get(), poses_);
		applyMapping(up);
		placeQuery = std::move(up.placeQuery);
		placeQueryTurns = std::move(up.placeQueryTurns);
		placeQueryContext = std::move(up.placeQueryContext);
		// Local BA may have moved this keyframe: the loop query starts from where it is now.
		job.kf.pose = poses_.at(job.kf.node);
		t.mapping = msSince(t0);
	}
	if (loopDetector_)
	{
		const auto t0 = Clock::now();
		std::vector<std::pair<uint64_t, uint64_t>> accepted;
		job.kf.scan = job.scan.get();
		job.kf.raster = job.raster.get();
		job.kf.placeQuery = &placeQuery;
		job.kf.placeQueryTurns = &placeQueryTurns;
		job.kf.placeQueryContext = &placeQueryContext;
		job.kf.inMapFrame = anchored_;
		auto loops = loopDetector_->detect(job.kf, mapManager_->map(), poses_);
		job.kf.scan = nullptr;
		job.kf.raster = nullptr;
		job.kf.placeQuery = nullptr;
		job.kf.placeQueryTurns = nullptr;
		job.kf.placeQueryContext = nullptr;
		if (anchored_ && !caughtUp_)
		{
			// Anchored since the last keyframe: the keyframes made before are in the map's
			// frame now too, and are searched for the earlier sessions once.
			caughtUp_ = true;
			const Map& map = mapManager_->map();
			std::vector<std::pair<mrpt::graphs::TNodeID, mrpt::poses::CPose3D>> before;
			{
				std::lock_guard<std::mutex> lk(graphMutex_);
				for (const auto& [id, pose] : res_.graph.nodes)
					if (!fixed_.count(id) && id != job.kf.node)
						before.emplace_back(id, pose);
			}
			for (const auto& [id, pose] : before)
			{
				const auto it = map.keyframes.find(id);
				if (it == map.keyframes.end())
					continue;
				KeyframeInfo info;
				info.node = id;
				info.scanIndex = it->second->scanIndex;
				info.stamp = it->second->stamp;
				info.pose = pose;
				info.data = it->second;
				info.inMapFrame = true;
				for (auto& lc : loopDetector_->searchEarlierSessions(info, map, poses_))
					loops.push_back(lc);
			}
		}
		for (auto lc : loops)
		{
			std::lock_guard<std::mutex> lk(graphMutex_);
			const bool toPrior = fixed_.count(lc.from) || !res_.graph.nodes.count(lc.from);
			if (toPrior)
				++res_.loopsToPriorMap;
			if (!res_.graph.nodes.count(lc.from))
			{
				// A keyframe of an earlier session (--map-in). Once this session is anchored in
				// that map the loop joins them: the keyframe enters the graph, fixed.
				if (!anchored_ || !poses_.prior || !poses_.prior->count(lc.from))
					continue;
				addFixedNode(lc.from, poses_.prior->at(lc.from));
			}
			if (!res_.graph.nodes.count(lc.to))
				continue;
			if (toPrior)
				++res_.priorMapLoopEdges;
			if (s_.testCorruptLoops > 0 &&
			    std::uniform_real_distribution<double>(0, 1)(corruptRng_) < s_.testCorruptLoops)
			{
				// Test hook: a wrong loop, as a perceptual alias would give (5 m, 20 deg).
				lc.T_from_to = lc.T_from_to + mrpt::poses::CPose3D(5, -2, 0, 20 * M_PI / 180, 0, 0);
				++res_.corruptedLoops;
			}
			mrpt::graphs::CNetworkOfPoses3DInf::edge_t e;
			e.mean = lc.T_from_to;
			e.cov_inv = lc.information;
			res_.graph.insertEdge(lc.from, lc.to, e);
			res_.uncertainEdges.insert({lc.from, lc.to});
			accepted.emplace_back(lc.from, lc.to);
			++res_.loopEdges;
			optimizationPending_ = true;
		}
		// Outside the graph lock: this may write a local map to the offline store, and the
		// tracking takes that lock every scan.
		for (const auto& [from, to] : accepted)
			mapManager_->loopAccepted(from, to, job.kf.stamp);
		// Paper, "Loop Closure": the trajectory is optimized after a loop constraint is added
		// (at most every optimize_every_keyframes keyframes).
		++kfSinceOptimization_;
		if (optimizer_ && s_.optimizeOnline && optimizationPending_ &&
		    kfSinceOptimization_ >= static_cast<std::size_t>(s_.optimizeEveryKeyframes))
		{
			// Cleared first: a request the tracking makes meanwhile stays for the next time.
			optimizationPending_ = false;
			kfSinceOptimization_ = 0;
			optimizeNow();
		}
		// Taken last: if anything above throws, they stay with the loop detector and the
		// engine hands them over at the end of the run, counted once.
		if (s_.onLoopDecisions)
		{
			handOver = loopDetector_->takeDecisions();
			res_.loopDecisionsMade += handOver.size();
			for (const auto& d : handOver)
				res_.loopsByContext += d.accepted && d.byContext;
		}
		t.loop = msSince(t0);
	}
	// Handed over once the map is free: the receiver writes to a file, and the tracking
	// thread waits for this lock to relocalize.
	mapLock.unlock();
	if (!handOver.empty())
	{
		const auto t0 = Clock::now();
		s_.onLoopDecisions(std::move(handOver));
		t.loop += msSince(t0);
	}
	times_.emplace_back(job.record, t);
}

}  // namespace rasterslam::detail
