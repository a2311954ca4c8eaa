// rasterslam-eval scene: statistics of the scenes in LiDAR inputs, side by side, to compare
// simulated scans with real ones (see rasterslam/eval/scene_stats.h).
#include <rasterslam/eval/scene_stats.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/rawlog_source.h>

#include "cli.h"

namespace rasterslam_eval_cli
{
namespace
{
namespace fs = std::filesystem;

const char* kSceneAbout =
    "Statistics of the scans of each INPUT (an MRPT rawlog, or a folder of KITTI .bin scans), "
    "one column per input: points a scan, the share of ground points (within 0.25 m of the "
    "RANSAC ground plane, or below it), the shares of points by horizontal range, the shares "
    "of the other points by height above the ground, the bird's-eye cells (0.2 m) they occupy "
    "within 40 m, how evenly the walls face every direction (isotropy: 0 = one way, as in a "
    "straight street of plain facades; 1 = every way alike) and the intensities. A scan in "
    "which no ground plane is found is left out and counted. Used to check that simulated "
    "scenes look like real ones.";

struct SceneOptions
{
	std::vector<std::string> inputs, labels;
	std::size_t every = 1, maxScans = 0;
	bool json = false;
};

eval::SceneStats statsOf(const std::string& input, const SceneOptions& o)
{
	eval::SceneStatsAccumulator acc;
	std::size_t index = 0, used = 0;
	const auto take = [&]()
	{ return index++ % o.every == 0 && (o.maxScans == 0 || used < o.maxScans); };
	if (fs::is_directory(input))
	{
		const auto bins = io::listKittiBins(input);
		if (bins.empty())
			throw std::runtime_error(input + ": a folder without KITTI .bin scans");
		for (const auto& b : bins)
			if (take())
			{
				acc.add(io::loadKittiBin(b));
				used++;
			}
	}
	else
	{
		io::RawlogSource src(input);
		while (auto scan = src.next())
			if (take())
			{
				acc.add(scan->points);
				used++;
			}
		if (!src.stopReason().empty())
			throw std::runtime_error(input + ": " + src.stopReason());
	}
	try
	{
		return acc.finish();
	}
	catch (const std::invalid_argument& e)
	{
		throw std::runtime_error(input + ": " + e.what());
	}
}

Json toJson(const std::string& label, const eval::SceneStats& s)
{
	Json j;
	j["label"] = label;
	j["scans"] = s.scans;
	j["scans_without_ground"] = s.scansWithoutGround;
	j["points"] = jsonNumber(s.points);
	j["ground_share"] = jsonNumber(s.groundShare);
	j["range_share"] = Json::array();
	for (double v : s.rangeShare)
		j["range_share"].push_back(jsonNumber(v));
	j["height_share"] = Json::array();
	for (double v : s.heightShare)
		j["height_share"].push_back(jsonNumber(v));
	j["structure_cells"] = jsonNumber(s.structureCells);
	j["isotropy"] = jsonNumber(s.isotropy);
	j["mean_intensity"] = jsonNumber(s.meanIntensity);
	j["bright_share"] = jsonNumber(s.brightShare);
	return j;
}

int runScene(const SceneOptions& o)
{
	if (!o.labels.empty() && o.labels.size() != o.inputs.size())
		cli::usageError("rasterslam-eval scene", "give one --label per INPUT or none");
	std::vector<std::string> labels = o.labels;
	if (labels.empty())
		for (const auto& in : o.inputs)
		{
			// "dir/" has no file name: take the last component that has one.
			const fs::path p = fs::path(in).lexically_normal();
			const std::string name =
			    p.has_filename() ? p.filename().string() : p.parent_path().filename().string();
			labels.push_back(name.substr(0, 12));
		}
	std::vector<eval::SceneStats> stats;
	for (const auto& in : o.inputs)
		stats.push_back(statsOf(in, o));
	if (o.json)
	{
		Json all = Json::array();
		for (std::size_t i = 0; i < stats.size(); i++)
			all.push_back(toJson(labels[i], stats[i]));
		std::cout << jsonLine(all);
		return 0;
	}
	std::cout << eval::formatSceneStats(labels, stats);
	return 0;
}
}  // namespace

Command addScene(CLI::App& app)
{
	CLI::App* sub = cli::subcommand(app, "scene", "scene statistics of LiDAR inputs", kSceneAbout);
	auto o = std::make_shared<SceneOptions>();
	sub->add_option("INPUT", o->inputs, "rawlogs or folders of KITTI .bin scans")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingPath))
	    ->type_name("PATH");
	sub->add_option("--label", o->labels, "a column's name, once per INPUT in order")
	    ->allow_extra_args(false)  // --label A in1 --label B in2: A and B only
	    ->type_name("NAME");
	sub->add_option("--every", o->every, "use every N-th scan")
	    ->check(wholeNumber(1, 1000000))
	    ->type_name("N");
	sub->add_option("--max-scans", o->maxScans, "use at most N scans of each input (0: all)")
	    ->check(wholeNumber(0, 100000000))
	    ->type_name("N");
	sub->add_flag("--json", o->json, "print one JSON array instead of text");
	return {sub, [o] { return runScene(*o); }};
}
}  // namespace rasterslam_eval_cli
