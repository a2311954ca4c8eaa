// rasterslam-eval localmaps: how well the keyframes of each local map agree with the ground
// truth relative to each other (what local BA refines).
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/map/map.h>

#include <algorithm>

#include "cli.h"

namespace rasterslam_eval_cli
{
namespace
{
// Below the options in --help (the formatter wraps it at 100 columns, keeping line breaks).
const char* kLocalMapsAbout =
    "Relative errors inside local maps: for every local map of the map DIR (--map; written by "
    "rasterslam run --map-out) and every pair of its keyframes, the keyframes' relative pose "
    "against the ground truth G (--gt; TUM, a run's groundtruth.tum) at their stamps. Also the "
    "local BA figures the map stores (tracks, RMS residual before and after).";

struct LocalMapsOptions
{
	std::string map, gt;
	double maxDt = 0.02;
	bool json = false;
};

double median(std::vector<double> v)
{
	if (v.empty())
		return std::nan("");
	std::sort(v.begin(), v.end());
	return v[v.size() / 2];
}
double mean(const std::vector<double>& v)
{
	if (v.empty())
		return std::nan("");
	double s = 0;
	for (const double x : v)
		s += x;
	return s / static_cast<double>(v.size());
}

int runLocalMaps(const LocalMapsOptions& o)
{
	const std::string& mapDir = o.map;
	const std::string& gtFile = o.gt;
	const double maxDt = o.maxDt;
	const auto map = rasterslam::loadMap(mapDir);
	const auto gt = io::loadTrajectory(gtFile);
	if (gt.empty())
		throw std::runtime_error("'" + gtFile + "' holds no pose");
	auto gtAt = [&](double stamp) -> const Eigen::Isometry3d*
	{
		const auto it =
		    std::lower_bound(gt.begin(), gt.end(), stamp,
		                     [](const io::StampedPose& p, double t) { return p.stamp < t; });
		const io::StampedPose* best = nullptr;
		if (it != gt.end())
			best = &*it;
		if (it != gt.begin() &&
		    (!best || std::abs(std::prev(it)->stamp - stamp) < std::abs(best->stamp - stamp)))
			best = &*std::prev(it);
		return best && std::abs(best->stamp - stamp) <= maxDt ? &best->pose : nullptr;
	};
	std::vector<double> et, er, exy, ez, eyaw, tracks, rms0, rms1;
	std::size_t maps = 0, missing = 0;
	for (const auto& [id, lm] : map.localMaps)
	{
		if (lm->keyframes.size() < 2)
			continue;
		++maps;
		if (lm->baTracks > 0)
		{
			tracks.push_back(lm->baTracks);
			rms0.push_back(lm->baInitialRms_m);
			rms1.push_back(lm->baFinalRms_m);
		}
		for (std::size_t i = 0; i < lm->keyframes.size(); i++)
			for (std::size_t j = i + 1; j < lm->keyframes.size(); j++)
			{
				const auto& ki = *map.keyframes.at(lm->keyframes[i]);
				const auto& kj = *map.keyframes.at(lm->keyframes[j]);
				const auto* gi = gtAt(ki.stamp);
				const auto* gj = gtAt(kj.stamp);
				if (!gi || !gj)
				{
					++missing;
					continue;
				}
				const Eigen::Isometry3d est =
				    rasterslam::toIsometry(map.priorPoses.at(ki.id)).inverse() *
				    rasterslam::toIsometry(map.priorPoses.at(kj.id));
				const Eigen::Isometry3d truth = gi->inverse() * *gj;
				const Eigen::Isometry3d d = truth.inverse() * est;
				et.push_back(d.translation().norm());
				er.push_back(Eigen::AngleAxisd(d.linear()).angle() * 180 / M_PI);
				exy.push_back(d.translation().head<2>().norm());
				ez.push_back(std::abs(d.translation().z()));
				eyaw.push_back(std::abs(std::atan2(d.linear()(1, 0), d.linear()(0, 0))) * 180 /
				               M_PI);
			}
	}
	if (et.empty())
		throw std::runtime_error("no keyframe pair of a local map has ground truth");
	if (o.json)
	{
		Json j;
		j["local_maps"] = maps;
		j["pairs"] = et.size();
		j["pairs_without_gt"] = missing;
		j["trans_err_mean_m"] = jsonNumber(mean(et));
		j["trans_err_median_m"] = jsonNumber(median(et));
		j["rot_err_mean_deg"] = jsonNumber(mean(er));
		j["horizontal_err_mean_m"] = jsonNumber(mean(exy));
		j["vertical_err_mean_m"] = jsonNumber(mean(ez));
		j["yaw_err_mean_deg"] = jsonNumber(mean(eyaw));
		j["ba_maps"] = tracks.size();
		j["ba_tracks_mean"] = jsonNumber(mean(tracks), !tracks.empty());
		j["ba_rms_before_m"] = jsonNumber(mean(rms0), !rms0.empty());
		j["ba_rms_after_m"] = jsonNumber(mean(rms1), !rms1.empty());
		std::cout << jsonLine(j);
		return 0;
	}
	std::printf(
	    "local maps   : %zu with 2 or more keyframes, %zu keyframe pairs (%zu without ground "
	    "truth)\n"
	    "relative err: translation mean %.4f m, median %.4f m; rotation mean %.4f deg\n"
	    "  of which  : horizontal %.4f m, vertical %.4f m, yaw %.4f deg\n",
	    maps, et.size(), missing, mean(et), median(et), mean(er), mean(exy), mean(ez), mean(eyaw));
	if (!tracks.empty())
		std::printf("local BA    : %zu maps, %.0f tracks a map, RMS residual %.3f -> %.3f m\n",
		            tracks.size(), mean(tracks), mean(rms0), mean(rms1));
	return 0;
}

}  // namespace

Command addLocalMaps(CLI::App& app)
{
	CLI::App* sub =
	    cli::subcommand(app, "localmaps", "relative errors between the keyframes of each local map",
	                    kLocalMapsAbout);
	auto o = std::make_shared<LocalMapsOptions>();
	sub->add_option("--map", o->map, "a saved map DIR")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingDirectory))
	    ->type_name("DIR");
	sub->add_option("--gt", o->gt, "ground-truth TUM trajectory G")
	    ->required()
	    ->check(cli::unnamed(CLI::ExistingFile))
	    ->type_name("FILE");
	sub->add_option("--max-dt", o->maxDt, "largest stamp difference to the ground truth (s)")
	    ->check(nonNegativeNumber())
	    ->type_name("S")
	    ->capture_default_str();
	sub->add_flag("--json", o->json, "print one JSON object instead of text");
	return {sub, [o] { return runLocalMaps(*o); }};
}

}  // namespace rasterslam_eval_cli
