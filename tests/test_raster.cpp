// The elevation rasterizer: RANSAC ground plane and ground removal on simulated scans, BEV and
// equation (1) projections against hand-computed pixels, pixel ownership, grey levels and
// outlier removal.
#include <rasterslam/raster/elevation_image.h>
#include <rasterslam/raster/ground_plane.h>
#include <rasterslam/sim/simulator.h>

#include <cmath>
#include <memory>
#include <opencv2/core.hpp>
#include <set>

#include "test_support.h"

namespace
{
using namespace rasterslam;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

/** A noiseless HDL-64 scan of a hand-built scene (ground z = tilt . (x, y), a wall, a parked
 *  car and a pole), and the true ground plane in the sensor frame. */
struct Scene
{
	Scan scan;
	mrpt::poses::CPose3D T;  //!< sensor in the world
	Eigen::Vector3d n;       //!< true ground plane in the sensor frame: n.p + d = height
	double d = 0;
	double trueHeight(const PointXYZI& p) const
	{
		return n.x() * p.x + n.y() * p.y + n.z() * p.z + d;
	}
	Eigen::Vector3d world(const PointXYZI& p) const
	{
		double x, y, z;
		T.composePoint(p.x, p.y, p.z, x, y, z);
		return {x, y, z};
	}
	bool onWall(const PointXYZI& p) const
	{
		const auto w = world(p);
		return std::abs(w.x() - 15) < 0.51 && std::abs(w.y()) < 6.01;
	}
	bool onCar(const PointXYZI& p) const
	{
		const auto w = world(p);
		return std::abs(w.x()) < 2.21 && std::abs(w.y() + 8) < 0.91;
	}
};

Scene makeScene(const Eigen::Vector2d& tilt, double pitchDeg, double rollDeg, double h = 1.73)
{
	sim::World world(sim::GroundModel(0, tilt, {}));
	world.addBoxOnGround(15, 0, 0, 0.5, 6, 3, sim::ObjectKind::Wall);     // across the road ahead
	world.addBoxOnGround(0, -8, 0, 2.2, 0.9, 1.5, sim::ObjectKind::Car);  // parked on the right
	world.addCylinderOnGround(-10, 5, 0.2, 5, sim::ObjectKind::Pole);
	sim::SimulatorOptions o;
	o.noise.range_sigma_m = 0;
	o.noise.dropout_prob = 0;
	o.noise.intensity_sigma = 0;
	o.point_resolution_m = 0;
	const sim::Simulator simu(std::make_shared<const sim::World>(std::move(world)),
	                          sim::LidarModel::hdl64(), sim::Route(), o);
	Scene s;
	s.T = mrpt::poses::CPose3D(0, 0, h, 0, pitchDeg * kDeg, rollDeg * kDeg);
	s.scan = simu.scanFrom(s.T, 0, 0);
	// World plane: (-tx, -ty, 1).p / N = height; in the sensor frame n_s = R^T n_w and
	// d_s = n_w . t (the ground passes through the origin).
	const Eigen::Vector3d nw = Eigen::Vector3d(-tilt.x(), -tilt.y(), 1).normalized();
	const Eigen::Matrix3d R = s.T.getRotationMatrix().asEigen();
	s.n = R.transpose() * nw;
	s.d = nw.dot(Eigen::Vector3d(0, 0, h));
	return s;
}

/** Fits the ground, rasterizes and checks the plane, the ground removal and that the wall
 *  and the car are in the image. */
void checkGroundRemoval(const Scene& s, raster::ProjectionMode mode)
{
	SCOPED_TRACE(mode == raster::ProjectionMode::Bev ? "BEV" : "pinhole");
	const auto plane = raster::fitGroundPlane(s.scan.points, raster::GroundParams(), 1);
	ASSERT_TRUE(plane.valid);
	const double angle = std::acos(std::clamp(plane.n.cast<double>().dot(s.n), -1.0, 1.0)) / kDeg;
	EXPECT_LT(angle, 1.0);
	EXPECT_NEAR(plane.d, s.d, 0.05);
	EXPECT_GT(plane.inliers, 1000);

	raster::RasterParams p;
	p.mode = mode;
	RasterFrame f;
	const auto st = raster::rasterizeElevation(s.scan.points, plane, p, f);
	EXPECT_GT(st.ground, st.input / 2);  // most returns of this open scene are ground
	EXPECT_GT(st.pixels, 60u);
	std::size_t groundPixels = 0;
	for (const int32_t idx : f.pixelToPoint)
		if (idx >= 0 && s.trueHeight(s.scan.points[static_cast<std::size_t>(idx)]) < 0.1)
			++groundPixels;
	EXPECT_EQ(groundPixels, 0u);

	// Pixels that wall / car points (clearly above the ground threshold) fall into: each
	// must be occupied, by a point of the same object (nothing else stands there). Measured:
	// all 60 / 26 wall / car pixels in BEV, 510 / 72 in pinhole on flat ground; the plane is
	// within 0.001 deg and 1 mm of the truth.
	const int size = static_cast<int>(f.image.getWidth());
	auto objectPixels = [&](auto onObject, std::size_t& occupied)
	{
		std::set<std::size_t> pixels;
		for (const auto& q : s.scan.points)
		{
			const double r = std::hypot(q.x, q.y);
			if (!onObject(q) || s.trueHeight(q) < 0.35 || r < p.minRange_m || r > p.maxRange_m)
				continue;
			float u, v;
			if (!raster::projectPoint(p, q.x, q.y, q.z, u, v))
				continue;
			const int c = static_cast<int>(std::floor(u)), row = static_cast<int>(std::floor(v));
			if (c >= 0 && row >= 0 && c < size && row < size)
				pixels.insert(static_cast<std::size_t>(row) * size + c);
		}
		occupied = 0;
		for (const auto k : pixels)
			if (f.pixelToPoint[k] >= 0 &&
			    onObject(s.scan.points[static_cast<std::size_t>(f.pixelToPoint[k])]))
				++occupied;
		return pixels.size();
	};
	std::size_t wallOk = 0, carOk = 0;
	const auto wall = objectPixels([&](const PointXYZI& q) { return s.onWall(q); }, wallOk);
	const auto car = objectPixels([&](const PointXYZI& q) { return s.onCar(q); }, carOk);
	EXPECT_GT(wall, 20u);
	EXPECT_GT(car, 20u);
	EXPECT_GE(wallOk, 0.98 * wall) << wallOk << " of " << wall << " wall pixels";
	EXPECT_GE(carOk, 0.98 * car) << carOk << " of " << car << " car pixels";
}
}  // namespace

TEST(RasterGround, FlatGroundRemovedObjectsKept)
{
	const auto s = makeScene({0, 0}, 0, 0);
	checkGroundRemoval(s, raster::ProjectionMode::Bev);
	checkGroundRemoval(s, raster::ProjectionMode::Pinhole);
}

TEST(RasterGround, SlopedGroundAndTiltedSensor)
{
	// 5 % and -3 % slopes, and the sensor pitched 2 deg and rolled -1.5 deg on top: the
	// ground is tilted by about 4.5 deg in the sensor frame.
	const auto s = makeScene({0.05, -0.03}, 2.0, -1.5);
	EXPECT_GT(std::acos(s.n.z()) / kDeg, 4.0);
	checkGroundRemoval(s, raster::ProjectionMode::Bev);
	checkGroundRemoval(s, raster::ProjectionMode::Pinhole);
}

TEST(RasterGround, LowMountedSensorFindsItsGround)
{
	// A sensor 0.6 m above the ground (a small robot): its ground lies above the candidates'
	// fixed bound (1 m below the sensor), so the bound is raised above the scan's lowest dense
	// layer. Measured on rawlogs/town-vlp16.yaml with the sensor at 0.6 m (slam.yaml,
	// scripts/benchmark-mounting.sh): ATE 27.1 m with the bound fixed, 0.185 m raised.
	for (const double slope : {0.0, 0.04})
	{
		SCOPED_TRACE("slope " + std::to_string(slope));
		const auto s = makeScene({slope, 0}, 0, 0, 0.6);
		checkGroundRemoval(s, raster::ProjectionMode::Bev);
		if (slope > 0)
			continue;  // its ground behind falls below the fixed bound: found either way
		raster::GroundParams fixed;
		fixed.layerMargin_m = 0;
		const auto wrong = raster::fitGroundPlane(s.scan.points, fixed, 1);
		EXPECT_TRUE(!wrong.valid || std::abs(wrong.d - s.d) > 0.2) << wrong.d;
	}
}

TEST(RasterGround, GroundBelowTheFixedBoundKeepsItsCandidates)
{
	// Where a ground lies below the fixed bound, nothing changes: sensors at the usual
	// heights keep their planes to the last bit (and the KITTI sample's trajectory stays the
	// same to the byte, measured: README, "Mounting height").
	for (const double h : {1.73, 2.5})
	{
		SCOPED_TRACE("sensor at " + std::to_string(h) + " m");
		const auto s = makeScene({0.05, -0.03}, 2.0, -1.5, h);
		raster::GroundParams fixed;
		fixed.layerMargin_m = 0;
		const auto a = raster::fitGroundPlane(s.scan.points, raster::GroundParams(), 1);
		const auto b = raster::fitGroundPlane(s.scan.points, fixed, 1);
		ASSERT_TRUE(a.valid);
		EXPECT_NEAR(a.d, s.d, 0.05);
		EXPECT_EQ(a.d, b.d);
		EXPECT_EQ(a.n, b.n);
		EXPECT_EQ(a.inliers, b.inliers);
	}
}

TEST(RasterGround, RaisedBoundStopsAMetreAboveTheSensor)
{
	// Nothing below the sensor, one flat surface above, and a table top 0.5 m up, 4-8 m ahead
	// (441 points: no dense layer). A ceiling taken for the ground would drop every point
	// below it as an outlier, and a bound raised under it would take the table for the
	// ground: a layer reaching more than 1 m above the origin raises nothing, so no plane is
	// found (the rasterizer then takes sensor_height_m): a ceiling at 3 m, and at 1.05 m (its
	// 0.2 m layer tops out at 1.2 m). A surface whose layer stays within 1 m is reached:
	// 0.85 m up (the bound raised to 1 m, not to 1.3) and a vehicle frame's ground (z = 0).
	std::vector<PointXYZI> surface, table;
	for (int i = -60; i <= 60; i++)
		for (int j = -60; j <= 60; j++)
			surface.push_back({0.25f * float(i), 0.25f * float(j), 0.0f, 0});
	for (int i = 0; i <= 20; i++)
		for (int j = -10; j <= 10; j++)
			table.push_back({4.0f + 0.2f * float(i), 0.2f * float(j), 0.5f, 0});
	const auto at = [&](float z, bool withTable)
	{
		auto pts = surface;
		for (auto& p : pts)
			p.z = z;
		if (withTable)
			pts.insert(pts.end(), table.begin(), table.end());
		return raster::fitGroundPlane(pts, raster::GroundParams(), 1);
	};
	EXPECT_FALSE(at(3.0f, true).valid);
	EXPECT_FALSE(at(1.05f, true).valid);
	// The table alone (no ceiling) is the scan's lowest dense layer and is taken.
	const auto tableAlone = raster::fitGroundPlane(table, raster::GroundParams(), 1);
	ASSERT_TRUE(tableAlone.valid);
	EXPECT_NEAR(tableAlone.d, -0.5, 1e-3);
	const auto high = at(0.85f, false);
	ASSERT_TRUE(high.valid);
	EXPECT_NEAR(high.d, -0.85, 1e-3);
	const auto ground = at(0.0f, false);
	ASSERT_TRUE(ground.valid);
	EXPECT_NEAR(ground.d, 0.0, 1e-3);
	EXPECT_GT(ground.n.z(), 0.999f);
}

TEST(RasterGround, TooFewCandidatesOrTooSteep)
{
	std::vector<PointXYZI> pts = {{5, 0, -1.7, 0}, {0, 5, -1.7, 0}};
	EXPECT_FALSE(raster::fitGroundPlane(pts, raster::GroundParams(), 1).valid);
	// A 45 deg slope is no ground (maxTilt 20 deg).
	pts.clear();
	for (int i = -10; i <= 10; i++)
		for (int j = -10; j <= 10; j++)
			pts.push_back({float(i), float(j), -2.0f - float(i), 0});  // 45 deg
	raster::GroundParams g;
	g.candidateMaxZ_m = 100;
	EXPECT_FALSE(raster::fitGroundPlane(pts, g, 1).valid);
}

// Two scans of one flat road: the planes give the height, roll and pitch back.
TEST(RasterGround, AlignGroundPlanesFixesHeightAndTilt)
{
	// The road z = -1.7 in the reference frame; the current sensor stands 4 m ahead and 1 m
	// left of it, level, so it sees the road 1.7 m below too.
	const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
	Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
	truth.translation() = Eigen::Vector3d(4, 1, 0);
	truth.rotate(Eigen::AngleAxisd(0.3, up));
	// An estimate 0.4 m too high, rolled by 2 degrees.
	Eigen::Isometry3d est = truth;
	est.translation().z() += 0.4;
	est.rotate(Eigen::AngleAxisd(2 * M_PI / 180, Eigen::Vector3d::UnitX()));
	double angle = 0;
	const auto fixed = raster::alignGroundPlanes(est, up, 1.7, up, 1.7, 5.0, &angle);
	ASSERT_TRUE(fixed);
	EXPECT_NEAR(angle, 2.0, 1e-6);
	EXPECT_NEAR(fixed->translation().z(), 0, 1e-9);
	// The turn is about the reference's origin: x and y move by 1.4 cm here.
	EXPECT_LT((fixed->translation() - truth.translation()).norm(), 0.02);
	EXPECT_LT(Eigen::AngleAxisd(fixed->linear().transpose() * truth.linear()).angle(), 1e-6);
	// A tilt beyond the bound is refused, with its angle.
	const auto refused = raster::alignGroundPlanes(est, up, 1.7, up, 1.7, 1.0, &angle);
	EXPECT_FALSE(refused);
	EXPECT_NEAR(angle, 2.0, 1e-6);
}

// canonical_yaw: the same street seen turned by 20 degrees gives the same image again.
TEST(RasterProjection, CanonicalYawUndoesATurn)
{
	// Walls along x and y (a street crossing), 3 m high, points every 5 cm.
	std::vector<PointXYZI> street;
	for (double a = -30; a <= 30; a += 0.05)
		for (double z = -1.5; z <= 1.5; z += 0.25)
			for (const double off : {-7.0, 7.0})
			{
				street.push_back({float(a), float(off), float(z), 0});
				if (std::abs(a) > 7.5)
					street.push_back({float(off), float(a), float(z), 0});
			}
	const auto turned = [&](double deg)
	{
		const double c = std::cos(deg * M_PI / 180), sn = std::sin(deg * M_PI / 180);
		auto pts = street;
		for (auto& p : pts)
		{
			const float x = p.x, y = p.y;
			p.x = float(c * x - sn * y);
			p.y = float(sn * x + c * y);
		}
		return pts;
	};
	raster::RasterParams p;
	p.removeGround = false;
	p.equalize = false;
	const auto overlap = [&](bool canonical)
	{
		p.canonicalYaw = canonical;
		RasterFrame a, b;
		raster::rasterizeElevation(turned(0), raster::Plane(), p, a);
		raster::rasterizeElevation(turned(20), raster::Plane(), p, b);
		const cv::Mat ia = a.image.asCvMatRef(), ib = b.image.asCvMatRef();
		// The turn is a multiple of 90 degrees away once both are canonical: compare with
		// the best of the four quarter turns.
		double best = 0;
		for (int k = 0; k < 4; k++)
		{
			cv::Mat r = ib.clone();
			for (int i = 0; i < k; i++)
				cv::rotate(r, r, cv::ROTATE_90_CLOCKWISE);
			// Share of a's occupied pixels with one of r's within 2 pixels (the estimated
			// turn is good to about a degree: a wall 30 m out moves by up to 3 pixels).
			double both = 0, occupied = 0;
			for (int y = 2; y < ia.rows - 2; y++)
				for (int x = 2; x < ia.cols - 2; x++)
				{
					if (!ia.at<uint8_t>(y, x))
						continue;
					occupied++;
					bool near = false;
					for (int dy = -2; dy <= 2 && !near; dy++)
						for (int dx = -2; dx <= 2 && !near; dx++)
							near = r.at<uint8_t>(y + dy, x + dx) != 0;
					both += near;
				}
			const double either = occupied;
			best = std::max(best, both / either);
		}
		return best;
	};
	const double plain = overlap(false), canonical = overlap(true);
	std::printf("share of wall pixels matched: %.3f plain, %.3f canonical\n", plain, canonical);
	EXPECT_LT(plain, 0.2);      // the walls no longer cover the same pixels (0.06)
	EXPECT_GT(canonical, 0.7);  // most of them do again (0.75: the turn is found to a degree)
	RasterFrame f;
	p.canonicalYaw = true;
	raster::rasterizeElevation(turned(20), raster::Plane(), p, f);
	// The two turns differ by 70 degrees (-20 modulo 90).
	RasterFrame g;
	raster::rasterizeElevation(turned(0), raster::Plane(), p, g);
	EXPECT_NEAR((f.imageYaw - g.imageYaw) * 180 / M_PI, 70, 2.0);
}

TEST(RasterProjection, BevPixelsByHand)
{
	raster::RasterParams p;  // BEV, 0.2 m, 50 m: a 500 x 500 image
	float u, v;
	ASSERT_TRUE(raster::projectPoint(p, 10, 5, 0, u, v));
	EXPECT_NEAR(u, 225.0, 1e-3);  // (50 - 5) / 0.2
	EXPECT_NEAR(v, 200.0, 1e-3);  // (50 - 10) / 0.2
	ASSERT_TRUE(raster::projectPoint(p, -3.3f, 12.7f, 7, u, v));
	EXPECT_NEAR(u, 186.5, 1e-3);  // (50 - 12.7) / 0.2
	EXPECT_NEAR(v, 266.5, 1e-3);  // (50 + 3.3) / 0.2
	ASSERT_TRUE(raster::projectPoint(p, 49.9f, -49.9f, 0, u, v));
	EXPECT_NEAR(u, 499.5, 1e-3);  // (50 + 49.9) / 0.2: right is the last column
	EXPECT_NEAR(v, 0.5, 1e-3);    // (50 - 49.9) / 0.2: forward is up, the first row

	RasterFrame f;
	const std::vector<PointXYZI> pts = {{10, 5, 0, 0}, {-3.3f, 12.7f, 2, 0}};
	const auto st = raster::rasterizeElevation(pts, raster::Plane(), p, f);
	ASSERT_EQ(f.image.getWidth(), 500u);
	ASSERT_EQ(f.image.getHeight(), 500u);
	ASSERT_EQ(f.pixelToPoint.size(), 500u * 500u);
	EXPECT_EQ(st.projected, 2u);
	EXPECT_EQ(st.pixels, 2u);
	EXPECT_EQ(f.pixelToPoint[200 * 500 + 225], 0);
	EXPECT_EQ(f.pixelToPoint[266 * 500 + 186], 1);
	EXPECT_NE(f.image.at<uint8_t>(225, 200), 0);
	EXPECT_NE(f.image.at<uint8_t>(186, 266), 0);
}

TEST(RasterProjection, PinholeEquationOneByHand)
{
	raster::RasterParams p;
	p.mode = raster::ProjectionMode::Pinhole;  // 500 px, H = 20 m, sensor 1.73 m, 50 m
	// f = 0.5 * 500 * (20 + 1.73) / 50 = 108.65, c = 250
	float u, v;
	ASSERT_TRUE(raster::projectPoint(p, 10, 5, 0, u, v));
	EXPECT_NEAR(u, 222.8375, 1e-3);  // 108.65 * -5 / 20 + 250
	EXPECT_NEAR(v, 195.675, 1e-3);   // 108.65 * -10 / 20 + 250
	ASSERT_TRUE(raster::projectPoint(p, 0, -20, 5, u, v));
	EXPECT_NEAR(u, 394.86667, 1e-3);  // 108.65 * 20 / 15 + 250
	EXPECT_NEAR(v, 250.0, 1e-3);
	// The ground at maxRange straight ahead reaches the top border: 108.65 * -50 / 21.73 + 250.
	ASSERT_TRUE(raster::projectPoint(p, 50, 0, -1.73f, u, v));
	EXPECT_NEAR(v, 0.0, 1e-3);
	EXPECT_NEAR(u, 250.0, 1e-3);
	// At or above the camera (z_cam = 20 - 19.6 < 0.5): not projected.
	EXPECT_FALSE(raster::projectPoint(p, 10, 0, 19.6f, u, v));
	EXPECT_FALSE(raster::projectPoint(p, 10, 0, 25, u, v));

	RasterFrame f;
	const std::vector<PointXYZI> pts = {{0, -20, 5, 0}, {10, 5, 0, 0}, {10, 0, 19.6f, 0}};
	const auto st = raster::rasterizeElevation(pts, raster::Plane(), p, f);
	EXPECT_EQ(st.projected, 2u);
	EXPECT_EQ(f.pixelToPoint[195 * 500 + 222], 1);
	EXPECT_EQ(f.pixelToPoint[250 * 500 + 394], 0);
}

TEST(RasterProjection, HighestPointWinsAndGreyLevelsFollowHeight)
{
	raster::RasterParams p;
	p.equalize = false;
	// Without a plane, height = z + 1.73; level = 1 + round(254 * h / 8).
	const std::vector<PointXYZI> pts = {
	    {10.05f, 5.05f, 1.0f, 0},    // 0: pixel (224, 199), h 2.73, beats point 1
	    {10.1f, 5.1f, 0.0f, 0},      // 1: same pixel, lower
	    {20.1f, 0.1f, -0.5f, 0},     // 2: pixel (249, 149), lower first...
	    {20.1f, 0.1f, 2.27f, 0},     // 3: ...then higher (h = 4.0): the order does not matter
	    {0.1f, 20.1f, 0.0f, 0},      // 4: pixel (149, 249), h 1.73 -> 1 + round(54.93) = 56
	    {-20.1f, 0.1f, 6.27f, 0},    // 5: pixel (249, 350), h 8.0 -> 255
	    {0.1f, -20.1f, 20.0f, 0},    // 6: pixel (350, 249), above greyMax: clamped to 255
	    {-10.1f, -10.1f, -1.2f, 0},  // 7: pixel (300, 300), h 0.53 -> 1 + round(16.83) = 18
	};
	RasterFrame f;
	const auto st = raster::rasterizeElevation(pts, raster::Plane(), p, f);
	EXPECT_EQ(st.projected, 8u);
	EXPECT_EQ(st.pixels, 6u);
	auto owner = [&](int c, int r)
	{ return f.pixelToPoint[static_cast<std::size_t>(r) * 500 + c]; };
	auto grey = [&](int c, int r) { return static_cast<int>(f.image.at<uint8_t>(c, r)); };
	EXPECT_EQ(owner(224, 199), 0);
	EXPECT_EQ(owner(249, 149), 3);
	EXPECT_EQ(owner(149, 249), 4);
	EXPECT_EQ(owner(249, 350), 5);
	EXPECT_EQ(owner(350, 249), 6);
	EXPECT_EQ(owner(300, 300), 7);
	EXPECT_EQ(grey(249, 149), 128);  // h 4.0: 1 + 127
	EXPECT_EQ(grey(149, 249), 56);
	EXPECT_EQ(grey(249, 350), 255);
	EXPECT_EQ(grey(350, 249), 255);
	EXPECT_EQ(grey(300, 300), 18);
	EXPECT_LT(grey(300, 300), grey(149, 249));
	EXPECT_LT(grey(149, 249), grey(224, 199));
	EXPECT_LT(grey(224, 199), grey(249, 149));
	// Every other pixel is empty: 0 in the image, -1 in the index.
	std::size_t nonzero = 0, owned = 0;
	for (int r = 0; r < 500; r++)
		for (int c = 0; c < 500; c++)
		{
			nonzero += grey(c, r) != 0;
			owned += owner(c, r) >= 0;
			if ((grey(c, r) != 0) != (owner(c, r) >= 0))
				ADD_FAILURE() << "pixel " << c << "," << r;
		}
	EXPECT_EQ(nonzero, 6u);
	EXPECT_EQ(owned, 6u);

	// With equalization, the order of the levels is kept and empty pixels stay 0.
	p.equalize = true;
	RasterFrame g;
	raster::rasterizeElevation(pts, raster::Plane(), p, g);
	auto geq = [&](int c, int r) { return static_cast<int>(g.image.at<uint8_t>(c, r)); };
	EXPECT_EQ(geq(0, 0), 0);
	EXPECT_GT(geq(300, 300), 0);
	EXPECT_LT(geq(300, 300), geq(149, 249));
	EXPECT_LT(geq(149, 249), geq(224, 199));
	EXPECT_LT(geq(224, 199), geq(249, 149));
	EXPECT_EQ(geq(249, 350), 255);
}

TEST(RasterProjection, PointAtPixelSearchesTheNeighbourhood)
{
	raster::RasterParams p;
	const std::vector<PointXYZI> pts = {{10, 5, 0, 0},
	                                    {10, 4.5f, 0, 0}};  // pixels (225,200), (227,200)
	RasterFrame f;
	raster::rasterizeElevation(pts, raster::Plane(), p, f);
	ASSERT_EQ(f.pixelToPoint[200 * 500 + 227], 1);
	EXPECT_EQ(raster::pointAtPixel(f, 225.5f, 200.5f, 0), 0);
	EXPECT_EQ(raster::pointAtPixel(f, 226.2f, 200.5f, 0), -1);  // empty pixel, no radius
	EXPECT_EQ(raster::pointAtPixel(f, 226.2f, 200.5f, 1), 0);   // nearer to (225, 200)
	EXPECT_EQ(raster::pointAtPixel(f, 226.8f, 200.5f, 1), 1);   // nearer to (227, 200)
	EXPECT_EQ(raster::pointAtPixel(f, 225.5f, 202.5f, 1), -1);  // two rows away
	EXPECT_EQ(raster::pointAtPixel(f, 225.5f, 202.5f, 2), 0);
	EXPECT_EQ(raster::pointAtPixel(f, -5.0f, -5.0f, 1), -1);  // outside the image
	EXPECT_EQ(raster::pointAtPixel(f, 0.5f, 0.5f, 3), -1);
}

TEST(RasterOutliers, RangeWindowAndBelowGround)
{
	raster::RasterParams p;  // range 2..50 m, 0.5 m below ground, ground within 0.25 m
	raster::Plane plane;
	plane.valid = true;
	plane.n = Eigen::Vector3f::UnitZ();
	plane.d = 1.73f;  // ground at z = -1.73
	const std::vector<PointXYZI> pts = {
	    {1.0f, 1.0f, 0, 0},  // 0: 1.41 m, inside minRange: outlier
	    {40, 40, 0, 0},      // 1: 56.6 m, beyond maxRange although inside the image: outlier
	    {60, 0, 0, 0},       // 2: beyond maxRange and outside the image: outlier
	    {10, 0, -2.5f, 0},   // 3: 0.77 m below the plane: outlier
	    {12, 0, -2.1f, 0},   // 4: 0.37 m below: not an outlier, but ground
	    {14, 0, -1.6f, 0},   // 5: 0.13 m above: ground
	    {16, 0, -1.2f, 0},   // 6: 0.53 m above: projected
	    {0, 49, 0, 0},       // 7: 49 m: projected
	};
	RasterFrame f;
	auto st = raster::rasterizeElevation(pts, plane, p, f);
	EXPECT_EQ(st.input, 8u);
	EXPECT_EQ(st.outliers, 4u);
	EXPECT_EQ(st.ground, 2u);
	EXPECT_EQ(st.projected, 2u);
	std::set<int32_t> seen;
	for (const int32_t i : f.pixelToPoint)
		if (i >= 0)
			seen.insert(i);
	EXPECT_EQ(seen, (std::set<int32_t>{6, 7}));
	EXPECT_EQ(f.pixelToPoint[200 * 500 + 250], -1);  // where point 3 would land: (250, 200)
	EXPECT_EQ(f.pixelToPoint[(50 - 40) * 5 * 500 + (50 - 40) * 5], -1);  // point 1: (50, 50)

	// Without ground removal, points 4 and 5 are projected; 3 is still an outlier.
	p.removeGround = false;
	st = raster::rasterizeElevation(pts, plane, p, f);
	EXPECT_EQ(st.outliers, 4u);
	EXPECT_EQ(st.ground, 0u);
	EXPECT_EQ(st.projected, 4u);
	EXPECT_EQ(f.pixelToPoint[190 * 500 + 250], 4);   // (50 - 12) / 0.2 = 190
	EXPECT_EQ(f.pixelToPoint[200 * 500 + 250], -1);  // point 3 at x = 10

	// Without a plane, the height is z + sensorHeight: point 3 (z = -2.5) is 0.77 m below.
	st = raster::rasterizeElevation(pts, raster::Plane(), p, f);
	EXPECT_EQ(st.outliers, 4u);
}

TEST(Raster, AppendMovedTransformsIntoTheTargetFrameAndKeepsWhatWasThere)
{
	// p' = T p: turned 90 degrees about z, then moved by (1, 2, 3).
	Eigen::Isometry3f T = Eigen::Isometry3f::Identity();
	T.linear() = Eigen::AngleAxisf(static_cast<float>(M_PI / 2), Eigen::Vector3f::UnitZ()).matrix();
	T.translation() = Eigen::Vector3f(1, 2, 3);
	std::vector<PointXYZI> out{{9, 9, 9, 0.1f}};
	raster::appendMoved({{1, 0, 0, 0.5f}, {0, 2, -1, 0.25f}}, T, out);
	ASSERT_EQ(out.size(), 3u);
	EXPECT_EQ(out[0].x, 9.f);  // what was there stays
	EXPECT_NEAR(out[1].x, 1, 1e-6);
	EXPECT_NEAR(out[1].y, 3, 1e-6);
	EXPECT_NEAR(out[1].z, 3, 1e-6);
	EXPECT_EQ(out[1].intensity, 0.5f);
	EXPECT_NEAR(out[2].x, -1, 1e-6);
	EXPECT_NEAR(out[2].y, 2, 1e-6);
	EXPECT_NEAR(out[2].z, 2, 1e-6);
	EXPECT_EQ(out[2].intensity, 0.25f);
}
