// rasterslam-eval loops: loop-closure precision and recall against ground truth.
#include "cli.h"

namespace rasterslam_eval_cli
{
namespace
{
// Below the options in --help (the formatter wraps it at 100 columns, keeping line breaks).
const char* kLoopsAbout =
    "Precision and recall of loop closure: F (--loops) is the loops.txt of a run (one line per "
    "candidate the detector examined), G (--gt) the ground truth (TUM; a run's groundtruth.tum). "
    "A query is positive when the ground truth holds a pose at least --exclude-s older within "
    "--distance of it. A detection is a query's highest-scoring candidate; it is correct when "
    "its registration (the pose of the query in the candidate's frame) is within "
    "--registration metres and --registration-deg degrees of the ground truth's, however far "
    "apart the places are, and then its query counts as a positive too; a line without a "
    "registration, or every line with --registration 0, is correct when the two places are "
    "within --distance (candidates less than --exclude-s older than the query are ignored).\n"
    "detector: the detector's own decisions (accepted lines);\n"
    "sweep: per score threshold, the best verified candidate with score >= threshold; every "
    "distinct score of F and +inf; F1 max (ties: higher precision).";

struct LoopsOptions
{
	std::string loops, gt, csv, plot;
	eval::LoopEvalParams params;
	bool json = false;
};

std::string thresholdText(double t)
{
	if (std::isinf(t))
		return "inf";
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.6g", t);
	return buf;
}

Json jsonPoint(const eval::PrPoint& p, bool withThreshold)
{
	Json j;
	if (withThreshold)
		j["threshold"] = std::isinf(p.threshold) ? Json("inf") : jsonNumber(p.threshold);
	j["precision"] = jsonNumber(p.precision);
	j["recall"] = jsonNumber(p.recall, p.valid);
	j["f1"] = jsonNumber(p.f1, p.valid);
	j["tp"] = p.tp;
	j["fp"] = p.fp;
	j["fn"] = p.fn;
	return j;
}

int runLoops(const LoopsOptions& o)
{
	const std::string& loopsPath = o.loops;
	const std::string& gtPath = o.gt;
	const eval::LoopEvalParams& params = o.params;

	const eval::LoopLog log = eval::loadLoopLog(loopsPath);
	const io::Trajectory gt = io::loadTrajectory(gtPath, io::TrajectoryFormat::Tum);
	if (gt.empty())
		throw std::runtime_error("ground-truth file '" + gtPath + "' has no poses");
	const eval::LoopEvalResult r = eval::evaluateLoops(log, gt, params);

	if (!o.csv.empty())
		io::writeFileAtomically(o.csv, eval::loopSweepCsv(r));
	if (!o.plot.empty())
	{
		char title[256];
		std::snprintf(title, sizeof(title), "Loop closure: %s (%g m, %g s)",
		              std::filesystem::path(loopsPath).parent_path().filename().string().c_str(),
		              params.distance_m, params.exclude_s);
		eval::saveLoopPrPlot(o.plot, r, title);
	}

	const bool hasBest = r.best != eval::LoopEvalResult::npos;
	if (o.json)
	{
		Json j;
		j["loops"] = loopsPath;
		j["gt"] = gtPath;
		j["distance_m"] = jsonNumber(params.distance_m);
		j["exclude_s"] = jsonNumber(params.exclude_s);
		j["max_dt"] = jsonNumber(params.maxDt);
		j["registration_m"] = jsonNumber(params.registration_m);
		j["registration_deg"] = jsonNumber(params.registration_deg);
		j["registered_lines"] = r.registeredLines;
		j["registered_far"] = r.registeredFar;
		j["lines"] = r.lines;
		j["queries"] = r.queries;
		j["positives"] = r.positives;
		j["recent_lines"] = r.recentLines;
		j["accepted_lines"] = r.acceptedLines;
		j["accepted_wrong"] = r.acceptedWrong;
		j["accepted_recent"] = r.acceptedRecent;
		j["detector"] = jsonPoint(r.detector, false);
		j["f1_max"] = hasBest ? jsonPoint(r.sweep[r.best], true) : Json(nullptr);
		j["thresholds"] = r.sweep.size();
		j["csv"] = o.csv.empty() ? Json(nullptr) : Json(o.csv);
		j["plot"] = o.plot.empty() ? Json(nullptr) : Json(o.plot);
		std::cout << jsonLine(j);
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
	          << "criteria     : correct within " << params.distance_m << " m";
	if (params.registration_m > 0)
		std::cout << " or registered within " << params.registration_m << " m and "
		          << params.registration_deg << " deg (" << r.registeredLines << " registrations, "
		          << r.registeredFar << " correct farther than " << params.distance_m << " m)";
	std::cout << ", places younger than " << params.exclude_s << " s excluded (" << r.recentLines
	          << " lines ignored)\n"
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
	if (!o.csv.empty())
		std::cout << "sweep        : " << o.csv << " (" << r.sweep.size() << " thresholds)\n";
	if (!o.plot.empty())
		std::cout << "plot         : " << o.plot << "\n";
	return 0;
}

}  // namespace

Command addLoops(CLI::App& app)
{
	CLI::App* sub = cli::subcommand(
	    app, "loops", "loop closure precision/recall against ground truth, PR plot", kLoopsAbout);
	auto o = std::make_shared<LoopsOptions>();
	sub->add_option("--loops", o->loops, "the detector's loops.txt F")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--gt", o->gt, "ground-truth TUM trajectory G")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--distance", o->params.distance_m, "largest distance of a correct loop (m)")
	    ->check(nonNegativeNumber())
	    ->type_name("M")
	    ->capture_default_str();
	sub->add_option("--registration", o->params.registration_m,
	                "largest translation error of a correct registration (m); 0: judge by "
	                "--distance only")
	    ->check(nonNegativeNumber())
	    ->type_name("M")
	    ->capture_default_str();
	sub->add_option("--registration-deg", o->params.registration_deg,
	                "largest rotation error of a correct registration (deg)")
	    ->check(nonNegativeNumber())
	    ->type_name("DEG")
	    ->capture_default_str();
	sub->add_option("--exclude-s", o->params.exclude_s,
	                "places younger than S seconds are no loops")
	    ->check(nonNegativeNumber())
	    ->type_name("S")
	    ->capture_default_str();
	sub->add_option("--max-dt", o->params.maxDt, "largest stamp difference to the ground truth (s)")
	    ->check(nonNegativeNumber())
	    ->type_name("S")
	    ->capture_default_str();
	sub->add_option("--csv", o->csv, "write the sweep: threshold,precision,recall,f1,tp,fp,fn")
	    ->check(outputFile())
	    ->type_name("FILE");
	sub->add_option("--plot", o->plot, "write the precision-recall curve as PNG")
	    ->check(outputFile())
	    ->type_name("FILE");
	sub->add_flag("--json", o->json, "print one JSON object instead of text");
	return {sub, [o] { return runLoops(*o); }};
}

}  // namespace rasterslam_eval_cli
