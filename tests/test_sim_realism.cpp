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
#include <set>
#include <tuple>

#include "sim_test_support.h"
#include "test_support.h"

namespace
{
using namespace rasterslam;
constexpr double kDeg = 3.14159265358979323846 / 180;

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
	// A scan without ground (only a wall) is left out and counted, not measured from the
	// sensor's level.
	std::vector<PointXYZI> wallOnly;
	addWall(wallOnly, {-5, 6}, {5, 6}, 0.5f);
	eval::SceneStatsAccumulator c;
	c.add(wallOnly);
	EXPECT_THROW(c.finish(), std::invalid_argument);
	c.add(street);
	const auto withSkip = c.finish();
	EXPECT_EQ(withSkip.scans, 1u);
	EXPECT_EQ(withSkip.scansWithoutGround, 1u);
	EXPECT_DOUBLE_EQ(withSkip.groundShare, s.groundShare);
	const std::string text = eval::formatSceneStats({"street", "room"}, {s, r});
	EXPECT_NE(text.find("ground share"), std::string::npos) << text;
	EXPECT_NE(text.find("wall isotropy"), std::string::npos) << text;
	EXPECT_THROW(eval::formatSceneStats({"a"}, {s, r}), std::invalid_argument);
}

/** One exact scan of flat empty ground with these options, from (0, 0) at `height` m. */
std::vector<PointXYZI> flatScan(const sim::LidarModel& lidar, sim::SimulatorOptions o)
{
	const sim::Simulator s(std::make_shared<const sim::World>(), lidar, sim::Route(), o);
	return s.scanFrom(mrpt::poses::CPose3D(0, 0, o.sensor_height_m, 0, 0, 0), 0, 0).points;
}

TEST(SimLidarModel, Hdl64eBeamsAndLaserHeights)
{
	const auto m = sim::LidarModel::hdl64e();
	ASSERT_EQ(m.beamCount(), 64);
	EXPECT_NEAR(m.elevationsDeg().front(), -24.5551, 1e-9);
	EXPECT_NEAR(m.elevationsDeg().back(), 1.9601, 1e-9);
	// Two blocks: 32 beams below -8.7 deg about 1/2 deg apart, 32 above about 1/3 deg apart.
	EXPECT_LT(m.elevationsDeg()[31], -8.7);
	EXPECT_GT(m.elevationsDeg()[32], -8.6);
	EXPECT_NEAR((m.elevationsDeg()[31] - m.elevationsDeg()[0]) / 31, 0.51, 0.02);
	EXPECT_NEAR((m.elevationsDeg()[63] - m.elevationsDeg()[32]) / 31, 0.34, 0.02);
	EXPECT_EQ(sim::LidarModel::byName("hdl64e").name(), "hdl64e");
	// Each laser above the frame's origin: a ground point of beam b lies at the ground
	// (z = -sensor height in the frame) and (H + lift) / tan(-elevation) away.
	auto o = test::exactSimOptions();
	const auto pts = flatScan(m, o);
	const double H = o.sensor_height_m;
	int checked = 0;
	for (int b : {0, 10, 31, 32, 40})
	{
		const double el = m.elevationsDeg()[static_cast<std::size_t>(b)] * kDeg;
		const double lift = m.originHeights_m()[static_cast<std::size_t>(b)];
		const double d = (H + lift) / std::tan(-el);
		int found = 0;
		for (const auto& p : pts)
			if (std::abs(std::hypot(p.x, p.y) - d) < 0.005)
			{
				EXPECT_NEAR(p.z, -H, 1e-4) << "beam " << b;
				found++;
			}
		EXPECT_NEAR(found, m.azimuthSteps(), m.azimuthSteps() / 50) << "beam " << b;
		checked++;
	}
	EXPECT_EQ(checked, 5);
}

TEST(SimNoise, DarkSurfacesAreSeenLessFar)
{
	const auto m = sim::LidarModel::hdl64e();
	auto o = test::exactSimOptions();
	const auto farthest = [](const std::vector<PointXYZI>& pts)
	{
		double r = 0;
		for (const auto& p : pts)
			r = std::max(r, std::hypot(double{p.x}, double{p.y}));
		return r;
	};
	const double all = farthest(flatScan(m, o));
	o.noise.range_by_reflectivity = true;
	const double limit =
	    m.maxRange_m() * std::sqrt(sim::nominalIntensity(sim::ObjectKind::Ground) / 0.8);
	const double dark = farthest(flatScan(m, o));
	EXPECT_GT(all, limit + 10) << "without it the ground is seen beyond " << limit << " m";
	EXPECT_LE(dark, limit);
	EXPECT_GT(dark, limit - 15);
}

TEST(SimEgo, TheCarryingVehicleHidesWhatIsBehindItAndNothingElse)
{
	{
		// A box up to the sensor would hide everything: refused.
		auto tall = test::exactSimOptions();
		tall.ego_cabin = {1, 1, 1, tall.sensor_height_m + 0.1};
		EXPECT_THROW(sim::Simulator(std::make_shared<const sim::World>(), sim::LidarModel::vlp16(),
		                            sim::Route(), tall),
		             std::invalid_argument);
	}
	const auto m = sim::LidarModel::hdl64e();
	auto o = test::exactSimOptions();
	const auto open = flatScan(m, o);
	o.ego_body = {2.0, 1.8, 0.9, 1.0};
	o.ego_cabin = {0.5, 1.2, 0.75, 1.5};
	const auto shaded = flatScan(m, o);
	ASSERT_LT(shaded.size(), open.size());
	EXPECT_GT(shaded.size(), open.size() / 2);
	// A point stays exactly when the straight line from its laser to it misses both boxes.
	const auto inBox = [&](const sim::EgoBox& b, const Eigen::Vector3d& q)
	{
		return q.x() > -b.back_m && q.x() < b.front_m && std::abs(q.y()) < b.half_width_m &&
		       q.z() < b.height_m - o.sensor_height_m;
	};
	std::set<std::tuple<float, float, float>> kept;
	for (const auto& p : shaded)
		kept.insert({p.x, p.y, p.z});
	std::size_t hidden = 0, wrong = 0;
	double farthestHidden = 0;
	for (const auto& p : open)
	{
		// The laser: above the origin by its lift, found from the point's elevation.
		const double r = std::hypot(p.x, p.y);
		double lift = 0, best = 1e9;
		for (int b = 0; b < m.beamCount(); b++)
		{
			const double l = m.originHeights_m()[static_cast<std::size_t>(b)];
			const double e = std::abs(std::atan2(p.z - l, r) / kDeg -
			                          m.elevationsDeg()[static_cast<std::size_t>(b)]);
			if (e < best)
			{
				best = e;
				lift = l;
			}
		}
		// Walk the line over its first 3 m (the boxes lie within 2.1 m): in 2.5 mm steps, and
		// in 0.02 mm steps where that disagrees (a ray grazing a corner).
		const Eigen::Vector3d from(0, 0, lift), to(p.x, p.y, p.z);
		const double len = (to - from).norm(), span = std::min(len, 3.0);
		const auto walk = [&](double step)
		{
			for (double t = step; t < span; t += step)
			{
				const Eigen::Vector3d q = from + (to - from) * (t / len);
				if (inBox(o.ego_body, q) || inBox(o.ego_cabin, q))
					return true;
			}
			return false;
		};
		const bool stays = kept.count({p.x, p.y, p.z}) > 0;
		bool crosses = walk(0.0025);
		if (stays == crosses)
			crosses = walk(0.00002);
		hidden += !stays;
		wrong += stays == crosses;
		if (!stays)
			farthestHidden = std::max(farthestHidden, r);
	}
	EXPECT_EQ(hidden, open.size() - shaded.size());
	EXPECT_EQ(wrong, 0u) << "of " << hidden << " hidden";
	// What is hidden is the steep rays' ground near the car: more than three beams' worth,
	// all within 10 m.
	EXPECT_GT(hidden, 3u * static_cast<std::size_t>(m.azimuthSteps()));
	EXPECT_LT(farthestHidden, 10);
}

bool sameShape(const sim::Shape& a, const sim::Shape& b)
{
	return a.type == b.type && a.kind == b.kind && a.cx == b.cx && a.cy == b.cy && a.cz == b.cz &&
	       a.a == b.a && a.b == b.b && a.zmin == b.zmin && a.zmax == b.zmax;
}

TEST(SimTown, StreetDetailKeepsTheLayout)
{
	sim::TownParams plain;
	sim::TownParams rich = plain;
	rich.hedge_share = 0.6;
	rich.signs_per_100m = 3;
	rich.street_furniture_per_100m = 5;
	rich.facade_detail = true;
	rich.curb_m = 0.12;
	rich.irregular_crowns = true;
	const auto a = sim::World::generate(plain, 42), b = sim::World::generate(rich, 42);
	// Every shape of the plain town is in the detailed one, in the same order.
	std::size_t j = 0;
	for (const auto& s : a.shapes())
	{
		while (j < b.shapes().size() && !sameShape(s, b.shapes()[j]))
			j++;
		ASSERT_LT(j, b.shapes().size()) << "a shape of the plain town is missing";
		j++;
	}
	EXPECT_GT(b.shapes().size(), 3 * a.shapes().size());
	// Kerb slabs 0.12 m high, flat signs, lobes: the added shapes are what was asked for.
	std::size_t slabs = 0, panels = 0;
	for (const auto& s : b.shapes())
	{
		slabs += s.kind == sim::ObjectKind::Ground && s.type == sim::ShapeType::Box;
		panels += s.kind == sim::ObjectKind::Pole && s.type == sim::ShapeType::Box;
	}
	EXPECT_GT(slabs, 500u);
	EXPECT_GT(panels, 10u);

	// Vans and SUVs: taller parked vehicles.
	rich.van_share = 0.5;
	const auto c = sim::World::generate(rich, 42);
	std::size_t tall = 0;
	for (const auto& s : c.shapes())
		tall += s.kind == sim::ObjectKind::Car && s.zmax - s.zmin > 1.5;  // a car: 0.7-1.0
	EXPECT_GT(tall, 10u) << "vans stand 1.9-2.4 m high, 0.3 m off the ground";
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
	// Labels between the inputs, and a folder given with a trailing slash.
	const std::string velo = test::sharedData("kitti00-0000-0100/velodyne");
	const auto mixed = test::runCommand(eval + " scene --label first " + velo + " --label second " +
	                                    velo + " --every 50 --json");
	ASSERT_EQ(mixed.exitCode, 0) << mixed.output;
	const auto jm = nlohmann::json::parse(mixed.output);
	ASSERT_EQ(jm.size(), 2u);
	EXPECT_EQ(jm[0]["label"], "first");
	EXPECT_EQ(jm[1]["label"], "second");
	const auto slash = test::runCommand(eval + " scene " + velo + "/ --every 50 --json");
	ASSERT_EQ(slash.exitCode, 0) << slash.output;
	EXPECT_EQ(nlohmann::json::parse(slash.output)[0]["label"], "velodyne");
}
}  // namespace
