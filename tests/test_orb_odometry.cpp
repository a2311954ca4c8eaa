// The paper's tracking through its plugins (ElevationRasterizer + OrbOdometry): a simulated
// drive against ground truth, real KITTI frame pairs, the keyframe rule, and scans with
// nothing to track.
#include <rasterslam/core/engine.h>
#include <rasterslam/core/plugin_loader.h>
#include <rasterslam/eval/trajectory_metrics.h>
#include <rasterslam/features/icp.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/trajectory_io.h>
#include <rasterslam/sim/scenario.h>
#include <rasterslam/sim/simulator.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <random>
#include <string>

#include "test_support.h"

namespace
{
using namespace rasterslam;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

/** A rasterizer and an odometry, fresh, as the engine chains them. */
struct Tracker
{
	std::shared_ptr<Rasterizer> rasterizer;
	std::shared_ptr<Odometry> odometry;
	explicit Tracker(const std::string& odometryParams = "")
	{
		auto& loader = PluginLoader::instance();
		loader.load();
		rasterizer = loader.create<Rasterizer>("rasterslam::ElevationRasterizer");
		odometry = loader.create<Odometry>("rasterslam::OrbOdometry");
		if (!rasterizer || !odometry)
			return;
		rasterizer->initialize(mrpt::containers::yaml::Map());
		if (odometryParams.empty())
			odometry->initialize(mrpt::containers::yaml::Map());
		else
			odometry->initialize(mrpt::containers::yaml::FromText(odometryParams));
	}
	OdometryResult step(const Scan& s, RasterFrame* keep = nullptr)
	{
		RasterFrame f;
		rasterizer->rasterize(s, f);
		auto r = odometry->process(s, &f);
		if (keep)
			*keep = f;
		return r;
	}
};

/** The first 41 scans of rawlogs/town-vlp16.yaml (made once). */
const std::vector<Scan>& townScans()
{
	static const std::vector<Scan> scans = []
	{
		auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-vlp16.yaml"));
		if (std::getenv("HDL"))
			sc.lidar = "hdl64";
		const auto simu = sim::Simulator::fromScenario(sc);
		std::vector<Scan> v;
		for (std::size_t k = 0; k <= 40; k++)
			v.push_back(simu.scan(k));
		return v;
	}();
	return scans;
}

Eigen::Isometry3d toEigen(const mrpt::poses::CPose3D& p)
{
	Eigen::Isometry3d T;
	T.matrix() = p.getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
	return T;
}
double angleDeg(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B)
{
	return Eigen::AngleAxisd(A.linear().transpose() * B.linear()).angle() / kDeg;
}
Scan loadKitti(const std::string& dir, std::size_t i)
{
	Scan s;
	s.index = i;
	char name[32];
	std::snprintf(name, sizeof name, "/velodyne/%06zu.bin", i);
	s.points = io::loadKittiBin(dir + name);
	return s;
}
}  // namespace

TEST(OrbOdometry, SimulatedDriveFollowsGroundTruth)
{
	const auto& scans = townScans();
	Tracker t;
	ASSERT_TRUE(t.rasterizer && t.odometry);
	// Poses chained as the engine does: against the last keyframe when T_kf_curr is given.
	mrpt::poses::CPose3D pose, lastKf;
	double travelled = 0, worstStep_m = 0;
	for (std::size_t k = 0; k < scans.size(); k++)
	{
		const auto r = t.step(scans[k]);
		if (k == 0)
		{
			EXPECT_EQ(r.status, TrackingStatus::Initializing);
			EXPECT_TRUE(r.keyframe);
		}
		else
		{
			EXPECT_EQ(r.status, TrackingStatus::Ok) << "scan " << k << ": " << r.message;
			EXPECT_GE(r.inliers, 20u);  // min_inliers
			const auto gtStep = *scans[k].groundTruth - *scans[k - 1].groundTruth;
			travelled += gtStep.norm();
			worstStep_m = std::max(
			    worstStep_m, (r.T_prev_curr.asVectorVal() - gtStep.asVectorVal()).head<3>().norm());
		}
		ASSERT_TRUE(r.T_kf_curr.has_value());
		pose = lastKf + *r.T_kf_curr;
		if (r.keyframe)
			lastKf = pose;
	}
	const auto gt = *scans.back().groundTruth - *scans.front().groundTruth;
	const double drift = (toEigen(pose).translation() - toEigen(gt).translation()).norm();
	const double yawErr = std::abs(mrpt::math::wrapToPi(pose.yaw() - gt.yaw())) / kDeg;
	ASSERT_NEAR(travelled, 24.0, 0.1);         // 40 scans at 6 m/s and 10 Hz
	EXPECT_GT(std::abs(gt.yaw()) / kDeg, 30);  // the drive turns a corner
	// Measured: drift 0.094 m (0.39 %), yaw 0.0004-0.115 deg (depending on where the keyframes
	// fall), worst step 0.47 m (mostly z: a VLP-16 sees few beams on each object, so the
	// highest point of a pixel moves in z).
	EXPECT_LT(drift, 0.01 * travelled);
	EXPECT_LT(yawErr, 0.3);
	EXPECT_LT(worstStep_m, 0.75);
	// Pitch and roll drift more (measured 2.8 deg in total after 24 m): a loose bound that
	// still catches a broken rotation.
	EXPECT_LT(angleDeg(toEigen(pose), toEigen(gt)), 4.0);
}

TEST(OrbOdometry, KittiFramePairs)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const std::string dir = test::sharedData("kitti00-0000-0100");
	const auto gt = io::kittiCameraToVelodyne(io::loadTrajectory(dir + "/poses_semantickitti.txt"),
	                                          io::loadKittiCalibTr(dir + "/calib.txt"));
	ASSERT_EQ(gt.size(), 101u);
	// Measured (translation, rotation error): 0-1: 2.7 cm, 0.06 deg; 20-23: 1.0 cm, 0.11 deg;
	// 60-65 (4.7 m apart): 2.2 cm, 0.44 deg. Without the ground alignment 60-65 reads 0.11
	// deg: the two ground planes fitted there disagree by a few tenths of a degree (over the
	// whole clip the alignment still lowers the error, 0.63 % -> 0.34 %).
	for (const auto& [a, b] :
	     std::vector<std::pair<std::size_t, std::size_t>>{{0, 1}, {20, 23}, {60, 65}})
	{
		SCOPED_TRACE(std::to_string(a) + "-" + std::to_string(b));
		Tracker t;  // fresh: the second scan is tracked against the first
		const auto r0 = t.step(loadKitti(dir, a));
		EXPECT_EQ(r0.status, TrackingStatus::Initializing);
		const auto r = t.step(loadKitti(dir, b));
		ASSERT_EQ(r.status, TrackingStatus::Ok) << r.message;
		EXPECT_GE(r.inliers, 100u);
		const Eigen::Isometry3d truth = gt[a].pose.inverse() * gt[b].pose;
		const Eigen::Isometry3d est = toEigen(r.T_prev_curr);
		EXPECT_LT((est.translation() - truth.translation()).norm(), 0.05);
		EXPECT_LT(angleDeg(est, truth), 0.6);
		ASSERT_TRUE(r.T_kf_curr.has_value());
		EXPECT_TRUE(
		    toEigen(*r.T_kf_curr).isApprox(est, 1e-9));  // the first keyframe is the previous scan
		EXPECT_GT(r.information(0, 0), 1.0);             // from the inliers, not the Lost guess
	}
}

/** Checks the keyframe rule on one result: a keyframe when at least `minFrames` scans have
 *  passed and `minShared` inliers are shared, or after `maxFrames`, or when lost. */
void checkKeyframe(const OdometryResult& r, int sinceKf, int minFrames, std::size_t minShared,
                   int maxFrames)
{
	const bool expected = (sinceKf >= minFrames && r.inliers >= minShared) ||
	                      sinceKf >= maxFrames || r.status == TrackingStatus::Lost;
	EXPECT_EQ(r.keyframe, expected)
	    << sinceKf << " scans after the keyframe, " << r.inliers << " inliers";
	EXPECT_EQ(static_cast<bool>(r.keyframeData), r.keyframe);
	if (!r.keyframeData)
		return;
	const auto& k = *r.keyframeData;
	EXPECT_GE(k.size(), 100u);
	EXPECT_EQ(k.descriptors.size(), 32 * k.size());
	EXPECT_EQ(k.xyz.size(), 3 * k.size());
	EXPECT_EQ(k.v.size(), k.size());
	EXPECT_EQ(k.octave.size(), k.size());
}

TEST(OrbOdometry, KeyframeRuleOnTheSimulatedDrive)
{
	const auto& scans = townScans();
	struct Case
	{
		const char* params;
		int minFrames;
		std::size_t minShared;
		int maxFrames;
		std::string flags;  // expected for scans 0..13
	};
	// VLP-16 town: 164, 124, 104, 71, 75, 49 ... inliers against the first keyframe (measured),
	// so the paper's 100 shared points are not reached by scan 5: lowered to 40 here.
	const std::vector<Case> cases = {
	    {"keyframe_min_shared: 40", 5, 40, 20, "K....K....K..."},
	    {"keyframe_min_shared: 40\nkeyframe_min_frames: 3", 3, 40, 20, "K..K..K..K..K."},
	    {"keyframe_min_shared: 100000\nkeyframe_max_frames: 6", 5, 100000, 6, "K.....K.....K."},
	    {"", 5, 100, 20, ""},
	};
	for (const auto& c : cases)
	{
		SCOPED_TRACE(c.params);
		Tracker t(c.params);
		std::string flags;
		int sinceKf = 0;
		for (std::size_t k = 0; k < 14; k++)
		{
			const auto r = t.step(scans[k]);
			if (k > 0)
				checkKeyframe(r, ++sinceKf, c.minFrames, c.minShared, c.maxFrames);
			flags += r.keyframe ? 'K' : '.';
			if (r.keyframe)
				sinceKf = 0;
		}
		EXPECT_EQ(flags[0], 'K');
		if (!c.flags.empty())
		{
			EXPECT_EQ(flags, c.flags);
		}
	}
}

TEST(OrbOdometry, KeyframeRuleOnKitti)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const std::string dir = test::sharedData("kitti00-0000-0100");
	// Measured inliers against keyframe 0: 360, 310, 230, 217, 202 for scans 1..5.
	for (const auto& [params, minFrames, expected] :
	     std::vector<std::tuple<const char*, int, std::string>>{
	         {"", 5, "K....K.."}, {"keyframe_min_frames: 3", 3, "K..K..K."}})
	{
		SCOPED_TRACE(params);
		Tracker t(params);
		std::string flags;
		int sinceKf = 0;
		for (std::size_t k = 0; k <= 7; k++)
		{
			const auto r = t.step(loadKitti(dir, k));
			if (k > 0)
			{
				EXPECT_EQ(r.status, TrackingStatus::Ok) << r.message;
				checkKeyframe(r, ++sinceKf, minFrames, 100, 20);
			}
			flags += r.keyframe ? 'K' : '.';
			if (r.keyframe)
				sinceKf = 0;
		}
		EXPECT_EQ(flags, expected);
	}
}

namespace
{
mrpt::poses::CPose3D stepOf(Tracker& t, const Scan& s, TrackingStatus expected)
{
	OdometryResult r;
	RasterFrame f;
	EXPECT_NO_THROW(r = t.step(s, &f));
	EXPECT_EQ(r.status, expected) << "scan " << s.index << " (" << s.points.size() << " points)";
	std::size_t pixels = 0;
	for (const auto i : f.pixelToPoint)
		pixels += i >= 0;
	EXPECT_LT(pixels, 10u) << "scan " << s.index;
	// The first scan is the first keyframe; later, a scan with too few features never becomes
	// the reference: the next scan still has the old keyframe to match.
	EXPECT_EQ(r.keyframe, expected == TrackingStatus::Initializing);
	return r.T_prev_curr;
}
}  // namespace

TEST(OrbOdometry, NothingToSeeIsLostWithThePrior)
{
	const mrpt::poses::CPose3D identity;
	{  // Only flat, empty ground: all of it is removed.
		const sim::Simulator simu(std::make_shared<const sim::World>(), sim::LidarModel::hdl64(),
		                          sim::Route(), sim::SimulatorOptions());
		Tracker t;
		for (std::size_t k = 0; k < 3; k++)
		{
			const auto s =
			    simu.scanFrom(mrpt::poses::CPose3D(0.6 * k, 0, 1.73, 0, 0, 0), k, 0.1 * k);
			ASSERT_GT(s.points.size(), 50000u);
			const auto T =
			    stepOf(t, s, k == 0 ? TrackingStatus::Initializing : TrackingStatus::Lost);
			EXPECT_EQ(T, identity);
		}
	}
	{  // Only far points (a ring 70 m away) and a handful of near points.
		Tracker t;
		Scan far, few;
		for (int a = 0; a < 3600; a++)
			for (int z = 0; z < 10; z++)
				far.points.push_back({float(70 * std::cos(a * 0.1 * kDeg)),
				                      float(70 * std::sin(a * 0.1 * kDeg)), float(z), 0});
		few.points = {{5, 0, 0, 0}, {0, 5, 1, 0}, {-5, 0, 2, 0}, {0, -5, 0.5f, 0}, {7, 7, 0, 0}};
		far.index = 0;
		few.index = 1;
		EXPECT_EQ(stepOf(t, far, TrackingStatus::Initializing), identity);
		EXPECT_EQ(stepOf(t, few, TrackingStatus::Lost), identity);
		Scan none;
		none.index = 2;
		EXPECT_EQ(stepOf(t, none, TrackingStatus::Lost), identity);
	}
	{  // During a drive: the motion is the constant-velocity prior, the last good step.
		const auto& scans = townScans();
		Tracker t;
		mrpt::poses::CPose3D last;
		for (std::size_t k = 0; k < 6; k++)
			last = t.step(scans[k]).T_prev_curr;
		ASSERT_GT(last.norm(), 0.4);
		Scan blank = scans[6];
		blank.points.resize(5);
		const auto T = stepOf(t, blank, TrackingStatus::Lost);
		EXPECT_LT((T.asVectorVal() - last.asVectorVal()).norm(), 1e-9) << T << " vs " << last;
	}
}

TEST(OrbOdometry, ImplausibleStepIsRejected)
{
	// KITTI 05 frames 540 and 1319: the same place 8.9 m and 28 deg apart, as two consecutive
	// scans. The features match (ungated), but the step exceeds max_step_m (5 m): lost, with
	// the prior (identity), not a jump.
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const std::string dir = test::sharedData("kitti05-revisit-0540-1319");
	Tracker t;
	Scan a, b;
	a.index = 540;
	a.points = io::loadKittiBin(dir + "/000540.bin");
	b.index = 1319;
	b.points = io::loadKittiBin(dir + "/001319.bin");
	t.step(a);
	const auto r = t.step(b);
	EXPECT_EQ(r.status, TrackingStatus::Lost);
	EXPECT_NE(r.message.find("rejected a step of 8."), std::string::npos) << r.message;
	EXPECT_EQ(r.T_prev_curr, mrpt::poses::CPose3D());
	// With a larger limit, the same pair is tracked (measured: 8.84 m).
	Tracker loose("max_step_m: 20");
	loose.step(a);
	const auto r2 = loose.step(b);
	EXPECT_EQ(r2.status, TrackingStatus::Ok) << r2.message;
	EXPECT_NEAR(r2.T_prev_curr.norm(), 8.84, 0.2);
}

// BUG (plugins/orb_odometry/src/orb_odometry.cpp, process(): `r.keyframe = ... || !ok`): a
// lost scan becomes the keyframe even when it has no features, so the good scan after it has
// nothing to track against and is lost too. Enable once fixed.
TEST(OrbOdometry, OneBlankScanLosesOnlyItself)
{
	const auto& scans = townScans();
	Tracker t;
	for (std::size_t k = 0; k < 10; k++)
	{
		Scan s = scans[k];
		if (k == 6)
			s.points.resize(5);
		const auto r = t.step(s);
		if (k != 0 && k != 6)
		{
			EXPECT_EQ(r.status, TrackingStatus::Ok) << "scan " << k << ": " << r.message;
		}
	}
}

namespace
{
/** One step with the elevation image blanked (no feature can be found), as in a street whose
 *  image is empty or a turn the features cannot follow. */
OdometryResult blindStep(Tracker& t, const Scan& s)
{
	RasterFrame f;
	t.rasterizer->rasterize(s, f);
	f.image = mrpt::img::CImage(f.image.getWidth(), f.image.getHeight(), mrpt::img::CH_GRAY);
	f.image.filledRectangle(0, 0, static_cast<int>(f.image.getWidth()) - 1,
	                        static_cast<int>(f.image.getHeight()) - 1, mrpt::img::TColor(0, 0, 0));
	std::fill(f.pixelToPoint.begin(), f.pixelToPoint.end(), -1);
	return t.odometry->process(s, &f);
}
}  // namespace

TEST(OrbOdometry, LostFeaturesRecoveredByIcpOnKitti)
{
	// KITTI 00 scans 10-13, the image of scan 13 blanked: the features see nothing, the
	// fallback registers the points on scan 12's. Measured: 2.3 cm and 0.04 deg from the
	// SemanticKITTI step (0.85 m, 0.19 deg); overlap 0.75, constraint 0.13 (bound 0.02).
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const std::string dir = test::sharedData("kitti00-0000-0100");
	const auto gt = io::kittiCameraToVelodyne(io::loadTrajectory(dir + "/poses_semantickitti.txt"),
	                                          io::loadKittiCalibTr(dir + "/calib.txt"));
	for (const std::string params : {"", "lost_fallback: none"})
	{
		SCOPED_TRACE(params.empty() ? "default (icp)" : params);
		Tracker t(params);
		for (std::size_t k = 10; k <= 12; k++)
			ASSERT_NE(t.step(loadKitti(dir, k)).status, TrackingStatus::Lost);
		const auto r = blindStep(t, loadKitti(dir, 13));
		if (!params.empty())
		{
			EXPECT_EQ(r.status, TrackingStatus::Lost) << r.message;
			continue;
		}
		ASSERT_EQ(r.status, TrackingStatus::Ok) << r.message;
		EXPECT_NE(r.message.find("recovered by ICP"), std::string::npos) << r.message;
		const Eigen::Isometry3d truth = gt[12].pose.inverse() * gt[13].pose;
		const Eigen::Isometry3d est = toEigen(r.T_prev_curr);
		EXPECT_LT((est.translation() - truth.translation()).norm(), 0.05)
		    << est.translation().transpose() << " vs " << truth.translation().transpose();
		EXPECT_LT(angleDeg(est, truth), 0.2);
		// A street constrains every direction: the information is that of a few cm.
		for (int i = 0; i < 6; i++)
			EXPECT_GT(r.information(i, i), 100.0) << "axis " << i;
		// The blind scan has no features: it cannot be the next reference.
		EXPECT_FALSE(r.keyframe);
		// Tracking goes on from it.
		EXPECT_EQ(t.step(loadKitti(dir, 14)).status, TrackingStatus::Ok);
	}
}

TEST(OrbOdometry, IcpFallbackRefusesFlatGround)
{
	// Only flat ground (and the blanked image): the points pin z, roll and pitch but not x, y
	// or yaw; the fallback must say so and leave the scan lost, with the prior.
	const sim::Simulator simu(std::make_shared<const sim::World>(), sim::LidarModel::hdl64(),
	                          sim::Route(), sim::SimulatorOptions());
	Tracker t;
	for (std::size_t k = 0; k < 3; k++)
	{
		const auto s = simu.scanFrom(mrpt::poses::CPose3D(0.6 * k, 0, 1.73, 0, 0, 0), k, 0.1 * k);
		const auto r = blindStep(t, s);
		if (k == 0)
			continue;
		EXPECT_EQ(r.status, TrackingStatus::Lost);
		EXPECT_NE(r.message.find("degenerate geometry"), std::string::npos) << r.message;
		EXPECT_EQ(r.T_prev_curr, mrpt::poses::CPose3D());
	}
}

TEST(OrbOdometry, TwoHertzDriveTrackedThroughItsTurns)
{
	// rawlogs/town-loop.yaml at 2 Hz: 4 m between scans, a turn in two or three scans. The
	// features alone lose two of the first 90 scans (16 inliers where 20 are needed); the
	// constant-velocity prior then misses the turn: measured 52 m and 48 deg off at the end.
	// The points (ICP from the prior, from straight on and from the features' weak fit)
	// carry every scan: measured 0 lost, 2.4 m (0.66 %) and 0.93 deg off after 355 m.
	auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-loop.yaml"));
	sc.rate_hz = 2;
	sc.scans = 90;
	const auto simu = sim::Simulator::fromScenario(sc);
	for (const std::string params : {"", "lost_fallback: none"})
	{
		SCOPED_TRACE(params.empty() ? "default (icp)" : params);
		Tracker t(params);
		mrpt::poses::CPose3D pose, lastKf, first;
		std::size_t lost = 0;
		double travelled = 0;
		mrpt::poses::CPose3D prevGt;
		for (std::size_t k = 0; k < sc.scans; k++)
		{
			const Scan s = simu.scan(k);
			const auto r = t.step(s);
			lost += r.status == TrackingStatus::Lost;
			ASSERT_TRUE(r.T_kf_curr.has_value());
			pose = lastKf + *r.T_kf_curr;
			if (r.keyframe)
				lastKf = pose;
			if (k == 0)
				first = *s.groundTruth;
			else
				travelled += (*s.groundTruth - prevGt).norm();
			prevGt = *s.groundTruth;
		}
		const auto gt = prevGt - first;
		const double endErr = (toEigen(pose).translation() - toEigen(gt).translation()).norm();
		const double yawErr = std::abs(mrpt::math::wrapToPi(pose.yaw() - gt.yaw())) / kDeg;
		if (!params.empty())
		{
			EXPECT_GE(lost, 1u);  // what the fallback is for
			continue;
		}
		EXPECT_EQ(lost, 0u);
		EXPECT_LT(endErr, 0.01 * travelled);
		EXPECT_LT(yawErr, 2.0);
	}
}

TEST(OrbOdometry, BridgedFramesKeepTheGroundOnFlatGround)
{
	// rawlogs/town-vlp16.yaml on flat ground: the truth never tilts, so every degree of tilt
	// in the estimate is drift. A VLP-16 often tracks its keyframe weakly and bridges through
	// the previous frame; those frames become keyframes. Taking their roll and pitch from the
	// features (the highest points of objects, which move in z as the sensor passes) tilted
	// the keyframes by up to 1.84 deg within 300 scans (measured; pitch drift -2.7 deg per
	// 100 m); from the previous frame's ground plane, 0.12 deg.
	auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-vlp16.yaml"));
	sc.town.hills = 0;
	sc.town.max_slope = 0;
	sc.scans = 300;
	const auto simu = sim::Simulator::fromScenario(sc);
	Tracker t;
	ASSERT_TRUE(t.rasterizer && t.odometry);
	mrpt::poses::CPose3D pose, lastKf;
	double worstTilt = 0;
	std::size_t lost = 0, keyframes = 0, bridged = 0;
	for (std::size_t k = 0; k < sc.scans; k++)
	{
		const Scan s = simu.scan(k);
		const auto r = t.step(s);
		lost += r.status == TrackingStatus::Lost;
		keyframes += r.keyframe;
		bridged += r.message.rfind("tracked through the previous frame", 0) == 0;
		ASSERT_TRUE(r.T_kf_curr.has_value());
		pose = lastKf + *r.T_kf_curr;
		if (!r.keyframe)
			continue;
		// The keyframes carry the chain (a frame between them is forgotten by the next).
		lastKf = pose;
		const Eigen::Vector3d up = toEigen(pose).linear() * Eigen::Vector3d::UnitZ();
		worstTilt = std::max(worstTilt, std::acos(std::min(1.0, up.z())) / kDeg);
	}
	EXPECT_EQ(lost, 0u);
	EXPECT_GT(keyframes, 25u);  // the chain of keyframes is long enough to drift
	EXPECT_GE(bridged, 5u);     // the drive exercises the bridge
	EXPECT_LT(worstTilt, 0.4) << "the keyframes tilt on flat ground";
}

TEST(OrbOdometry, GroundMotionCheckRemovesTiltStepsOfTheVlp16)
{
	// rawlogs/town-vlp16.yaml with the ground grid (as lifelong.yaml tracks): on a frame whose
	// few far features tilt it, the planes ask for a correction above
	// ground_max_correction_deg, which is refused as "a change of slope" unless
	// ground_motion_check lets the motion model decide. Measured over the 400 scans, the
	// worst roll/pitch error of one scan's step: 2.60 deg without the check, 0.15 deg with it.
	auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-vlp16.yaml"));
	const auto simu = sim::Simulator::fromScenario(sc);
	std::map<bool, double> worst;
	for (const bool check : {false, true})
	{
		Tracker t(std::string("ground_model: grid\nground_motion_check: ") +
		          (check ? "true" : "false"));
		ASSERT_TRUE(t.rasterizer && t.odometry);
		mrpt::poses::CPose3D pose, lastKf, prev, prevGt;
		std::size_t lost = 0;
		for (std::size_t k = 0; k < sc.scans; k++)
		{
			const auto r = t.step(simu.scan(k));
			lost += r.status == TrackingStatus::Lost;
			ASSERT_TRUE(r.T_kf_curr.has_value());
			pose = lastKf + *r.T_kf_curr;
			if (r.keyframe)
				lastKf = pose;
			const mrpt::poses::CPose3D gt = simu.sensorPose(k);
			if (k > 0)
			{
				// The step's error, its yaw left out: where the up axis goes.
				const Eigen::Matrix3d E =
				    toEigen(gt - prevGt).linear().transpose() * toEigen(pose - prev).linear();
				const double tilt = std::acos(std::min(1.0, (E * Eigen::Vector3d::UnitZ()).z()));
				worst[check] = std::max(worst[check], tilt / kDeg);
			}
			prev = pose;
			prevGt = gt;
		}
		EXPECT_EQ(lost, 0u) << check;
	}
	std::cout << "worst tilt error of a step: " << worst[false] << " deg without the check, "
	          << worst[true] << " deg with it\n";
	EXPECT_GT(worst[false], 2.0) << "the drive no longer has the tilt step this test is about";
	EXPECT_LT(worst[true], 0.5);
}

TEST(GicpBaseline, ReportsLostWhereItIsWrong)
{
	// The GICP baseline on the first 40 scans of the 2 Hz town drive: from a standing start its
	// prior (the last motion) is none, and GICP stays put where the car moved 4 m; the fitness
	// stays low (most matched points are ground). Judged by overlap and constraint it reports
	// each such scan lost. Measured on the 150-scan drive: 43 steps more than 1 m off, all 43
	// reported lost, and one more (44 lost).
	auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-loop.yaml"));
	sc.rate_hz = 2;
	sc.scans = 40;
	const auto simu = sim::Simulator::fromScenario(sc);
	auto& loader = PluginLoader::instance();
	loader.load();
	auto gicp = loader.create<Odometry>("rasterslam::GicpOdometry");
	ASSERT_TRUE(gicp);
	gicp->initialize(mrpt::containers::yaml::Map());
	std::size_t wrong = 0, wrongLost = 0, lost = 0;
	mrpt::poses::CPose3D prevGt;
	for (std::size_t k = 0; k < sc.scans; k++)
	{
		const Scan s = simu.scan(k);
		const auto r = gicp->process(s, nullptr);
		if (k > 0)
		{
			const auto truth = *s.groundTruth - prevGt;
			const double err = (r.T_prev_curr.asVectorVal() - truth.asVectorVal()).head<3>().norm();
			const bool isLost = r.status == TrackingStatus::Lost;
			lost += isLost;
			if (err > 1.0)
			{
				++wrong;
				wrongLost += isLost;
				EXPECT_TRUE(isLost) << "scan " << k << ": " << err << " m off, reported ok";
			}
		}
		prevGt = *s.groundTruth;
	}
	EXPECT_GE(wrong, 5u);  // the case this is about happens here
	EXPECT_EQ(wrongLost, wrong);
	EXPECT_LE(lost, wrong + 2);  // and good steps are not called lost
}

namespace
{
class SimScans : public ScanSource
{
   public:
	/** lift_m: every point raised by this, as a rawlog's sensorPose puts a sensor mounted
	 *  that high above the vehicle frame's origin (on the ground). */
	SimScans(const sim::Simulator& s, std::size_t n, float lift_m = 0)
	    : sim_(s), n_(n), lift_m_(lift_m)
	{
	}
	std::optional<Scan> next() override
	{
		if (k_ >= n_)
			return std::nullopt;
		auto scan = sim_.scan(k_++);
		for (auto& p : scan.points)
			p.z += lift_m_;
		return scan;
	}
	std::string name() const override { return "simulator"; }

   private:
	const sim::Simulator& sim_;
	std::size_t n_, k_ = 0;
	float lift_m_ = 0;
};

/** The simulator's first n sensor poses, stamped as its scans. */
eval::Trajectory truthOf(const sim::Simulator& simu, std::size_t n)
{
	eval::Trajectory t;
	for (std::size_t k = 0; k < n; k++)
		t.push_back({simu.stamp(k), toEigen(simu.sensorPose(k))});
	return t;
}

/** An engine run's poses, stamped as the simulator's scans. */
eval::Trajectory estimateOf(const sim::Simulator& simu,
                            const std::vector<mrpt::poses::CPose3D>& poses)
{
	eval::Trajectory t;
	for (std::size_t k = 0; k < poses.size(); k++)
		t.push_back({simu.stamp(k), toEigen(poses[k])});
	return t;
}

/** The simulator's first n scans (their points raised by lift_m) tracked by an engine of
 *  `cfg` (read from `source`): relative errors on 50..200 m segments, ATE, scans lost
 *  (printed with `label`). */
struct SimTracking
{
	eval::KittiRelativeResult rel;
	double ate = 0;
	std::size_t lost = 0;
};
SimTracking trackSimulated(const sim::Simulator& simu, std::size_t n,
                           const mrpt::containers::yaml& cfg, const std::string& source,
                           const std::string& label, float lift_m = 0)
{
	SimTracking out;
	Engine e(cfg, source);
	SimScans src(simu, n, lift_m);
	const auto res = e.run(src, {});
	EXPECT_TRUE(res.error.empty()) << res.error;
	EXPECT_EQ(res.poses.size(), n);
	if (!res.error.empty() || res.poses.size() != n)
		return out;
	out.lost = res.lost;
	const auto gt = truthOf(simu, n);
	const auto est = estimateOf(simu, res.poses);
	const auto a = eval::associate(gt, est, true);
	out.rel = eval::computeKittiRelative(gt, est, a, {50, 100, 150, 200});
	out.ate = eval::computeAte(gt, est, a).rmse_m;
	std::cout << label << ": RTE " << out.rel.t_err_pct << " %, RRE " << out.rel.r_err_deg_per_m
	          << " deg/m, ATE " << out.ate << " m\n";
	return out;
}
}  // namespace

TEST(Deskew, SweepsTakenWhileMovingAreTrackedBetterDeskewed)
{
	// rawlogs/town-sweep.yaml: the demo town with motion within each sweep (0.8 m and up to
	// 3.8 deg over a sweep), first 300 scans, the paper's tracking with and without
	// engine.deskew. Measured: RTE 2.36 % -> 1.36 %, RRE 0.034 -> 0.022 deg/m, ATE 1.31 ->
	// 0.33 m (50..200 m segments). On KITTI, whose scans are already motion-compensated, the
	// same de-skewing makes tracking worse (0.34 % -> 1.09 %): it is off by default.
	auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-sweep.yaml"));
	ASSERT_TRUE(sc.motion_within_sweep);
	const std::size_t n = 300;
	const auto simu = sim::Simulator::fromScenario(sc);
	const auto gt = truthOf(simu, n);
	std::map<std::string, eval::KittiRelativeResult> rel;
	std::map<std::string, double> ate;
	// Also with the ground grid (odometry ground_model: grid) and deskew: planar (the last
	// step's translation and yaw; its roll and pitch would put the estimate's noise into the
	// ground the grid compares). Measured: RTE 0.96 %, RRE 0.0100 deg/m, ATE 0.24 m; with
	// constant_velocity the grid drifts in roll (2.15 %), with planar the planes 1.30 %.
	for (const std::string mode : {"none", "constant_velocity", "grid+planar"})
	{
		auto cfg = mrpt::containers::yaml::FromFile(
		    test::sourcePath("share/rasterslam/config/tracking.yaml"));
		cfg["engine"]["deskew"] = mode == "grid+planar" ? std::string("planar") : mode;
		if (mode == "grid+planar")
			cfg["odometry"]["params"]["ground_model"] = std::string("grid");
		Engine e(cfg, "tracking.yaml");
		SimScans src(simu, n);
		const auto res = e.run(src, {});
		ASSERT_TRUE(res.error.empty()) << res.error;
		ASSERT_EQ(res.poses.size(), n);
		EXPECT_EQ(res.lost, 0u) << mode;
		const auto est = estimateOf(simu, res.poses);
		const auto a = eval::associate(gt, est, true);
		rel[mode] = eval::computeKittiRelative(gt, est, a, {50, 100, 150, 200});
		ate[mode] = eval::computeAte(gt, est, a).rmse_m;
		std::cout << "deskew " << mode << ": RTE " << rel[mode].t_err_pct << " %, RRE "
		          << rel[mode].r_err_deg_per_m << " deg/m, ATE " << ate[mode] << " m\n";
	}
	const auto &off = rel["none"], &on = rel["constant_velocity"];
	EXPECT_LT(on.t_err_pct, 1.5);
	EXPECT_LT(on.t_err_pct, 0.7 * off.t_err_pct);
	EXPECT_LT(on.r_err_deg_per_m, 0.8 * off.r_err_deg_per_m);
	EXPECT_LT(ate["constant_velocity"], 0.5 * ate["none"]);
	const auto& grid = rel["grid+planar"];
	EXPECT_LT(grid.t_err_pct, 1.2);
	EXPECT_LT(grid.t_err_pct, on.t_err_pct);
	EXPECT_LT(grid.r_err_deg_per_m, 0.015);
	EXPECT_LT(ate["grid+planar"], 0.35);
}

TEST(OrbOdometry, LocalMapRefinementLowersTheVlp16RotationDrift)
{
	// rawlogs/town-vlp16.yaml (400 VLP-16 scans, 320 m), tracking.yaml with the ground grid
	// and each keyframe's rotation refined by ICP on the last 10 keyframes' points (the
	// benchmark's tracking+grid+refine). Measured on 50..200 m segments: RRE 0.0095 deg/m and
	// ATE 0.40 m with the grid alone, and the same when a refinement needs the fallback's
	// overlap (0.4: the VLP-16's sparse rings pass none); 0.0043 deg/m and 0.25 m with
	// refine_min_overlap at its default 0.2.
	const auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-vlp16.yaml"));
	const std::size_t n = sc.scans;
	ASSERT_EQ(n, 400u);
	const auto simu = sim::Simulator::fromScenario(sc);
	auto cfg =
	    mrpt::containers::yaml::FromFile(test::sourcePath("share/rasterslam/config/tracking.yaml"));
	cfg["odometry"]["params"]["ground_model"] = std::string("grid");
	cfg["odometry"]["params"]["refine"] = std::string("rotation");
	cfg["odometry"]["params"]["refine_frames"] = std::string("keyframes");
	const auto r = trackSimulated(simu, n, cfg, "tracking.yaml", "grid + refinement");
	const auto& rel = r.rel;
	const double ate = r.ate;
	EXPECT_EQ(r.lost, 0u);
	EXPECT_LT(rel.r_err_deg_per_m, 0.006);  // 0.0043 measured, 0.0095 unrefined
	EXPECT_LT(rel.t_err_pct, 0.6);          // 0.485 measured
	EXPECT_LT(ate, 0.32);                   // 0.25 measured, 0.40 unrefined
}

TEST(OrbOdometry, LowMountedVlp16IsTracked)
{
	// rawlogs/town-vlp16.yaml with the sensor 0.6 m above the ground (a small robot) instead
	// of 1.73 m, tracking.yaml as shipped: the ground lies above the ground candidates' fixed
	// bound (1 m below the sensor), which the rasterizer raises over the scan's lowest dense
	// layer. Measured on 50..200 m segments: RTE 1.43 %, RRE 0.027 deg/m, ATE 0.348 m (at
	// 1.73 m: 1.14 %, 0.023 deg/m, 0.590 m); with the bound fixed
	// (ground_candidate_layer_margin_m: 0) the ground stays in the images: RTE 56 %, ATE 27.1 m.
	auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-vlp16.yaml"));
	sc.sensor_height_m = 0.6;
	const std::size_t n = sc.scans;
	ASSERT_EQ(n, 400u);
	const auto simu = sim::Simulator::fromScenario(sc);
	const auto cfg =
	    mrpt::containers::yaml::FromFile(test::sourcePath("share/rasterslam/config/tracking.yaml"));
	const auto r = trackSimulated(simu, n, cfg, "tracking.yaml", "VLP-16 at 0.6 m");
	EXPECT_EQ(r.lost, 0u);
	EXPECT_LT(r.rel.t_err_pct, 2.0);
	EXPECT_LT(r.rel.r_err_deg_per_m, 0.06);
	EXPECT_LT(r.ate, 1.0);
}

TEST(OrbOdometry, LowMountedHdl64eKeepsTheCornerWithTheFeaturesConfirmingTheIcp)
{
	// rawlogs/town-loop.yaml with the HDL-64E 0.8 m above the ground, first 450 scans,
	// tracking.yaml as shipped. In the corner at scans 383-384 the features find too few
	// inliers (0 and 13 of the 20 needed) and the ICP fallback's registrations, right within
	// 6 cm and 0.1 deg, pin the motion too weakly (constraint 0.011-0.012, bound 0.02): both
	// scans were lost, the motion prior missing the corner by up to 8 deg. Now the features,
	// matched around where a registration puts them, confirm it (18 and 22 inliers, within
	// 0.3 m and 1 deg; fallback_confirm_inliers 12). Measured on 50..200 m segments: no scan
	// lost, RTE 0.83 %, ATE 0.62 m; without the confirmation (fallback_confirm_inliers: 0)
	// 2 lost, RTE 1.71 %, ATE 2.17 m.
	auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-loop.yaml"));
	sc.sensor_height_m = 0.8;
	const std::size_t n = 450;
	const auto simu = sim::Simulator::fromScenario(sc);
	std::map<int, SimTracking> r;
	for (const int confirm : {0, 12})
	{
		auto cfg = mrpt::containers::yaml::FromFile(
		    test::sourcePath("share/rasterslam/config/tracking.yaml"));
		if (confirm == 0)
			cfg["odometry"]["params"]["fallback_confirm_inliers"] = 0;
		r[confirm] =
		    trackSimulated(simu, n, cfg, "tracking.yaml",
		                   "HDL-64E at 0.8 m, fallback_confirm_inliers " + std::to_string(confirm));
	}
	EXPECT_GE(r[0].lost, 1u) << "the corner no longer loses scans without the confirmation";
	EXPECT_EQ(r[12].lost, 0u);
	EXPECT_LT(r[12].ate, 1.0);
	EXPECT_LT(r[12].ate, r[0].ate / 2);
}

TEST(OrbOdometry, ScansInAVehicleFrameOnTheGroundAreTracked)
{
	// rawlogs/town-vlp16.yaml as shipped (the sensor 1.73 m up), its points given in a
	// vehicle frame whose origin is on the ground, as a rawlog whose sensorPose is (0, 0,
	// 1.73) delivers them: the ground lies at z = 0, far above the ground candidates' fixed
	// bound (z < -1 m). tracking.yaml as shipped. Measured on 50..200 m segments: RTE 0.94 %,
	// RRE 0.022 deg/m, ATE 0.33 m (in the sensor's own frame 1.14 %, 0.023 deg/m, 0.59 m); with
	// the bound fixed (ground_candidate_layer_margin_m: 0): RTE 52 %, ATE 24.9 m.
	const auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-vlp16.yaml"));
	ASSERT_EQ(sc.sensor_height_m, 1.73);
	const std::size_t n = sc.scans;
	const auto simu = sim::Simulator::fromScenario(sc);
	const auto cfg =
	    mrpt::containers::yaml::FromFile(test::sourcePath("share/rasterslam/config/tracking.yaml"));
	const auto r = trackSimulated(simu, n, cfg, "tracking.yaml", "VLP-16, vehicle frame", 1.73f);
	EXPECT_EQ(r.lost, 0u);
	EXPECT_LT(r.rel.t_err_pct, 1.3);
	EXPECT_LT(r.ate, 0.5);
}

TEST(OrbOdometry, RobustRefitLowersTheRefinedTrackingsErrorOnTheTown)
{
	// rawlogs/town-loop.yaml (560 HDL-64E scans), tracking-refined.yaml as shipped (the
	// features' fit refitted on its inliers with a Cauchy loss, refit_cauchy_m: 0.1) against
	// the same with least squares (0). Measured on 50..200 m segments (scripts/benchmark-refit.sh):
	// RTE 0.584 -> 0.316 %, RRE 0.0034 -> 0.0009 deg/m, ATE 0.413 -> 0.224 m.
	const auto sc = sim::loadScenario(test::sourcePath("rawlogs/town-loop.yaml"));
	const std::size_t n = sc.scans;
	ASSERT_EQ(n, 560u);
	const auto simu = sim::Simulator::fromScenario(sc);
	std::map<double, SimTracking> r;
	for (const double cauchy : {0.0, 0.1})
	{
		auto cfg = mrpt::containers::yaml::FromFile(
		    test::sourcePath("share/rasterslam/config/tracking-refined.yaml"));
		ASSERT_EQ(cfg["odometry"]["params"]["refit_cauchy_m"].as<double>(), 0.1);
		cfg["odometry"]["params"]["refit_cauchy_m"] = cauchy;
		r[cauchy] = trackSimulated(simu, n, cfg, "tracking-refined.yaml",
		                           "refit_cauchy_m " + std::to_string(cauchy));
		EXPECT_EQ(r[cauchy].lost, 0u);
	}
	EXPECT_LT(r[0.1].rel.t_err_pct, 0.4);
	EXPECT_LT(r[0.1].rel.t_err_pct, 0.7 * r[0.0].rel.t_err_pct);
	EXPECT_LT(r[0.1].rel.r_err_deg_per_m, 0.5 * r[0.0].rel.r_err_deg_per_m);
	EXPECT_LT(r[0.1].ate, 0.3);
}

TEST(Indoor, HandheldWalkTrackedWithTheIndoorConfigs)
{
	// rawlogs/indoor-handheld.yaml, first 200 scans (24 m, three rooms, turns of up to 13 deg
	// a scan). Measured on all 450: gicp-indoor.yaml 0 lost, ATE 0.063 m; the paper's tracking
	// (indoor.yaml, each estimate refined by ICP on the last 10 keyframes' points) 0 lost, ATE
	// 0.034 m (the README's goal: at or below GICP's). On these 200: GICP 0 lost, ATE 0.022 m;
	// the features 0 lost, ATE 0.015 m (0.049 m refined on the keyframe alone, 3 lost and 0.24 m
	// without the refinement).
	const auto sc = sim::loadScenario(test::sourcePath("rawlogs/indoor-handheld.yaml"));
	const std::size_t n = 200;
	const auto simu = sim::Simulator::fromScenario(sc);
	const auto gt = truthOf(simu, n);
	double gicpAte = 0;
	for (const std::string name : {"gicp-indoor", "indoor"})
	{
		Engine e(mrpt::containers::yaml::FromFile(
		             test::sourcePath("share/rasterslam/config/" + name + ".yaml")),
		         name + ".yaml");
		SimScans src(simu, n);
		const auto res = e.run(src, {});
		ASSERT_TRUE(res.error.empty()) << res.error;
		ASSERT_EQ(res.poses.size(), n);
		const auto est = estimateOf(simu, res.poses);
		const double ate = eval::computeAte(gt, est, eval::associate(gt, est, true)).rmse_m;
		std::cout << name << ": " << res.lost << " lost, ATE " << ate << " m\n";
		if (name == "gicp-indoor")
		{
			EXPECT_EQ(res.lost, 0u);
			EXPECT_LT(ate, 0.1);
			gicpAte = ate;
		}
		else
		{
			EXPECT_EQ(res.lost, 0u);
			EXPECT_LT(ate, 0.025);  // 0.015 m measured on these 200 scans
			EXPECT_LE(ate, gicpAte);
		}
	}
}

TEST(Indoor, IcpConvergesWhereAMatchFlipsBackAndForth)
{
	// Nearest-neighbour matching can flip a few correspondences back and forth at the end, and
	// Gauss-Newton then cycles through two to four poses a fraction of a millimetre apart for
	// ever: on the handheld walk 31 of 401 refinements (0.2 m voxels, from the features'
	// estimate) ran to their 30 iterations unconverged and were thrown away (RTE 1.64 % ->
	// 0.88 % once counted as converged), and so did the fallback of every lost scan. Here each scan
	// of the walk's first 120 is registered on the one before, from the true motion disturbed by 2
	// cm and 0.5 deg (seeded), as the indoor refinement does (0.2 m voxels, rotation judged at the
	// points' distance).
	const auto sc = sim::loadScenario(test::sourcePath("rawlogs/indoor-handheld.yaml"));
	const auto simu = sim::Simulator::fromScenario(sc);
	features::IcpParams prm;
	prm.voxel_m = 0.2;
	prm.lever_m = 0;
	auto cloud = [&](std::size_t k)
	{
		std::vector<Eigen::Vector3f> v;
		for (const auto& p : simu.scan(k).points)
			if (std::hypot(p.x, p.y) < 15.f)
				v.emplace_back(p.x, p.y, p.z);
		return v;
	};
	std::mt19937 rng(7);
	std::normal_distribution<double> noise(0, 1);
	std::size_t converged = 0, total = 0;
	double worstDeg = 0, worstM = 0;
	auto target = cloud(0);
	for (std::size_t k = 1; k <= 120; k++)
	{
		const auto source = cloud(k);
		const Eigen::Isometry3d truth =
		    toEigen(simu.sensorPose(k - 1)).inverse() * toEigen(simu.sensorPose(k));
		Eigen::Isometry3d start = truth;
		start.translation() += 0.02 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
		start.linear() = start.linear() *
		                 Eigen::AngleAxisd(0.5 * M_PI / 180 * noise(rng), Eigen::Vector3d::UnitZ())
		                     .toRotationMatrix();
		const auto r = features::icpPointToPlane(source, target, start, prm);
		total++;
		converged += r.converged;
		if (r.converged)
		{
			worstDeg = std::max(worstDeg, angleDeg(r.T, truth));
			worstM = std::max(worstM, (r.T.translation() - truth.translation()).norm());
		}
		target = source;
	}
	std::cout << converged << " of " << total << " converged; worst " << worstM << " m, "
	          << worstDeg << " deg\n";
	// Measured: 120 of 120 (114 when only a small step counted as converged, 119 when a return
	// to the pose two steps back did too: the cycles run through up to four poses), worst
	// 2.4 cm and 0.55 deg (scan to scan in turns of up to 13 deg a scan).
	EXPECT_EQ(converged, total);
	EXPECT_LT(worstM, 0.04);
	EXPECT_LT(worstDeg, 0.8);
}
