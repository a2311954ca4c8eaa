// rasterslam-eval loops: loop-closure precision and recall against ground truth.
#include "cli.h"

namespace rasterslam_eval_cli
{
namespace
{
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
}  // namespace

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

}  // namespace rasterslam_eval_cli
