// Trajectory metrics: association, ATE, RPE, the KITTI devkit's relative errors, the CLI.
#include <rasterslam/eval/trajectory_metrics.h>

#include <cstdio>
#include <random>
#include <regex>

#include "test_support.h"

using namespace rasterslam;

namespace
{
constexpr double kDeg = M_PI / 180.0;

/** A planar drive of about `length_m` metres: random step lengths and gently varying yaw,
 *  with the body's x axis along the motion. */
io::Trajectory planarDrive(double length_m, double meanStep, bool straight, unsigned seed)
{
	std::mt19937 rng(seed);
	std::uniform_real_distribution<double> stepD(0.5 * meanStep, 1.5 * meanStep), turn(-0.02, 0.02);
	io::Trajectory t;
	Eigen::Vector3d p(3.0, -2.0, 0.5);
	double yaw = 0.4, dist = 0, yawRate = 0;
	for (int i = 0; dist <= length_m; ++i)
	{
		io::StampedPose sp;
		sp.stamp = 100.0 + 0.1 * i;
		sp.pose.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
		sp.pose.translation() = p;
		t.push_back(sp);
		const double s = stepD(rng);
		p += s * Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0);
		dist += s;
		if (!straight)
		{
			yawRate = std::clamp(yawRate + turn(rng) * s, -0.05, 0.05);  // rad/m
			yaw += yawRate * s;
		}
	}
	return t;
}

Eigen::Isometry3d someRigidTransform()
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() = (Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) *
	              Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX()))
	                 .toRotationMatrix();
	T.translation() = Eigen::Vector3d(12.0, -40.0, 3.0);
	return T;
}

const std::vector<double> kShort = {10, 20, 30, 40, 50, 60, 70, 80};
}  // namespace

TEST(Eval, IdenticalTrajectoriesScoreZero)
{
	const auto gt = planarDrive(200, 0.8, false, 1);
	const auto a = eval::associate(gt, gt, true);
	ASSERT_EQ(a.gt.size(), gt.size());
	const auto ate = eval::computeAte(gt, gt, a);
	EXPECT_LT(ate.rmse_m, 1e-9);
	EXPECT_LT(ate.max_m, 1e-9);
	const auto rpe = eval::computeRpe(gt, gt, a);
	EXPECT_EQ(rpe.n, gt.size() - 1);
	EXPECT_LT(rpe.trans_rmse_m, 1e-12);
	EXPECT_LT(rpe.rot_rmse_deg, 1e-5);  // acos near 1 amplifies round-off to ~1e-6 deg
	const auto rel = eval::computeKittiRelative(gt, gt, a, kShort);
	EXPECT_GT(rel.count, 100u);
	EXPECT_LT(rel.t_err_pct, 1e-9);
	EXPECT_LT(rel.r_err_deg_per_m, 1e-6);
}

TEST(Eval, RigidTransformIsAlignedAway)
{
	const auto gt = planarDrive(200, 0.8, false, 2);
	const Eigen::Isometry3d T = someRigidTransform();
	io::Trajectory est = gt;
	for (auto& sp : est)
		sp.pose = T * sp.pose;
	const auto a = eval::associate(gt, est, true);
	const auto ate = eval::computeAte(gt, est, a);
	EXPECT_LT(ate.rmse_m, 1e-6);
	// The alignment found is the inverse of the transform applied.
	EXPECT_LT((ate.T_gt_est.matrix() - T.inverse().matrix()).norm(), 1e-6);
	const auto rpe = eval::computeRpe(gt, est, a);
	EXPECT_LT(rpe.trans_rmse_m, 1e-9);
	const auto rel = eval::computeKittiRelative(gt, est, a, kShort);
	EXPECT_GT(rel.count, 100u);
	EXPECT_LT(rel.t_err_pct, 1e-6);
	EXPECT_LT(rel.r_err_deg_per_m, 1e-5);
}

TEST(Eval, OnePercentScaleDriftReadsOnePercent)
{
	// Straight path, fine steps: the devkit's segment overshoots its length by at most a step.
	const auto gt = planarDrive(900, 0.25, true, 3);
	io::Trajectory est = gt;
	for (auto& sp : est)
		sp.pose.translation() *= 1.01;
	const auto a = eval::associate(gt, est, true);
	const auto rel = eval::computeKittiRelative(gt, est, a, eval::parseSegmentSpec("100:800:100"));
	EXPECT_NEAR(rel.t_err_pct, 1.00, 0.01);
	EXPECT_LT(rel.r_err_deg_per_m, 1e-6);
	ASSERT_EQ(rel.perLength.size(), 8u);
	EXPECT_GT(rel.perLength.back().count, 0u);  // 800 m segments exist on a 900 m path
	EXPECT_NEAR(rel.perLength.back().t_err_pct, 1.00, 0.01);
	// RPE: every step is 1 % too long.
	double s2 = 0;
	for (std::size_t i = 0; i + 1 < gt.size(); ++i)
		s2 += (gt[i + 1].pose.translation() - gt[i].pose.translation()).squaredNorm();
	const auto rpe = eval::computeRpe(gt, est, a);
	EXPECT_NEAR(rpe.trans_rmse_m, 0.01 * std::sqrt(s2 / static_cast<double>(gt.size() - 1)), 1e-9);
	EXPECT_LT(rpe.rot_rmse_deg, 1e-5);
}

TEST(Eval, ConstantYawDriftReadsDegreesPerMetre)
{
	const double drift = 0.01;  // deg/m
	const auto gt = planarDrive(300, 0.05, false, 4);
	const auto a = eval::associate(gt, gt, true);
	const auto dist = eval::trajectoryDistances(gt, a);
	io::Trajectory est = gt;
	for (std::size_t i = 0; i < est.size(); ++i)
		est[i].pose.linear() =
		    est[i].pose.linear() *
		    Eigen::AngleAxisd(drift * kDeg * dist[i], Eigen::Vector3d::UnitZ()).toRotationMatrix();
	const auto rel = eval::computeKittiRelative(gt, est, a, kShort);
	EXPECT_GT(rel.count, 100u);
	// Steps of at most 7.5 cm overshoot a 10 m segment by < 1 %.
	EXPECT_NEAR(rel.r_err_deg_per_m, drift, 0.01 * drift);
	for (const auto& pl : rel.perLength)
		EXPECT_NEAR(pl.r_err_deg_per_m, drift, 0.01 * drift);
	const auto rpe = eval::computeRpe(gt, est, a);
	EXPECT_NEAR(rpe.rot_mean_deg, drift * dist.back() / static_cast<double>(rpe.n), 1e-3 * drift);
}

TEST(Eval, AteReadsAKnownResidual)
{
	// Alternating +-5 cm vertical offsets cannot be aligned away.
	const auto gt = planarDrive(200, 1.0, false, 5);
	io::Trajectory est = gt;
	for (std::size_t i = 0; i < est.size(); ++i)
		est[i].pose.translation().z() += (i % 2 ? -0.05 : 0.05);
	if (est.size() % 2)
		est.pop_back();
	io::Trajectory gt2(gt.begin(), gt.begin() + static_cast<std::ptrdiff_t>(est.size()));
	const auto ate = eval::computeAte(gt2, est, eval::associate(gt2, est, true));
	EXPECT_NEAR(ate.rmse_m, 0.05, 0.001);
	EXPECT_NEAR(ate.median_m, 0.05, 0.001);
	EXPECT_NEAR(ate.max_m, 0.05, 0.002);
}

TEST(Eval, TooShortPathGivesNoSegments)
{
	const auto gt = planarDrive(60, 1.0, false, 6);
	const auto rel = eval::computeKittiRelative(gt, gt, eval::associate(gt, gt, true),
	                                            eval::parseSegmentSpec("100:800:100"));
	EXPECT_EQ(rel.count, 0u);
	EXPECT_EQ(rel.perLength.size(), 8u);
	EXPECT_EQ(rel.perLength[0].count, 0u);
}

TEST(Eval, AssociationByStampAndByIndex)
{
	const auto gt = planarDrive(50, 1.0, false, 7);
	io::Trajectory est;
	// Every other pose, stamps off by 5 ms, plus one pose far from any gt stamp.
	for (std::size_t i = 0; i < gt.size(); i += 2)
	{
		est.push_back(gt[i]);
		est.back().stamp += 0.005;
	}
	est.push_back(gt.back());
	est.back().stamp += 10.0;
	const auto a = eval::associate(gt, est, false, 0.02);
	ASSERT_EQ(a.gt.size(), est.size() - 1);
	for (std::size_t k = 0; k < a.gt.size(); ++k)
	{
		EXPECT_EQ(a.gt[k], 2 * k);
		EXPECT_EQ(a.est[k], k);
	}
	EXPECT_EQ(eval::associate(gt, est, false, 0.001).gt.size(), 0u);
	try
	{
		eval::associate(gt, est, true);
		ADD_FAILURE() << "lengths differ: must throw";
	}
	catch (const std::runtime_error& e)
	{
		const std::string m = e.what();
		EXPECT_NE(m.find(std::to_string(gt.size())), std::string::npos) << m;
		EXPECT_NE(m.find(std::to_string(est.size())), std::string::npos) << m;
	}
}

TEST(Eval, SegmentSpecParsing)
{
	const auto l = eval::parseSegmentSpec("10:80:10");
	ASSERT_EQ(l.size(), 8u);
	EXPECT_DOUBLE_EQ(l.front(), 10);
	EXPECT_DOUBLE_EQ(l[3], 40);
	EXPECT_DOUBLE_EQ(l.back(), 80);
	EXPECT_EQ(eval::parseSegmentSpec("100:800:100").size(), 8u);
	EXPECT_EQ(eval::parseSegmentSpec("0.5:1.5:0.1").size(), 11u);
	const auto list = eval::parseSegmentSpec("100,200,400");
	ASSERT_EQ(list.size(), 3u);
	EXPECT_DOUBLE_EQ(list[2], 400);
	for (const char* bad : {"", "10:80", "10:80:10:5", "a:80:10", "10:80:0", "80:10:10",
	                        "-10:80:10", "10:80:-5", "10,,20", "10:80:10x", "nan:80:10"})
		EXPECT_THROW(eval::parseSegmentSpec(bad), std::invalid_argument) << "'" << bad << "'";
}

TEST(Eval, RotationAngleUsesTheDevkitFormula)
{
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
	T.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
	EXPECT_NEAR(eval::rotationAngle(T), 0.3, 1e-12);
	T.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
	EXPECT_NEAR(eval::rotationAngle(T), M_PI, 1e-6);
}

namespace
{
/** Runs a shell command, returns its exit code and standard output. */
int runCommand(const std::string& cmd, std::string& out)
{
	out.clear();
	FILE* p = ::popen(cmd.c_str(), "r");
	if (!p)
		return -1;
	char buf[4096];
	std::size_t n;
	while ((n = std::fread(buf, 1, sizeof(buf), p)) > 0)
		out.append(buf, n);
	const int status = ::pclose(p);
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

double jsonValue(const std::string& json, const std::string& key)
{
	std::smatch m;
	const std::regex re("\"" + key + "\": ([-0-9.eE+]+)");
	if (!std::regex_search(json, m, re))
		return std::nan("");
	return std::stod(m[1]);
}

std::string evalBin()
{
	const std::string bin = std::string(RASTERSLAM_BIN_DIR) + "/rasterslam-eval";
	if (!std::filesystem::exists(bin))
		ADD_FAILURE() << bin << " not built (build rasterslam-eval)";
	return bin;
}
}  // namespace

TEST(EvalCli, OfficialVersusSemanticKittiOnTheShortClip)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const std::string dir = test::sharedData("kitti00-0000-0100");
	const std::string base = evalBin() + " traj --gt " + dir + "/poses_semantickitti.txt --est " +
	                         dir + "/poses_official.txt --calib " + dir +
	                         "/calib.txt --est-calib " + dir +
	                         "/calib.txt --segments 10:80:10 --json";
	std::string out;

	// Every frame a first frame: the data notes' anchor (official vs SemanticKITTI, 1.83 %).
	ASSERT_EQ(runCommand(base + " --step 1", out), 0) << base << "\n" << out;
	const double rte1 = jsonValue(out, "rel_trans_pct");
	std::printf("official vs SemanticKITTI, step 1: RTE %.3f %%, RRE %.5f deg/m, ATE %.3f m\n",
	            rte1, jsonValue(out, "rel_rot_deg_per_m"), jsonValue(out, "ate_rmse_m"));
	EXPECT_GE(rte1, 1.5) << out;
	EXPECT_LE(rte1, 2.2) << out;

	// The devkit's own step (10 frames): 37 segments only, so a different figure. Reference
	// values from a line-by-line plain-Python transcription of the devkit (full 4x4 inverses).
	ASSERT_EQ(runCommand(base, out), 0) << base << "\n" << out;
	const double rte = jsonValue(out, "rel_trans_pct");
	const double ate = jsonValue(out, "ate_rmse_m");
	std::printf(
	    "official vs SemanticKITTI, step 10: RTE %.3f %%, RRE %.5f deg/m, ATE %.3f m, path %.2f "
	    "m\n",
	    rte, jsonValue(out, "rel_rot_deg_per_m"), ate, jsonValue(out, "path_length_m"));
	EXPECT_NEAR(rte, 2.2803, 0.001) << out;
	EXPECT_NEAR(jsonValue(out, "rel_rot_deg_per_m"), 0.021481, 1e-5) << out;
	EXPECT_EQ(jsonValue(out, "rel_count"), 37);
	EXPECT_EQ(jsonValue(out, "n_associated"), 101);
	// The two disagree by 1.1 m over the first 10 frames (data README): ATE is decimetres.
	EXPECT_GT(ate, 0.1);
	EXPECT_LT(ate, 1.0);

	// With the default 100..800 m segments the 84 m clip has none: null, exit 0.
	const std::string cmdLong = evalBin() + " traj --gt " + dir +
	                            "/poses_semantickitti.txt --est " + dir +
	                            "/poses_official.txt --json";
	ASSERT_EQ(runCommand(cmdLong, out), 0) << out;
	EXPECT_NE(out.find("\"rel_trans_pct\": null"), std::string::npos) << out;
	EXPECT_NE(out.find("try --segments 10:80:10"), std::string::npos) << out;
}

TEST(EvalCli, ErrorsGiveNonZeroExitCodes)
{
	const auto dir = test::tempDir("evalcli");
	std::string out;
	const std::string missing = (dir / "missing.txt").string();
	EXPECT_EQ(runCommand(evalBin() + " traj --gt " + missing + " --est " + missing + " 2>&1", out),
	          1);
	EXPECT_NE(out.find(missing), std::string::npos) << out;
	EXPECT_EQ(runCommand(evalBin() + " traj --gt a --est b --bogus 2>&1", out), 2);
	EXPECT_NE(out.find("--bogus"), std::string::npos) << out;
	EXPECT_EQ(runCommand(evalBin() + " traj --gt a 2>&1", out), 2);
	EXPECT_NE(out.find("--est"), std::string::npos) << out;
	EXPECT_EQ(runCommand(evalBin() + " nosuchcommand 2>&1", out), 2);
	EXPECT_EQ(runCommand(evalBin() + " --help", out), 0);
	EXPECT_NE(out.find("traj"), std::string::npos) << out;
	EXPECT_EQ(runCommand(evalBin() + " traj --help", out), 0);
	EXPECT_NE(out.find("--segments"), std::string::npos) << out;
}
