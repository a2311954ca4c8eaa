// The ground grid and the alignment of two scans' ground patch by patch (height, roll and
// pitch): on rolling ground, where making the two RANSAC planes parallel is wrong by the
// road's own change of slope; its refusals; and on real KITTI pairs against the SemanticKITTI
// poses, with the scans' 0.205 deg beam offset corrected (core/sweep.h).
#include <rasterslam/core/sweep.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/trajectory_io.h>
#include <rasterslam/raster/ground_grid.h>
#include <rasterslam/raster/ground_plane.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "test_support.h"

namespace
{
using namespace rasterslam;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

/** A road over a crest with a camber: height and slope change under the car. */
double road(double x, double y)
{
	return 0.04 * x - 0.0012 * x * x - 0.004 * y * y;
}

/** The car standing on that road at (x, y) facing +x: its pitch and roll follow the road's
 *  slope at the wheels, plus a suspension roll; the sensor 1.73 m above. */
Eigen::Isometry3d carAt(double x, double y, double extraRoll_deg)
{
	const double e = 1e-3;
	const double dzdx = (road(x + e, y) - road(x - e, y)) / (2 * e);
	const double dzdy = (road(x, y + e) - road(x, y - e)) / (2 * e);
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	// Nose up when climbing (a rotation about y by -atan(slope)), left side up when the road
	// rises to the left (about x by atan(slope)).
	T.linear() =
	    (Eigen::AngleAxisd(std::atan(dzdy) + extraRoll_deg * kDeg, Eigen::Vector3d::UnitX()) *
	     Eigen::AngleAxisd(-std::atan(dzdx), Eigen::Vector3d::UnitY()))
	        .toRotationMatrix();
	T.translation() = Eigen::Vector3d(x, y, road(x, y)) + T.linear() * Eigen::Vector3d(0, 0, 1.73);
	return T;
}

/** Ground points seen from pose T (rings every 0.5 deg of azimuth at 3..25 m, 1 cm noise),
 *  in the sensor frame; with `car`, a 2 x 4.5 m car's sides at (8, 5) in the sensor frame
 *  hide the ground behind them and add its low body (0.25 m above the road). */
std::vector<PointXYZI> groundScan(const Eigen::Isometry3d& T, uint32_t seed, bool car = false)
{
	std::mt19937 rng(seed);
	std::normal_distribution<double> noise(0, 0.01);
	std::vector<PointXYZI> pts;
	const Eigen::Isometry3d inv = T.inverse();
	for (double r = 3; r <= 25; r *= 1.06)
		for (double a = 0; a < 360; a += 0.5)
		{
			const Eigen::Vector3d dir(std::cos(a * kDeg), std::sin(a * kDeg), 0);
			const Eigen::Vector3d sensorXY = T.translation();
			const Eigen::Vector3d w0 = sensorXY + r * (T.linear() * dir);
			Eigen::Vector3d w(w0.x(), w0.y(), road(w0.x(), w0.y()) + noise(rng));
			Eigen::Vector3d p = inv * w;
			if (car && p.x() > 6 && p.x() < 10.5 && p.y() > 4 && p.y() < 6)
				p.z() += 0.25;  // the car's sill instead of the road
			PointXYZI q;
			q.x = static_cast<float>(p.x());
			q.y = static_cast<float>(p.y());
			q.z = static_cast<float>(p.z());
			pts.push_back(q);
		}
	return pts;
}

raster::Plane planeOf(const std::vector<PointXYZI>& pts)
{
	raster::GroundParams gp;
	gp.candidateMaxZ_m = -0.5;
	return raster::fitGroundPlane(pts, gp, 7);
}

double rollPitchErrorDeg(const Eigen::Isometry3d& est, const Eigen::Isometry3d& truth)
{
	// The error's rotation about the reference's vertical axis is the features' business.
	const Eigen::Vector3d up = est.linear() * Eigen::Vector3d::UnitZ();
	const Eigen::Vector3d upTrue = truth.linear() * Eigen::Vector3d::UnitZ();
	return std::acos(std::clamp(up.dot(upTrue), -1.0, 1.0)) / kDeg;
}

Eigen::Isometry3d perturbed(const Eigen::Isometry3d& T, double dz, double roll_deg,
                            double pitch_deg)
{
	Eigen::Isometry3d P = Eigen::Isometry3d::Identity();
	P.linear() = (Eigen::AngleAxisd(roll_deg * kDeg, Eigen::Vector3d::UnitX()) *
	              Eigen::AngleAxisd(pitch_deg * kDeg, Eigen::Vector3d::UnitY()))
	                 .toRotationMatrix();
	P.translation() = Eigen::Vector3d(0, 0, dz);
	return P * T;
}
}  // namespace

TEST(GroundGrid, RollingGroundAlignedWherePlanesAreNot)
{
	// Two scans 6 m apart over a crest, the second rolled 0.3 deg more by its suspension, and
	// a parked car seen only from the second.
	const Eigen::Isometry3d A = carAt(0, 0.5, 0), B = carAt(6, 0.8, 0.3);
	const Eigen::Isometry3d truth = A.inverse() * B;
	const auto ptsA = groundScan(A, 1), ptsB = groundScan(B, 2, true);
	const auto plA = planeOf(ptsA), plB = planeOf(ptsB);
	ASSERT_TRUE(plA.valid && plB.valid);
	raster::GroundGrid gA, gB;
	gA.build(ptsA, plA);
	gB.build(ptsB, plB);
	ASSERT_GT(gA.samples().size(), 500u);
	ASSERT_GT(gB.samples().size(), 500u);
	// The ground under A at a point ahead, from A's grid: the road's height there.
	const Eigen::Vector3d ahead = A * Eigen::Vector3d(10, -3, 0);
	const Eigen::Vector3d onRoad =
	    A.inverse() * Eigen::Vector3d(ahead.x(), ahead.y(), road(ahead.x(), ahead.y()));
	const auto h = gA.heightAt(static_cast<float>(onRoad.x()), static_cast<float>(onRoad.y()));
	ASSERT_TRUE(h.has_value());
	EXPECT_NEAR(*h, onRoad.z(), 0.02);
	EXPECT_FALSE(gA.heightAt(0, 0).has_value());   // under the car: no ground seen
	EXPECT_FALSE(gA.heightAt(40, 0).has_value());  // beyond the grid

	// The features' estimate: x, y and yaw right, z, roll and pitch off.
	const Eigen::Isometry3d start = perturbed(truth, 0.12, -0.6, 0.5);
	const auto byPlanes = raster::alignGroundPlanes(start, plA.n.cast<double>(), plA.d,
	                                                plB.n.cast<double>(), plB.d, 2.0);
	ASSERT_TRUE(byPlanes.has_value());
	// The planes are each the best plane through their own stretch of the crest: made
	// parallel, they leave the change of slope between the two places as an error.
	EXPECT_GT(rollPitchErrorDeg(*byPlanes, truth), 0.2);

	const auto g = raster::alignGroundGrids(*byPlanes, gA, gB);
	ASSERT_TRUE(g.ok) << g.why;
	std::printf("roll/pitch error: planes %.3f deg, grid %.4f deg (%d cells, rms %.4f m)\n",
	            rollPitchErrorDeg(*byPlanes, truth), rollPitchErrorDeg(g.T, truth), g.used,
	            g.rms_m);
	EXPECT_GT(g.used, 300);
	EXPECT_LT(g.rms_m, 0.03);
	EXPECT_LT(rollPitchErrorDeg(g.T, truth), 0.03);
	EXPECT_NEAR(g.T.translation().z(), truth.translation().z(), 0.01);
	// x, y and yaw stay the features'.
	EXPECT_LT((g.T.translation() - byPlanes->translation()).head<2>().norm(), 0.01);
	const Eigen::Vector3d fwd = g.T.linear() * Eigen::Vector3d::UnitX(),
	                      fwd0 = byPlanes->linear() * Eigen::Vector3d::UnitX();
	EXPECT_NEAR(std::atan2(fwd.y(), fwd.x()), std::atan2(fwd0.y(), fwd0.x()), 1e-3);
	// From the features' estimate directly, without the planes first: the same answer.
	const auto direct = raster::alignGroundGrids(start, gA, gB);
	ASSERT_TRUE(direct.ok) << direct.why;
	EXPECT_LT(rollPitchErrorDeg(direct.T, truth), 0.03);
}

TEST(GroundGrid, RefusesWhatTheGroundCannotTell)
{
	const Eigen::Isometry3d A = carAt(0, 0, 0), B = carAt(5, 0, 0);
	const Eigen::Isometry3d truth = A.inverse() * B;
	const auto ptsA = groundScan(A, 3), ptsB = groundScan(B, 4);
	raster::GroundGrid gA, gB, empty;
	gA.build(ptsA, planeOf(ptsA));
	gB.build(ptsB, planeOf(ptsB));
	ASSERT_TRUE(raster::alignGroundGrids(truth, gA, gB).ok);

	// No ground, or no plane to say what ground is.
	auto r = raster::alignGroundGrids(truth, gA, empty);
	EXPECT_FALSE(r.ok);
	EXPECT_TRUE(r.T.isApprox(truth));
	raster::GroundGrid noPlane;
	noPlane.build(ptsB, raster::Plane{});
	EXPECT_TRUE(noPlane.empty());

	// Scans that share no ground.
	Eigen::Isometry3d far = truth;
	far.translation().x() += 80;
	r = raster::alignGroundGrids(far, gA, gB);
	EXPECT_FALSE(r.ok);
	EXPECT_STREQ(r.why, "too few ground cells in common");

	// A strip of ground 1 m wide (a corridor): roll is free.
	std::vector<PointXYZI> strip;
	for (const auto& p : ptsB)
		if (std::abs(p.y) < 0.6f)
			strip.push_back(p);
	raster::GroundGrid gStrip;
	gStrip.build(strip, planeOf(ptsB));
	r = raster::alignGroundGrids(truth, gA, gStrip);
	EXPECT_FALSE(r.ok);
	EXPECT_STREQ(r.why, "the ground cells in common do not spread over the ground");

	// A start 3 deg off in pitch asks for more than the 2 deg allowed.
	r = raster::alignGroundGrids(perturbed(truth, 0, 0, 3.0), gA, gB);
	EXPECT_FALSE(r.ok);
	EXPECT_GT(r.correction_deg, 2.5);
	raster::GroundAlignParams wide;
	wide.maxCorrection_deg = 5;
	r = raster::alignGroundGrids(perturbed(truth, 0, 0, 3.0), gA, gB, wide);
	ASSERT_TRUE(r.ok) << r.why;
	EXPECT_LT(rollPitchErrorDeg(r.T, truth), 0.03);

	// A step in the ground (a kerb) within a cell: the cell is not used.
	std::vector<PointXYZI> kerb = ptsA;
	for (auto& p : kerb)
		if (p.x > 5 && p.x < 6 && std::fmod(std::abs(p.y), 1.0f) < 0.5f)
			p.z += 0.2f;
	raster::GroundGrid gKerb;
	gKerb.build(kerb, planeOf(ptsA));
	EXPECT_LT(gKerb.samples().size(), gA.samples().size());
}

TEST(GroundGrid, KittiPairsAgainstSemanticKittiPoses)
{
	// Pairs 5 scans (3.5-5 m) apart, from a start 0.4 deg off in roll and pitch and 8 cm in
	// height. Measured: roll and pitch error (the angle between the estimated and the true
	// up direction) 0.066 deg on average with the grid, 0.109 deg with the planes.
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const std::string dir = test::sharedData("kitti00-0000-0100");
	const auto gt = io::kittiCameraToVelodyne(io::loadTrajectory(dir + "/poses_semantickitti.txt"),
	                                          io::loadKittiCalibTr(dir + "/calib.txt"));
	ASSERT_EQ(gt.size(), 101u);
	auto load = [&](std::size_t i, raster::Plane& pl)
	{
		char name[32];
		std::snprintf(name, sizeof name, "/velodyne/%06zu.bin", i);
		auto pts = io::loadKittiBin(dir + name);
		correctElevation(pts, 0.205);
		pl = raster::fitGroundPlane(pts, raster::GroundParams{}, 11);
		raster::GroundGrid g;
		g.build(pts, pl);
		return g;
	};
	double sumGrid = 0, sumPlanes = 0, worstGrid = 0;
	int n = 0;
	for (std::size_t a = 0; a + 5 < gt.size(); a += 10)
	{
		SCOPED_TRACE(std::to_string(a));
		raster::Plane pa, pb;
		const auto ga = load(a, pa), gb = load(a + 5, pb);
		ASSERT_TRUE(pa.valid && pb.valid);
		const Eigen::Isometry3d truth = gt[a].pose.inverse() * gt[a + 5].pose;
		const Eigen::Isometry3d start = perturbed(truth, 0.08, 0.4, -0.4);
		const auto planes = raster::alignGroundPlanes(start, pa.n.cast<double>(), pa.d,
		                                              pb.n.cast<double>(), pb.d, 2.0);
		ASSERT_TRUE(planes.has_value());
		const auto g = raster::alignGroundGrids(*planes, ga, gb);
		ASSERT_TRUE(g.ok) << g.why;
		const double e = rollPitchErrorDeg(g.T, truth);
		EXPECT_LT(e, 0.2);
		EXPECT_LT(std::abs(g.T.translation().z() - truth.translation().z()), 0.05);
		sumGrid += e;
		worstGrid = std::max(worstGrid, e);
		sumPlanes += rollPitchErrorDeg(*planes, truth);
		n++;
	}
	ASSERT_EQ(n, 10);
	std::printf("roll/pitch error, mean of %d pairs: grid %.3f deg (worst %.3f), planes %.3f deg\n",
	            n, sumGrid / n, worstGrid, sumPlanes / n);
	EXPECT_LT(sumGrid / n, 0.09);
	EXPECT_LT(sumGrid, 0.8 * sumPlanes);
}
