// Realism of the simulator: scene statistics (rasterslam/eval/scene_stats.h) on scenes with
// known answers, and the KITTI-like street (rawlogs/town-kitti.yaml) against the real KITTI
// sample, within the tolerances the README states.
#include <rasterslam/eval/scene_stats.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/sim/scenario.h>
#include <rasterslam/sim/simulator.h>

#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>

#include "test_support.h"

namespace
{
using namespace rasterslam;

/** Flat ground (z = -1.73 in the sensor frame) on a grid, plus `walls` as point lists. */
std::vector<PointXYZI> groundGrid(double half, double step)
{
	std::vector<PointXYZI> pts;
	for (double x = -half; x <= half; x += step)
		for (double y = -half; y <= half; y += step)
			pts.push_back({static_cast<float>(x), static_cast<float>(y), -1.73f, 0.25f});
	return pts;
}
void addWall(std::vector<PointXYZI>& pts, Eigen::Vector2d a, Eigen::Vector2d b, float intensity)
{
	const double len = (b - a).norm();
	for (double s = 0; s <= len; s += 0.05)
		for (double z = 0.5; z <= 3.0; z += 0.25)
		{
			const Eigen::Vector2d q = a + (b - a) * (s / len);
			pts.push_back({static_cast<float>(q.x()), static_cast<float>(q.y()),
			               static_cast<float>(-1.73 + z), intensity});
		}
}

TEST(SceneStats, KnownScenes)
{
	// A straight street: ground and one long wall 6 m to the left.
	auto street = groundGrid(20, 0.5);
	const std::size_t groundN = street.size();
	addWall(street, {-30, 6}, {30, 6}, 0.75f);
	eval::SceneStatsAccumulator a;
	a.add(street);
	const auto s = a.finish();
	EXPECT_EQ(s.scans, 1u);
	EXPECT_DOUBLE_EQ(s.points, static_cast<double>(street.size()));
	EXPECT_NEAR(s.groundShare, static_cast<double>(groundN) / street.size(), 1e-9);
	EXPECT_LT(s.isotropy, 0.05) << "one wall faces one way";
	// Wall heights above ground 0.5..3.0: bins [0.25,1) [1,2) [2,4).
	EXPECT_NEAR(s.heightShare[0], 2.0 / 11, 1e-6);
	EXPECT_NEAR(s.heightShare[1], 4.0 / 11, 1e-6);
	EXPECT_NEAR(s.heightShare[2], 5.0 / 11, 1e-6);
	EXPECT_EQ(s.heightShare[3] + s.heightShare[4], 0);
	double ranges = 0;
	for (double v : s.rangeShare)
		ranges += v;
	EXPECT_NEAR(ranges, 1, 1e-9);
	EXPECT_GT(s.rangeShare[2], 0) << "ground corners and wall ends lie 20-31 m away";
	EXPECT_EQ(s.rangeShare[3] + s.rangeShare[4], 0) << "nothing beyond 40 m";

	// A square room: walls face all four ways alike.
	auto room = groundGrid(10, 0.5);
	addWall(room, {-8, -8}, {8, -8}, 0.75f);
	addWall(room, {8, -8}, {8, 8}, 0.75f);
	addWall(room, {8, 8}, {-8, 8}, 0.75f);
	addWall(room, {-8, 8}, {-8, -8}, 0.75f);
	eval::SceneStatsAccumulator b;
	b.add(room);
	const auto r = b.finish();
	EXPECT_GT(r.isotropy, 0.9);
	EXPECT_GT(r.brightShare, 0.3);
	EXPECT_LT(r.meanIntensity, 0.75);

	EXPECT_THROW(eval::SceneStatsAccumulator().finish(), std::invalid_argument);
	const std::string text = eval::formatSceneStats({"street", "room"}, {s, r});
	EXPECT_NE(text.find("ground share"), std::string::npos) << text;
	EXPECT_NE(text.find("wall isotropy"), std::string::npos) << text;
	EXPECT_THROW(eval::formatSceneStats({"a"}, {s, r}), std::invalid_argument);
}

eval::SceneStats simulated(const std::string& scenario, std::size_t count)
{
	const auto sc = sim::loadScenario(test::sourcePath("rawlogs/" + scenario));
	const auto simulator = sim::Simulator::fromScenario(sc);
	eval::SceneStatsAccumulator acc;
	for (std::size_t i = 0; i < count; i++)
		acc.add(simulator.scan(i * sc.scans / count).points);
	return acc.finish();
}

TEST(SimRealism, SceneStatisticsNearTheKittiSample)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	eval::SceneStatsAccumulator k;
	const auto bins = io::listKittiBins(test::sharedData("kitti00-0000-0100/velodyne"));
	ASSERT_EQ(bins.size(), 101u);
	for (std::size_t i = 0; i < bins.size(); i += 5)
		k.add(io::loadKittiBin(bins[i]));
	const auto kitti = k.finish();
	const auto street = simulated("town-kitti.yaml", 40);
	const auto plain = simulated("town-loop.yaml", 40);
	std::cout << eval::formatSceneStats({"KITTI", "town-kitti", "town-loop"},
	                                    {kitti, street, plain});

	// The tolerances the README states.
	EXPECT_NEAR(street.points / kitti.points, 1, 0.10);
	EXPECT_NEAR(street.groundShare, kitti.groundShare, 0.05);
	const double rangeTol[5] = {0.12, 0.12, 0.04, 0.015, 0.01};
	for (int i = 0; i < 5; i++)
		EXPECT_NEAR(street.rangeShare[i], kitti.rangeShare[i], rangeTol[i]) << "range bin " << i;
	const double heightTol[5] = {0.1, 0.1, 0.12, 0.01, 0.01};
	for (int i = 0; i < 5; i++)
		EXPECT_NEAR(street.heightShare[i], kitti.heightShare[i], heightTol[i])
		    << "height bin " << i;
	EXPECT_GT(street.structureCells, 0.5 * kitti.structureCells);
	EXPECT_NEAR(street.isotropy, kitti.isotropy, 0.1);
	EXPECT_NEAR(street.meanIntensity, kitti.meanIntensity, 0.03);

	// The plain town does not pass: the statistics tell the two apart.
	EXPECT_GT(std::abs(plain.groundShare - kitti.groundShare), 0.2);
	EXPECT_LT(plain.structureCells, 0.5 * kitti.structureCells);
}

TEST(SimRealism, EvalSceneCommand)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const std::string eval = test::bin("rasterslam-eval");
	const auto r =
	    test::runCommand(eval + " scene " + test::sharedData("kitti00-0000-0100/velodyne") +
	                     " --every 50 --label kitti --json");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto j = nlohmann::json::parse(r.output);
	ASSERT_EQ(j.size(), 1u);
	EXPECT_EQ(j[0]["label"], "kitti");
	EXPECT_EQ(j[0]["scans"], 3);
	EXPECT_GT(j[0]["points"].get<double>(), 100000);
	const auto bad = test::runCommand(eval + " scene /nonexistent/x.rawlog");
	EXPECT_NE(bad.exitCode, 0);
	EXPECT_NE(bad.output.find("x.rawlog"), std::string::npos) << bad.output;
	const auto labels = test::runCommand(
	    eval + " scene " + test::sharedData("kitti00-0000-0100/velodyne") + " --label a --label b");
	EXPECT_EQ(labels.exitCode, 2) << labels.output;
}
}  // namespace
