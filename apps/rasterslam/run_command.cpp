// `rasterslam run`: play a rawlog through the configured pipeline and write the outputs.
#include <mrpt/core/format.h>
#include <mrpt/system/os.h>
#include <rasterslam/core/config.h>
#include <rasterslam/core/engine.h>
#include <rasterslam/core/heap.h>
#include <rasterslam/eval/trajectory_metrics.h>
#include <rasterslam/io/rawlog_source.h>
#include <rasterslam/io/run_outputs.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <optional>

#include "cli.h"

namespace fs = std::filesystem;
using mrpt::containers::yaml;

namespace rasterslam::cli
{
namespace
{
// Ctrl-C (SIGINT) and SIGTERM: the first lets the run finish the current scan and write every
// output for what was processed (and the map); a second ends the process at once.
std::atomic<int> gStopSignal{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void onStopSignal(int sig)
{
	int none = 0;
	if (!gStopSignal.compare_exchange_strong(none, sig))
		::_exit(128 + sig);
	static const char msg[] =
	    "\nrasterslam: stopping after this scan and writing the outputs (again to quit at once)\n";
	const ssize_t n = ::write(2, msg, sizeof msg - 1);
	(void)n;
}

void installStopHandlers()
{
	struct sigaction sa
	{
	};
	sa.sa_handler = onStopSignal;
	sigemptyset(&sa.sa_mask);
	sa.sa_flags = SA_RESTART;  // reads and writes in progress go on
	::sigaction(SIGINT, &sa, nullptr);
	::sigaction(SIGTERM, &sa, nullptr);
}

const char* signalName(int sig)
{
	return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "a signal";
}

/** Temporary outputs (NAME.tmp-PID) that a run killed while writing left in `dir`: removed
 *  when their process is gone. */
void removeStaleTemporaries(const fs::path& dir)
{
	std::error_code ec;
	for (const auto& e : fs::directory_iterator(dir, ec))
	{
		const auto name = e.path().filename().string();
		const auto at = name.rfind(".tmp-");
		if (at == std::string::npos || !e.is_regular_file(ec))
			continue;
		const std::string pid = name.substr(at + 5);
		if (pid.empty() || pid.size() > 9 ||
		    pid.find_first_not_of("0123456789") != std::string::npos)
			continue;
		const auto p = static_cast<pid_t>(std::stol(pid));
		if (p != ::getpid() && ::kill(p, 0) != 0 && errno == ESRCH)
			fs::remove(e.path(), ec);
	}
}

double percentile(std::vector<double> v, double q)
{
	if (v.empty())
		return 0;
	std::sort(v.begin(), v.end());
	const double pos = q * (v.size() - 1);
	const auto lo = static_cast<std::size_t>(pos);
	const auto hi = std::min(lo + 1, v.size() - 1);
	return v[lo] + (pos - lo) * (v[hi] - v[lo]);
}

/** One line that rewrites itself on a terminal; plain lines every 10% otherwise. */
class Progress
{
   public:
	explicit Progress(bool quiet) : tty_(isatty(2) == 1), quiet_(quiet) {}
	void update(const ScanRecord& r, double frac)
	{
		++n_;
		if (quiet_)
			return;
		const double el = std::chrono::duration<double>(Clock::now() - t0_).count();
		const double rate = el > 0 ? n_ / el : 0;
		const double eta = frac > 0.01 ? el * (1 - frac) / frac : -1;
		if (tty_)
		{
			if (std::chrono::duration<double>(Clock::now() - last_).count() < 0.1 && frac < 1)
				return;
			last_ = Clock::now();
			const int width = 30, filled = frac >= 0 ? static_cast<int>(frac * width) : 0;
			std::string bar(filled, '=');
			bar.resize(width, ' ');
			std::fprintf(stderr, "\r[%s] %3.0f%%  scan %zu  %.1f scans/s  ETA %s   ", bar.c_str(),
			             std::max(0.0, frac) * 100, r.index, rate,
			             eta >= 0 ? mrpt::format("%.0fs", eta).c_str() : "?");
		}
		else
		{
			const int decile = frac >= 0 ? static_cast<int>(frac * 10) : static_cast<int>(n_ / 100);
			if (decile == lastDecile_)
				return;
			lastDecile_ = decile;
			std::fprintf(
			    stderr,
			    "[rasterslam] %zu scans (index %zu, %.0f%% of input), %.1f scans/s, ETA %s\n", n_,
			    r.index, std::max(0.0, frac) * 100, rate,
			    eta >= 0 ? mrpt::format("%.0fs", eta).c_str() : "?");
		}
	}
	void done()
	{
		if (tty_ && !quiet_ && n_ > 0)
			std::fprintf(stderr, "\n");
	}

   private:
	using Clock = std::chrono::steady_clock;
	bool tty_, quiet_;
	std::size_t n_ = 0;
	int lastDecile_ = -1;
	Clock::time_point t0_ = Clock::now(), last_{};
};
}  // namespace

namespace
{
struct RunArgs
{
	std::string rawlog, outDir, configPath, sensor, mapOut, mapIn;
	std::optional<std::size_t> first, last;
	bool realtime = false, dropLate = false;
	double rate = 1;
	bool quiet = false, verbose = false, saveImages = false, overwrite = false,
	     requireLocalization = false;
};

int runCommand(const RunArgs& args);
}  // namespace

Command addRunCommand(CLI::App& app)
{
	auto a = std::make_shared<RunArgs>();
	CLI::App* sub = subcommand(
	    app, "run", "SLAM over an MRPT rawlog: trajectory, timings, run.yaml, the map",
	    "Without --config the paper's whole system runs (slam): tracking, local maps, loop "
	    "closure over the bag-of-words place index and pose-graph optimization; --config tracking "
	    "runs the tracking alone.");
	sub->add_option("--rawlog", a->rawlog,
	                "MRPT rawlog (either format, gzip or plain) with 3D scans")
	    ->required()
	    ->type_name("FILE");
	sub->add_option("--out", a->outDir,
	                "output folder: trajectory.tum, trajectory.kitti, timings.csv, run.yaml, "
	                "pose_graph.graph, loops.txt, groundtruth.{tum,kitti} when the rawlog has "
	                "ground truth")
	    ->required()
	    ->type_name("DIR");
	sub->add_option("--config", a->configPath, configHelp("slam"))->type_name("FILE|NAME");
	addIndex(*sub, "--first", a->first, "skip scans before input index N (0-based)");
	addIndex(*sub, "--last", a->last, "stop after input index N (inclusive)");
	auto* rt = sub->add_flag("--realtime", a->realtime,
	                         "play scans at their time stamps; the summary counts late scans");
	sub->add_option("--rate", a->rate, "clock scale for --realtime (2 = twice as fast)")
	    ->check(unnamed(CLI::PositiveNumber))
	    ->needs(rt)
	    ->type_name("R")
	    ->capture_default_str();
	sub->add_flag("--drop-late", a->dropLate,
	              "with --realtime: skip a scan whose processing could only start a whole period "
	              "(the step from the previous stamp) after its time; counted in run.yaml")
	    ->needs(rt);
	sub->add_option("--sensor", a->sensor, "use only scans with this sensor label")
	    ->type_name("LABEL");
	sub->add_flag("--save-images", a->saveImages,
	              "write each scan's elevation image to DIR/images/NNNNNN.png");
	auto* in = sub->add_option("--map-in", a->mapIn,
	                           "start in a map saved by --map-out: the session is located in it "
	                           "(poses are then in that map's frame) and mapping goes on")
	               ->type_name("DIR");
	auto* out =
	    sub->add_option("--map-out", a->mapOut,
	                    "save the map (keyframes, local maps, their graph, the place index: "
	                    "DIR/map.rsmap, DIR/store/, DIR/localmaps/*.png). A map already there is "
	                    "only replaced when it is the --map-in map or with --overwrite")
	        ->type_name("DIR");
	sub->add_flag("--overwrite", a->overwrite, "let --map-out replace a map that is not --map-in")
	    ->needs(out);
	sub->add_flag("--require-localization", a->requireLocalization,
	              "with --map-in: exit 1 when the session is never located in the map (a "
	              "session never located is not saved into it either way)")
	    ->needs(in);
	auto* q = sub->add_flag("--quiet", a->quiet, "only errors and the final summary");
	sub->add_flag("--verbose", a->verbose, "debug logging and the config in force")->excludes(q);
	return {sub, [a]
	        {
		        if (a->first && a->last && *a->first > *a->last)
			        usageError("rasterslam run", "--first is after --last");
		        return runCommand(*a);
	        }};
}

namespace
{
int runCommand(const RunArgs& args)
{
	std::string configPath = args.configPath;
	const std::string &rawlog = args.rawlog, &outDir = args.outDir, &sensor = args.sensor,
	                  &mapOut = args.mapOut, &mapIn = args.mapIn;
	const bool quiet = args.quiet, verbose = args.verbose, saveImages = args.saveImages,
	           overwrite = args.overwrite, requireLocalization = args.requireLocalization;
	RunOptions opts;
	opts.first = args.first;
	opts.last = args.last;
	opts.realtime = args.realtime;
	opts.rate = args.rate;
	opts.dropLate = args.dropLate;

	const auto logLevel = verbose ? mrpt::system::LVL_DEBUG
	                              : (quiet ? mrpt::system::LVL_ERROR : mrpt::system::LVL_INFO);
	// From the start: a Ctrl-C while the config, the plugins or a big map load ends the run
	// before its first scan (exit 130), like one during the scans.
	installStopHandlers();
	RunResult res;
	yaml info = yaml::Map();
	std::unique_ptr<Engine> engine;
	std::unique_ptr<io::RawlogSource> source;
	// Held until the process ends: no other process saves over or prunes the maps this run
	// reads and writes (MapUseLock).
	std::unique_ptr<MapUseLock> mapOutLock, mapInLock;
	try
	{
		io::ensureWritableDir(outDir);
		removeStaleTemporaries(outDir);
		if (!mapOut.empty())
		{
			// A saved map is the work of earlier sessions: replace it only when it is the one this
			// session extends, or when asked to (checked under the lock: no other writer can
			// save one there meanwhile).
			io::ensureWritableDir(mapOut);
			mapOutLock =
			    std::make_unique<MapUseLock>(mapOut, MapUseLock::Mode::Write, "rasterslam run");
			std::error_code ec;
			const bool exists = fs::exists(mapFilePath(mapOut), ec);
			const bool same =
			    !mapIn.empty() && fs::exists(mapIn, ec) && fs::equivalent(mapIn, mapOut, ec);
			if (exists && !same && !overwrite)
				throw std::runtime_error("--map-out " + mapOut +
				                         " holds a map already: pass --map-in " + mapOut +
				                         " to extend it, or --overwrite to replace it");
		}
		if (std::error_code ec; !mapIn.empty() && fs::is_directory(mapIn, ec) &&
		                        !(mapOutLock && fs::equivalent(mapIn, mapOut, ec)))
			mapInLock =
			    std::make_unique<MapUseLock>(mapIn, MapUseLock::Mode::Read, "rasterslam run");
		configPath = resolveConfig(configPath, "slam");
		const yaml cfg = loadYamlFile(configPath);
		engine = std::make_unique<Engine>(cfg, configPath);
		if (!mapIn.empty())
		{
			if (!engine->mapManager() || !engine->loopDetector() || !engine->rasterizer())
				throw std::runtime_error(
				    "--map-in needs a rasterizer, a map_manager and a loop_detector in the config, "
				    "e.g. --config slam");
			engine->loadMap(mapIn);
			opts.relocalizeFirstScan = true;
		}
		if (!mapOut.empty() && !engine->mapManager())
			throw std::runtime_error(
			    "--map-out needs a map_manager in the config (it keeps the map), e.g. "
			    "--config slam");
		engine->setLogLevel(logLevel);
		io::RawlogSourceOptions so;
		so.sensorLabel = sensor;
		source = std::make_unique<io::RawlogSource>(rawlog, so);
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam: error: " << e.what() << "\n";
		return kExitError;
	}
	if (!quiet)
	{
		std::fprintf(stderr, "[rasterslam] config %s\n", configPath.c_str());
		std::stringstream ss;
		ss << emitYaml(engine->configInForce());
		if (verbose)
			std::fprintf(stderr, "%s", ss.str().c_str());
	}

	Progress progress(quiet);
	opts.onScan = [&](const ScanRecord& r, double frac) { progress.update(r, frac); };
	std::string imageError;
	if (saveImages)
	{
		const fs::path imgDir = fs::path(outDir) / "images";
		fs::create_directories(imgDir);
		opts.onRaster = [&, imgDir](const Scan& s, const RasterFrame& f)
		{
			const auto path = imgDir / mrpt::format("%06zu.png", s.index);
			const auto tmp = imgDir / mrpt::format(".%06zu.png.tmp.png", s.index);
			if (!f.image.saveToFile(tmp.string()) && imageError.empty())
				imageError = "cannot write image '" + path.string() + "'";
			else
				fs::rename(tmp, path);
		};
	}
	// The loop detector's decisions go to a temporary file as they are made (a lifelong run
	// keeps none in memory) and into loops.txt at the end; kept in memory only when no
	// temporary file can be made.
	std::unique_ptr<io::LoopDecisionSpool> loopSpool;
	try
	{
		loopSpool = std::make_unique<io::LoopDecisionSpool>();
		opts.onLoopDecisions = [spool = loopSpool.get()](std::vector<LoopDecision>&& d)
		{ spool->append(d); };
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam: warning: " << e.what() << "; loop decisions kept in memory\n";
	}
	// The per-scan records too (264 bytes a scan, read back at the end for the outputs).
	opts.spoolScans = true;
	std::string runError;
	opts.stop = &gStopSignal;
	try
	{
		res = engine->run(*source, opts);
	}
	catch (const std::exception& e)
	{
		runError = e.what();
	}
	progress.done();
	// The engine warns of it in its log; --quiet silences the log, not this warning.
	if (quiet && opts.spoolScans && !res.scans.isSpooled() && !res.scans.empty())
	{
		const char* t = std::getenv("TMPDIR");
		std::cerr << "rasterslam: warning: no temporary file for the scan records in '"
		          << (t && *t ? t : "/tmp") << "'; they were kept in memory\n";
	}
	if (!res.error.empty())
		runError = res.error;
	if (runError.empty() && !imageError.empty())
		runError = imageError;
	// A spool that lost lines (a full disk) costs loops.txt, not the run's other outputs.
	bool loopsLost = false;
	if (loopSpool)
	{
		if (auto why = loopSpool->finish(); !why.empty())
		{
			loopsLost = true;
			if (runError.empty())
				runError = why + "; loops.txt is not written";
			else
				std::cerr << "rasterslam: error: " << why << "; loops.txt is not written\n";
		}
	}

	// Summary figures.
	// The records are read back from their temporary file; one that lost some (a full disk)
	// has given its reason in res.error, and no trajectory.
	const bool recordsKept = res.scans.error().empty() && res.poses.size() == res.scans.size();
	std::vector<double> total, odo, ras, rd;
	bool allGt = recordsKept && !res.scans.empty();
	if (recordsKept)
		res.scans.forEach(
		    [&](const ScanRecord& r)
		    {
			    total.push_back(r.ms.total);
			    odo.push_back(r.ms.odometry);
			    ras.push_back(r.ms.rasterize);
			    rd.push_back(r.ms.read);
			    allGt = allGt && r.groundTruth.has_value();
		    });
	double pathLen = 0;
	for (std::size_t i = 1; i < res.poses.size(); i++)
		pathLen += (res.poses[i].translation() - res.poses[i - 1].translation()).norm();

	info["rasterslam_version"] = std::string(RASTERSLAM_VERSION);
	info["mrpt_version"] = mrpt::system::MRPT_getVersion();
	info["allocator"] = std::string(heapAllocator());
	yaml input = yaml::Map();
	input["rawlog"] = fs::absolute(rawlog).string();
	input["first"] = opts.first ? static_cast<int>(*opts.first) : -1;
	input["last"] = opts.last ? static_cast<int>(*opts.last) : -1;
	input["sensor"] = sensor;
	input["realtime"] = opts.realtime;
	input["rate"] = opts.rate;
	input["drop_late"] = opts.dropLate;
	input["config"] = fs::absolute(configPath).string();
	info["input"] = input;
	info["config"] = engine->configInForce();
	yaml counts = yaml::Map();
	counts["scans"] = static_cast<uint64_t>(res.scans.size());
	counts["keyframes"] = static_cast<uint64_t>(res.keyframes);
	counts["lost"] = static_cast<uint64_t>(res.lost);
	counts["late"] = static_cast<uint64_t>(res.late);
	counts["dropped_late"] = static_cast<uint64_t>(res.droppedLate);
	counts["stamps_out_of_order"] = static_cast<uint64_t>(res.stampsOutOfOrder);
	counts["loop_decisions"] = static_cast<uint64_t>(res.loopDecisionsMade);
	counts["loop_edges"] = static_cast<uint64_t>(res.loopEdges);
	counts["loops_by_context"] = static_cast<uint64_t>(res.loopsByContext);
	counts["rawlog_odometry_edges"] = static_cast<uint64_t>(res.odometryEdges);
	counts["relocalized"] = static_cast<uint64_t>(res.relocalized);
	counts["relocalization_failures"] = static_cast<uint64_t>(res.relocalizationFailures);
	counts["loops_to_prior_map"] = static_cast<uint64_t>(res.loopsToPriorMap);
	counts["prior_map_loop_edges"] = static_cast<uint64_t>(res.priorMapLoopEdges);
	counts["local_maps"] = static_cast<uint64_t>(res.localMaps);
	counts["local_ba_runs"] = static_cast<uint64_t>(res.localBaRuns);
	counts["online_optimizations"] = static_cast<uint64_t>(res.onlineOptimizations);
	if (res.corruptedLoops > 0)
		counts["corrupted_loops_test_hook"] = static_cast<uint64_t>(res.corruptedLoops);
	counts["skipped_bad_scans"] = static_cast<uint64_t>(res.skippedBadScans);
	info["counts"] = counts;
	yaml summary = yaml::Map();
	summary["wall_s"] = res.wall_s;
	summary["ms_per_scan_median"] = percentile(total, 0.5);
	summary["ms_per_scan_p95"] = percentile(total, 0.95);
	summary["read_ms_median"] = percentile(rd, 0.5);
	summary["rasterize_ms_median"] = percentile(ras, 0.5);
	summary["odometry_ms_median"] = percentile(odo, 0.5);
	summary["peak_rss_mb"] = peakRssMb();
	summary["online_optimization_ms_total"] = res.onlineOptimization_ms;
	summary["local_maps_replaced"] = res.localMapsReplaced;
	summary["memory_trim_ms_total"] = res.memoryTrim_ms;
	summary["online_optimization_nodes_mean"] =
	    res.onlineOptimizations
	        ? static_cast<double>(res.onlineOptimizationNodes) / res.onlineOptimizations
	        : 0.0;
	yaml cpu = yaml::Map();
	cpu["tracking_s"] = res.cpuTracking_s;
	cpu["mapping_and_loop_closing_s"] = res.cpuBackend_s;
	summary["cpu"] = cpu;
	if (res.optimizer.ran)
	{
		summary["final_optimization_ms"] = res.optimizer.time_ms;
		std::size_t downweighted = 0;
		for (const auto& [e, w] : res.optimizer.edgeWeights)
			downweighted += w < 0.1;
		if (!res.optimizer.edgeWeights.empty())
			summary["loop_edges_downweighted"] = static_cast<uint64_t>(downweighted);
	}
	if (engine->mapManager())
	{
		const auto& m = engine->mapManager()->map();
		summary["map_memory_mb"] = m.memoryBytes() / 1e6;
		counts["local_maps_online"] = static_cast<uint64_t>(m.onlineCount());
		counts["local_maps_offline"] = static_cast<uint64_t>(m.localMaps.size() - m.onlineCount());
		info["counts"] = counts;
	}
	summary["path_length_m"] = pathLen;
	std::optional<double> ate, gtPathLen;
	if (allGt)
	{
		io::Trajectory gt, est;
		std::size_t i = 0;
		res.scans.forEach(
		    [&](const ScanRecord& r)
		    {
			    gt.push_back({r.stamp, io::toIsometry(mrpt::poses::CPose3D(*r.groundTruth))});
			    est.push_back({r.stamp, io::toIsometry(res.poses[i++])});
		    });
		const auto a = eval::associate(gt, est, true);
		ate = eval::computeAte(gt, est, a).rmse_m;
		summary["ate_rmse_m"] = *ate;
		// The route's length is the ground truth's: the estimate's is shorter where it drifts.
		gtPathLen = eval::trajectoryDistances(gt, a).back();
		summary["ground_truth_path_length_m"] = *gtPathLen;
	}
	if (!res.stopReason.empty())
		summary["stopped_early"] = res.stopReason;
	if (res.stoppedBy != 0)
		summary["interrupted_by"] = std::string(signalName(res.stoppedBy));
	const bool unlocated = opts.relocalizeFirstScan && !res.localized;
	if (opts.relocalizeFirstScan)
	{
		summary["localized_in_prior_map"] = res.localized;
		summary["prior_map_hits"] = static_cast<uint64_t>(res.anchorHits);
		if (res.localizedAtScan)
			summary["localized_at_scan"] = static_cast<uint64_t>(*res.localizedAtScan);
	}
	if (unlocated && !mapOut.empty() && runError.empty())
		runError = "the session was never located in the prior map " + mapIn +
		           ": the map is not saved (it would hold two frames)";
	else if (unlocated && requireLocalization && runError.empty())
		runError =
		    "the session was never located in the prior map " + mapIn + " (--require-localization)";
	if (!runError.empty())
		summary["error"] = runError;
	info["summary"] = summary;

	if (!mapOut.empty() && !res.scans.empty() && !unlocated)
	{
		try
		{
			engine->saveMap(mapOut, res.graph);
		}
		catch (const std::exception& e)
		{
			if (runError.empty())
			{
				runError = std::string("saving the map: ") + e.what();
				summary["error"] = runError;  // run.yaml records it
				info["summary"] = summary;
			}
		}
	}
	bool wrote = false;
	try
	{
		if (!res.scans.empty())
		{
			io::writeRunOutputs(outDir, res, info, loopsLost ? nullptr : loopSpool.get());
			wrote = true;
		}
	}
	catch (const std::exception& e)
	{
		// Reported with the run's other error, if any, and the summary below.
		if (runError.empty())
			runError = std::string("writing the outputs: ") + e.what();
		else
			std::cerr << "rasterslam: error writing outputs: " << e.what() << "\n";
	}

	std::printf(
	    "rasterslam: %zu scans, %zu keyframes, %zu lost%s in %.1f s: %.1f ms/scan median, "
	    "%.1f p95 (%.1f scans/s), peak memory %.0f MB\n",
	    res.scans.size(), res.keyframes, res.lost,
	    opts.realtime
	        ? mrpt::format(
	              ", %zu late%s", res.late,
	              opts.dropLate ? mrpt::format(", %zu dropped late", res.droppedLate).c_str() : "")
	              .c_str()
	        : "",
	    res.wall_s, percentile(total, 0.5), percentile(total, 0.95),
	    res.wall_s > 0 ? res.scans.size() / res.wall_s : 0.0, peakRssMb());
	if (ate)
		std::printf(
		    "rasterslam: ATE against the rawlog's ground truth: %.3f m RMSE over %.1f m (ground "
		    "truth's route)\n",
		    *ate, *gtPathLen);
	if (opts.relocalizeFirstScan)
		std::printf("rasterslam: %s in the prior map %s (%zu hits in earlier sessions)\n",
		            res.localized ? "located" : "NOT located", mapIn.c_str(), res.anchorHits);
	if (res.stampsOutOfOrder > 0)
		std::fprintf(stderr,
		             "rasterslam: warning: %zu scans have a time stamp that does not increase "
		             "(engine.stamp_order: error makes that an error)\n",
		             res.stampsOutOfOrder);
	if (!res.stopReason.empty())
		std::fprintf(
		    stderr,
		    "rasterslam: error: the input stopped early, outputs cover the %zu scans before: %s\n",
		    res.scans.size(), res.stopReason.c_str());
	if (wrote)
		std::printf("rasterslam: outputs in %s\n", fs::absolute(outDir).lexically_normal().c_str());
	if (!runError.empty())
	{
		std::cerr << "rasterslam: error: " << runError << "\n";
		return kExitError;
	}
	if (res.stoppedBy != 0)
	{
		// The shell's convention for a process ended by a signal: 128 + its number.
		std::fprintf(stderr, "rasterslam: interrupted by %s after %zu scans%s\n",
		             signalName(res.stoppedBy), res.scans.size(),
		             wrote ? (mapOut.empty() ? "; outputs written for them"
		                                     : "; outputs and the map written for them")
		                   : "; nothing to write");
		return 128 + res.stoppedBy;
	}
	if (res.scans.empty())
	{
		std::cerr << "rasterslam: error: " << rawlog
		          << ": no 3D scans were read (CObservationPointCloud, "
		             "CObservationVelodyneScan, CObservationRotatingScan or CObservation3DRangeScan"
		          << (sensor.empty() ? "" : " with label '" + sensor + "'") << ")\n";
		return kExitError;
	}
	// A damaged input processed up to the damage is still a failed run for scripts.
	return res.stopReason.empty() ? 0 : kExitError;
}

}  // namespace

}  // namespace rasterslam::cli
