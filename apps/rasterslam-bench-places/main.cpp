// rasterslam-bench-places: how well the bag-of-words database ranks the true place among
// many distractors. Places are scans of several simulated towns (one database entry a place,
// every few metres of each town's route), or with --local-maps local-map images as the map
// manager makes them (the non-ground points of 5 keyframes in the first one's frame, poses
// from the simulator); queries are scans of the same towns from other poses (to the side,
// turned, or driven the other way) with other noise, and with --other-towns scans of towns
// that are not in the database. Reports recall@1 and recall@5 against a random ranking, the
// precision-recall curve of the best place's normalized score, and the query time.
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/registerAllClasses.h>
#include <rasterslam/bow/vocabulary.h>
#include <rasterslam/cli/app.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/raster/elevation_image.h>
#include <rasterslam/sim/simulator.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace cli = rasterslam::cli;
using namespace rasterslam;

namespace
{
const char* kDescription =
    "rasterslam-bench-places: ranks the true place among many simulated distractor places with "
    "the BOW database (vocabulary tree, TF-IDF, L1 score) and reports recall@1, recall@5, the "
    "precision-recall curve of the best place's normalized score and the query time. A place "
    "is the elevation image of one scan, or with --local-maps a local-map image as the map "
    "manager makes it; this measures the ranking alone, without verification.";

struct Args
{
	std::string scenario, vocabulary;
	int towns = 20;
	long long seed0 = 1000;
	double every_m = 8, offset_m = 3, yaw_deg = 20, truth_m = 8;
	int queriesPerTown = 6;
	bool json = false;
	bool localMaps = false, queryLocalMaps = false;
	int keyframes = 5;
	double keyframeEvery_m = 4;
	int otherTowns = 0;
};

struct Place
{
	int town = 0;
	std::vector<Eigen::Vector3d> positions;  //!< of its scan, or of its local map's keyframes
	double distanceTo(const Eigen::Vector3d& p) const
	{
		double d = std::numeric_limits<double>::infinity();
		for (const auto& q : positions)
			d = std::min(d, (q - p).head<2>().norm());
		return d;
	}
};

bool gCanonical = false;

std::vector<bow::Descriptor> descriptorsOf(const cv::Mat& image, features::OrbExtractor& orb)
{
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb.extract(image, kps, desc);
	return bow::toDescriptors(desc.ptr<uint8_t>(), desc.empty() ? 0 : desc.rows);
}

RasterFrame rasterOf(const Scan& scan, uint32_t seed)
{
	const raster::Plane plane = raster::fitGroundPlane(scan.points, raster::GroundParams(), seed);
	raster::RasterParams rp;
	rp.canonicalYaw = gCanonical;
	RasterFrame f;
	raster::rasterizeElevation(scan.points, plane, rp, f);
	return f;
}

/** A scan's words and (as the loop detector normalizes a query with no previous keyframe)
 *  the score of its even features against its odd ones. */
bow::BowVector wordsOf(const Scan& scan, const bow::Vocabulary& vocab, features::OrbExtractor& orb,
                       uint32_t seed, double* selfScore = nullptr)
{
	const auto desc = descriptorsOf(rasterOf(scan, seed).image.asCvMatRef(), orb);
	bow::BowVector b;
	vocab.transform(desc, b);
	if (selfScore)
		*selfScore = vocab.selfScore(desc);
	return b;
}

/** The local-map image of scans at `poses` (the map manager's way): each scan's projected
 *  points (its image's, ground removed) moved into the first scan's frame, rasterized with
 *  the map manager's defaults (0.2 m a pixel, +-60 m, no ground removal). */
bow::BowVector localMapWords(const std::vector<Scan>& scans,
                             const std::vector<mrpt::poses::CPose3D>& poses,
                             const bow::Vocabulary& vocab, features::OrbExtractor& orb,
                             uint32_t seed, double* selfScore = nullptr)
{
	std::vector<PointXYZI> pts;
	for (std::size_t i = 0; i < scans.size(); i++)
	{
		const RasterFrame f = rasterOf(scans[i], seed + static_cast<uint32_t>(i));
		const Eigen::Isometry3f T = toIsometry(poses[i] - poses[0]).cast<float>();
		for (const auto idx : f.pixelToPoint)
			if (idx >= 0)
			{
				const auto& q = scans[i].points[static_cast<std::size_t>(idx)];
				const Eigen::Vector3f w = T * Eigen::Vector3f(q.x, q.y, q.z);
				pts.push_back({w.x(), w.y(), w.z(), q.intensity});
			}
	}
	raster::RasterParams mp = raster::localMapRasterParams();
	mp.canonicalYaw = gCanonical;
	RasterFrame img;
	raster::rasterizeElevation(pts, raster::Plane(), mp, img);
	const auto desc = descriptorsOf(img.image.asCvMatRef(), orb);
	bow::BowVector b;
	vocab.transform(desc, b);
	if (selfScore)
		*selfScore = vocab.selfScore(desc);
	return b;
}

int run(const Args& a)
{
	const auto vocab = bow::loadVocabularyFile(a.vocabulary);
	features::OrbParams op;
	op.numFeatures = 3000;  // as the loop detector's queries and the map manager's images
	op.levels = 3;
	features::OrbExtractor orb(op);
	bow::Database db;
	std::vector<Place> places;  // by entry id order of insertion
	std::vector<bow::Database::EntryId> ids;
	struct Query
	{
		int town;  // -1: a town not in the database
		Eigen::Vector3d position;
		bow::BowVector words;
		double selfScore;
		bool opposite;
	};
	std::vector<Query> queries;
	const auto t0 = std::chrono::steady_clock::now();
	std::size_t scansSimulated = 0;
	for (int t = 0; t < a.towns + a.otherTowns; t++)
	{
		const bool other = t >= a.towns;  // queries only: its places are not in the database
		sim::Scenario sc = sim::loadScenario(a.scenario);
		sc.seed = static_cast<uint32_t>(a.seed0 + t);
		sc.threads = 2;
		const sim::Simulator s = sim::Simulator::fromScenario(sc);
		// Metres a scan and scans a lap; a vehicle that slows for corners (corner_accel_mps2)
		// takes lapTime() over it, and a scan is then the mean step.
		const bool slows = sc.corner_accel_mps2 > 0;
		const double step =
		    slows ? s.route().length() / (s.lapTime() * sc.rate_hz) : sc.speed_mps / sc.rate_hz;
		const auto lap = static_cast<std::size_t>(s.route().length() / step);
		// A local map: `keyframes` keyframes `keyframeEvery_m` apart, and the next one starts
		// at its last keyframe (as the map manager's consecutive maps share one).
		const auto kfEvery =
		    std::max<std::size_t>(1, static_cast<std::size_t>(a.keyframeEvery_m / step));
		const auto every =
		    a.localMaps ? kfEvery * static_cast<std::size_t>(std::max(1, a.keyframes - 1))
		                : std::max<std::size_t>(1, static_cast<std::size_t>(a.every_m / step));
		for (std::size_t k = 0; !other && k < lap; k += every)
		{
			Place place;
			place.town = t;
			if (a.localMaps)
			{
				std::vector<Scan> scans;
				std::vector<mrpt::poses::CPose3D> poses;
				for (int i = 0; i < a.keyframes; i++)
				{
					const std::size_t kk = (k + static_cast<std::size_t>(i) * kfEvery) % lap;
					poses.push_back(s.sensorPose(kk));
					scans.push_back(s.scanFrom(poses.back(), kk, s.stamp(kk)));
					place.positions.emplace_back(poses.back().x(), poses.back().y(),
					                             poses.back().z());
				}
				scansSimulated += scans.size();
				ids.push_back(
				    db.add(localMapWords(scans, poses, *vocab, orb, static_cast<uint32_t>(k + 1))));
			}
			else
			{
				const auto pose = s.sensorPose(k);
				const Scan scan = s.scanFrom(pose, k, s.stamp(k));
				++scansSimulated;
				ids.push_back(db.add(wordsOf(scan, *vocab, orb, static_cast<uint32_t>(k + 1))));
				place.positions.emplace_back(pose.x(), pose.y(), pose.z());
			}
			places.push_back(std::move(place));
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
			const mrpt::poses::CPose3D aside(0, side, 0, yaw, 0, 0);
			const auto pose = s.sensorPose(k) + aside;
			double self = 0;
			bow::BowVector words;
			if (a.queryLocalMaps)
			{
				// A local map of the query's drive around k, its keyframes in the order of
				// that drive (the other way: from the far end).
				std::vector<Scan> scans;
				std::vector<mrpt::poses::CPose3D> poses;
				for (int i = 0; i < a.keyframes; i++)
				{
					const long step =
					    (q % 2 ? -1L : 1L) * (i - a.keyframes / 2) * static_cast<long>(kfEvery);
					const long n = static_cast<long>(lap);
					const auto kk =
					    static_cast<std::size_t>(((static_cast<long>(k) + step) % n + n) % n);
					poses.push_back(s.sensorPose(kk) + aside);
					scans.push_back(s.scanFrom(poses.back(), 1000000 + kk, s.stamp(kk)));
				}
				scansSimulated += scans.size();
				words =
				    localMapWords(scans, poses, *vocab, orb, static_cast<uint32_t>(k + 7), &self);
			}
			else
			{
				const Scan scan = s.scanFrom(pose, 1000000 + k, s.stamp(k));
				++scansSimulated;
				words = wordsOf(scan, *vocab, orb, static_cast<uint32_t>(k + 7), &self);
			}
			queries.push_back({other ? -1 : t, Eigen::Vector3d(pose.x(), pose.y(), pose.z()),
			                   std::move(words), self, q % 2 == 1});
		}
	}
	const double tBuild =
	    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

	std::size_t at1 = 0, at5 = 0, withTruth = 0, opp = 0, oppAt5 = 0, others = 0;
	std::vector<double> ms;
	// The best place of each query: its normalized score, and whether it is a true place
	// (false for every query of another town).
	std::vector<std::pair<double, bool>> best;
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
			return places[i].town == q.town && places[i].distanceTo(q.position) <= a.truth_m;
		};
		if (!res.empty())
			best.emplace_back(q.selfScore > 1e-6 ? res.front().score / q.selfScore : 0,
			                  q.town >= 0 && isTrue(res.front().entry));
		if (q.town < 0)
		{
			++others;
			continue;
		}
		bool any = false;
		for (const auto& p : places)
			any = any || (p.town == q.town && p.distanceTo(q.position) <= a.truth_m);
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
	std::size_t ownQueries = 0;
	for (const auto& q : queries)
	{
		if (q.town < 0)
			continue;
		++ownQueries;
		for (const auto& p : places)
			truePerQuery += p.town == q.town && p.distanceTo(q.position) <= a.truth_m;
	}
	truePerQuery /= static_cast<double>(std::max<std::size_t>(1, ownQueries));
	const double random5 = std::min(1.0, 5.0 * truePerQuery / static_cast<double>(places.size()));
	// The precision-recall curve of accepting a query's best place when its normalized score
	// reaches a bound (the loop detector's min_score, before any verification): recall over
	// the queries that have a true place, precision over everything accepted (queries of
	// other towns included).
	struct PrPoint
	{
		double bound, precision, recall;
	};
	std::vector<PrPoint> curve;
	double recallAtPrecision1 = 0;
	{
		auto sorted = best;
		std::sort(sorted.begin(), sorted.end(),
		          [](const auto& x, const auto& y) { return x.first > y.first; });
		std::size_t accepted = 0, right = 0;
		for (std::size_t i = 0; i < sorted.size(); i++)
		{
			++accepted;
			right += sorted[i].second;
			// A bound sits between two different scores.
			if (i + 1 < sorted.size() && sorted[i + 1].first == sorted[i].first)
				continue;
			const double precision = static_cast<double>(right) / static_cast<double>(accepted);
			const double recall =
			    withTruth ? static_cast<double>(right) / static_cast<double>(withTruth) : 0;
			curve.push_back({sorted[i].first, precision, recall});
			if (right == accepted)
				recallAtPrecision1 = recall;
		}
	}
	if (a.json)
	{
		nlohmann::ordered_json j;
		j["towns"] = a.towns;
		j["places"] = places.size();
		j["place_kind"] = a.localMaps ? "local_map" : "scan";
		j["query_kind"] = a.queryLocalMaps ? "local_map" : "scan";
		j["scans_simulated"] = scansSimulated;
		j["queries"] = withTruth;
		j["other_town_queries"] = others;
		j["recall_at_1"] = r1;
		j["recall_at_5"] = r5;
		j["random_recall_at_5"] = random5;
		j["recall_at_5_same_way"] = withTruth > opp ? static_cast<double>(at5 - oppAt5) /
		                                                  static_cast<double>(withTruth - opp)
		                                            : 0.0;
		j["recall_at_5_other_way"] =
		    opp ? static_cast<double>(oppAt5) / static_cast<double>(opp) : 0.0;
		j["answered_queries"] = best.size();
		j["recall_at_precision_1"] = recallAtPrecision1;
		auto& c = j["pr_curve"] = nlohmann::ordered_json::array();
		for (const auto& p : curve)
			c.push_back({{"min_score", p.bound}, {"precision", p.precision}, {"recall", p.recall}});
		j["query_ms_median"] = median;
		j["query_ms_max"] = worst;
		j["build_s"] = tBuild;
		std::cout << j.dump() << "\n";
		return 0;
	}
	std::printf(
	    "%d towns, %zu places (%s), %zu queries (%.0f m aside, turned %.0f deg or driven the "
	    "other way), %zu of other towns; %zu scans simulated, built in %.1f s\n"
	    "recall@1 %.3f, recall@5 %.3f (random ranking: %.4f; recall@5 same way %zu of %zu, "
	    "other way %zu of %zu); query %.3f ms median, %.3f ms max\n",
	    a.towns, places.size(),
	    a.localMaps ? (std::to_string(a.keyframes) + " keyframes " +
	                   std::to_string(a.keyframeEvery_m).substr(0, 4) + " m apart each")
	                      .c_str()
	                : ("every " + std::to_string(a.every_m).substr(0, 4) + " m").c_str(),
	    withTruth, a.offset_m, a.yaw_deg, others, scansSimulated, tBuild, r1, r5, random5,
	    at5 - oppAt5, withTruth - opp, oppAt5, opp, median, worst);
	// The curve, thinned to about 12 rows.
	std::printf(
	    "best place accepted when its normalized score reaches:\n  min_score  precision  recall\n");
	const std::size_t stride = std::max<std::size_t>(1, curve.size() / 12);
	for (std::size_t i = 0; i < curve.size(); i++)
		if (i % stride == 0 || i + 1 == curve.size())
			std::printf("  %9.3f  %9.3f  %6.3f\n", curve[i].bound, curve[i].precision,
			            curve[i].recall);
	std::printf("recall at precision 1: %.3f\n", recallAtPrecision1);
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
	app.add_flag("--local-maps", args.localMaps,
	             "a place is a local-map image (--keyframes scans --keyframe-every m apart, the "
	             "map manager's way) instead of one scan's image");
	app.add_flag("--query-local-maps", args.queryLocalMaps,
	             "the queries are local-map images too (of their own drive, centred on the query "
	             "pose) instead of one scan's image");
	app.add_option("--keyframes", args.keyframes,
	               "keyframes a local map, of places and local-map queries (5)")
	    ->check(CLI::Range(1, 32).description(""))
	    ->type_name("N");
	app.add_option("--keyframe-every", args.keyframeEvery_m,
	               "metres between the keyframes of a local map (4)")
	    ->check(CLI::Range(0.5, 100.0).description(""))
	    ->type_name("M");
	app.add_option("--other-towns", args.otherTowns,
	               "also --queries queries from each of N towns not in the database (0)")
	    ->check(CLI::Range(0, 100000).description(""))
	    ->type_name("N");
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
