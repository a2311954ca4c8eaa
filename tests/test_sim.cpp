// Tests of the LiDAR simulator: beam geometry, ranges against analytic scenes, noise and
// dropouts, determinism, the route, the town, scenario files and the rawlog it writes.
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/maps/CPointsMap.h>
#include <mrpt/maps/registerAllClasses.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/registerAllClasses.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/core/sweep.h>
#include <rasterslam/io/rawlog_writer.h>
#include <rasterslam/sim/simulator.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <set>

#include "sim_test_support.h"
#include "test_support.h"

namespace
{
using namespace rasterslam;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180;

sim::Simulator makeSim(sim::World world, const sim::LidarModel& lidar, sim::SimulatorOptions o)
{
	return sim::Simulator(std::make_shared<const sim::World>(std::move(world)), lidar, sim::Route(),
	                      o);
}

double elevationDeg(const PointXYZI& p)
{
	return std::atan2(p.z, std::hypot(p.x, p.y)) / kDeg;
}
double rangeOf(const PointXYZI& p)
{
	return std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z);
}

/** Index of the beam nearest to `elevDeg`, and the distance to it. */
int nearestBeam(const sim::LidarModel& m, double elevDeg, double& errDeg)
{
	int best = 0;
	errDeg = 1e9;
	for (int b = 0; b < m.beamCount(); b++)
		if (std::abs(m.elevationsDeg()[b] - elevDeg) < errDeg)
		{
			errDeg = std::abs(m.elevationsDeg()[b] - elevDeg);
			best = b;
		}
	return best;
}

sim::Shape box(double x0, double x1, double y0, double y1, double z0, double z1, sim::ObjectKind k)
{
	sim::Shape s;
	s.type = sim::ShapeType::Box;
	s.kind = k;
	s.cx = (x0 + x1) / 2;
	s.cy = (y0 + y1) / 2;
	s.a = (x1 - x0) / 2;
	s.b = (y1 - y0) / 2;
	s.zmin = z0;
	s.zmax = z1;
	return s;
}

std::string scenarioPath(const std::string& name)
{
	return std::string(RASTERSLAM_SOURCE_DIR) + "/rawlogs/" + name;
}

std::string writeFile(const std::filesystem::path& p, const std::string& text)
{
	std::ofstream(p) << text;
	return p.string();
}
}  // namespace

TEST(SimLidarModel, BeamTables)
{
	const auto hdl = sim::LidarModel::hdl64();
	ASSERT_EQ(hdl.beamCount(), 64);
	EXPECT_NEAR(hdl.elevationsDeg().front(), -24.8, 1e-9);
	EXPECT_NEAR(hdl.elevationsDeg().back(), 2.0, 1e-9);
	EXPECT_EQ(hdl.azimuthSteps(), 2083);
	EXPECT_NEAR(hdl.azimuthStepDeg(), 0.1728, 1e-4);
	for (int b = 1; b < 64; b++)
		EXPECT_NEAR(hdl.elevationsDeg()[b] - hdl.elevationsDeg()[b - 1], 26.8 / 63, 1e-9);
	const auto vlp = sim::LidarModel::vlp16();
	ASSERT_EQ(vlp.beamCount(), 16);
	EXPECT_DOUBLE_EQ(vlp.elevationsDeg().front(), -15.0);
	EXPECT_DOUBLE_EQ(vlp.elevationsDeg().back(), 15.0);
	for (int b = 1; b < 16; b++)
		EXPECT_NEAR(vlp.elevationsDeg()[b] - vlp.elevationsDeg()[b - 1], 2.0, 1e-12);
	EXPECT_EQ(vlp.azimuthSteps(), 1800);
	EXPECT_THROW(sim::LidarModel::byName("hdl32"), std::invalid_argument);
}

TEST(SimLidarModel, ElevationsAndAzimuthsRecoveredFromPoints)
{
	for (const auto& model : {sim::LidarModel::hdl64(), sim::LidarModel::vlp16()})
	{
		SCOPED_TRACE(model.name());
		// Flat ground inside a closed room: every beam, even the upward ones, returns.
		sim::World world;
		world.add(box(-30, 30, -30, 30, -1, 15, sim::ObjectKind::Building));
		const auto scan = makeSim(world, model, test::exactSimOptions())
		                      .scanFrom(mrpt::poses::CPose3D(0, 0, 1.73, 0.3, 0, 0), 0, 0);
		ASSERT_EQ(scan.points.size(), static_cast<std::size_t>(model.raysPerScan()));
		std::map<int, int> perBeam;
		std::set<long> azimuths;
		double worst = 0;
		for (const auto& p : scan.points)
		{
			double err = 0;
			perBeam[nearestBeam(model, elevationDeg(p), err)]++;
			worst = std::max(worst, err);
			const double az = std::atan2(p.y, p.x) / kDeg;
			const double steps = (az < 0 ? az + 360 : az) / model.azimuthStepDeg();
			EXPECT_NEAR(steps, std::round(steps), 1e-3);
			azimuths.insert(std::lround(steps) % model.azimuthSteps());
		}
		EXPECT_LT(worst, 0.01);
		EXPECT_EQ(perBeam.size(), static_cast<std::size_t>(model.beamCount()));
		for (const auto& [beam, n] : perBeam)
			EXPECT_EQ(n, model.azimuthSteps()) << beam;
		EXPECT_EQ(azimuths.size(), static_cast<std::size_t>(model.azimuthSteps()));
	}
}

TEST(SimRaycast, FlatGroundRangesAreExact)
{
	const auto model = sim::LidarModel::hdl64();
	const double h = 1.73;
	const auto scan = makeSim(sim::World(), model, test::exactSimOptions())
	                      .scanFrom(mrpt::poses::CPose3D(5, -3, h, 1.0, 0, 0), 0, 0);
	std::size_t expectedCount = 0;
	for (const double e : model.elevationsDeg())
	{
		if (e >= 0)
			continue;
		const double r = h / std::sin(-e * kDeg);
		if (r >= model.minRange_m() && r <= model.maxRange_m())
			expectedCount += model.azimuthSteps();
	}
	EXPECT_EQ(scan.points.size(), expectedCount);
	double worst = 0;
	for (const auto& p : scan.points)
	{
		double err = 0;
		const int b = nearestBeam(model, elevationDeg(p), err);
		const double expected = h / std::sin(-model.elevationsDeg()[b] * kDeg);
		worst = std::max(worst, std::abs(rangeOf(p) - expected));
	}
	EXPECT_LT(worst, 1e-3);
}

TEST(SimRaycast, PointResolutionRoundsCoordinates)
{
	const auto model = sim::LidarModel::vlp16();
	auto o = test::exactSimOptions();
	o.point_resolution_m = 1.0 / 1024;
	o.noise.intensity_sigma = 0.05;
	const auto scan =
	    makeSim(sim::World(), model, o).scanFrom(mrpt::poses::CPose3D(0, 0, 1.73, 0.2, 0, 0), 0, 0);
	ASSERT_GT(scan.points.size(), 1000u);
	double worst = 0;
	for (const auto& p : scan.points)
	{
		for (const float c : {p.x, p.y, p.z})
			ASSERT_EQ(c * 1024, std::round(c * 1024)) << c;
		ASSERT_EQ(p.intensity * 256, std::round(p.intensity * 256)) << p.intensity;
		double err = 0;
		const int b = nearestBeam(model, elevationDeg(p), err);
		worst = std::max(worst,
		                 std::abs(rangeOf(p) - 1.73 / std::sin(-model.elevationsDeg()[b] * kDeg)));
	}
	EXPECT_LT(worst, std::sqrt(3.0) / 2048 + 1e-5);
}

TEST(SimRaycast, PointsLieOnSlopedGround)
{
	const sim::GroundModel ground(0.5, {0.02, -0.015},
	                              {{20, 10, 2.0, 60}, {-30, -25, -1.5, 50}, {5, -40, 1.0, 30}});
	EXPECT_LE(ground.maxSlope(), 0.2);
	const sim::World world(ground);
	const auto T = sim::sensorPoseOnGround(ground, {3, 4, 0.7}, 1.73);
	const auto scan =
	    makeSim(world, sim::LidarModel::hdl64(), test::exactSimOptions()).scanFrom(T, 0, 0);
	EXPECT_GT(scan.points.size(), 40u * 2083u);
	double worst = 0;
	for (const auto& p : scan.points)
	{
		double gx, gy, gz;
		T.composePoint(p.x, p.y, p.z, gx, gy, gz);
		worst = std::max(worst, std::abs(gz - ground.height(gx, gy)));
	}
	EXPECT_LT(worst, 2e-3);
}

TEST(SimRaycast, WallAtKnownDistance)
{
	const auto model = sim::LidarModel::hdl64();
	const double h = 1.73, wallX = 10, halfY = 5, top = 3;
	sim::World world;
	world.add(box(wallX, wallX + 1, -halfY, halfY, -0.5, top, sim::ObjectKind::Wall));
	const auto scan = makeSim(world, model, test::exactSimOptions())
	                      .scanFrom(mrpt::poses::CPose3D(0, 0, h, 0, 0, 0), 0, 0);
	// Rays that reach the plane x = wallX inside the wall's face before reaching the ground.
	std::size_t expected = 0;
	for (int a = 0; a < model.azimuthSteps(); a++)
		for (const double e : model.elevationsDeg())
		{
			const double az = 2 * kPi * a / model.azimuthSteps();
			const double dx = std::cos(e * kDeg) * std::cos(az),
			             dy = std::cos(e * kDeg) * std::sin(az);
			if (dx <= 0)
				continue;
			const double t = wallX / dx, y = t * dy, z = h + t * std::sin(e * kDeg);
			if (std::abs(y) < halfY && z > 1e-3 && z < top)
				expected++;
		}
	std::size_t onWall = 0;
	for (const auto& p : scan.points)
	{
		if (std::abs(p.x - wallX) < 1e-3 && std::abs(p.y) <= halfY && p.z + h > 1e-3)
			onWall++;
		// Nothing behind the wall inside its shadow.
		const double s = wallX / p.x;
		if (p.x > wallX + 1e-3 && std::abs(p.y * s) < halfY && h + p.z * s > 0 && h + p.z * s < top)
			ADD_FAILURE() << "point behind the wall: " << p.x << " " << p.y << " " << p.z;
	}
	EXPECT_GT(expected, 1000u);
	EXPECT_EQ(onWall, expected);
}

TEST(SimRaycast, PoleAndShapes)
{
	sim::World world;
	world.addCylinderOnGround(8, 2, 0.3, 5, sim::ObjectKind::Pole);
	const auto scan = makeSim(world, sim::LidarModel::hdl64(), test::exactSimOptions())
	                      .scanFrom(mrpt::poses::CPose3D(0, 0, 1.73, 0, 0, 0), 0, 0);
	int onPole = 0;
	for (const auto& p : scan.points)
	{
		const double d = std::hypot(p.x - 8, p.y - 2);
		if (d < 0.6 && p.z + 1.73 > 0.01)
		{
			EXPECT_NEAR(d, 0.3, 1e-3);
			onPole++;
		}
	}
	EXPECT_GT(onPole, 100);

	// Direct intersections with known answers.
	sim::Shape e;
	e.type = sim::ShapeType::Ellipsoid;
	e.cx = 10;
	e.a = 2;
	e.b = 3;
	EXPECT_NEAR(sim::intersectShape(e, {0, 0, 0}, {1, 0, 0}), 8, 1e-12);
	EXPECT_NEAR(sim::intersectShape(e, {10, 0, -10}, {0, 0, 1}), 7, 1e-12);
	EXPECT_TRUE(std::isinf(sim::intersectShape(e, {0, 0, 3.1}, {1, 0, 0})));
	sim::Shape b = box(-1, 1, -1, 1, 0, 1, sim::ObjectKind::Car);
	b.cosYaw = b.sinYaw = std::sqrt(0.5);
	EXPECT_NEAR(sim::intersectShape(b, {-10, 0, 0.5}, {1, 0, 0}), 10 - std::sqrt(2.0), 1e-12);
	EXPECT_NEAR(sim::intersectShape(b, {0, 0, 0.5}, {0, 1, 0}), std::sqrt(2.0), 1e-12);
	EXPECT_TRUE(std::isinf(sim::intersectShape(b, {-10, 0, 1.5}, {1, 0, 0})));
}

TEST(SimNoise, DropoutRateAndRangeSigma)
{
	const auto model = sim::LidarModel::hdl64();
	const mrpt::poses::CPose3D T(0, 0, 1.73, 0, 0, 0);
	const auto clean = makeSim(sim::World(), model, test::exactSimOptions()).scanFrom(T, 0, 0);
	auto o = test::exactSimOptions();
	o.noise.dropout_prob = 0.1;
	o.noise.range_sigma_m = 0.02;
	const auto noisy = makeSim(sim::World(), model, o).scanFrom(T, 0, 0);
	const double kept = static_cast<double>(noisy.points.size()) / clean.points.size();
	EXPECT_NEAR(kept, 0.9, 0.01);
	double sum = 0, sum2 = 0;
	for (const auto& p : noisy.points)
	{
		double err = 0;
		const int b = nearestBeam(model, elevationDeg(p), err);
		const double d = rangeOf(p) - 1.73 / std::sin(-model.elevationsDeg()[b] * kDeg);
		sum += d;
		sum2 += d * d;
	}
	const double n = static_cast<double>(noisy.points.size());
	EXPECT_NEAR(sum / n, 0, 1e-3);
	EXPECT_NEAR(std::sqrt(sum2 / n), 0.02, 1e-3);
}

TEST(SimNoise, IntensityByKind)
{
	sim::World world;
	world.add(box(6, 10, -1, 1, 0.3, 1.5, sim::ObjectKind::Car));
	auto o = test::exactSimOptions();
	o.noise.intensity_sigma = 0.05;
	const auto scan = makeSim(world, sim::LidarModel::hdl64(), o)
	                      .scanFrom(mrpt::poses::CPose3D(0, 0, 1.73, 0, 0, 0), 0, 0);
	double groundSum = 0, carSum = 0;
	int groundN = 0, carN = 0;
	for (const auto& p : scan.points)
	{
		EXPECT_GE(p.intensity, 0.f);
		EXPECT_LE(p.intensity, 1.f);
		if (std::abs(p.z + 1.73) < 1e-3 && p.x < 5)
		{
			groundSum += p.intensity;
			groundN++;
		}
		if (p.x > 5.99 && p.x < 10 && std::abs(p.y) <= 1 && p.z + 1.73 > 0.31)
		{
			carSum += p.intensity;
			carN++;
		}
	}
	ASSERT_GT(groundN, 1000);
	ASSERT_GT(carN, 100);
	EXPECT_NEAR(groundSum / groundN, 0.28, 0.01);
	EXPECT_NEAR(carSum / carN, 0.22, 0.01);
}

TEST(SimSimulator, DeterministicForASeed)
{
	auto sc = sim::loadScenario(scenarioPath("town-vlp16.yaml"));
	const auto a = sim::Simulator::fromScenario(sc).scan(17);
	sc.threads = 1;
	const auto b = sim::Simulator::fromScenario(sc).scan(17);
	ASSERT_EQ(a.points.size(), b.points.size());
	ASSERT_GT(a.points.size(), 10000u);
	for (std::size_t i = 0; i < a.points.size(); i++)
	{
		ASSERT_EQ(a.points[i].x, b.points[i].x) << i;
		ASSERT_EQ(a.points[i].y, b.points[i].y) << i;
		ASSERT_EQ(a.points[i].z, b.points[i].z) << i;
		ASSERT_EQ(a.points[i].intensity, b.points[i].intensity) << i;
	}
	EXPECT_EQ((a.groundTruth->asVectorVal() - b.groundTruth->asVectorVal()).norm(), 0.0);
	EXPECT_DOUBLE_EQ(a.stamp, sc.start_stamp_s + 1.7);

	sc.seed += 1;
	const auto c = sim::Simulator::fromScenario(sc).scan(17);
	std::size_t same = 0;
	for (std::size_t i = 0; i < std::min(a.points.size(), c.points.size()); i++)
		same += a.points[i].x == c.points[i].x && a.points[i].y == c.points[i].y;
	EXPECT_LT(same, a.points.size() / 10);
}

TEST(SimTown, DeterministicAndStreetsClear)
{
	sim::TownParams p;
	const auto w1 = sim::World::generate(p, 3), w2 = sim::World::generate(p, 3);
	const auto w3 = sim::World::generate(p, 4);
	ASSERT_EQ(w1.shapes().size(), w2.shapes().size());
	for (std::size_t i = 0; i < w1.shapes().size(); i++)
	{
		ASSERT_EQ(w1.shapes()[i].cx, w2.shapes()[i].cx);
		ASSERT_EQ(w1.shapes()[i].zmax, w2.shapes()[i].zmax);
	}
	EXPECT_FALSE(w1.shapes().size() == w3.shapes().size() &&
	             w1.shapes()[5].cx == w3.shapes()[5].cx);
	EXPECT_LE(w1.ground().maxSlope(), p.max_slope + 1e-12);

	std::map<sim::ObjectKind, int> kinds;
	const double P = p.pitch(), hw = p.street_width_m / 2;
	for (const auto& s : w1.shapes())
	{
		kinds[s.kind]++;
		if (s.kind == sim::ObjectKind::TreeCrown)
			continue;  // overhangs, 2 m up
		const double ex = s.type == sim::ShapeType::Box
		                      ? std::abs(s.cosYaw) * s.a + std::abs(s.sinYaw) * s.b
		                      : s.a;
		const double ey = s.type == sim::ShapeType::Box
		                      ? std::abs(s.sinYaw) * s.a + std::abs(s.cosYaw) * s.b
		                      : s.a;
		// Distance of the shape's extent from each street centre line; cars keep to the kerb.
		const double keep = s.kind == sim::ObjectKind::Car ? hw - 2.1 : hw;
		for (int i = 0; i <= p.blocks_x; i++)
		{
			if (s.cy > -hw && s.cy < p.blocks_y * P + hw)
			{
				EXPECT_GE(std::abs(s.cx - i * P) - ex, keep - 1e-9) << sim::kindName(s.kind);
			}
		}
		for (int j = 0; j <= p.blocks_y; j++)
		{
			if (s.cx > -hw && s.cx < p.blocks_x * P + hw)
			{
				EXPECT_GE(std::abs(s.cy - j * P) - ey, keep - 1e-9) << sim::kindName(s.kind);
			}
		}
	}
	for (const auto k :
	     {sim::ObjectKind::Building, sim::ObjectKind::Wall, sim::ObjectKind::Car,
	      sim::ObjectKind::Pole, sim::ObjectKind::TreeTrunk, sim::ObjectKind::TreeCrown})
		EXPECT_GT(kinds[k], 3) << sim::kindName(k);
}

TEST(SimRoute, FilletGeometry)
{
	sim::TownParams t;
	const double R = 6;
	const sim::Route r(sim::Route::blockLoop(t, 2, 1), true, R);
	// Each of the four right-angle corners replaces 2R of straight by a quarter circle.
	EXPECT_NEAR(r.length(), 2 * (2 + 1) * t.pitch() - 4 * R * (2 - kPi / 2), 1e-9);
	const auto start = r.at(0);
	EXPECT_NEAR(start.x, t.pitch(), 1e-9);
	EXPECT_NEAR(start.y, 0, 1e-9);
	const double ds = 0.05;
	for (double s = 0; s < r.length(); s += ds)
	{
		const auto a = r.at(s), b = r.at(s + ds);
		ASSERT_NEAR(std::hypot(b.x - a.x, b.y - a.y), ds, 1e-4) << s;
		const double dyaw = std::remainder(b.yaw - a.yaw, 2 * kPi);
		ASSERT_LE(std::abs(dyaw), ds / R + 1e-9) << s;
	}
	const auto lap = r.at(r.length() + 1.0), one = r.at(1.0);
	EXPECT_NEAR(lap.x, one.x, 1e-9);
	EXPECT_NEAR(lap.y, one.y, 1e-9);
}

TEST(SimRoute, SlowsForCornersWithinItsBounds)
{
	sim::TownParams t;
	const double R = 6, vmax = 8, aLat = 2.5, aLon = 1.5;
	const sim::Route route(sim::Route::blockLoop(t, 2, 1), true, R);
	const auto world = std::make_shared<const sim::World>();  // flat: the sensor right above
	sim::SimulatorOptions o;
	o.speed_mps = vmax;
	const sim::Simulator constant(world, sim::LidarModel::vlp16(), route, o);
	// Off by default: speed_mps everywhere, the distance exactly speed * t.
	for (double t0 : {0.0, 1.3, 47.0, 1000.5})
		EXPECT_EQ(constant.distanceAt(t0), vmax * t0);
	EXPECT_DOUBLE_EQ(constant.lapTime(), route.length() / vmax);

	o.corner_accel_mps2 = aLat;
	o.accel_mps2 = aLon;
	const sim::Simulator slowing(world, sim::LidarModel::vlp16(), route, o);
	const double lap = slowing.lapTime();
	EXPECT_GT(lap, route.length() / vmax + 4 * 2 * (vmax - std::sqrt(aLat * R)) / aLon * 0.2);
	EXPECT_NEAR(slowing.distanceAt(lap), route.length(), 1e-6);
	EXPECT_NEAR(slowing.distanceAt(lap + 3.3), route.length() + slowing.distanceAt(3.3), 1e-6);
	// Speed and acceleration from the distance every 0.1 s over a lap.
	const double dt = 0.1, vCorner = std::sqrt(aLat * R);
	double slowest = vmax, prevV = -1;
	int onArcs = 0;
	for (double t0 = 0; t0 + dt < lap; t0 += dt)
	{
		const double s0 = slowing.distanceAt(t0), s1 = slowing.distanceAt(t0 + dt);
		const double v = (s1 - s0) / dt;
		ASSERT_GT(v, 0) << t0;
		ASSERT_LE(v, vmax + 1e-6) << t0;
		if (route.curvatureAt(s0) > 0 && route.curvatureAt(s1) > 0)
		{
			onArcs++;
			ASSERT_LE(v, vCorner * 1.001) << "too fast in a corner at t = " << t0;
		}
		if (prevV >= 0)
		{
			ASSERT_LE(std::abs(v - prevV) / dt, aLon * 1.05) << t0;
		}
		prevV = v;
		slowest = std::min(slowest, v);
	}
	EXPECT_GT(onArcs, 4 * 5);  // four corners of 9.4 m at 3.9 m/s: 2.4 s each
	EXPECT_NEAR(slowest, vCorner, 0.05);
	// The pose follows: the sensor is where the route is at that distance.
	const auto p = slowing.sensorPoseAt(o.start_stamp_s + 20);
	const auto q = route.at(slowing.distanceAt(20));
	EXPECT_NEAR(p.x(), q.x, 1e-6);
	EXPECT_NEAR(p.y(), q.y, 1e-6);

	o.accel_mps2 = 0;
	EXPECT_THROW(sim::Simulator(world, sim::LidarModel::vlp16(), route, o), std::invalid_argument);
}

TEST(SimRoute, DemoClosesItsLoopOnTheGround)
{
	const auto sc = sim::loadScenario(scenarioPath("town-loop.yaml"));
	const auto simu = sim::Simulator::fromScenario(sc);
	const auto& ground = simu.world().ground();
	std::vector<mrpt::poses::CPose3D> poses;
	for (std::size_t k = 0; k < sc.scans; k++)
		poses.push_back(simu.sensorPose(k));
	bool closes = false;
	for (std::size_t i = 0; i < poses.size() && !closes; i++)
		for (std::size_t j = i + static_cast<std::size_t>(30 * sc.rate_hz) + 1; j < poses.size();
		     j++)
			if (poses[i].distanceTo(poses[j]) < 3)
			{
				closes = true;
				break;
			}
	EXPECT_TRUE(closes);
	for (std::size_t k = 0; k < poses.size(); k++)
	{
		const auto& T = poses[k];
		const Eigen::Vector2d g = ground.gradient(T.x(), T.y());
		const Eigen::Vector3d n = Eigen::Vector3d(-g.x(), -g.y(), 1).normalized();
		const Eigen::Vector3d up = T.getRotationMatrix().asEigen().col(2);
		ASSERT_NEAR(T.z() - ground.height(T.x(), T.y()), sc.sensor_height_m, 0.02) << k;
		ASSERT_GT(up.dot(n), std::cos(0.5 * kDeg)) << k;
		if (k > 0)
		{
			ASSERT_NEAR(T.distanceTo(poses[k - 1]), sc.speed_mps / sc.rate_hz, 0.03) << k;
		}
		// The road is clear: straight down is ground, sideways there is room.
		const Eigen::Vector3d o(T.x(), T.y(), T.z());
		ASSERT_EQ(simu.world().raycast(o, {0, 0, -1}, 10).kind, sim::ObjectKind::Ground) << k;
		const Eigen::Vector3d left = T.getRotationMatrix().asEigen().col(1);
		const Eigen::Vector3d low = o - 1.0 * up;
		EXPECT_GT(simu.world().raycast(low, left, 10).range, 2.5) << k;
		EXPECT_GT(simu.world().raycast(low, -left, 10).range, 2.5) << k;
	}
}

TEST(SimScenario, DefaultsAndErrors)
{
	const auto dir = test::tempDir("sim");
	const auto minimal = writeFile(dir / "min.yaml", "seed: 5\n");
	const auto sc = sim::loadScenario(minimal);
	EXPECT_EQ(sc.seed, 5u);
	EXPECT_EQ(sc.scans, 300u);
	EXPECT_EQ(sc.lidar, "hdl64");
	EXPECT_EQ(sc.town.blocks_x, 3);
	EXPECT_DOUBLE_EQ(sc.noise.dropout_prob, 0.02);
	EXPECT_DOUBLE_EQ(sc.sensor_height_m, 1.73);

	const auto wp = sim::loadScenario(writeFile(
	    dir / "wp.yaml", "route: [[0, 0], [64, 0], [64, 64]]\nnoise: {dropout_prob: 0.5}\n"));
	EXPECT_EQ(wp.route.pattern, "waypoints");
	ASSERT_EQ(wp.route.waypoints.size(), 3u);
	EXPECT_DOUBLE_EQ(wp.route.waypoints[1].x(), 64);
	EXPECT_DOUBLE_EQ(wp.noise.dropout_prob, 0.5);

	const auto expectError =
	    [&](const std::string& name, const std::string& text, const std::string& key)
	{
		const auto path = writeFile(dir / name, text);
		try
		{
			sim::loadScenario(path);
			ADD_FAILURE() << "no error for " << text;
		}
		catch (const std::runtime_error& e)
		{
			const std::string msg = e.what();
			EXPECT_NE(msg.find(path), std::string::npos) << msg;
			EXPECT_NE(msg.find(key), std::string::npos) << msg;
		}
	};
	expectError("unknown.yaml", "town:\n  blocks_z: 3\n", "town.blocks_z");
	expectError("unknowntop.yaml", "sead: 3\n", "sead");
	expectError("type.yaml", "scans: many\n", "scans");
	expectError("frac.yaml", "town:\n  blocks_x: 2.5\n", "town.blocks_x");
	expectError("range.yaml", "noise:\n  dropout_prob: 1.5\n", "noise.dropout_prob");
	expectError("lidar.yaml", "lidar: hdl32\n", "lidar");
	expectError("map.yaml", "noise: 3\n", "noise");
	expectError("world.yaml", "world: moon\n", "world");
	// The realism keys (rawlogs/town-kitti.yaml).
	expectError("body.yaml", "body:\n  pitch_deg: 9\n", "body.pitch_deg");
	expectError("ego.yaml", "ego:\n  body: {front_m: -1}\n", "ego.body");
	expectError("egokey.yaml", "ego:\n  roof: {front_m: 1}\n", "ego.roof");
	expectError("egohalf.yaml", "ego:\n  body: {front_m: 2}\n", "ego.body");
	expectError("egotall.yaml",
	            "ego:\n  cabin: {front_m: 1, back_m: 1, half_width_m: 1, height_m: 1.8}\n",
	            "ego.cabin");
	expectError("signs.yaml", "town:\n  signs_per_100m: 1000\n", "town.signs_per_100m");
	expectError("corner.yaml", "corner_accel_mps2: -1\n", "corner_accel_mps2");
	expectError("accel.yaml", "accel_mps2: 0\n", "accel_mps2");
	expectError("foliage.yaml", "noise:\n  foliage_depth_m: 3\n", "noise.foliage_depth_m");
	expectError("refl.yaml", "noise:\n  range_by_reflectivity: 3\n", "noise.range_by_reflectivity");
	expectError("hedge.yaml", "town:\n  hedge_share: 2\n", "town.hedge_share");
	expectError("curb.yaml", "town:\n  curb_m: 1\n", "town.curb_m");
	expectError("van.yaml", "town:\n  van_share: -0.1\n", "town.van_share");
	expectError("jitter.yaml", "town:\n  parking_jitter_m: 2\n", "town.parking_jitter_m");
	expectError("facade.yaml", "town:\n  facade_detail: maybe\n", "town.facade_detail");
	expectError("tour.yaml", "route: room_tour\n", "route.pattern");  // a town has no rooms
	expectError("rows.yaml", "world: indoor\nroute: room_tour\nindoor: {rooms_y: 3}\n",
	            "indoor.rooms_y");  // a closed tour of 3 rows would cross walls
	expectError("one.yaml", "world: indoor\nroute: room_tour\nindoor: {rooms_x: 1, rooms_y: 1}\n",
	            "indoor.rooms_x");
	EXPECT_THROW(sim::loadScenario((dir / "missing.yaml").string()), std::runtime_error);
}

TEST(SimRawlog, WrittenAndReadBackByMrpt)
{
	mrpt::maps::registerAllClasses_mrpt_maps();
	mrpt::obs::registerAllClasses_mrpt_obs();
	auto sc = sim::loadScenario(scenarioPath("town-vlp16.yaml"));
	const auto simu = sim::Simulator::fromScenario(sc);
	const auto path = (test::tempDir("sim") / "small.rawlog").string();
	const std::size_t n = 4;
	std::vector<Scan> scans;
	{
		io::RawlogWriter w(path, 1);
		for (std::size_t k = 0; k < n; k++)
		{
			scans.push_back(simu.scan(k * 10));
			w.writeScan(scans.back());
		}
		w.close();
	}
	mrpt::io::CFileGZInputStream f(path);
	auto ar = mrpt::serialization::archiveFrom(f);
	std::size_t clouds = 0, poses = 0;
	for (;;)
	{
		mrpt::serialization::CSerializable::Ptr obj;
		try
		{
			obj = ar.ReadObject();
		}
		catch (const mrpt::serialization::CExceptionEOF&)
		{
			break;
		}
		if (auto pc = std::dynamic_pointer_cast<mrpt::obs::CObservationPointCloud>(obj))
		{
			ASSERT_LT(clouds, n);
			ASSERT_TRUE(pc->pointcloud);
			EXPECT_EQ(pc->pointcloud->size(), scans[clouds].points.size());
			EXPECT_GT(pc->pointcloud->size(), 5000u);
			EXPECT_EQ(pc->sensorLabel, "LIDAR");
			EXPECT_NEAR(mrpt::Clock::toDouble(pc->timestamp), scans[clouds].stamp, 1e-5);
			clouds++;
		}
		else if (auto rp = std::dynamic_pointer_cast<mrpt::obs::CObservationRobotPose>(obj))
		{
			ASSERT_LT(poses, n);
			EXPECT_LT(
			    (rp->pose.mean.asVectorVal() - scans[poses].groundTruth->asVectorVal()).norm(),
			    1e-9);
			poses++;
		}
		else
			ADD_FAILURE() << "unexpected " << obj->GetRuntimeClass()->className;
	}
	EXPECT_EQ(clouds, n);
	EXPECT_EQ(poses, n);
}

// Motion within a sweep: every point of a moving sweep was measured from the pose of its own
// instant (its azimuth gives the instant), and deskewSweep with the sweep's motion moves it
// into the sensor frame at the sweep's end, where the scan's ground truth is.
TEST(SimSweep, EachAzimuthIsMeasuredAtItsInstantAndDeskewingUndoesTheMotion)
{
	auto sc = sim::loadScenario(scenarioPath("town-sweep.yaml"));
	ASSERT_TRUE(sc.motion_within_sweep);
	sc.noise.range_sigma_m = 0;  // exact ranges: every point is on a surface
	sc.noise.dropout_prob = 0;
	sc.point_resolution_m = 0;
	const auto simu = sim::Simulator::fromScenario(sc);
	// The scan of the fastest turn among the first 150 (the sweep turns and moves the most).
	std::size_t k = 1;
	double fastest = 0;
	for (std::size_t i = 1; i < 150; i++)
	{
		const auto d = simu.sensorPose(i) - simu.sensorPose(i - 1);
		if (std::abs(d.yaw()) > fastest)
			fastest = std::abs(d.yaw()), k = i;
	}
	ASSERT_GT(fastest / kDeg, 3.0) << "no turn in the first 150 scans";
	const Scan scan = simu.scan(k);
	ASSERT_GT(scan.points.size(), 50000u);
	const double period = 1 / sc.rate_hz, end = simu.stamp(k);
	const mrpt::poses::CPose3D Pend = simu.sensorPose(k);
	EXPECT_NEAR((*scan.groundTruth - Pend).norm(), 0.0, 1e-9)
	    << "the ground truth is the sweep's end";
	SweepModel model;
	model.startAzimuth_deg = sc.sweep_start_azimuth_deg;
	model.clockwise = sc.sweep_clockwise;

	// Each point, placed in the world from the pose of the instant its azimuth gives, lies on
	// what the world has there: a ray cast from that pose towards it stops at it.
	std::size_t onSurface = 0, checked = 0;
	std::vector<Eigen::Vector3d> exact;  // each point in the sensor frame at the sweep's end
	exact.reserve(scan.points.size());
	for (std::size_t i = 0; i < scan.points.size(); i++)
	{
		const auto& p = scan.points[i];
		const double f = model.fraction(std::atan2(p.y, p.x));
		const mrpt::poses::CPose3D P = simu.sensorPoseAt(end - (1 - f) * period);
		double wx, wy, wz;
		P.composePoint(p.x, p.y, p.z, wx, wy, wz);
		double ex, ey, ez;
		Pend.inverseComposePoint(wx, wy, wz, ex, ey, ez);
		exact.emplace_back(ex, ey, ez);
		if (i % 50 == 0)
		{
			const Eigen::Vector3d o(P.x(), P.y(), P.z()), w(wx, wy, wz);
			const double r = (w - o).norm();
			const auto hit = simu.world().raycast(o, (w - o) / r, r + 5);
			++checked;
			onSurface += hit.hit() && std::abs(hit.range - r) < 0.01;
		}
	}
	// Only points right at the sweep's seam (the first and last azimuth) may miss.
	EXPECT_GT(static_cast<double>(onSurface), 0.99 * static_cast<double>(checked));

	// Un-corrected, the points are off by up to the sweep's whole motion; de-skewed with the
	// sweep's true motion, by at most the constant-velocity model's error (the route bends).
	const auto offsets = [&](const std::vector<PointXYZI>& pts)
	{
		std::vector<double> d;
		for (std::size_t i = 0; i < pts.size(); i++)
			d.push_back((Eigen::Vector3d(pts[i].x, pts[i].y, pts[i].z) - exact[i]).norm());
		std::sort(d.begin(), d.end());
		return std::make_pair(d[d.size() / 2], d.back());
	};
	const auto [rawMedian, rawMax] = offsets(scan.points);
	const auto Pstart = simu.sensorPoseAt(end - period);
	const auto T = Pend - Pstart;
	std::vector<PointXYZI> fixedPts = scan.points;
	deskewSweep(
	    fixedPts,
	    Eigen::Isometry3d(T.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen()),
	    model);
	const auto [fixedMedian, fixedMax] = offsets(fixedPts);
	EXPECT_GT(rawMedian, 0.2);
	EXPECT_GT(rawMax, 0.6);
	EXPECT_LT(fixedMedian, 0.01);
	EXPECT_LT(fixedMax, 0.08);
	std::cout << "scan " << k << " (yaw " << fastest / kDeg << " deg a scan): point offsets median "
	          << rawMedian << " m, max " << rawMax << " m; de-skewed: " << fixedMedian << " m, "
	          << fixedMax << " m\n";
}

TEST(SimSweep, FractionFollowsTheSpin)
{
	SweepModel cw;  // starts behind, clockwise seen from above
	EXPECT_NEAR(cw.fraction(kPi), 0.0, 1e-12);
	EXPECT_NEAR(cw.fraction(kPi / 2), 0.25, 1e-12);   // left after a quarter
	EXPECT_NEAR(cw.fraction(0), 0.5, 1e-12);          // ahead at half
	EXPECT_NEAR(cw.fraction(-kPi / 2), 0.75, 1e-12);  // right at three quarters
	SweepModel ccw;
	ccw.clockwise = false;
	ccw.startAzimuth_deg = 0;
	EXPECT_NEAR(ccw.fraction(kPi / 2), 0.25, 1e-12);
	EXPECT_NEAR(ccw.fraction(-kPi / 2), 0.75, 1e-12);
	for (double a = -3; a < 3; a += 0.1)
	{
		EXPECT_GE(cw.fraction(a), 0.0);
		EXPECT_LT(cw.fraction(a), 1.0);
	}
	// Points at the sweep's end stay; de-skewing with no motion moves nothing.
	std::vector<PointXYZI> pts = {{10, 0, 1, 0}, {0, 10, 1, 0}, {-10, 0.01f, 1, 0}};
	auto same = pts;
	deskewSweep(same, Eigen::Isometry3d::Identity(), cw);
	for (std::size_t i = 0; i < pts.size(); i++)
		EXPECT_FLOAT_EQ(same[i].x, pts[i].x);
	// A pure forward motion of 1 m over the sweep: the point ahead (half way) moves back by
	// 0.5 m into the end frame; the one just after the start by almost the whole metre.
	Eigen::Isometry3d fwd = Eigen::Isometry3d::Identity();
	fwd.translation() = Eigen::Vector3d(1, 0, 0);
	auto moved = pts;
	deskewSweep(moved, fwd, cw);
	EXPECT_NEAR(moved[0].x, 10 - 0.5, 0.01);
	EXPECT_NEAR(moved[1].x, -0.75, 0.01);  // left: a quarter of the way
	EXPECT_NEAR(moved[2].x, -10 - 1.0, 0.01);
	// A non-finite point stays non-finite (and is not an error).
	std::vector<PointXYZI> bad = {{std::numeric_limits<float>::quiet_NaN(), 0, 0, 0}};
	deskewSweep(bad, fwd, cw);
	EXPECT_TRUE(std::isnan(bad[0].x));
}

// The indoor world and the handheld walk (rawlogs/indoor-handheld.yaml): rooms joined by
// doors under a ceiling, a walk that fits through the doors and turns about 10 deg a scan.
TEST(SimIndoor, RoomsDoorsCeilingAndAHandheldWalkThroughThem)
{
	const auto sc = sim::loadScenario(scenarioPath("indoor-handheld.yaml"));
	ASSERT_EQ(sc.world, "indoor");
	ASSERT_TRUE(sc.handheld);
	const auto simu = sim::Simulator::fromScenario(sc);
	const auto& w = simu.world();
	const auto& in = sc.indoor;
	// Up from a room's centre: the ceiling; down: the floor; sideways along the lanes: the
	// door in the wall (the ray passes it) or the outer wall (closed).
	const Eigen::Vector2d c = in.roomCentre(0, 0);
	const Eigen::Vector3d o(c.x(), c.y(), 1.0);
	EXPECT_NEAR(w.raycast(o, Eigen::Vector3d::UnitZ(), 50).range, in.ceiling_m - 1.0, 1e-6);
	EXPECT_EQ(w.raycast(o, Eigen::Vector3d::UnitZ(), 50).kind, sim::ObjectKind::Ceiling);
	EXPECT_NEAR(w.raycast(o, -Eigen::Vector3d::UnitZ(), 50).range, 1.0, 1e-6);
	const double S = in.room_size_m, half = S / 2 - in.wall_m / 2;
	EXPECT_NEAR(w.raycast(o, -Eigen::Vector3d::UnitX(), 50).range, half, 1e-6);  // outer wall
	EXPECT_GT(w.raycast(o, Eigen::Vector3d::UnitX(), 50).range, S);              // the door
	// Just beside the door's middle, the inner wall.
	const Eigen::Vector3d beside(c.x(), c.y() + in.door_m / 2 + 0.1, 1.0);
	EXPECT_NEAR(w.raycast(beside, Eigen::Vector3d::UnitX(), 50).range, half, 1e-6);

	// The walk never comes within 0.3 m of a wall or a piece of furniture, doors included.
	double closest = 1e9, fastestYaw = 0;
	for (std::size_t k = 0; k < sc.scans; k++)
	{
		const auto P = simu.sensorPose(k);
		const Eigen::Vector3d at(P.x(), P.y(), 1.0);
		for (int a = 0; a < 36; a++)
		{
			const Eigen::Vector3d d(std::cos(a * 10 * kDeg), std::sin(a * 10 * kDeg), 0);
			closest = std::min(closest, w.raycast(at, d, 50).range);
		}
		if (k > 0)
			fastestYaw =
			    std::max(fastestYaw,
			             std::abs(mrpt::math::wrapToPi((P - simu.sensorPose(k - 1)).yaw())) / kDeg);
	}
	EXPECT_GT(closest, 0.3);
	EXPECT_GT(fastestYaw, 10.0);  // the turns in the rooms' centres
	EXPECT_LT(fastestYaw, 20.0);
	// The hand's sway tilts the sensor: roll and pitch of a few degrees.
	double maxTilt = 0;
	for (std::size_t k = 0; k < 50; k++)
	{
		const auto P = simu.sensorPose(k);
		maxTilt = std::max({maxTilt, std::abs(P.pitch()) / kDeg, std::abs(P.roll()) / kDeg});
	}
	EXPECT_GT(maxTilt, 2.0);
	EXPECT_LT(maxTilt, 4.5);
	// A VLP-16 indoors: nearly every ray returns (walls all round), most within the room.
	const Scan s = simu.scan(10);
	EXPECT_GT(s.points.size(), 25000u);
	std::vector<double> ranges;
	for (const auto& p : s.points)
		ranges.push_back(rangeOf(p));
	std::sort(ranges.begin(), ranges.end());
	EXPECT_LT(ranges[ranges.size() / 2], S);
}
