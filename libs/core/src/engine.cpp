#include <rasterslam/core/engine.h>
#include <rasterslam/core/plugin_loader.h>
#include <rasterslam/core/sweep.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <random>
#include <thread>

#include "backend.h"
#include "information.h"

namespace rasterslam
{
using mrpt::containers::yaml;
using Clock = std::chrono::steady_clock;

namespace
{
double msSince(Clock::time_point t0)
{
	return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
/** The edge a relocalization gives, from the matched keyframe to the scan: the relative pose
 *  counts (the map's keyframe pose may predate an optimization). */
/** Wall-clock time now, ISO 8601 UTC (e.g. 2026-11-29T11:02:03Z). */
std::string isoTimeNow()
{
	const std::time_t t = std::time(nullptr);
	std::tm tm{};
	gmtime_r(&t, &tm);
	char buf[32];
	std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
	return buf;
}

LoopConstraint relocalizationConstraint(const RelocalizationResult& rl)
{
	LoopConstraint c;
	c.from = rl.keyframe;
	c.T_from_to = rl.pose - rl.keyframePose;
	c.information = diagonalInformation(0.1, 0.5);
	return c;
}
const std::vector<std::string> kSections = {
    "plugins", "rasterizer", "odometry", "map_manager", "loop_detector", "optimizer", "engine"};
}  // namespace

std::string rasterslamVersion()
{
	return RASTERSLAM_VERSION;
}

namespace
{
/** A "Vm...:" line of /proc/self/status (kB), in MB; -1 when absent. */
double procStatusMb(const std::string& key)
{
	std::ifstream f("/proc/self/status");
	std::string line;
	while (std::getline(f, line))
		if (line.rfind(key, 0) == 0)
			return std::stod(line.substr(key.size())) / 1024.0;
	return -1;
}
}  // namespace

double currentRssMb()
{
	return procStatusMb("VmRSS:");
}
double peakRssMb()
{
	return procStatusMb("VmHWM:");
}

Plugin::Ptr Engine::makeRole(const yaml& cfg, const std::string& section,
                             const mrpt::rtti::TRuntimeClassId* role, bool required)
{
	if (!cfg.has(section) || cfg[section].isNullNode())
	{
		if (required)
			throw ConfigError(source_ + ": section '" + section + "' is required (class: ...)");
		return {};
	}
	const yaml& s = cfg[section];
	if (!s.isMap())
		throw ConfigError(source_ + ": section '" + section + "' must be a map {class, params}");
	for (const auto& kv : s.asMap())
	{
		const auto k = kv.first.as<std::string>();
		if (k != "class" && k != "params")
			throw ConfigError(configLocation(source_, section + "." + k) + ": unknown key '" +
			                  section + "." + k + "' (expected class, params)");
	}
	if (!s.has("class") || !s["class"].isScalar())
		throw ConfigError(source_ + ": key '" + section + ".class' is required (a class name)");
	const auto className = s["class"].as<std::string>();
	Plugin::Ptr p;
	try
	{
		p = PluginLoader::instance().create(className, role);
	}
	catch (const std::exception& e)
	{
		throw ConfigError(configLocation(source_, section + ".class") + ": key '" + section +
		                  ".class': " + e.what());
	}
	p->setMinLoggingLevel(getMinLoggingLevel());
	p->setLoggerName(section);
	p->initialize(s.has("params") ? s["params"] : yaml(), source_);
	yaml out = yaml::Map();
	out["class"] = className;
	out["params"] = p->paramsInForce();
	inForce_[section] = out;
	return p;
}

Engine::Engine(const yaml& cfg, const std::string& configSource)
    : mrpt::system::COutputLogger("engine"), source_(configSource)
{
	if (!cfg.isMap())
		throw ConfigError(source_ + ": expected a map of sections");
	for (const auto& kv : cfg.asMap())
	{
		const auto k = kv.first.as<std::string>();
		if (std::find(kSections.begin(), kSections.end(), k) == kSections.end())
		{
			std::string list;
			for (const auto& s : kSections)
				list += (list.empty() ? "" : ", ") + s;
			throw ConfigError(configLocation(source_, k) + ": unknown section '" + k +
			                  "' (known: " + list + ")");
		}
	}
	std::vector<std::string> modules;
	if (cfg.has("plugins") && !cfg["plugins"].isNullNode())
	{
		if (!cfg["plugins"].isSequence())
			throw ConfigError(source_ + ": 'plugins' must be a list of module file names");
		for (const auto& m : cfg["plugins"].asSequence())
			modules.push_back(m.as<std::string>());
		yaml seq = yaml::Sequence();
		for (const auto& m : modules)
			seq.push_back(m);
		inForce_["plugins"] = seq;
	}
	PluginLoader::instance().load(modules);

	{
		ParamReader p(cfg.has("engine") ? cfg["engine"] : yaml(), "engine", source_);
		skipBadScans_ = p.getChoice("on_bad_scan", "error", {"error", "skip"}) == "skip";
		minPoints_ = p.getInt("min_points", 100);
		optimizeAtEnd_ = p.getBool("optimize_at_end", true);
		useRawlogOdometry_ = p.getBool("use_rawlog_odometry", false);
		relocalizeOnLoss_ = p.getBool("relocalize_on_loss", true);
		dropNonFinite_ = p.getBool("drop_nonfinite_points", false);
		rawlogOdoSigma_m_ = p.getDouble("rawlog_odometry_sigma_m", rawlogOdoSigma_m_);
		rawlogOdoSigma_deg_ = p.getDouble("rawlog_odometry_sigma_deg", rawlogOdoSigma_deg_);
		optimizeOnline_ = p.getBool("optimize_online", optimizeOnline_);
		optimizeEveryKeyframes_ = p.getInt("optimize_every_keyframes", optimizeEveryKeyframes_);
		optimizeOnlineWindow_ =
		    p.getChoice("optimize_online_window", optimizeOnlineWindow_ ? "online_maps" : "all",
		                {"online_maps", "all"}) == "online_maps";
		testCorruptLoops_ = p.getDouble("test_corrupt_loops", testCorruptLoops_);
		anchorMinAgreeing_ = p.getInt("anchor_min_agreeing", anchorMinAgreeing_);
		anchorAgree_m_ = p.getDouble("anchor_agree_m", anchorAgree_m_);
		anchorAgree_deg_ = p.getDouble("anchor_agree_deg", anchorAgree_deg_);
		anchorEveryScan_ = p.getBool("anchor_every_scan", anchorEveryScan_);
		anchorHitSpacing_s_ = p.getDouble("anchor_hit_spacing_s", anchorHitSpacing_s_);
		stampOrderError_ = p.getChoice("stamp_order", "warn", {"warn", "error"}) == "error";
		realtimeMaxWait_s_ = p.getDouble("realtime_max_wait_s", realtimeMaxWait_s_);
		{
			const auto mode = p.getChoice(
			    "deskew", deskew_ ? (deskewPlanar_ ? "planar" : "constant_velocity") : "none",
			    {"none", "constant_velocity", "planar"});
			deskew_ = mode != "none";
			deskewPlanar_ = mode == "planar";
		}
		sweep_.startAzimuth_deg = p.getDouble("sweep_start_azimuth_deg", sweep_.startAzimuth_deg);
		sweep_.clockwise =
		    p.getChoice("sweep_direction", sweep_.clockwise ? "cw" : "ccw", {"cw", "ccw"}) == "cw";
		sweepPeriod_s_ = p.getDouble("sweep_period_s", sweepPeriod_s_);
		verticalCorrection_deg_ = p.getDouble("vertical_correction_deg", verticalCorrection_deg_);
		p.finish();
		p.requireRange(verticalCorrection_deg_, -5, 5, "vertical_correction_deg");
		p.requireAtLeast(minPoints_, 1, "min_points");
		p.requirePositive(rawlogOdoSigma_m_, "rawlog_odometry_sigma_m");
		p.requirePositive(rawlogOdoSigma_deg_, "rawlog_odometry_sigma_deg");
		p.requireAtLeast(optimizeEveryKeyframes_, 1, "optimize_every_keyframes");
		p.requireRange(testCorruptLoops_, 0, 1, "test_corrupt_loops");
		p.requireAtLeast(anchorMinAgreeing_, 1, "anchor_min_agreeing");
		p.requirePositive(anchorAgree_m_, "anchor_agree_m");
		p.requirePositive(anchorAgree_deg_, "anchor_agree_deg");
		p.requireAtLeast(anchorHitSpacing_s_, 0, "anchor_hit_spacing_s");
		p.requirePositive(realtimeMaxWait_s_, "realtime_max_wait_s");
		p.requireRange(sweep_.startAzimuth_deg, -360, 360, "sweep_start_azimuth_deg");
		p.requireRange(sweepPeriod_s_, 0, 10, "sweep_period_s");
		inForce_["engine"] = p.inForce();
	}
	rasterizer_ = std::dynamic_pointer_cast<Rasterizer>(
	    makeRole(cfg, "rasterizer", CLASS_ID(Rasterizer), false));
	odometry_ =
	    std::dynamic_pointer_cast<Odometry>(makeRole(cfg, "odometry", CLASS_ID(Odometry), true));
	mapManager_ = std::dynamic_pointer_cast<MapManager>(
	    makeRole(cfg, "map_manager", CLASS_ID(MapManager), false));
	loopDetector_ = std::dynamic_pointer_cast<LoopDetector>(
	    makeRole(cfg, "loop_detector", CLASS_ID(LoopDetector), false));
	optimizer_ = std::dynamic_pointer_cast<Optimizer>(
	    makeRole(cfg, "optimizer", CLASS_ID(Optimizer), false));
	if (loopDetector_ && !mapManager_)
		throw ConfigError(source_ +
		                  ": section 'loop_detector' needs a 'map_manager' (it queries the map the "
		                  "manager keeps), e.g. "
		                  "map_manager: {class: rasterslam::LocalMapManager}");
}

void Engine::loadMap(const std::string& dir)
{
	if (!mapManager_)
		throw std::runtime_error("loading a map needs a map_manager in the config");
	mapManager_->loadMap(dir);
	if (loopDetector_)
	{
		try
		{
			loopDetector_->loadPlaceIndex(mapManager_->map());
		}
		catch (const std::exception& e)
		{
			throw std::runtime_error("cannot read map '" + mapFilePath(dir) + "': " + e.what());
		}
	}
}

void Engine::saveMap(const std::string& dir, const mrpt::graphs::CNetworkOfPoses3DInf& graph)
{
	if (!mapManager_)
		throw std::runtime_error("saving a map needs a map_manager in the config");
	PoseView poses;
	poses.live = [&graph](uint64_t id) -> const mrpt::poses::CPose3D*
	{
		const auto it = graph.nodes.find(id);
		return it == graph.nodes.end() ? nullptr : &it->second;
	};
	poses.prior = &mapManager_->map().priorPoses;
	std::vector<uint8_t> index;
	std::string cls;
	if (loopDetector_)
	{
		index = loopDetector_->savePlaceIndex();
		cls = loopDetector_->GetRuntimeClass()->className;
	}
	mapManager_->saveMap(dir, poses, cls, index);
}

void Engine::setLogLevel(mrpt::system::VerbosityLevel level)
{
	setMinLoggingLevel(level);
	for (Plugin* p :
	     std::initializer_list<Plugin*>{rasterizer_.get(), odometry_.get(), mapManager_.get(),
	                                    loopDetector_.get(), optimizer_.get()})
		if (p)
			p->setMinLoggingLevel(level);
}

mrpt::graphs::CNetworkOfPoses3DInf::edge_t Engine::rawlogOdometryEdge(
    const mrpt::poses::CPose3DPDFGaussian& odo) const
{
	mrpt::graphs::CNetworkOfPoses3DInf::edge_t e;
	e.mean = odo.mean;
	const auto& C = odo.cov;
	if (C.asEigen().isZero(0) || std::abs(C.det()) < 1e-18)
	{
		// No usable covariance in the input: the configured model.
		e.cov_inv.setZero();
		const double st = rawlogOdoSigma_m_, sr = rawlogOdoSigma_deg_ * M_PI / 180;
		for (int i = 0; i < 3; i++)
			e.cov_inv(i, i) = 1 / (st * st);
		for (int i = 3; i < 6; i++)
			e.cov_inv(i, i) = 1 / (sr * sr);
	}
	else
		e.cov_inv = C.inverse_LLt();
	return e;
}

bool Engine::anchorsAgree(const mrpt::poses::CPose3D& d) const
{
	const double angleDeg = Eigen::AngleAxisd(d.getRotationMatrix().asEigen()).angle() * 180 / M_PI;
	return d.norm() < anchorAgree_m_ && angleDeg < anchorAgree_deg_;
}

/** One run's state: the tracking's poses and keyframe, the back end, the session's anchoring
 *  in a prior map, and the result being filled. */
struct Engine::RunState
{
	RunState(Engine& e, ScanSource& src, const RunOptions& o, const detail::BackendSettings& bs)
	    : source(src),
	      opts(o),
	      backend(e.mapManager_.get(), e.loopDetector_.get(), e.optimizer_.get(), bs, res, e,
	              !o.realtime),
	      poses(backend.poses()),
	      anchored(!o.relocalizeFirstScan)
	{
	}
	ScanSource& source;
	const RunOptions& opts;
	RunResult res;
	// Mapping and loop closing: on their own thread; in batch mode in step with the tracking.
	detail::Backend backend;
	const PoseView& poses;
	const double cpu0 = detail::threadCpuSeconds();
	const Clock::time_point wall0 = Clock::now();

	// Input
	std::size_t currentIndex = 0;
	double readMs = 0;  //!< reading the current scan
	std::optional<double> firstStamp;
	std::optional<double> lastStamp;          //!< of the last admitted scan
	std::optional<double> lastPacedStamp;     //!< of the last scan paced (--realtime)
	std::optional<Clock::time_point> clock0;  //!< --realtime: when the first scan was due
	// The input's own odometry composed since the last keyframe (paper: visual odometry
	// factors fused into the graph; here any odometry the rawlog carries).
	std::optional<mrpt::poses::CPose3DPDFGaussian> odoSinceKf;

	// Tracking
	mrpt::graphs::TNodeID nextNode = 0;
	RasterFrame raster;
	mrpt::poses::CPose3D currPose;  //!< odometry pose of the current scan
	mrpt::poses::CPose3D lastKfPose;
	mrpt::poses::CPose3D T_kf_prev;  //!< the previous scan in the frame of its keyframe
	mrpt::graphs::TNodeID lastKf = 0;
	bool haveKf = false;
	std::size_t stepsSinceKf = 0;
	bool lostSinceKf = false;
	// De-skewing: the last tracked step and the time it took (constant-velocity model).
	std::optional<mrpt::poses::CPose3D> lastStep;
	double lastStepDt = 0;
	std::optional<double> lastTrackedStamp;
	std::optional<double> prevReadStamp, readStamp;  //!< of the scans read before and now

	// A session in a prior map (--map-in): candidate session-to-map transforms until enough
	// agree, then the hit that anchors the session at the next keyframe.
	struct AnchorHit
	{
		RelocalizationResult rl;
		mrpt::poses::CPose3D poseAtHit;  //!< the hit scan's pose in the session's frame
	};
	bool anchored;  //!< false until located in a --map-in map
	std::vector<mrpt::poses::CPose3D> anchorHits;
	std::optional<double> lastAnchorHitStamp;
	std::optional<AnchorHit> anchorReady;  //!< agreed, waiting for a keyframe
};

// The run reads in the order the data flows: read and check a scan, pace it, rasterize it,
// track it, locate it in a prior map or after a loss, make it a keyframe (handed to the back
// end for mapping, loop closing and online optimization), record it; at the end, finish the
// back end and optimize the whole graph.
RunResult Engine::run(ScanSource& source, const RunOptions& opts)
{
	detail::BackendSettings bs;
	bs.optimizeOnline = optimizeOnline_;
	bs.optimizeEveryKeyframes = optimizeEveryKeyframes_;
	bs.optimizeOnlineWindow = optimizeOnlineWindow_;
	bs.testCorruptLoops = testCorruptLoops_;
	bs.onLoopDecisions = opts.onLoopDecisions;
	RunState s(*this, source, opts, bs);
	if (opts.spoolScans)
	{
		try
		{
			s.res.scans = ScanLog::spooled(opts.scanSpoolDir);
		}
		catch (const std::exception& e)
		{
			MRPT_LOG_WARN_STREAM(e.what() << "; the scan records are kept in memory");
		}
	}
	s.res.graph.clear();
	// Keyframe ids continue those of a loaded map: unique across its sessions.
	s.nextNode = mapManager_ ? mapManager_->map().nextKeyframeId() : 0;
	s.res.graph.root = s.nextNode;
	try
	{
		for (;;)
		{
			if (s.opts.stop && (s.res.stoppedBy = s.opts.stop->load()) != 0)
				break;
			std::optional<Scan> scan = readScan(s);
			if (!scan)
				break;
			addInputOdometry(s, *scan);
			if (!admitScan(s, *scan))
			{
				if (!s.res.error.empty())
					break;
				continue;
			}
			ScanRecord rec = beginScan(s, *scan);
			if (!pace(s, *scan, rec))
				continue;
			const auto tScan = Clock::now();
			if (verticalCorrection_deg_ != 0)
				correctElevation(scan->points, verticalCorrection_deg_);
			deskew(s, *scan, rec);
			const RasterFrame* raster = rasterize(s, *scan, rec);
			const OdometryResult odo = track(s, *scan, raster, rec);
			const bool atKeyframe = !s.haveKf || odo.keyframe;
			std::optional<LoopConstraint> relocEdge;
			// Once enough hits agree the search is over: the anchoring only waits for a
			// keyframe (a graph node), and a later hit must not move or recount it.
			if (loopDetector_ && raster && !s.anchored && !s.anchorReady &&
			    (atKeyframe || anchorEveryScan_))
				seekAnchor(s, *scan, *raster, rec);
			if (s.anchorReady && !s.anchored && atKeyframe)
			{
				relocEdge = anchor(s);
				s.res.localizedAtScan = scan->index;
			}
			if (!relocEdge && s.anchored && loopDetector_ && raster && s.haveKf &&
			    odo.status == TrackingStatus::Lost && relocalizeOnLoss_)
				relocEdge = relocalizeAfterLoss(s, *scan, *raster, rec);
			if (atKeyframe)
				addKeyframe(s, *scan, raster, odo, relocEdge, rec);
			recordScan(s, rec, tScan);
		}
	}
	catch (const std::exception& e)
	{
		// A plugin or the input failed on one scan: what came before is kept and written.
		std::string what = e.what();
		if (const auto pos = what.find("Call stack"); pos != std::string::npos)
			what.resize(pos);
		s.res.error = source.name() + ": scan #" + std::to_string(s.currentIndex) + ": " + what;
	}
	finishRun(s);
	return std::move(s.res);
}

std::optional<Scan> Engine::readScan(RunState& s)
{
	for (;;)
	{
		const auto tRead = Clock::now();
		std::optional<Scan> scan = s.source.next();
		s.readMs = msSince(tRead);
		if (!scan)
			return std::nullopt;
		if (s.opts.first && scan->index < *s.opts.first)
			continue;
		if (s.opts.last && scan->index > *s.opts.last)
			return std::nullopt;
		s.currentIndex = scan->index;
		s.prevReadStamp = s.readStamp;
		s.readStamp = scan->stamp;
		return scan;
	}
}

void Engine::addInputOdometry(RunState& s, const Scan& scan)
{
	// The input's odometry of every scan counts, also of a scan dropped below.
	if (useRawlogOdometry_ && s.haveKf && scan.odometryIncrement)
	{
		if (!s.odoSinceKf)
			s.odoSinceKf = *scan.odometryIncrement;
		else
			*s.odoSinceKf += *scan.odometryIncrement;
	}
}

bool Engine::admitScan(RunState& s, Scan& scan)
{
	// Bad scans: non-finite coordinates or too few points.
	std::size_t nonFinite = 0;
	for (const auto& p : scan.points)
		if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
			++nonFinite;
	if (nonFinite > 0 && dropNonFinite_)
	{
		// Organized clouds mark "no return" with NaN: drop those points only.
		auto& v = scan.points;
		v.erase(std::remove_if(v.begin(), v.end(),
		                       [](const PointXYZI& p) {
			                       return !std::isfinite(p.x) || !std::isfinite(p.y) ||
			                              !std::isfinite(p.z);
		                       }),
		        v.end());
	}
	if ((nonFinite == 0 || dropNonFinite_) &&
	    scan.points.size() >= static_cast<std::size_t>(minPoints_))
		return stampInOrder(s, scan);
	const std::string what =
	    nonFinite > 0 && !dropNonFinite_
	        ? mrpt::format(
	              "%s: scan #%zu (t=%.6f) has %zu non-finite points (NaN or inf) among "
	              "%zu; set engine.drop_nonfinite_points: true to drop such points",
	              s.source.name().c_str(), scan.index, scan.stamp, nonFinite, scan.points.size())
	        : mrpt::format(
	              "%s: scan #%zu (t=%.6f) has %zu points; expected at least %d "
	              "(engine.min_points)",
	              s.source.name().c_str(), scan.index, scan.stamp, scan.points.size(), minPoints_);
	if (!skipBadScans_)
	{
		s.res.error = what + "; set engine.on_bad_scan: skip to drop such scans";
		return false;
	}
	MRPT_LOG_WARN_STREAM(what << "; skipped");
	++s.res.skippedBadScans;
	return false;
}

ScanRecord Engine::beginScan(RunState& s, const Scan& scan)
{
	if (!s.firstStamp)
	{
		s.firstStamp = scan.stamp;
		if (mapManager_)
		{
			SessionRecord session;
			session.firstStamp = scan.stamp;
			session.sensor = scan.sensorLabel;
			session.input = s.source.name();
			session.startedAt = isoTimeNow();
			std::lock_guard<std::mutex> lk(s.backend.mapMutex());
			mapManager_->describeSession(session);
		}
	}
	ScanRecord rec;
	rec.index = scan.index;
	rec.stamp = scan.stamp;
	rec.numPoints = scan.points.size();
	if (scan.groundTruth)
		rec.groundTruth = scan.groundTruth->asTPose();
	rec.ms.read = s.readMs;
	return rec;
}

bool Engine::stampInOrder(RunState& s, const Scan& scan)
{
	const std::optional<double> previous = s.lastStamp;
	s.lastStamp = scan.stamp;
	if (!previous || scan.stamp > *previous)
		return true;
	++s.res.stampsOutOfOrder;
	const std::string what =
	    mrpt::format("%s: scan #%zu (t=%.6f): its time stamp %s the previous scan's (t=%.6f)",
	                 s.source.name().c_str(), scan.index, scan.stamp,
	                 scan.stamp < *previous ? "goes back from" : "stands still at", *previous);
	if (stampOrderError_)
	{
		s.res.error = what + " (engine.stamp_order: error)";
		return false;
	}
	MRPT_LOG_THROTTLE_WARN_STREAM(5.0, what << "; " << s.res.stampsOutOfOrder
	                                        << " such scans so far (engine.stamp_order: error "
	                                           "stops the run at the first)");
	return true;
}

bool Engine::pace(RunState& s, const Scan& scan, ScanRecord& rec)
{
	if (!s.opts.realtime)
		return true;
	// The clock starts at the first scan: the time spent loading before it does not count.
	const auto now = Clock::now();
	if (!s.clock0)
		s.clock0 = now;
	const double rate = std::max(s.opts.rate, 1e-6);
	const double due_s = (scan.stamp - *s.firstStamp) / rate;
	const auto due = *s.clock0 + std::chrono::duration_cast<Clock::duration>(
	                                 std::chrono::duration<double>(due_s));
	const std::optional<double> previous = s.lastPacedStamp;
	s.lastPacedStamp = scan.stamp;
	if (now < due)
	{
		const double wait_s = std::chrono::duration<double>(due - now).count();
		if (wait_s > realtimeMaxWait_s_)
			MRPT_LOG_WARN_FMT(
			    "scan #%zu (t=%.6f): waiting %.1f s for its time stamp: a gap in the "
			    "input (engine.realtime_max_wait_s = %.1f)",
			    scan.index, scan.stamp, wait_s, realtimeMaxWait_s_);
		// In steps, so that a stop request (Ctrl-C) is not held up by a long gap in the stamps.
		while (Clock::now() < due && !(s.opts.stop && s.opts.stop->load() != 0))
			std::this_thread::sleep_until(
			    std::min(due, Clock::now() + std::chrono::milliseconds(100)));
		return true;
	}
	const double late_s = std::chrono::duration<double>(now - due).count();
	if (late_s <= 1e-3)
		return true;
	// A scan already a whole period late (the step from the previous stamp) is dropped with
	// --drop-late: the run then keeps up with the input instead of falling behind for good.
	const double period_s =
	    previous && scan.stamp > *previous ? (scan.stamp - *previous) / rate : 0;
	if (s.opts.dropLate && period_s > 0 && late_s > period_s)
	{
		++s.res.droppedLate;
		return false;
	}
	rec.late = true;
	++s.res.late;
	return true;
}

void Engine::deskew(RunState& s, Scan& scan, ScanRecord& rec)
{
	if (!deskew_ || !s.lastStep || !(s.lastStepDt > 0) || !s.lastTrackedStamp)
		return;
	// The sweep lasts the configured period, or the time since the last scan (a spinning
	// sensor's sweeps follow each other). Over it the sensor moves as over the last step.
	// Measured on simulated sweeps (38 deg/s turns): the last step alone beats a motion
	// averaged over 0.5 s (RTE 0.9-1.7 % against 1.0-1.8 %; none: 2.0-3.8 %), which lags in
	// turns.
	const auto t0 = Clock::now();
	// Since the sweep before this one, tracked or not (a scan dropped late or skipped as bad
	// was a sweep too); the step's own length is lastStepDt.
	const double sinceLast = s.prevReadStamp ? scan.stamp - *s.prevReadStamp : 0;
	const double period = sweepPeriod_s_ > 0 ? sweepPeriod_s_ : sinceLast;
	// A gap (dropped scans, a pause): the last step says nothing about this sweep.
	if (!(period > 0) || sinceLast > 3 * s.lastStepDt || period > 3 * s.lastStepDt)
		return;
	const Eigen::Isometry3d M = scaleMotion(
	    Eigen::Isometry3d(
	        s.lastStep->getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen()),
	    period / s.lastStepDt);
	Eigen::Isometry3d motion = M;
	if (deskewPlanar_)
	{
		const double yaw = std::atan2(M.linear()(1, 0), M.linear()(0, 0));
		motion.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
	}
	deskewSweep(scan.points, motion, sweep_);
	rec.ms.rasterize += msSince(t0);
}

const RasterFrame* Engine::rasterize(RunState& s, const Scan& scan, ScanRecord& rec)
{
	if (!rasterizer_)
		return nullptr;
	const auto t0 = Clock::now();
	rasterizer_->rasterize(scan, s.raster);
	rec.ms.rasterize += msSince(t0);
	if (s.opts.onRaster)
		s.opts.onRaster(scan, s.raster);
	return &s.raster;
}

OdometryResult Engine::track(RunState& s, const Scan& scan, const RasterFrame* raster,
                             ScanRecord& rec)
{
	const auto tOdo = Clock::now();
	OdometryResult odo = odometry_->process(scan, raster);
	rec.ms.odometry = msSince(tOdo);
	rec.status = odo.status;
	rec.inliers = odo.inliers;
	if (odo.status == TrackingStatus::Lost)
	{
		++s.res.lost;
		if (!(loopDetector_ && raster && relocalizeOnLoss_ && s.anchored))
			s.lostSinceKf = true;
		MRPT_LOG_THROTTLE_WARN_STREAM(1.0, "scan " << scan.index << ": tracking lost ("
		                                           << odo.message << "); using the motion prior");
	}
	if (s.haveKf)
	{
		// The back end may have moved the keyframe (local BA, a loop): track from there.
		std::lock_guard<std::mutex> lk(s.backend.graphMutex());
		s.lastKfPose = s.res.graph.nodes.at(s.lastKf);
	}
	if (!s.haveKf)
		s.currPose = mrpt::poses::CPose3D();
	else if (odo.T_kf_curr)
		s.currPose = s.lastKfPose + *odo.T_kf_curr;
	else
		s.currPose = s.lastKfPose + (s.T_kf_prev + odo.T_prev_curr);
	++s.stepsSinceKf;
	if (odo.status == TrackingStatus::Ok && s.lastTrackedStamp && scan.stamp > *s.lastTrackedStamp)
	{
		s.lastStep = odo.T_prev_curr;
		s.lastStepDt = scan.stamp - *s.lastTrackedStamp;
	}
	else
		s.lastStep.reset();  // lost or starting: no motion to de-skew the next sweep with
	s.lastTrackedStamp = scan.stamp;
	return odo;
}

// Relocalization (paper, "Re-localization"): at the start of a session with a prior map
// (seekAnchor, anchor), and whenever tracking is lost (relocalizeAfterLoss), the scan queries
// the loop detector's database with no pose prior. Found: the pose comes from the map (and, if
// the matched keyframe is in this run's graph, a constraint to it). Not found: tracking goes
// on from the motion prior, linked to the past only by a weak edge: a new, disconnected part
// that a later loop closure can join.
void Engine::seekAnchor(RunState& s, const Scan& scan, const RasterFrame& raster, ScanRecord& rec)
{
	// A session in a prior map: try every scan (or keyframe) until it is found there, then
	// move everything tracked so far into the map's frame.
	const auto t0 = Clock::now();
	// Held until the session is moved into the map's frame: the back end must not see half of
	// it (it holds this lock for a whole keyframe's work).
	std::lock_guard<std::mutex> mapLock(s.backend.mapMutex());
	const Map& map = mapManager_->map();
	const RelocalizationResult rl =
	    loopDetector_->relocalizeScan(scan, raster, scanContext(scan, raster), map, s.poses);
	// Only an earlier session's local map can anchor this one (its own are in its own frame).
	const bool earlier = rl.found && map.localMaps.at(rl.localMap)->session + 1 < map.sessions;
	rec.ms.loop += msSince(t0);
	// Hits count when they are apart in time: neighbouring scans see the same place and would
	// agree whether it is the right one or not.
	if (earlier &&
	    (!s.lastAnchorHitStamp || scan.stamp >= *s.lastAnchorHitStamp + anchorHitSpacing_s_))
	{
		// Where this hit puts the session's frame in the map's. One hit is not enough: a wrong
		// place can match as well as the right one, so the session is anchored only when
		// engine.anchor_min_agreeing hits agree on it.
		const mrpt::poses::CPose3D C = rl.pose + (mrpt::poses::CPose3D() - s.currPose);
		s.anchorHits.push_back(C);
		s.lastAnchorHitStamp = scan.stamp;
		std::size_t agreeing = 0;
		for (const auto& h : s.anchorHits)
		{
			// Compared where the vehicle is now: a heading difference then counts as the
			// offset it makes here, not at the session's origin.
			agreeing += anchorsAgree((h + s.currPose) - rl.pose);
		}
		s.res.anchorHits = s.anchorHits.size();
		if (agreeing >= static_cast<std::size_t>(anchorMinAgreeing_))
		{
			// The anchoring is made at a keyframe (a graph node): this one, or the next.
			s.anchorReady = RunState::AnchorHit{rl, s.currPose};
			MRPT_LOG_INFO_STREAM("scan " << scan.index << ": located in the prior map (local map "
			                             << rl.localMap << ", " << rl.inliers << " inliers; "
			                             << agreeing << " of " << s.anchorHits.size()
			                             << " hits agree)");
		}
		else
			MRPT_LOG_INFO_STREAM("scan " << scan.index << ": a place in the prior map (local map "
			                             << rl.localMap << ", " << rl.inliers << " inliers): "
			                             << agreeing << " of " << anchorMinAgreeing_
			                             << " agreeing hits needed to anchor");
	}
	else if (!earlier)
	{
		++s.res.relocalizationFailures;
		MRPT_LOG_THROTTLE_WARN_STREAM(1.0, "scan " << scan.index
		                                           << ": not located in the prior map yet ("
		                                           << rl.reason << ")");
	}
}

std::optional<LoopConstraint> Engine::anchor(RunState& s)
{
	// The hit's pose, carried to this scan by the odometry since.
	const auto& [rl, poseAtHit] = *s.anchorReady;
	const mrpt::poses::CPose3D sinceHit = s.currPose - poseAtHit;
	const mrpt::poses::CPose3D here = rl.pose + sinceHit;
	const mrpt::poses::CPose3D C = here + (mrpt::poses::CPose3D() - s.currPose);
	{
		std::lock_guard<std::mutex> lk(s.backend.graphMutex());
		for (auto& [id, p] : s.res.graph.nodes)
			p = C + p;
	}
	s.lastKfPose = C + s.lastKfPose;
	s.currPose = here;
	s.anchored = true;
	s.res.localized = true;
	s.backend.setAnchored();
	// The hit ties the session to the map in the graph (from this keyframe).
	std::optional<LoopConstraint> edge = relocalizationConstraint(rl);
	edge->T_from_to = here - rl.keyframePose;
	++s.res.relocalized;
	s.anchorReady.reset();
	return edge;
}

PlaceContext Engine::scanContext(const Scan& scan, const RasterFrame& raster) const
{
	return loopDetector_ && mapManager_ && loopDetector_->usesScanContexts()
	           ? mapManager_->placeContextOf(scan, raster)
	           : PlaceContext{};
}

std::optional<LoopConstraint> Engine::relocalizeAfterLoss(RunState& s, const Scan& scan,
                                                          const RasterFrame& raster,
                                                          ScanRecord& rec)
{
	const auto t0 = Clock::now();
	RelocalizationResult rl;
	{
		std::lock_guard<std::mutex> lk(s.backend.mapMutex());
		rl = loopDetector_->relocalizeScan(scan, raster, scanContext(scan, raster),
		                                   mapManager_->map(), s.poses);
	}
	rec.ms.loop += msSince(t0);
	std::optional<mrpt::poses::CPose3D> matched;  // the keyframe, when a node of this graph
	if (const auto* p = s.poses.live(rl.keyframe))
		matched = *p;
	if (!rl.found)
	{
		++s.res.relocalizationFailures;
		s.lostSinceKf = true;
		MRPT_LOG_THROTTLE_WARN_STREAM(1.0, "scan " << scan.index << ": relocalization failed ("
		                                           << rl.reason
		                                           << "): a new, disconnected part of the map "
		                                              "starts here");
		return std::nullopt;
	}
	++s.res.relocalized;
	MRPT_LOG_INFO_STREAM("scan " << scan.index << ": relocalized in local map " << rl.localMap
	                             << " (keyframe " << rl.keyframe << ", " << rl.inliers
	                             << " inliers)");
	if (!matched)
	{
		s.currPose = rl.pose;  // a keyframe of the prior map: already its frame
		return std::nullopt;
	}
	std::optional<LoopConstraint> edge = relocalizationConstraint(rl);
	s.currPose = *matched + edge->T_from_to;
	return edge;
}

void Engine::addKeyframe(RunState& s, const Scan& scan, const RasterFrame* raster,
                         const OdometryResult& odo, std::optional<LoopConstraint> relocEdge,
                         ScanRecord& rec)
{
	auto& graph = s.res.graph;
	const bool haveKfBefore = s.haveKf;
	const mrpt::graphs::TNodeID id = s.nextNode++;
	{
		std::lock_guard<std::mutex> lk(s.backend.graphMutex());
		if (s.haveKf)
		{
			// The back end may have moved the last keyframe since this scan read it (only then
			// recompose: composing a rotation with its own inverse feeds rounding into every
			// later keyframe).
			const mrpt::poses::CPose3D kfNow = graph.nodes.at(s.lastKf);
			if (!(kfNow == s.lastKfPose))
			{
				s.currPose = kfNow + (s.currPose - s.lastKfPose);
				s.lastKfPose = kfNow;
			}
		}
		graph.nodes[id] = s.currPose;
		if (s.haveKf)
		{
			mrpt::graphs::CNetworkOfPoses3DInf::edge_t e;
			e.mean = s.currPose - s.lastKfPose;
			// Information of a chain of n steps is roughly 1/n of one step's; an odometry that
			// tracks against the keyframe gives the edge's own.
			e.cov_inv = odo.information;
			if (!odo.T_kf_curr)
				e.cov_inv *= 1.0 / static_cast<double>(s.stepsSinceKf);
			graph.insertEdge(s.lastKf, id, e);
			if (s.odoSinceKf)
			{
				graph.insertEdge(s.lastKf, id, rawlogOdometryEdge(*s.odoSinceKf));
				++s.res.odometryEdges;
			}
		}
		s.odoSinceKf.reset();
		if (relocEdge && !graph.nodes.count(relocEdge->from))
		{
			// A keyframe of an earlier session: it enters the graph, fixed.
			if (const auto* prior = s.poses.prior; prior && prior->count(relocEdge->from))
				s.backend.addFixedNode(relocEdge->from, prior->at(relocEdge->from));
			else
				relocEdge.reset();
		}
		if (relocEdge)
		{
			mrpt::graphs::CNetworkOfPoses3DInf::edge_t e;
			e.mean = relocEdge->T_from_to;
			e.cov_inv = relocEdge->information;
			graph.insertEdge(relocEdge->from, id, e);
			s.res.uncertainEdges.insert({relocEdge->from, id});
			++s.res.loopEdges;
			s.backend.requestOptimization();
		}
	}
	s.lastKf = id;
	s.lastKfPose = s.currPose;
	s.haveKf = true;
	s.stepsSinceKf = 0;
	rec.keyframe = true;
	++s.res.keyframes;

	detail::KeyframeJob job;
	job.kf = KeyframeInfo{id,         scan.index,       scan.stamp,
	                      s.currPose, odo.keyframeData, s.lostSinceKf && haveKfBefore,
	                      {}};
	if (relocEdge)
		job.kf.locatedAt = relocEdge->from;
	s.lostSinceKf = false;
	if (job.kf.data)
	{
		job.kf.data->id = id;
		job.kf.data->scanIndex = scan.index;
		job.kf.data->stamp = scan.stamp;
		job.kf.data->pose = s.currPose;
	}
	job.record = s.res.scans.size();
	if (s.opts.realtime)
	{
		// The worker keeps its own copies: the tracking goes on with the next scan.
		job.scan = std::make_shared<const Scan>(scan);
		if (raster)
		{
			auto copy = std::make_shared<RasterFrame>(*raster);
			copy->image = raster->image.makeDeepCopy();  // CImage copies share pixels
			job.raster = copy;
		}
	}
	else
	{
		// Done before submit() returns: no copy needed.
		job.scan = std::shared_ptr<const Scan>(&scan, [](const Scan*) {});
		if (raster)
			job.raster = std::shared_ptr<const RasterFrame>(raster, [](const RasterFrame*) {});
	}
	if (mapManager_ || loopDetector_)
		s.backend.submit(std::move(job));
	if (!s.opts.realtime)
	{
		// Local BA or an optimization may have moved this keyframe.
		std::lock_guard<std::mutex> lk(s.backend.graphMutex());
		s.lastKfPose = s.currPose = graph.nodes.at(id);
	}
}

void Engine::recordScan(RunState& s, ScanRecord& rec, Clock::time_point tScan)
{
	rec.kfNode = s.lastKf;
	const mrpt::poses::CPose3D T_kf_scan = s.currPose - s.lastKfPose;
	rec.T_kf_scan = T_kf_scan.asTPose();
	rec.onlinePose = s.currPose.asTPose();
	// Exactly the identity on a keyframe: composing a rotation with its own inverse would feed
	// rounding back into every following scan.
	// Otherwise rebuilt from its angles: the next scan's pose is this one composed with the
	// keyframe's rotation and its transpose, so a rotation matrix that is not quite orthonormal
	// would grow that error by the scans' count at every keyframe (with an odometry that gives
	// only T_prev_curr, 3 scans a keyframe reached NaN after 29 keyframes).
	s.T_kf_prev = rec.keyframe ? mrpt::poses::CPose3D() : mrpt::poses::CPose3D(rec.T_kf_scan);
	rec.ms.total = msSince(tScan) + s.readMs;
	rec.rssMb = static_cast<float>(currentRssMb());
	s.res.scans.push_back(rec);
	if (s.opts.onScan)
		s.opts.onScan(rec, s.source.progress());
}

void Engine::finishRun(RunState& s)
{
	auto& res = s.res;
	res.stopReason = s.source.stopReason();
	try
	{
		s.backend.finish();
	}
	catch (const std::exception& e)
	{
		if (res.error.empty())
			res.error = std::string("finishing the map: ") + e.what();
	}
	if (res.error.empty() && !s.backend.error().empty())
		res.error = "mapping or loop closing: " + s.backend.error();
	bool recordsKept = res.scans.error().empty();
	if (!recordsKept && res.error.empty())
		res.error = res.scans.error();
	try
	{
		if (recordsKept)
			for (const auto& [record, t] : s.backend.timings())
				if (record < res.scans.size())
					res.scans.modify(record,
					                 [&t = t](ScanRecord& r)
					                 {
						                 r.ms.mapping += t.mapping;
						                 r.ms.loop += t.loop;
					                 });
	}
	catch (const std::exception& e)
	{
		recordsKept = false;
		if (res.error.empty())
			res.error = e.what();
	}
	if (loopDetector_)
	{
		// Moved, not copied: at the end of a long run they are the biggest record kept.
		auto d = loopDetector_->takeDecisions();
		res.loopDecisionsMade += d.size();
		for (const auto& x : d)
			res.loopsByContext += x.accepted && x.byContext;
		if (s.opts.onLoopDecisions)
		{
			if (!d.empty())
				s.opts.onLoopDecisions(std::move(d));
		}
		else
			res.loopDecisions = std::move(d);
	}
	res.cpuBackend_s = s.backend.cpuSeconds();
	res.memoryTrim_ms = s.backend.trimMs();
	res.cpuTracking_s = detail::threadCpuSeconds() - s.cpu0;

	auto& graph = res.graph;
	if (optimizer_ && optimizeAtEnd_ && (res.loopEdges > 0 || res.odometryEdges > 0))
	{
		MRPT_LOG_INFO_STREAM("optimizing the pose graph: " << graph.nodes.size() << " nodes, "
		                                                   << graph.edges.size() << " edges");
		res.optimizer = optimizer_->optimize(graph, res.uncertainEdges, s.backend.fixedNodes());
	}
	// Without every record there is no trajectory to give: res.error says why.
	try
	{
		if (recordsKept)
		{
			res.poses.reserve(res.scans.size());
			res.scans.forEach(
			    [&](const ScanRecord& r) {
				    res.poses.push_back(graph.nodes.at(r.kfNode) +
				                        mrpt::poses::CPose3D(r.T_kf_scan));
			    });
		}
	}
	catch (const std::exception& e)
	{
		res.poses.clear();
		if (res.error.empty())
			res.error = e.what();
	}
	res.wall_s = std::chrono::duration<double>(Clock::now() - s.wall0).count();
}

}  // namespace rasterslam
