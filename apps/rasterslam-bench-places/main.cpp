// rasterslam-bench-places: how well the bag-of-words database ranks the true place among
// many distractors. Places are scans of several simulated towns (one database entry a place,
// every few metres of each town's route); queries are scans of the same towns from other
// poses (to the side, turned, or driven the other way) with other noise. Reports recall@1 and
// recall@5 against a random ranking, and the query time.
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/registerAllClasses.h>
#include <rasterslam/bow/vocabulary.h>
#include <rasterslam/cli/app.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/raster/elevation_image.h>
#include <rasterslam/sim/simulator.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace cli = rasterslam::cli;
using namespace rasterslam;

namespace
{
const char* kDescription =
    "rasterslam-bench-places: ranks the true place among many simulated distractor places with "
    "the BOW database (vocabulary tree, TF-IDF, L1 score) and reports recall@1, recall@5 and "
    "the query time. A place is the elevation image of one scan (the system indexes local-map "
    "images; this measures the ranking alone, without verification).";

struct Args
{
	std::string scenario, vocabulary;
	int towns = 20;
	long long seed0 = 1000;
	double every_m = 8, offset_m = 3, yaw_deg = 20, truth_m = 8;
	int queriesPerTown = 6;
	bool json = false;
};

struct Place
{
	int town = 0;
	Eigen::Vector3d position;
};

bool gCanonical = false;

bow::BowVector wordsOf(const Scan& scan, const bow::Vocabulary& vocab, features::OrbExtractor& orb,
                       uint32_t seed)
{
	const raster::Plane plane = raster::fitGroundPlane(scan.points, raster::GroundParams(), seed);
	raster::RasterParams rp;
	rp.canonicalYaw = gCanonical;
	RasterFrame f;
	raster::rasterizeElevation(scan.points, plane, rp, f);
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb.extract(f.image.asCvMatRef(), kps, desc);
	bow::BowVector b;
	vocab.transform(bow::toDescriptors(desc.ptr<uint8_t>(), desc.empty() ? 0 : desc.rows), b);
	return b;
}

int run(const Args& a)
{
	const auto vocab = bow::loadVocabularyFile(a.vocabulary);
	features::OrbParams op;
	op.numFeatures = 3000;  // as the loop detector's queries
	op.levels = 3;
	features::OrbExtractor orb(op);
	bow::Database db;
	std::vector<Place> places;  // by entry id order of insertion
	std::vector<bow::Database::EntryId> ids;
	struct Query
	{
		int town;
		Eigen::Vector3d position;
		bow::BowVector words;
		bool opposite;
	};
	std::vector<Query> queries;
	const auto t0 = std::chrono::steady_clock::now();
	for (int t = 0; t < a.towns; t++)
	{
		sim::Scenario sc = sim::loadScenario(a.scenario);
		sc.seed = static_cast<uint32_t>(a.seed0 + t);
		sc.threads = 2;
		const sim::Simulator s = sim::Simulator::fromScenario(sc);
		// Metres a scan and scans a lap; a vehicle that slows for corners (corner_accel_mps2)
		// takes lapTime() over it, and a scan is then the mean step.
		const bool slows = sc.corner_accel_mps2 > 0;
		const double step =
		    slows ? s.route().length() / (s.lapTime() * sc.rate_hz) : sc.speed_mps / sc.rate_hz;
		const auto every = std::max<std::size_t>(1, static_cast<std::size_t>(a.every_m / step));
		const auto lap = static_cast<std::size_t>(s.route().length() / step);
		for (std::size_t k = 0; k < lap; k += every)
		{
			const auto pose = s.sensorPose(k);
			const Scan scan = s.scanFrom(pose, k, s.stamp(k));
			ids.push_back(db.add(wordsOf(scan, *vocab, orb, static_cast<uint32_t>(k + 1))));
			places.push_back({t, Eigen::Vector3d(pose.x(), pose.y(), pose.z())});
		}
		// Queries half-way between places, spread over the lap: to the side and turned,
		// alternately driven the other way; noise drawn for other scan indices.
		for (int q = 0; q < a.queriesPerTown; q++)
		{
			const std::size_t k = (lap * static_cast<std::size_t>(2 * q + 1)) /
			                          static_cast<std::size_t>(2 * a.queriesPerTown) +
			                      every / 2;
			const double side = (q % 2 ? -1 : 1) * a.offset_m;
			const double yaw = (q % 2 ? 180.0 : a.yaw_deg) * M_PI / 180;
			const auto pose = s.sensorPose(k) + mrpt::poses::CPose3D(0, side, 0, yaw, 0, 0);
			const Scan scan = s.scanFrom(pose, 1000000 + k, s.stamp(k));
			queries.push_back({t, Eigen::Vector3d(pose.x(), pose.y(), pose.z()),
			                   wordsOf(scan, *vocab, orb, static_cast<uint32_t>(k + 7)),
			                   q % 2 == 1});
		}
	}
	const double tBuild =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

	std::size_t at1 = 0, at5 = 0, withTruth = 0, opp = 0, oppAt5 = 0;
	std::vector<double> ms;
	for (const auto& q : queries)
	{
		const auto tq = std::chrono::steady_clock::now();
		const auto res = db.query(q.words, 5);
		ms.push_back(
		    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - tq)
		        .count());
		const auto isTrue = [&](bow::Database::EntryId e)
		{
			const auto i =
			    static_cast<std::size_t>(std::find(ids.begin(), ids.end(), e) - ids.begin());
			return places[i].town == q.town &&
			       (places[i].position - q.position).head<2>().norm() <= a.truth_m;
		};
		bool any = false;
		for (std::size_t i = 0; i < places.size(); i++)
			any = any || (places[i].town == q.town &&
			              (places[i].position - q.position).head<2>().norm() <= a.truth_m);
		if (!any)
			continue;
		withTruth++;
		opp += q.opposite;
		for (std::size_t r = 0; r < res.size(); r++)
			if (isTrue(res[r].entry))
			{
				at1 += r == 0;
				at5++;
				oppAt5 += q.opposite;
				break;
			}
	}
	std::sort(ms.begin(), ms.end());
	const double median = ms.empty() ? 0 : ms[ms.size() / 2], worst = ms.empty() ? 0 : ms.back();
	const double r1 = withTruth ? static_cast<double>(at1) / static_cast<double>(withTruth) : 0,
	             r5 = withTruth ? static_cast<double>(at5) / static_cast<double>(withTruth) : 0;
	// A random ranking finds one of the ~2 true places among the top 5 this often.
	double truePerQuery = 0;
	for (const auto& q : queries)
		for (const auto& p : places)
			truePerQuery +=
			    p.town == q.town && (p.position - q.position).head<2>().norm() <= a.truth_m;
	truePerQuery /= std::max<std::size_t>(1, queries.size());
	const double random5 = std::min(1.0, 5.0 * truePerQuery / static_cast<double>(places.size()));
	if (a.json)
	{
		nlohmann::ordered_json j;
		j["towns"] = a.towns;
		j["places"] = places.size();
		j["queries"] = withTruth;
		j["recall_at_1"] = r1;
		j["recall_at_5"] = r5;
		j["random_recall_at_5"] = random5;
		j["recall_at_5_same_way"] = withTruth > opp ? static_cast<double>(at5 - oppAt5) /
		                                                  static_cast<double>(withTruth - opp)
		                                            : 0.0;
		j["recall_at_5_other_way"] =
		    opp ? static_cast<double>(oppAt5) / static_cast<double>(opp) : 0.0;
		j["query_ms_median"] = median;
		j["query_ms_max"] = worst;
		j["build_s"] = tBuild;
		std::cout << j.dump() << "\n";
		return 0;
	}
	std::printf(
	    "%d towns, %zu places (every %.0f m), %zu queries (%.0f m aside, turned %.0f deg or "
	    "driven the other way); built in %.1f s\n"
	    "recall@1 %.3f, recall@5 %.3f (random ranking: %.4f; recall@5 same way %zu of %zu, "
	    "other way %zu of %zu); query %.3f ms median, %.3f ms max\n",
	    a.towns, places.size(), a.every_m, withTruth, a.offset_m, a.yaw_deg, tBuild, r1, r5,
	    random5, at5 - oppAt5, withTruth - opp, oppAt5, opp, median, worst);
	return 0;
}
}  // namespace

int main(int argc, char** argv)
{
	Args args;
	CLI::App app(kDescription, "rasterslam-bench-places");
	cli::configure(app);
	app.add_option("--scenario", args.scenario, "scenario of the towns (their seeds vary)")
	    ->required()
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE");
	app.add_option("--vocabulary", args.vocabulary, "vocabulary file")
	    ->required()
	    ->check(CLI::ExistingFile.description(""))
	    ->type_name("FILE");
	app.add_option("--towns", args.towns, "towns (default 20)")
	    ->check(CLI::Range(1, 100000).description(""))
	    ->type_name("N");
	app.add_option("--seed", args.seed0, "seed of the first town; the others follow (1000)")
	    ->check(CLI::Range(0LL, 0xFFFFFFFFLL).description(""))
	    ->type_name("S");
	app.add_option("--every", args.every_m, "metres between places along a route (8)")
	    ->check(CLI::Range(0.5, 1000.0).description(""))
	    ->type_name("M");
	app.add_option("--queries", args.queriesPerTown, "queries a town (6)")
	    ->check(CLI::Range(1, 1000).description(""))
	    ->type_name("N");
	app.add_option("--offset", args.offset_m, "queries this far to the side (3 m)")
	    ->check(CLI::Range(0.0, 50.0).description(""))
	    ->type_name("M");
	app.add_option("--yaw", args.yaw_deg, "same-way queries turned by this (20 deg)")
	    ->check(CLI::Range(-180.0, 180.0).description(""))
	    ->type_name("DEG");
	app.add_option("--truth", args.truth_m, "a place within this of the query is true (8 m)")
	    ->check(CLI::Range(0.1, 1000.0).description(""))
	    ->type_name("M");
	app.add_flag("--json", args.json, "print one JSON object");
	app.add_flag("--canonical", gCanonical,
	             "rasterize each scan turned so that its dominant edges run along the image axes");
	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;
	mrpt::maps::registerAllClasses_mrpt_maps();
	mrpt::obs::registerAllClasses_mrpt_obs();
	try
	{
		return run(args);
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam-bench-places: error: " << e.what() << "\n";
		return cli::kExitError;
	}
}
