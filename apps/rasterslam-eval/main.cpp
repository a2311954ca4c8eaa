// rasterslam-eval: accuracy metrics of SLAM outputs. Subcommands: traj, loops.
#include <rasterslam/eval/loop_metrics.h>
#include <rasterslam/eval/trajectory_metrics.h>
#include <rasterslam/io/trajectory_io.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace
{
namespace io = rasterslam::io;
namespace eval = rasterslam::eval;

/** Bad command line: exit code 2 (bad input files give 1). */
struct UsageError : std::runtime_error
{
	using std::runtime_error::runtime_error;
};

/** "--key value" and "--key=value" options; flags take no value. */
class Options
{
   public:
	Options(int argc, char** argv, const std::vector<std::string>& valued,
	        const std::vector<std::string>& flags)
	{
		for (int i = 0; i < argc; ++i)
		{
			std::string a = argv[i];
			std::string value;
			bool hasValue = false;
			if (const auto eq = a.find('='); a.rfind("--", 0) == 0 && eq != std::string::npos)
			{
				value = a.substr(eq + 1);
				a = a.substr(0, eq);
				hasValue = true;
			}
			if (contains(flags, a) && !hasValue)
				flags_.push_back(a);
			else if (contains(valued, a))
			{
				if (!hasValue)
				{
					if (i + 1 >= argc)
						throw UsageError("option " + a + " needs a value");
					value = argv[++i];
				}
				values_[a] = value;
			}
			else
				throw UsageError("unknown option '" + std::string(argv[i]) + "'");
		}
	}
	bool flag(const std::string& k) const { return contains(flags_, k); }
	bool has(const std::string& k) const { return values_.count(k) > 0; }
	std::string get(const std::string& k, const std::string& def = "") const
	{
		const auto it = values_.find(k);
		return it == values_.end() ? def : it->second;
	}
	std::string require(const std::string& k) const
	{
		if (!has(k))
			throw UsageError("missing required option " + k);
		return get(k);
	}
	double number(const std::string& k, double def) const
	{
		if (!has(k))
			return def;
		const std::string s = get(k);
		char* end = nullptr;
		const double v = std::strtod(s.c_str(), &end);
		if (s.empty() || *end != '\0' || !std::isfinite(v) || v < 0)
			throw UsageError("option " + k + ": expected a non-negative number, got '" + s + "'");
		return v;
	}

   private:
	static bool contains(const std::vector<std::string>& v, const std::string& s)
	{
		for (const auto& x : v)
		{
			if (x == s)
				return true;
		}
		return false;
	}
	std::map<std::string, std::string> values_;
	std::vector<std::string> flags_;
};

const char* kTrajUsage =
    R"(Usage: rasterslam-eval traj --gt G --est E [options]

Trajectory accuracy of an estimate E against a ground truth G:
  ATE   absolute trajectory error after the best SE(3) alignment (Umeyama, no scale)
  RPE   relative pose error between consecutive poses (per frame)
  KITTI the odometry devkit's relative translation (%) and rotation (deg/m) errors
Files are TUM ("t x y z qx qy qz qw") or KITTI (12 numbers of a 3x4 [R|t]), detected by
their column count. TUM vs TUM are associated by nearest time stamp; otherwise by index.

Options:
  --gt FILE             ground-truth trajectory (required)
  --est FILE            estimated trajectory (required)
  --calib FILE          KITTI calib.txt: G holds cam0 poses; convert them to the Velodyne
                        frame with inv(Tr) * P * Tr (rasterslam outputs Velodyne poses)
  --est-calib FILE      same conversion for E (when E is a KITTI cam0 pose file too)
  --gt-format F         auto|tum|kitti (default auto); --est-format F likewise
  --times FILE          KITTI times.txt: stamps for the KITTI-format file(s)
  --associate M         auto|index|stamp (default auto)
  --max-dt S            largest stamp difference when associating by time (default 0.02)
  --segments SPEC       segment lengths in metres, start:end:step or a list
                        (default 100:800:100; use 10:80:10 for short clips)
  --step N              first frames every N associated poses (default 10, as the devkit)
  --json                print one JSON object instead of text
  -h, --help            this help
Exit codes: 0 success, 1 bad input file, 2 bad command line.
)";

io::TrajectoryFormat parseFormat(const std::string& opt, const std::string& s)
{
	if (s == "auto")
		return io::TrajectoryFormat::Auto;
	if (s == "tum")
		return io::TrajectoryFormat::Tum;
	if (s == "kitti")
		return io::TrajectoryFormat::Kitti;
	throw UsageError("option " + opt + ": expected auto, tum or kitti, got '" + s + "'");
}

std::string jsonNumber(double v, bool valid = true)
{
	if (!valid || !std::isfinite(v))
		return "null";
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.9g", v);
	return buf;
}

std::string jsonString(const std::string& s)
{
	std::string out = "\"";
	for (const char c : s)
	{
		if (c == '"' || c == '\\')
			out += std::string("\\") + c;
		else if (static_cast<unsigned char>(c) < 0x20)
		{
			char buf[8];
			std::snprintf(buf, sizeof(buf), "\\u%04x", c);
			out += buf;
		}
		else
			out += c;
	}
	return out + "\"";
}

struct Input
{
	io::Trajectory traj;
	io::TrajectoryFormat format = io::TrajectoryFormat::Auto;
	bool stamped = false;  //!< real time stamps (TUM, or KITTI with --times)
};

Input loadInput(const Options& o, const std::string& fileOpt, const std::string& fmtOpt,
                const std::string& calibOpt)
{
	Input in;
	const std::string path = o.require(fileOpt);
	in.traj = io::loadTrajectory(path, parseFormat(fmtOpt, o.get(fmtOpt, "auto")), &in.format);
	if (in.traj.empty())
		throw std::runtime_error("trajectory file '" + path + "' has no poses");
	in.stamped = in.format == io::TrajectoryFormat::Tum;
	if (in.format == io::TrajectoryFormat::Kitti && o.has("--times"))
	{
		const auto times = io::loadKittiTimes(o.get("--times"));
		if (times.size() != in.traj.size())
		{
			throw std::runtime_error("times file '" + o.get("--times") + "' has " +
			                         std::to_string(times.size()) + " stamps but '" + path +
			                         "' has " + std::to_string(in.traj.size()) + " poses");
		}
		for (std::size_t i = 0; i < times.size(); ++i)
			in.traj[i].stamp = times[i];
		in.stamped = true;
	}
	if (o.has(calibOpt))
		in.traj = io::kittiCameraToVelodyne(in.traj, io::loadKittiCalibTr(o.get(calibOpt)));
	return in;
}

int runTraj(int argc, char** argv)
{
	const Options o(argc, argv,
	                {"--gt", "--est", "--calib", "--est-calib", "--gt-format", "--est-format",
	                 "--times", "--associate", "--max-dt", "--segments", "--step"},
	                {"--json", "--help", "-h"});
	if (o.flag("--help") || o.flag("-h"))
	{
		std::cout << kTrajUsage;
		return 0;
	}
	// Check the whole command line before reading any file.
	o.require("--gt");
	o.require("--est");
	parseFormat("--gt-format", o.get("--gt-format", "auto"));
	parseFormat("--est-format", o.get("--est-format", "auto"));
	const std::string segSpec = o.get("--segments", "100:800:100");
	std::vector<double> lengths;
	try
	{
		lengths = eval::parseSegmentSpec(segSpec);
	}
	catch (const std::invalid_argument& e)
	{
		throw UsageError(std::string("option --segments: ") + e.what());
	}
	const double maxDt = o.number("--max-dt", 0.02);
	const double stepD = o.number("--step", 10);
	if (stepD < 1 || stepD != std::floor(stepD))
		throw UsageError("option --step: expected a whole number >= 1");
	const auto step = static_cast<std::size_t>(stepD);
	const std::string assocMode = o.get("--associate", "auto");
	if (assocMode != "auto" && assocMode != "index" && assocMode != "stamp")
		throw UsageError("option --associate: expected auto, index or stamp, got '" + assocMode +
		                 "'");

	const Input gt = loadInput(o, "--gt", "--gt-format", "--calib");
	const Input est = loadInput(o, "--est", "--est-format", "--est-calib");

	const bool byStamp = assocMode == "stamp" || (assocMode == "auto" && gt.stamped && est.stamped);
	const eval::Association a = eval::associate(gt.traj, est.traj, !byStamp, maxDt);
	if (a.gt.size() < 2)
	{
		throw std::runtime_error("only " + std::to_string(a.gt.size()) +
		                         " pose pairs associated between '" + o.get("--gt") + "' and '" +
		                         o.get("--est") + "'" +
		                         (byStamp ? " (check the stamps or --max-dt)" : ""));
	}

	const eval::AteResult ate = eval::computeAte(gt.traj, est.traj, a);
	const eval::RpeResult rpe = eval::computeRpe(gt.traj, est.traj, a);
	const eval::KittiRelativeResult rel =
	    eval::computeKittiRelative(gt.traj, est.traj, a, lengths, step);
	const double pathLength = eval::trajectoryDistances(gt.traj, a).back();
	const bool relOk = rel.count > 0;
	double shortest = lengths.front();
	for (double l : lengths)
		shortest = std::min(shortest, l);
	std::ostringstream note;
	if (!relOk)
	{
		note << std::fixed << std::setprecision(2) << "path length " << pathLength
		     << " m is shorter than the shortest segment " << shortest
		     << " m; try --segments 10:80:10";
	}

	if (o.flag("--json"))
	{
		std::ostringstream j;
		j << "{\"gt\": " << jsonString(o.get("--gt")) << ", \"est\": " << jsonString(o.get("--est"))
		  << ", \"n_gt\": " << gt.traj.size() << ", \"n_est\": " << est.traj.size()
		  << ", \"n_associated\": " << a.gt.size() << ", \"association\": \""
		  << (byStamp ? "stamp" : "index") << "\", \"path_length_m\": " << jsonNumber(pathLength)
		  << ", \"ate_rmse_m\": " << jsonNumber(ate.rmse_m)
		  << ", \"ate_mean_m\": " << jsonNumber(ate.mean_m)
		  << ", \"ate_median_m\": " << jsonNumber(ate.median_m)
		  << ", \"ate_max_m\": " << jsonNumber(ate.max_m) << ", \"rpe_pairs\": " << rpe.n
		  << ", \"rpe_trans_rmse_m\": " << jsonNumber(rpe.trans_rmse_m)
		  << ", \"rpe_trans_mean_m\": " << jsonNumber(rpe.trans_mean_m)
		  << ", \"rpe_rot_rmse_deg\": " << jsonNumber(rpe.rot_rmse_deg)
		  << ", \"rpe_rot_mean_deg\": " << jsonNumber(rpe.rot_mean_deg) << ", \"segments\": [";
		for (std::size_t i = 0; i < lengths.size(); ++i)
			j << (i ? ", " : "") << jsonNumber(lengths[i]);
		j << "], \"step\": " << step << ", \"rel_count\": " << rel.count
		  << ", \"rel_trans_pct\": " << jsonNumber(rel.t_err_pct, relOk)
		  << ", \"rel_rot_deg_per_m\": " << jsonNumber(rel.r_err_deg_per_m, relOk)
		  << ", \"per_length\": [";
		for (std::size_t i = 0; i < rel.perLength.size(); ++i)
		{
			const auto& pl = rel.perLength[i];
			j << (i ? ", " : "") << "{\"length_m\": " << jsonNumber(pl.length_m)
			  << ", \"count\": " << pl.count
			  << ", \"t_err_pct\": " << jsonNumber(pl.t_err_pct, pl.count > 0)
			  << ", \"r_err_deg_per_m\": " << jsonNumber(pl.r_err_deg_per_m, pl.count > 0) << "}";
		}
		j << "], \"note\": " << (relOk ? "null" : jsonString(note.str())) << "}\n";
		std::cout << j.str();
		return 0;
	}

	auto fmtName = [](io::TrajectoryFormat f)
	{ return f == io::TrajectoryFormat::Tum ? "TUM" : "KITTI"; };
	char buf[256];
	std::cout << "ground truth : " << o.get("--gt") << " (" << fmtName(gt.format) << ", "
	          << gt.traj.size() << " poses" << (o.has("--calib") ? ", cam0 -> Velodyne" : "")
	          << ")\n"
	          << "estimate     : " << o.get("--est") << " (" << fmtName(est.format) << ", "
	          << est.traj.size() << " poses" << (o.has("--est-calib") ? ", cam0 -> Velodyne" : "")
	          << ")\n"
	          << "associated   : " << a.gt.size() << " pairs by "
	          << (byStamp ? "time stamp" : "index") << "\n";
	std::snprintf(buf, sizeof(buf), "path length  : %.2f m (ground truth)\n", pathLength);
	std::cout << buf;
	std::snprintf(buf, sizeof(buf),
	              "ATE (SE(3)-aligned): rmse %.4f m, mean %.4f m, median %.4f m, max %.4f m\n",
	              ate.rmse_m, ate.mean_m, ate.median_m, ate.max_m);
	std::cout << buf;
	std::snprintf(
	    buf, sizeof(buf),
	    "RPE per frame (%zu pairs): translation rmse %.4f m, mean %.4f m; rotation rmse %.4f deg, "
	    "mean %.4f deg\n",
	    rpe.n, rpe.trans_rmse_m, rpe.trans_mean_m, rpe.rot_rmse_deg, rpe.rot_mean_deg);
	std::cout << buf;
	if (!relOk)
	{
		std::cout << "KITTI relative errors: no segment (" << note.str() << ")\n";
		return 0;
	}
	std::snprintf(buf, sizeof(buf),
	              "KITTI relative errors (segments %s m, every %zu frames, %zu segments): "
	              "translation %.3f %%, rotation %.5f deg/m\n",
	              segSpec.c_str(), step, rel.count, rel.t_err_pct, rel.r_err_deg_per_m);
	std::cout << buf << "  length_m  count  t_err_%   r_err_deg/m\n";
	for (const auto& pl : rel.perLength)
	{
		if (pl.count)
			std::snprintf(buf, sizeof(buf), "  %8.1f  %5zu  %7.3f   %.5f\n", pl.length_m, pl.count,
			              pl.t_err_pct, pl.r_err_deg_per_m);
		else
			std::snprintf(buf, sizeof(buf), "  %8.1f  %5zu        -   -\n", pl.length_m, pl.count);
		std::cout << buf;
	}
	return 0;
}

const char* kLoopsUsage =
    R"(Usage: rasterslam-eval loops --loops F --gt G [options]

Precision and recall of loop closure: F is the loops.txt of a run (one line per candidate the
detector examined), G the ground truth (TUM; a run's groundtruth.tum). A query is positive when
the ground truth holds a pose at least --exclude-s older within --distance of it. A detection
is a query's highest-scoring candidate; it is correct when the two places are within
--distance (candidates less than --exclude-s older than the query are ignored).
  detector   the detector's own decisions (accepted lines)
  sweep      per score threshold, the best verified candidate with score >= threshold;
             every distinct score of F and +inf; F1 max (ties: higher precision)

Options:
  --loops FILE          the detector's loops.txt (required)
  --gt FILE             ground-truth TUM trajectory (required)
  --distance M          largest distance of a correct loop, metres (default 4)
  --exclude-s S         places younger than S seconds are no loops (default 30)
  --max-dt S            largest stamp difference to the ground truth (default 0.02)
  --csv FILE            write the sweep: threshold,precision,recall,f1,tp,fp,fn
  --plot FILE           write the precision-recall curve as PNG
  --json                print one JSON object instead of text
  -h, --help            this help
Exit codes: 0 success, 1 bad input file, 2 bad command line.
)";

std::string thresholdText(double t)
{
	if (std::isinf(t))
		return "inf";
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.6g", t);
	return buf;
}

std::string jsonPoint(const eval::PrPoint& p, bool withThreshold)
{
	std::ostringstream j;
	j << "{";
	if (withThreshold)
		j << "\"threshold\": " << (std::isinf(p.threshold) ? "\"inf\"" : jsonNumber(p.threshold))
		  << ", ";
	j << "\"precision\": " << jsonNumber(p.precision)
	  << ", \"recall\": " << jsonNumber(p.recall, p.valid)
	  << ", \"f1\": " << jsonNumber(p.f1, p.valid) << ", \"tp\": " << p.tp << ", \"fp\": " << p.fp
	  << ", \"fn\": " << p.fn << "}";
	return j.str();
}

int runLoops(int argc, char** argv)
{
	const Options o(argc, argv,
	                {"--loops", "--gt", "--distance", "--exclude-s", "--max-dt", "--csv", "--plot"},
	                {"--json", "--help", "-h"});
	if (o.flag("--help") || o.flag("-h"))
	{
		std::cout << kLoopsUsage;
		return 0;
	}
	// Check the whole command line before reading any file.
	const std::string loopsPath = o.require("--loops");
	const std::string gtPath = o.require("--gt");
	eval::LoopEvalParams params;
	params.distance_m = o.number("--distance", params.distance_m);
	params.exclude_s = o.number("--exclude-s", params.exclude_s);
	params.maxDt = o.number("--max-dt", params.maxDt);
	if (o.has("--csv") && o.get("--csv").empty())
		throw UsageError("option --csv: empty file name");
	if (o.has("--plot") && o.get("--plot").empty())
		throw UsageError("option --plot: empty file name");

	const eval::LoopLog log = eval::loadLoopLog(loopsPath);
	const io::Trajectory gt = io::loadTrajectory(gtPath, io::TrajectoryFormat::Tum);
	if (gt.empty())
		throw std::runtime_error("ground-truth file '" + gtPath + "' has no poses");
	const eval::LoopEvalResult r = eval::evaluateLoops(log, gt, params);

	if (o.has("--csv"))
		io::writeFileAtomically(o.get("--csv"), eval::loopSweepCsv(r));
	if (o.has("--plot"))
	{
		char title[256];
		std::snprintf(title, sizeof(title), "Loop closure: %s (%g m, %g s)",
		              std::filesystem::path(loopsPath).parent_path().filename().string().c_str(),
		              params.distance_m, params.exclude_s);
		eval::saveLoopPrPlot(o.get("--plot"), r, title);
	}

	const bool hasBest = r.best != eval::LoopEvalResult::npos;
	if (o.flag("--json"))
	{
		std::ostringstream j;
		j << "{\"loops\": " << jsonString(loopsPath) << ", \"gt\": " << jsonString(gtPath)
		  << ", \"distance_m\": " << jsonNumber(params.distance_m)
		  << ", \"exclude_s\": " << jsonNumber(params.exclude_s)
		  << ", \"max_dt\": " << jsonNumber(params.maxDt) << ", \"lines\": " << r.lines
		  << ", \"queries\": " << r.queries << ", \"positives\": " << r.positives
		  << ", \"recent_lines\": " << r.recentLines << ", \"accepted_lines\": " << r.acceptedLines
		  << ", \"accepted_wrong\": " << r.acceptedWrong
		  << ", \"accepted_recent\": " << r.acceptedRecent
		  << ", \"detector\": " << jsonPoint(r.detector, false)
		  << ", \"f1_max\": " << (hasBest ? jsonPoint(r.sweep[r.best], true) : "null")
		  << ", \"thresholds\": " << r.sweep.size()
		  << ", \"csv\": " << (o.has("--csv") ? jsonString(o.get("--csv")) : "null")
		  << ", \"plot\": " << (o.has("--plot") ? jsonString(o.get("--plot")) : "null") << "}\n";
		std::cout << j.str();
		return 0;
	}

	auto rate = [](double v, bool valid)
	{
		if (!valid)
			return std::string("-");
		char buf[32];
		std::snprintf(buf, sizeof(buf), "%.4f", v);
		return std::string(buf);
	};
	const auto& d = r.detector;
	std::cout << "loops        : " << loopsPath << " (" << r.lines << " candidate lines, "
	          << r.queries << " queries)\n"
	          << "ground truth : " << gtPath << " (" << gt.size() << " poses)\n"
	          << "criteria     : correct within " << params.distance_m << " m, places younger than "
	          << params.exclude_s << " s excluded (" << r.recentLines << " lines ignored)\n"
	          << "positives    : " << r.positives << " of " << r.queries << " queries\n"
	          << "detector     : precision " << rate(d.precision, true) << ", recall "
	          << rate(d.recall, d.valid) << " (tp " << d.tp << ", fp " << d.fp << ", fn " << d.fn
	          << "); " << r.acceptedLines << " loop edges, " << r.acceptedWrong << " wrong, "
	          << r.acceptedRecent << " to recent places\n";
	if (hasBest)
	{
		const auto& b = r.sweep[r.best];
		std::cout << "F1 max       : " << rate(b.f1, true)
		          << " at score >= " << thresholdText(b.threshold) << ": precision "
		          << rate(b.precision, true) << ", recall " << rate(b.recall, true) << " (tp "
		          << b.tp << ", fp " << b.fp << ", fn " << b.fn << ")\n";
	}
	else
		std::cout << "F1 max       : - (no positive query: recall is undefined)\n";
	if (o.has("--csv"))
		std::cout << "sweep        : " << o.get("--csv") << " (" << r.sweep.size()
		          << " thresholds)\n";
	if (o.has("--plot"))
		std::cout << "plot         : " << o.get("--plot") << "\n";
	return 0;
}

struct Command
{
	const char* name;
	const char* summary;
	std::function<int(int, char**)> run;
};

// Add subcommands here.
const std::vector<Command>& commands()
{
	static const std::vector<Command> cmds = {
	    {"traj", "trajectory errors: ATE, per-frame RPE, KITTI devkit relative errors", runTraj},
	    {"loops", "loop closure: precision/recall against ground truth, PR sweep and plot",
	     runLoops},
	};
	return cmds;
}

void printUsage(std::ostream& os)
{
	os << "Usage: rasterslam-eval <command> [options]\n\nCommands:\n";
	std::size_t width = 0;
	for (const auto& c : commands())
		width = std::max(width, std::strlen(c.name));
	for (const auto& c : commands())
		os << "  " << std::left << std::setw(static_cast<int>(width + 4)) << c.name << c.summary
		   << "\n";
	os << "\nrasterslam-eval <command> --help shows the options of a command.\n";
}
}  // namespace

int main(int argc, char** argv)
{
	if (argc < 2)
	{
		printUsage(std::cerr);
		return 2;
	}
	const std::string cmd = argv[1];
	if (cmd == "--help" || cmd == "-h" || cmd == "help")
	{
		printUsage(std::cout);
		return 0;
	}
	for (const auto& c : commands())
	{
		if (cmd != c.name)
			continue;
		try
		{
			return c.run(argc - 2, argv + 2);
		}
		catch (const UsageError& e)
		{
			std::cerr << "rasterslam-eval " << cmd << ": " << e.what() << "\n"
			          << "(rasterslam-eval " << cmd << " --help for the options)\n";
			return 2;
		}
		catch (const std::exception& e)
		{
			std::cerr << "rasterslam-eval " << cmd << ": error: " << e.what() << "\n";
			return 1;
		}
	}
	std::cerr << "rasterslam-eval: unknown command '" << cmd << "'\n";
	printUsage(std::cerr);
	return 2;
}
