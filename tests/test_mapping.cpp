// The map manager end to end on the simulated VLP-16 drive (rawlogs/town-vlp16.yaml, a 199 m
// block loop): local maps overlap and carry the optimized poses, keyframes give up their
// features once mapped, online poses are those a robot had, wrong loop edges are
// down-weighted by the robust loss, and local BA is deterministic.
#include <mrpt/core/format.h>
#include <mrpt/graphs/CNetworkOfPoses.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/registerAllClasses.h>
#include <rasterslam/io/trajectory_io.h>
#include <rasterslam/map/map.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "test_json.h"
#include "test_support.h"

using namespace rasterslam;
namespace fs = std::filesystem;

using test::jsonNumber;

namespace
{
const std::string& vlp16Rawlog()
{
	return test::townVlp16Rawlog();
}

/** slam.yaml (the vocabulary path made absolute), local BA on or off, extra engine lines. */
fs::path slamConfig(const fs::path& dir, bool localBa, const std::string& engineExtra)
{
	std::string y = test::shippedConfig("slam.yaml");
	y = std::regex_replace(y, std::regex("local_ba: false"),
	                       localBa ? "local_ba: true" : "local_ba: false");
	if (!engineExtra.empty())
		y = std::regex_replace(y, std::regex("\nengine:\n"), "\nengine:\n" + engineExtra);
	const auto p = dir / "cfg.yaml";
	std::ofstream(p) << y;
	return p;
}

test::CommandResult run(const fs::path& cfg, const fs::path& out, const std::string& extra = "")
{
	return test::runCommand(test::bin("rasterslam") + " run --rawlog " + vlp16Rawlog() +
	                        " --config " + cfg.string() + " --quiet --out " + out.string() + extra);
}

double yamlNumber(const fs::path& runYaml, const std::string& key)
{
	std::ifstream f(runYaml);
	const std::string y((std::istreambuf_iterator<char>(f)), {});
	std::smatch m;
	if (!std::regex_search(y, m, std::regex("\\b" + key + ": ([-0-9.eE+]+)")))
		return std::nan("");
	return std::stod(m[1]);
}

double ate(const fs::path& out, const std::string& est = "trajectory.tum")
{
	const auto r = test::runCommand(test::bin("rasterslam-eval") + " traj --gt " +
	                                (out / "groundtruth.tum").string() + " --est " +
	                                (out / est).string() + " --json");
	EXPECT_EQ(r.exitCode, 0) << r.output;
	return jsonNumber(r.output, "ate_rmse_m");
}
}  // namespace

TEST(Mapping, LocalMapsOverlapAndCarryTheOptimizedPoses)
{
	const test::ScopedTempDir dir("mapping");
	const auto r =
	    run(slamConfig(dir.path(), false, ""), dir / "out", " --map-out " + (dir / "map").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const Map map = loadMap((dir / "map").string());
	const auto keyframes = static_cast<std::size_t>(yamlNumber(dir / "out/run.yaml", "keyframes"));
	ASSERT_EQ(map.keyframes.size(), keyframes);
	ASSERT_GE(map.localMaps.size(), 5u);
	EXPECT_EQ(static_cast<std::size_t>(yamlNumber(dir / "out/run.yaml", "local_maps")),
	          map.localMaps.size());

	// Consecutive local maps share their boundary keyframe; every keyframe is in one or two.
	LocalMap::ConstPtr prev;
	for (const auto& [id, stub] : map.localMaps)
	{
		const auto lm = map.data(id);  // read from the map's store
		EXPECT_LE(lm->keyframes.size(), 5u);
		EXPECT_EQ(lm->keyframes, stub->keyframes);
		EXPECT_LE(lm->createdStamp, lm->updatedStamp);
		EXPECT_EQ(lm->points(), lm->observers.size());
		EXPECT_EQ(lm->points(), map.saved.at(id).points);
		EXPECT_GT(lm->points(), 100u);
		EXPECT_FALSE(lm->imagePng.empty());
		// slam.yaml keeps the keyframes' surfaces (surface_voxel_m: 0.5) in the anchor's
		// frame: the map points (features, also in that frame) lie on them.
		ASSERT_GT(lm->surfacePoints(), 1000u) << "local map " << id;
		std::size_t onSurface = 0;
		for (std::size_t i = 0; i < lm->points(); i++)
		{
			const Eigen::Vector3f p(lm->xyz[3 * i], lm->xyz[3 * i + 1], lm->xyz[3 * i + 2]);
			for (std::size_t k = 0; k < lm->surfaceCm.size(); k += 3)
				if ((Eigen::Vector3f(lm->surfaceCm[k], lm->surfaceCm[k + 1], lm->surfaceCm[k + 2]) *
				         0.01f -
				     p)
				        .squaredNorm() < 0.5f * 0.5f)
				{
					++onSurface;
					break;
				}
		}
		EXPECT_GT(static_cast<double>(onSurface), 0.8 * static_cast<double>(lm->points()))
		    << "local map " << id;
		if (prev)
		{
			EXPECT_EQ(lm->keyframes.front(), prev->keyframes.back()) << "local map " << id;
		}
		prev = lm;
	}
	for (const auto& [k, kf] : map.keyframes)
	{
		const auto n = map.localMapsOf(k).size();
		EXPECT_TRUE(n == 1 || n == 2) << "keyframe " << k << " in " << n << " local maps";
		// Mapped keyframes hold no features: the local maps' points have them.
		EXPECT_EQ(kf->size(), 0u) << "keyframe " << k;
	}
	// The local-map graph: one sequential edge between consecutive maps, a loop edge for each
	// pair of local maps the run's loops joined (several loops may join one pair).
	EXPECT_EQ(map.graph.count(LocalMapGraph::EdgeKind::Sequential), map.localMaps.size() - 1);
	const auto loops = static_cast<std::size_t>(yamlNumber(dir / "out/run.yaml", "loop_edges"));
	ASSERT_GE(loops, 2u);
	EXPECT_GE(map.graph.count(LocalMapGraph::EdgeKind::Loop), 1u);
	EXPECT_LE(map.graph.count(LocalMapGraph::EdgeKind::Loop), loops);

	// Saved keyframe poses (so the local maps' anchors) are the final, optimized ones: the
	// trajectory's poses at the keyframes' stamps.
	const auto traj = io::loadTrajectory((dir / "out/trajectory.tum").string());
	std::size_t checked = 0;
	for (const auto& [id, lm] : map.localMaps)
	{
		const auto& anchor = *map.keyframes.at(lm->anchor());
		for (const auto& p : traj)
			if (std::abs(p.stamp - anchor.stamp) < 1e-6)
			{
				const auto& q = map.priorPoses.at(anchor.id);
				EXPECT_LT((p.pose.translation() - Eigen::Vector3d(q.x(), q.y(), q.z())).norm(),
				          1e-4)
				    << id;
				++checked;
			}
	}
	EXPECT_EQ(checked, map.localMaps.size());
}

TEST(Mapping, OnlinePosesAreThoseOfTheTrackingUntilTheFirstLoop)
{
	const test::ScopedTempDir dir("mapping");
	ASSERT_EQ(run(slamConfig(dir.path(), false, ""), dir / "slam").exitCode, 0);
	ASSERT_EQ(run(test::sourcePath("share/rasterslam/config/tracking.yaml"), dir / "odo").exitCode,
	          0);
	const auto online = io::loadTrajectory((dir / "slam/trajectory_online.tum").string());
	const auto final = io::loadTrajectory((dir / "slam/trajectory.tum").string());
	const auto odo = io::loadTrajectory((dir / "odo/trajectory.tum").string());
	ASSERT_EQ(online.size(), final.size());
	ASSERT_EQ(online.size(), odo.size());
	// The first 30 s revisit nothing (the loop closes after 33 s): no loop has moved them yet.
	std::size_t same = 0, corrected = 0;
	for (std::size_t i = 0; i < online.size(); i++)
	{
		const double dOdo = (online[i].pose.translation() - odo[i].pose.translation()).norm();
		const double dFinal = (online[i].pose.translation() - final[i].pose.translation()).norm();
		if (online[i].stamp - online.front().stamp < 30)
		{
			EXPECT_LT(dOdo, 1e-6) << "scan " << i;
			same += dOdo < 1e-6;
			// ...but the final optimization has moved them.
			corrected += dFinal > 1e-3;
		}
	}
	EXPECT_GT(same, 100u);
	EXPECT_GT(corrected, same / 2);
	// The final trajectory is the better one.
	EXPECT_LT(ate(dir / "slam"), ate(dir / "slam", "trajectory_online.tum"));
}

TEST(Mapping, WrongLoopEdgesAreDownweighted)
{
	const test::ScopedTempDir dir("mapping");
	ASSERT_EQ(run(slamConfig(dir.path(), false, ""), dir / "clean").exitCode, 0);
	// The engine's test hook replaces accepted loop edges by wrong ones (5 m, 20 deg off).
	ASSERT_EQ(
	    run(slamConfig(dir.path(), false, "  test_corrupt_loops: 0.3\n"), dir / "wrong").exitCode,
	    0);
	const double corrupted = yamlNumber(dir / "wrong/run.yaml", "corrupted_loops_test_hook");
	ASSERT_GE(corrupted, 1);
	EXPECT_EQ(yamlNumber(dir / "wrong/run.yaml", "loop_edges_downweighted"), corrupted);
	EXPECT_EQ(yamlNumber(dir / "clean/run.yaml", "loop_edges_downweighted"), 0);
	// Measured: 0.200 m clean, 0.209 m with 2 of 4 loop edges wrong (0.3 without the loss).
	EXPECT_LT(ate(dir / "wrong"), 1.1 * ate(dir / "clean"));
}

TEST(Mapping, LocalBaRunsAndIsDeterministic)
{
	const test::ScopedTempDir dir("mapping");
	const auto cfg = slamConfig(dir.path(), true, "");
	for (const auto* out : {"a", "b"})
	{
		const auto r = run(cfg, dir / out, " --map-out " + (dir / out / "map").string());
		ASSERT_EQ(r.exitCode, 0) << r.output;
	}
	EXPECT_GE(yamlNumber(dir / "a/run.yaml", "local_ba_runs"), 5);
	for (const auto* f :
	     {"trajectory.kitti", "trajectory_online.tum", "loops.txt", "pose_graph.graph"})
	{
		std::ifstream fa(dir / "a" / f), fb(dir / "b" / f);
		const std::string sa((std::istreambuf_iterator<char>(fa)), {}),
		    sb((std::istreambuf_iterator<char>(fb)), {});
		EXPECT_FALSE(sa.empty()) << f;
		EXPECT_EQ(sa, sb) << f;
	}
	const Map map = loadMap((dir / "a/map").string());
	std::size_t withTracks = 0;
	for (const auto& [id, lm] : map.localMaps)
		withTracks += lm->baTracks > 0;  // kept with the labels
	EXPECT_GE(withTracks, map.localMaps.size() - 2);
}

TEST(Mapping, UpdateOnRevisitAndCullingKeepEveryLocalMap)
{
	const test::ScopedTempDir dir("mapping");
	// Culling only on loops: each revisited local map leaves the online graph for the store,
	// the new one made from the current scans stays.
	auto cfg = slamConfig(dir.path(), false, "");
	{
		std::ifstream in(cfg);
		std::string y((std::istreambuf_iterator<char>(in)), {});
		y = std::regex_replace(y, std::regex("    local_ba: false"),
		                       "    local_ba: false\n    cull_distance_m: 0\n    max_online_maps: "
		                       "0\n    offline_dir: " +
		                           (dir / "offline").string());
		std::ofstream(cfg) << y;
	}
	ASSERT_EQ(run(cfg, dir / "loop", " --map-out " + (dir / "loop/map").string()).exitCode, 0);
	const double loops = yamlNumber(dir / "loop/run.yaml", "loop_edges");
	ASSERT_GE(loops, 2);
	const double offline = yamlNumber(dir / "loop/run.yaml", "local_maps_offline");
	EXPECT_GE(offline, 1);
	EXPECT_LE(offline, loops);
	EXPECT_EQ(static_cast<std::size_t>(offline),
	          static_cast<std::size_t>(std::distance(fs::directory_iterator(dir / "offline"),
	                                                 fs::directory_iterator())));
	const Map map = loadMap((dir / "loop/map").string());
	std::size_t revisits = 0;
	for (const auto& e : map.graph.edges)
	{
		if (e.kind != LocalMapGraph::EdgeKind::Loop)
			continue;
		// The old place is offline, the new one online; both kept whole.
		EXPECT_FALSE(map.onlineWhenSaved.count(e.from)) << e.from;
		EXPECT_TRUE(map.onlineWhenSaved.count(e.to)) << e.to;
		EXPECT_LT(map.localMaps.at(e.from)->updatedStamp, map.localMaps.at(e.to)->createdStamp);
		EXPECT_GT(map.data(e.from)->points(), 100u);
		++revisits;
	}
	EXPECT_GE(revisits, 1u);
	EXPECT_LE(revisits, static_cast<std::size_t>(loops));

	// Culling by distance and by count as well: the same loops are found (offline maps are
	// read from the store for verification), and the online graph stays within its bound.
	const auto cfg2 = dir / "cfg2.yaml";
	{
		std::ifstream in(cfg);
		std::string y((std::istreambuf_iterator<char>(in)), {});
		y = std::regex_replace(y, std::regex("cull_distance_m: 0"), "cull_distance_m: 60");
		y = std::regex_replace(y, std::regex("max_online_maps: 0"), "max_online_maps: 4");
		y = std::regex_replace(y, std::regex("offline_dir: [^\n]*"),
		                       "offline_dir: " + (dir / "offline2").string());
		std::ofstream(cfg2) << y;
	}
	ASSERT_EQ(run(cfg2, dir / "cull", " --map-out " + (dir / "cull/map").string()).exitCode, 0);
	EXPECT_EQ(yamlNumber(dir / "cull/run.yaml", "loop_edges"), loops);
	EXPECT_LE(yamlNumber(dir / "cull/run.yaml", "local_maps_online"), 4);
	// Online optimizations move the online part only: fewer nodes than the run's keyframes.
	EXPECT_LT(yamlNumber(dir / "cull/run.yaml", "online_optimization_nodes_mean"),
	          yamlNumber(dir / "cull/run.yaml", "keyframes"));
	// A revisited place's older local map left the place index for the newer one.
	EXPECT_GE(yamlNumber(dir / "loop/run.yaml", "local_maps_replaced"), 1);
	EXPECT_LT(yamlNumber(dir / "cull/run.yaml", "map_memory_mb"),
	          yamlNumber(dir / "loop/run.yaml", "map_memory_mb"));
	const Map culled = loadMap((dir / "cull/map").string());
	ASSERT_EQ(culled.localMaps.size(), map.localMaps.size());
	for (const auto& [id, lm] : culled.localMaps)
		EXPECT_GT(culled.data(id)->points(), 100u) << id;
	// Culling changes what is in memory and which keyframes an online optimization moves
	// (those of online local maps), not what is found: the trajectories agree closely.
	EXPECT_NEAR(ate(dir / "cull"), ate(dir / "loop"), 0.02);
}

TEST(Mapping, SessionsShareAMapWithUniqueIdsAndAMapIsNotReplacedByAccident)
{
	const test::ScopedTempDir dir("mapping");
	const auto cfg = slamConfig(dir.path(), false, "");
	const auto map = (dir / "map").string();
	auto r = run(cfg, dir / "s1", " --last 150 --map-out " + map);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	std::ifstream f1(mapFilePath(map), std::ios::binary);
	const std::string before((std::istreambuf_iterator<char>(f1)), {});

	// Another session's --map-out over it, without --map-in of it: refused, map untouched.
	r = run(cfg, dir / "s2", " --last 150 --map-out " + map);
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("holds a map already"), std::string::npos) << r.output;
	std::ifstream f2(mapFilePath(map), std::ios::binary);
	EXPECT_EQ(std::string((std::istreambuf_iterator<char>(f2)), {}), before);

	// Extending it: the second session's keyframes and local maps get ids of their own.
	r = run(cfg, dir / "s2", " --first 20 --last 170 --map-in " + map + " --map-out " + map);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const Map two = loadMap(map);
	EXPECT_EQ(two.sessions, 2u);
	const auto k1 = static_cast<std::size_t>(yamlNumber(dir / "s1/run.yaml", "keyframes"));
	const auto k2 = static_cast<std::size_t>(yamlNumber(dir / "s2/run.yaml", "keyframes"));
	EXPECT_EQ(two.keyframes.size(), k1 + k2);
	std::size_t inSession[2] = {0, 0};
	for (const auto& [id, k] : two.keyframes)
	{
		ASSERT_LT(k->session, 2u);
		++inSession[k->session];
		EXPECT_EQ(id, k->id);
	}
	EXPECT_EQ(inSession[0], k1);
	EXPECT_EQ(inSession[1], k2);
	const auto info = test::runCommand(test::bin("rasterslam") + " map info " + map);
	ASSERT_EQ(info.exitCode, 0) << info.output;
	EXPECT_NE(info.output.find("sessions     : 2"), std::string::npos) << info.output;
	EXPECT_NE(info.output.find("session 1: " + std::to_string(k2) + " keyframes"),
	          std::string::npos)
	    << info.output;

	// --overwrite replaces it with a one-session map.
	r = run(cfg, dir / "s3", " --last 100 --map-out " + map + " --overwrite");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_EQ(loadMap(map).sessions, 1u);
	EXPECT_EQ(
	    test::runCommand(test::bin("rasterslam") + " map info " + (dir / "nope").string()).exitCode,
	    1);
	EXPECT_EQ(test::runCommand(test::bin("rasterslam") + " map bogus").exitCode, 2);
}

TEST(Mapping, PruneKeepsTheNewestOfEachPlaceAndTheMapStaysUsable)
{
	const test::ScopedTempDir dir("mapping");
	const auto cfg = slamConfig(dir.path(), false, "");
	const auto map = (dir / "map").string();
	ASSERT_EQ(run(cfg, dir / "s1", " --map-out " + map).exitCode, 0);
	ASSERT_EQ(run(cfg, dir / "s2", " --map-in " + map + " --map-out " + map).exitCode, 0);
	const Map two = loadMap(map);
	ASSERT_EQ(two.sessions, 2u);
	auto prune = [&](const std::string& args)
	{
		return test::runCommand(test::bin("rasterslam") + " map prune " + map + " --config " +
		                        cfg.string() + " --quiet " + args);
	};
	auto bytes = [&]
	{
		std::ifstream f(mapFilePath(map), std::ios::binary);
		return std::string((std::istreambuf_iterator<char>(f)), {});
	};
	const auto before = bytes();

	// A dry run changes nothing; a date before every stamp drops nothing; dropping what the
	// map was saved with online, or everything, is not possible.
	auto r = prune("--keep-per-place 1 --dry-run");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_NE(r.output.find("would drop"), std::string::npos) << r.output;
	EXPECT_EQ(bytes(), before);
	r = prune("--before 2000-01-01");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_NE(r.output.find("dropped 0 of"), std::string::npos) << r.output;
	EXPECT_EQ(prune("--before yesterday").exitCode, 2);
	EXPECT_EQ(prune("--keep-per-place 0").exitCode, 2);
	EXPECT_EQ(prune("").exitCode, 2);

	// The same loop driven twice: each place keeps the second session's local map.
	r = prune("--keep-per-place 1");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const Map one = loadMap(map);
	EXPECT_LT(one.localMaps.size(), two.localMaps.size());
	std::size_t kept[2] = {0, 0}, had[2] = {0, 0};
	for (const auto& [id, lm] : two.localMaps)
		++had[lm->session];
	for (const auto& [id, lm] : one.localMaps)
		++kept[lm->session];
	for (const auto id : two.onlineWhenSaved)
		EXPECT_TRUE(one.localMaps.count(id)) << id;
	EXPECT_EQ(one.onlineWhenSaved, two.onlineWhenSaved);  // a second prune protects them too
	EXPECT_GE(kept[1], two.onlineWhenSaved.size());
	EXPECT_LT(kept[0], had[0] / 2);
	// No keyframe is left without a local map, no edge without its ends (loadMap checks).
	std::set<uint64_t> held;
	for (const auto& [id, lm] : one.localMaps)
		held.insert(lm->keyframes.begin(), lm->keyframes.end());
	EXPECT_EQ(held.size(), one.keyframes.size());
	for (const auto& [id, p] : one.priorPoses)
		EXPECT_LT(p.distanceTo(two.priorPoses.at(id)), 1e-9);

	// The pruned map's place index knows only what is left: a third session is located in it.
	r = run(cfg, dir / "s3", " --last 150 --map-in " + map + " --require-localization");
	EXPECT_EQ(r.exitCode, 0) << r.output;
	EXPECT_NE(r.output.find("located in the prior map"), std::string::npos) << r.output;
}

TEST(Mapping, ASessionIsAnchoredOnlyWhenSeveralHitsAgree)
{
	const test::ScopedTempDir dir("mapping");
	const auto map = (dir / "map").string();
	ASSERT_EQ(run(slamConfig(dir.path(), false, ""), dir / "s1", " --map-out " + map).exitCode, 0);
	// Another town (the same scenario, another seed), with verification made lax enough
	// (8 inliers) that wrong places pass it.
	const auto other = (dir / "other.rawlog").string();
	auto r =
	    test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-vlp16.yaml") + " --seed 99 -o " + other);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	auto lax = [&](int agreeing)
	{
		const auto p = slamConfig(dir.path(), false,
		                          "  anchor_min_agreeing: " + std::to_string(agreeing) + "\n");
		std::ifstream in(p);
		std::string y((std::istreambuf_iterator<char>(in)), {});
		y = std::regex_replace(y, std::regex("min_inliers: 25 "), "min_inliers: 8 ");
		y = std::regex_replace(y, std::regex("relocalization_min_inliers: 18 "),
		                       "relocalization_min_inliers: 8 ");
		const auto out = dir / ("lax" + std::to_string(agreeing) + ".yaml");
		std::ofstream(out) << y;
		return out;
	};
	auto runOther = [&](const fs::path& cfg, const std::string& extra)
	{
		return test::runCommand(test::bin("rasterslam") + " run --rawlog " + other + " --config " +
		                        cfg.string() + " --quiet --out " + (dir / "s2").string() +
		                        " --map-in " + map + extra);
	};
	// One hit is enough without the check: the other town is anchored in this map (wrongly).
	r = runOther(lax(1), "");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_EQ(yamlNumber(dir / "s2/run.yaml", "prior_map_hits"), 1);
	EXPECT_NE(r.output.find("rasterslam: located in the prior map"), std::string::npos) << r.output;
	// With three agreeing hits required (the default) the wrong hits disagree: never anchored.
	std::ifstream f1(mapFilePath(map), std::ios::binary);
	const std::string before((std::istreambuf_iterator<char>(f1)), {});
	r = runOther(lax(3), " --map-out " + map);
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("NOT located in the prior map"), std::string::npos) << r.output;
	EXPECT_NE(r.output.find("the map is not saved"), std::string::npos) << r.output;
	EXPECT_GE(yamlNumber(dir / "s2/run.yaml", "prior_map_hits"), 2);
	EXPECT_TRUE(std::isnan(yamlNumber(dir / "s2/run.yaml", "localized_at_scan")));
	std::ifstream f2(mapFilePath(map), std::ios::binary);
	EXPECT_EQ(std::string((std::istreambuf_iterator<char>(f2)), {}),
	          before);  // the map is untouched
	r = runOther(lax(3), " --require-localization");
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("--require-localization"), std::string::npos) << r.output;
	// The same town again is anchored under the same lax settings.
	r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + vlp16Rawlog() +
	                     " --first 20 --last 200 --config " + lax(3).string() + " --quiet --out " +
	                     (dir / "s3").string() + " --map-in " + map + " --require-localization");
	EXPECT_EQ(r.exitCode, 0) << r.output;
	EXPECT_NE(r.output.find("rasterslam: located in the prior map"), std::string::npos) << r.output;
}

namespace
{
/** kitti2rawlog over every other frame of the KITTI sample (parity 0: even, 1: odd). */
std::string kittiEveryOther(const fs::path& dir, int parity)
{
	const auto D = test::sharedData("kitti00-0000-0100");
	const auto sub = dir / (parity ? "odd" : "even");
	fs::create_directories(sub / "velodyne");
	std::ifstream poses(D + "/poses_semantickitti.txt"), times(D + "/times.txt");
	std::ofstream po(sub / "poses.txt"), to(sub / "times.txt");
	std::string p, t;
	int frame = 0, kept = 0;
	while (std::getline(poses, p) && std::getline(times, t))
	{
		if (frame % 2 == parity)
		{
			fs::create_symlink(D + mrpt::format("/velodyne/%06d.bin", frame),
			                   sub / mrpt::format("velodyne/%06d.bin", kept++));
			po << p << "\n";
			to << t << "\n";
		}
		++frame;
	}
	po.close();
	to.close();
	const auto out = (sub / "scans.rawlog").string();
	const auto r = test::runCommand(
	    test::bin("kitti2rawlog") + " --velodyne " + (sub / "velodyne").string() + " --poses " +
	    (sub / "poses.txt").string() + " --calib " + D + "/calib.txt --times " +
	    (sub / "times.txt").string() + " --compress 0 -o " + out);
	EXPECT_EQ(r.exitCode, 0) << r.output;
	return out;
}

/** Both sessions' trajectories (or ground truths) as one, in stamp order. */
fs::path interleave(const fs::path& a, const fs::path& b, const std::string& file,
                    const fs::path& out)
{
	auto all = io::loadTrajectory((a / file).string());
	const auto more = io::loadTrajectory((b / file).string());
	all.insert(all.end(), more.begin(), more.end());
	std::sort(all.begin(), all.end(),
	          [](const auto& x, const auto& y) { return x.stamp < y.stamp; });
	io::saveTrajectoryTum(out.string(), all);
	return out;
}
}  // namespace

TEST(Mapping, TwoRealSessionsLieInOneFrame)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	// The even frames of the KITTI sample make the map; the odd frames come back to it as a
	// second session: located, its loops to the first session's keyframes joined.
	const test::ScopedTempDir dir("mapping");
	const auto cfg = slamConfig(dir.path(), false, "");
	const auto map = (dir / "map").string();
	auto r = test::runCommand(test::bin("rasterslam") + " run --rawlog " +
	                          kittiEveryOther(dir.path(), 0) + " --config " + cfg.string() +
	                          " --quiet --out " + (dir / "even").string() + " --map-out " + map);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " run --rawlog " +
	                     kittiEveryOther(dir.path(), 1) + " --config " + cfg.string() +
	                     " --quiet --out " + (dir / "odd").string() + " --map-in " + map +
	                     " --map-out " + map + " --require-localization");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_GE(yamlNumber(dir / "odd/run.yaml", "prior_map_loop_edges"), 2);
	const Map both = loadMap(map);
	EXPECT_EQ(both.sessions, 2u);
	// Where the second session was located, its local map is joined to the first session's.
	ASSERT_GE(both.graph.count(LocalMapGraph::EdgeKind::Relocalization), 1u);
	for (const auto& e : both.graph.edges)
		if (e.kind == LocalMapGraph::EdgeKind::Relocalization)
		{
			EXPECT_EQ(both.localMaps.at(e.from)->session, 0u);
			EXPECT_EQ(both.localMaps.at(e.to)->session, 1u);
		}

	// Measured: interleaved ATE 0.043 m, consecutive frames (one of each session) 0.049 m
	// apart from the truth on average (0.115 m and 0.186 m before the sessions were linked).
	const auto e = test::runCommand(
	    test::bin("rasterslam-eval") + " traj --json --gt " +
	    interleave(dir / "even", dir / "odd", "groundtruth.tum", dir / "gt.tum").string() +
	    " --est " +
	    interleave(dir / "even", dir / "odd", "trajectory.tum", dir / "est.tum").string());
	ASSERT_EQ(e.exitCode, 0) << e.output;
	auto num = [&](const std::string& key) { return jsonNumber(e.output, key); };
	EXPECT_EQ(num("n_associated"), 101);
	EXPECT_LT(num("ate_rmse_m"), 0.08) << e.output;
	EXPECT_LT(num("rpe_trans_mean_m"), 0.06) << e.output;
}

TEST(Mapping, MapsBuiltSeparatelyAreMergedIntoOneFrame)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	// The even and the odd frames of the KITTI sample, each a map of its own (each in the
	// frame of its first scan), joined by `map merge`.
	const test::ScopedTempDir dir("mapping");
	const auto cfg = slamConfig(dir.path(), false, "");
	for (int parity : {0, 1})
	{
		const std::string name = parity ? "odd" : "even";
		const auto r = test::runCommand(test::bin("rasterslam") + " run --rawlog " +
		                                kittiEveryOther(dir.path(), parity) + " --config " +
		                                cfg.string() + " --quiet --out " + (dir / name).string() +
		                                " --map-out " + (dir / ("map-" + name)).string());
		ASSERT_EQ(r.exitCode, 0) << r.output;
	}
	const auto merged = (dir / "merged").string();
	const auto merge =
	    [&](const std::string& a, const std::string& b, const std::string& extra = "")
	{
		return test::runCommand(test::bin("rasterslam") + " map merge " + (dir / a).string() + " " +
		                        (dir / b).string() + " --out " + merged + " --config " +
		                        cfg.string() + " --quiet" + extra);
	};
	auto r = merge("map-even", "map-odd");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const Map m = loadMap(merged), even = loadMap((dir / "map-even").string()),
	          odd = loadMap((dir / "map-odd").string());
	EXPECT_EQ(m.sessions, 2u);
	EXPECT_EQ(m.keyframes.size(), even.keyframes.size() + odd.keyframes.size());
	EXPECT_EQ(m.localMaps.size(), even.localMaps.size() + odd.localMaps.size());
	EXPECT_GE(m.graph.count(LocalMapGraph::EdgeKind::Relocalization), 1u);
	ASSERT_EQ(m.sessionRecords.size(), 2u);
	EXPECT_NE(m.sessionRecords.at(1).input.find("odd"), std::string::npos);
	// The first map stays where it was.
	for (const auto& [id, p] : even.priorPoses)
		EXPECT_LT(m.priorPoses.at(id).distanceTo(p), 1e-6) << id;
	for (const auto& [id, k] : m.keyframes)
		EXPECT_EQ(k->session, id < even.nextKeyframeId() ? 0u : 1u) << id;

	// Both sessions' keyframes in one frame against the SemanticKITTI poses. Measured: ATE
	// 0.032 m, consecutive keyframes (of different sessions, mostly) 0.042 m off on average.
	r = test::runCommand(test::bin("rasterslam") + " map export " + merged + " --out " +
	                     (dir / "exp").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	interleave(dir / "even", dir / "odd", "groundtruth.tum", dir / "gt.tum");
	fs::create_directories(dir / "s1");
	fs::copy_file(dir / "exp/keyframes-s1.tum", dir / "s1/keyframes-s0.tum");
	interleave(dir / "exp", dir / "s1", "keyframes-s0.tum", dir / "est.tum");
	const auto j =
	    test::runCommand(test::bin("rasterslam-eval") + " traj --json --gt " +
	                     (dir / "gt.tum").string() + " --est " + (dir / "est.tum").string());
	ASSERT_EQ(j.exitCode, 0) << j.output;
	auto num = [&](const std::string& key) { return jsonNumber(j.output, key); };
	EXPECT_EQ(num("n_associated"), static_cast<double>(m.keyframes.size()));
	EXPECT_LT(num("ate_rmse_m"), 0.08) << j.output;
	EXPECT_LT(num("rpe_trans_mean_m"), 0.05) << j.output;

	// The merged map is not replaced by accident, and B is never the output.
	r = merge("map-even", "map-odd");
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("--overwrite"), std::string::npos) << r.output;
	EXPECT_EQ(merge("map-even", "merged", " --overwrite").exitCode, 1);
	r = merge("map-even", "map-even", " --overwrite");
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("the same map"), std::string::npos) << r.output;
	EXPECT_EQ(loadMap(merged).keyframes.size(), m.keyframes.size());
}

TEST(Mapping, MapsOfDifferentTownsAreNotMerged)
{
	// Two simulated towns (other seeds, same sensor and street plan kind): no overlap, an
	// error, and nothing written.
	const test::ScopedTempDir dir("mapping");
	const auto cfg = slamConfig(dir.path(), false, "");
	const auto other = (dir / "other.rawlog").string();
	auto r = test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                          test::sourcePath("rawlogs/town-vlp16.yaml") +
	                          " --seed 8 --scans 200 --compress 0 -o " + other);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	ASSERT_EQ(run(cfg, dir / "a", " --last 199 --map-out " + (dir / "map-a").string()).exitCode, 0);
	r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + other + " --config " +
	                     cfg.string() + " --quiet --out " + (dir / "b").string() + " --map-out " +
	                     (dir / "map-b").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " map merge " + (dir / "map-a").string() + " " +
	                     (dir / "map-b").string() + " --out " + (dir / "c").string() +
	                     " --config " + cfg.string() + " --quiet");
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("no overlap found"), std::string::npos) << r.output;
	EXPECT_FALSE(fs::exists(dir / "c" / "map.rsmap"));
}

// Map merge locates each keyframe of B in A on its features, then asks the free space
// (loop_detector.relocalization_max_conflicts): where a keyframe's features put its local map,
// that local map's walls and poles must not stand on A's bare ground. The simulated town and
// another one (seed 1001), with the verification made lax on purpose (8 inliers, any score):
// unchecked, three wrong hits agree and the towns are merged; checked, the hits that put
// walls on the street are refused (their shares 0.06-0.51; true hits on the KITTI halves
// 0.000-0.003) and nothing is written.
TEST(Mapping, AMergeWhoseHitsStandOnTheOtherMapsBareGroundIsRefused)
{
	const test::ScopedTempDir dir("mapping");
	const auto town = (dir / "town.rawlog").string(), other = (dir / "other.rawlog").string();
	auto r =
	    test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-loop.yaml") + " --compress 0 -o " + town);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-loop.yaml") +
	                     " --seed 1001 --scans 300 --compress 0 -o " + other);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto cfg = slamConfig(dir.path(), false, "");
	for (const auto& [rawlog, name] : {std::pair{town, "a"}, std::pair{other, "b"}})
	{
		r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + rawlog + " --config " +
		                     cfg.string() + " --quiet --out " + (dir / name).string() +
		                     " --map-out " + (dir / ("map-" + std::string(name))).string());
		ASSERT_EQ(r.exitCode, 0) << r.output;
	}
	const auto merge =
	    [&](const std::string& maxConflicts, const std::string& out, const std::string& logging)
	{
		std::ifstream in(cfg);
		std::string y((std::istreambuf_iterator<char>(in)), {});
		const std::regex inliers("relocalization_min_inliers: 18 "), score("min_score: 0.3 ");
		EXPECT_TRUE(std::regex_search(y, inliers));
		EXPECT_TRUE(std::regex_search(y, score));
		y = std::regex_replace(y, inliers,
		                       "relocalization_max_conflicts: " + maxConflicts +
		                           "\n    relocalization_min_inliers: 8 ");
		y = std::regex_replace(y, score, "min_score: 0.0 ");
		const auto lax = dir / (out + ".yaml");
		std::ofstream(lax) << y;
		return test::runCommand(test::bin("rasterslam") + " map merge " + (dir / "map-a").string() +
		                        " " + (dir / "map-b").string() + " --out " + (dir / out).string() +
		                        " --config " + lax.string() + logging);
	};
	// Unchecked (any share taken): merged, in a town B is not in. This is what the check is
	// for; should a change stop merging them, the test needs other maps that pass the rest.
	r = merge("1", "unchecked", " --quiet");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_TRUE(fs::exists(dir / "unchecked" / "map.rsmap"));
	// With the shipped bound (0.05): hits refused on their free space, no overlap, nothing
	// written.
	r = merge("0.05", "checked", " --verbose");
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_NE(r.output.find("not located: free-space"), std::string::npos) << r.output;
	EXPECT_NE(r.output.find("no overlap found"), std::string::npos) << r.output;
	EXPECT_FALSE(fs::exists(dir / "checked" / "map.rsmap"));
}

TEST(Mapping, ExportedMapLoadsInMrptAndOtherTools)
{
	mrpt::maps::registerAllClasses_mrpt_maps();
	mrpt::obs::registerAllClasses_mrpt_obs();
	const test::ScopedTempDir dir("mapping");
	const auto map = (dir / "map").string();
	ASSERT_EQ(run(slamConfig(dir.path(), false, ""), dir / "run", " --last 200 --map-out " + map)
	              .exitCode,
	          0);
	const auto r = test::runCommand(test::bin("rasterslam") + " map export " + map + " --out " +
	                                (dir / "exp").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const Map m = loadMap(map);
	std::size_t points = 0;
	for (const auto& [id, lm] : m.localMaps)
		points += m.data(id)->points();

	// MRPT's own formats load back with MRPT: one keyframe of the simple map per local map,
	// its point cloud whole; one graph node per keyframe at its saved pose.
	mrpt::maps::CSimpleMap sm;
	ASSERT_TRUE(sm.loadFromFile((dir / "exp/map.simplemap").string()));
	ASSERT_EQ(sm.size(), m.localMaps.size());
	std::size_t smPoints = 0;
	for (std::size_t i = 0; i < sm.size(); i++)
	{
		const auto obs =
		    std::get<1>(sm.get(i))->getObservationByClass<mrpt::obs::CObservationPointCloud>();
		ASSERT_TRUE(obs);
		smPoints += obs->pointcloud->size();
	}
	EXPECT_EQ(smPoints, points);
	mrpt::graphs::CNetworkOfPoses3D g;
	g.loadFromTextFile((dir / "exp/map.graph").string());
	ASSERT_EQ(g.nodes.size(), m.keyframes.size());
	for (const auto& [id, p] : m.priorPoses)
		EXPECT_LT(g.nodes.at(id).distanceTo(p), 1e-3) << id;
	EXPECT_GE(g.edges.size(), m.keyframes.size() - 1);

	// The point clouds say how many points they hold in their headers; the images decode.
	auto header = [&](const fs::path& p, const std::string& key)
	{
		std::ifstream f(p, std::ios::binary);
		std::string line;
		while (std::getline(f, line) && line.rfind("DATA", 0) != 0 && line != "end_header")
			if (line.rfind(key, 0) == 0)
				return std::stoul(line.substr(key.size()));
		return 0ul;
	};
	EXPECT_EQ(header(dir / "exp/points.pcd", "POINTS "), points);
	EXPECT_EQ(header(dir / "exp/points.ply", "element vertex "), points);
	const auto top = cv::imread((dir / "exp/top.png").string());
	EXPECT_EQ(top.rows, 1000);
	EXPECT_EQ(
	    std::distance(fs::directory_iterator(dir / "exp/localmaps"), fs::directory_iterator()),
	    static_cast<std::ptrdiff_t>(m.localMaps.size()));
}

namespace
{
/** A scenario over the town of scripts/benchmark-sessions.sh: `lidar`, `scans` scans along a
 *  closed route through `waypoints`, stamps `day` days apart. */
fs::path townSession(const fs::path& dir, const std::string& name, const std::string& lidar,
                     int scans, int day, const std::string& waypoints,
                     const std::string& extra = "")
{
	const auto p = dir / (name + ".yaml");
	std::ofstream(p) << "seed: 42\nlidar: " << lidar << "\nscans: " << scans
	                 << "\nrate_hz: 10\nspeed_mps: 8\nstart_stamp_s: " << 1700000000 + 86400 * day
	                 << "\nroute: {waypoints: " << waypoints
	                 << ", closed: true, turn_radius_m: 6}\n"
	                    "town: {blocks_x: 3, blocks_y: 2, block_size_m: 50, street_width_m: 14, "
	                    "sidewalk_m: 3, building_height_min_m: 6, building_height_max_m: 24, "
	                    "trees_per_100m: 4, poles_per_100m: 3, cars_per_100m: 5, hills: 4, "
	                    "max_slope: 0.06, outskirts_m: 25}\n"
	                    "noise: {range_sigma_m: 0.02, dropout_prob: 0.02, intensity_sigma: 0.03}\n"
	                 << extra;
	const auto out = dir / (name + ".rawlog");
	const auto r = test::runCommand(test::bin("rasterslam-sim") + " --scenario " + p.string() +
	                                " --compress 0 -o " + out.string());
	EXPECT_EQ(r.exitCode, 0) << r.output;
	return out;
}

/** Poses of a TUM file by stamp (rounded to 1 ms). */
std::map<long long, Eigen::Isometry3d> tumPoses(const fs::path& file)
{
	std::map<long long, Eigen::Isometry3d> out;
	std::ifstream f(file);
	std::string line;
	while (std::getline(f, line))
	{
		if (line.empty() || line[0] == '#')
			continue;
		std::istringstream s(line);
		double t, x, y, z, qx, qy, qz, qw;
		if (!(s >> t >> x >> y >> z >> qx >> qy >> qz >> qw))
			continue;
		Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
		T.linear() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
		T.translation() = Eigen::Vector3d(x, y, z);
		out[std::llround(t * 1000)] = T;
	}
	return out;
}
}  // namespace

namespace
{
struct GuidedLink
{
	double queryStamp;
	double error_m;  // registration against the two sessions' ground truths
};

// Each accepted guided loop of the second session (its out directory) against the truth: the
// query's pose in the matched keyframe's frame, from the two sessions' ground truths.
std::vector<GuidedLink> guidedLinks(const fs::path& firstOut, const fs::path& secondOut)
{
	const auto gt1 = tumPoses(firstOut / "groundtruth.tum"),
	           gt2 = tumPoses(secondOut / "groundtruth.tum");
	std::ifstream loops(secondOut / "loops.txt");
	std::vector<GuidedLink> out;
	std::string line;
	while (std::getline(loops, line))
	{
		std::istringstream s(line);
		double q, c, score, x, y, z;
		int inliers, verified, accepted;
		std::string reason;
		if (line.empty() || line[0] == '#' ||
		    !(s >> q >> c >> score >> inliers >> verified >> accepted >> reason >> x >> y >> z))
			continue;
		if (reason != "guided" || !accepted)
			continue;
		const auto cq = gt1.find(std::llround(c * 1000));
		const auto qq = gt2.find(std::llround(q * 1000));
		if (cq == gt1.end() || qq == gt2.end())
			throw std::runtime_error("no ground truth for loop line: " + line);
		const Eigen::Vector3d truth = (cq->second.inverse() * qq->second).translation();
		out.push_back({q, (truth - Eigen::Vector3d(x, y, z)).norm()});
	}
	return out;
}

// The first of two sessions: maps `rawlog` into DIR/map, its outputs in DIR/o1.
test::CommandResult mapFirstSession(const fs::path& dir, const fs::path& rawlog,
                                    const fs::path& config)
{
	return test::runCommand(test::bin("rasterslam") + " run --rawlog " + rawlog.string() +
	                        " --config " + config.string() + " --quiet --out " +
	                        (dir / "o1").string() + " --map-out " + (dir / "map").string());
}
}  // namespace

TEST(Mapping, AnotherSensorsSessionIsLinkedByTheGuidedSearch)
{
	// An HDL-64E session maps the town; a VLP-16 session drives the same block the other way
	// round. Its features match few of the map's (other heights of the same walls): the BOW
	// search links it to the first session rarely; once it is anchored, the guided search
	// (earlier sessions' local maps near its pose, matching gated by the predicted positions)
	// links it along the way, and each of those links is right. Measured here: 27 guided
	// edges, the largest registration 0.51 m from the truth; 0 edges to the first session
	// without the guided search.
	const test::ScopedTempDir dir("mapping");
	const auto s1 =
	    townSession(dir.path(), "s1", "hdl64", 530, 1, "[[0,0],[128,0],[128,64],[0,64]]");
	const auto s2 =
	    townSession(dir.path(), "s2", "vlp16", 400, 2, "[[0,64],[128,64],[128,0],[0,0]]");
	const auto cfg = slamConfig(dir.path(), false, "");
	const auto map = (dir / "map").string();
	auto r = mapFirstSession(dir.path(), s1, cfg);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	auto session2 = [&](const fs::path& config, const std::string& out)
	{
		return test::runCommand(test::bin("rasterslam") + " run --rawlog " + s2.string() +
		                        " --config " + config.string() + " --quiet --out " +
		                        (dir / out).string() + " --map-in " + map +
		                        " --require-localization");
	};
	r = session2(cfg, "o2");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const double guidedEdges = yamlNumber(dir / "o2/run.yaml", "prior_map_loop_edges");

	int guided = 0;
	double worst = 0;
	for (const auto& l : guidedLinks(dir / "o1", dir / "o2"))
	{
		++guided;
		worst = std::max(worst, l.error_m);
	}
	EXPECT_GE(guided, 15);
	EXPECT_LE(guided, guidedEdges);
	EXPECT_LT(worst, 0.75);

	// Without it, fewer links to the first session.
	std::ifstream in(cfg);
	std::string y((std::istreambuf_iterator<char>(in)), {});
	y = std::regex_replace(
	    y, std::regex("\nloop_detector:\n  class: rasterslam::BowLoopDetector\n  params:\n"),
	    "\nloop_detector:\n  class: rasterslam::BowLoopDetector\n  params:\n    guided_radius_m: "
	    "0\n");
	const auto off = dir / "off.yaml";
	std::ofstream(off) << y;
	r = session2(off, "o3");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_LT(yamlNumber(dir / "o3/run.yaml", "prior_map_loop_edges") + 5, guidedEdges);
}

TEST(Mapping, KeyframesMadeBeforeTheAnchoringAreLinkedThroughTheirLocalMaps)
{
	// A session located late (anchor hits 8 s apart: three of them take some 17 s) has
	// finished several local maps on the mapped street before it is anchored, and their
	// keyframes' features are released by then. Once it is anchored, those keyframes are
	// searched in the earlier session through the local maps they anchor: links reach back
	// beyond the open local map (without that, none did: the way driven before the
	// anchoring hung from the last few keyframes, session 5 of benchmark-sessions.sh 1.6 m
	// off at its start). Each link agrees with the truth.
	const test::ScopedTempDir dir("mapping");
	const auto s1 =
	    townSession(dir.path(), "s1", "hdl64", 530, 1, "[[0,0],[128,0],[128,64],[0,64]]");
	const auto s2 =
	    townSession(dir.path(), "s2", "hdl64", 300, 2, "[[0,0],[128,0],[128,64],[0,64]]");
	const auto cfg = slamConfig(dir.path(), false, "  anchor_hit_spacing_s: 8\n");
	const auto map = (dir / "map").string();
	auto r = mapFirstSession(dir.path(), s1, cfg);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + s2.string() + " --config " +
	                     cfg.string() + " --out " + (dir / "o2").string() + " --map-in " + map +
	                     " --require-localization");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	std::smatch m;
	ASSERT_TRUE(
	    std::regex_search(r.output, m, std::regex("scan ([0-9]+): located in the prior map")))
	    << r.output;
	// Scans are 0.1 s apart from the session's first stamp.
	const double anchoredAt = 1700000000 + 86400 * 2 + 0.1 * std::stod(m[1]);
	ASSERT_GT(anchoredAt, 1700000000 + 86400 * 2 + 12.0) << "anchored too early to test this";

	std::set<long long> linkedEarly;  // query keyframes over 6 s (48 m) before the anchoring
	double worst = 0;
	for (const auto& l : guidedLinks(dir / "o1", dir / "o2"))
	{
		worst = std::max(worst, l.error_m);
		if (l.queryStamp < anchoredAt - 6.0)
			linkedEarly.insert(std::llround(l.queryStamp * 1000));
	}
	EXPECT_GE(linkedEarly.size(), 2u) << "anchored at scan " << m[1];
	EXPECT_LT(worst, 0.75);
}

TEST(Mapping, LifelongConfigLocatesAnotherSensorInAChangedTown)
{
	// Sessions 1 and 2 of scripts/benchmark-sessions.sh: an HDL-64E maps the town with cars and
	// people moving; a VLP-16 drives it the other way a day later, when parked cars have left or
	// come, walls and shop fronts changed and trees grown (epoch 1), cars and people moving
	// again. With lifelong.yaml (images of the 3 m band both sensors see) it is located in the
	// map with no prior, at the right place; the README states ATE 0.269 m in the map's frame.
	const test::ScopedTempDir dir("mapping");
	const std::string moving = "traffic: {cars: 8, pedestrians: 20}\n";
	const auto s1 =
	    townSession(dir.path(), "s1", "hdl64", 530, 1, "[[0,0],[128,0],[128,64],[0,64]]", moving);
	const auto s2 = townSession(dir.path(), "s2", "vlp16", 530, 2,
	                            "[[0,64],[128,64],[128,0],[0,0]]", "epoch: 1\n" + moving);
	const std::string y = test::shippedConfig("lifelong.yaml");
	ASSERT_NE(y.find("max_height_m: 3 "), std::string::npos);
	const auto cfg = dir / "lifelong.yaml";
	std::ofstream(cfg) << y;
	const auto map = (dir / "map").string();
	auto r = mapFirstSession(dir.path(), s1, cfg);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	// Sessions 2 and 4 (a VLP-16 on another route 3 epochs later) also as maps of their own,
	// each merged into session 1's (map merge): few of their keyframes are located alone; a
	// local map none of whose keyframes is located is located whole.
	const auto s4 = townSession(dir.path(), "s4", "vlp16", 530, 4,
	                            "[[0,0],[0,128],[64,128],[64,0]]", "epoch: 3\n" + moving);
	for (const auto& [rawlog, name] : {std::pair{s2, "b2"}, std::pair{s4, "b4"}})
	{
		const auto b = dir / name;
		r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + rawlog.string() +
		                     " --config " + cfg.string() + " --quiet --out " + b.string() +
		                     " --map-out " + (b / "map").string());
		ASSERT_EQ(r.exitCode, 0) << r.output;
		r = test::runCommand(test::bin("rasterslam") + " map merge " + map + " " +
		                     (b / "map").string() + " --out " + (b / "merged").string() +
		                     " --config " + cfg.string() + " --quiet");
		ASSERT_EQ(r.exitCode, 0) << r.output;
		EXPECT_TRUE(
		    std::regex_search(r.output, std::regex(" and [1-9][0-9]* of [0-9]+ local maps whole")))
		    << r.output;
		r = test::runCommand(test::bin("rasterslam") + " map export " + (b / "merged").string() +
		                     " --out " + (b / "x").string());
		ASSERT_EQ(r.exitCode, 0) << r.output;
	}
	r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + s2.string() + " --config " +
	                     cfg.string() + " --quiet --out " + (dir / "o2").string() + " --map-in " +
	                     map + " --map-out " + map + " --require-localization");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_NE(r.output.find("located in the prior map"), std::string::npos) << r.output;
	EXPECT_GE(yamlNumber(dir / "o2/run.yaml", "prior_map_hits"), 3);
	// The scan that anchored it: three hits 1 s apart (engine.anchor_hit_spacing_s) at 10 Hz
	// take at least 20 scans after the first.
	EXPECT_GE(yamlNumber(dir / "o2/run.yaml", "localized_at_scan"), 20);
	// In the map's frame: session 2 judged with session 1's alignment to the world.
	const auto eval = [&](const std::string& out, const std::string& align)
	{
		return test::runCommand(test::bin("rasterslam-eval") + " traj --gt " +
		                        (dir / out / "groundtruth.tum").string() + " --est " +
		                        (dir / out / "trajectory.tum").string() + " --json" +
		                        (align.empty() ? "" : " --align " + align));
	};
	const auto e1 = eval("o1", "");
	ASSERT_EQ(e1.exitCode, 0) << e1.output;
	std::smatch m;
	ASSERT_TRUE(std::regex_search(e1.output, m, std::regex("\"T_gt_est\": *\"([^\"]+)\"")))
	    << e1.output;
	const auto e2 = eval("o2", m[1].str());
	ASSERT_EQ(e2.exitCode, 0) << e2.output;
	const double ate2 = jsonNumber(e2.output, "ate_rmse_m");
	EXPECT_LT(ate2, 0.4) << "session 2 in the map's frame";
	// The merged maps' keyframes of sessions 2 and 4 in the map's frame, judged the same way;
	// the README states 0.30 and 0.58 m (1.13 and 0.76 m with the keyframes' hits alone, and
	// 0.30 and 0.82 m with the hits' rotation weighted 0.1 rad instead of 0.5 deg).
	const auto merged = [&](const std::string& name)
	{
		const auto em = test::runCommand(test::bin("rasterslam-eval") + " traj --gt " +
		                                 (dir / name / "groundtruth.tum").string() + " --est " +
		                                 (dir / name / "x/keyframes-s1.tum").string() +
		                                 " --json --align " + m[1].str());
		EXPECT_EQ(em.exitCode, 0) << em.output;
		return jsonNumber(em.output, "ate_rmse_m");
	};
	const double ateB2 = merged("b2"), ateB4 = merged("b4");
	std::printf(
	    "in the map's frame: session 2 ATE %.3f m (--map-in), %.3f m (merged); session 4 "
	    "merged %.3f m\n",
	    ate2, ateB2, ateB4);
	EXPECT_LT(ateB2, 0.4) << "session 2 merged, in the map's frame";
	EXPECT_LT(ateB4, 0.7) << "session 4 merged, in the map's frame";
}
