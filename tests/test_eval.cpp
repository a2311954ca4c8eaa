// Trajectory metrics: association, ATE, RPE, the KITTI devkit's relative errors, the CLI.
#include <rasterslam/eval/trajectory_metrics.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <random>

#include "test_json.h"
#include "test_support.h"

using namespace rasterslam;

using test::number;
using test::parseJson;

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
	// All of it in yaw, the right sign: 0.01 deg/m is 1 deg per 100 m.
	EXPECT_NEAR(rpe.rot_drift_deg_per_100m.z(), 100 * drift, 1e-6);
	EXPECT_NEAR(rpe.rot_drift_deg_per_100m.x(), 0, 1e-9);
	EXPECT_NEAR(rpe.rot_drift_deg_per_100m.y(), 0, 1e-9);
}

TEST(Eval, RotationDriftIsToldApartByAxis)
{
	// A pitch bias of 0.02 deg a frame (nose down, negative about y) and zero-mean roll noise:
	// the drift reads the bias per 100 m in pitch and next to nothing in roll.
	const auto gt = planarDrive(400, 0.5, false, 6);
	const auto a = eval::associate(gt, gt, true);
	io::Trajectory est;
	est.push_back(gt[0]);
	for (std::size_t i = 1; i < gt.size(); ++i)
	{
		const Eigen::Isometry3d dG = eval::fullInverse(gt[i - 1].pose) * gt[i].pose;
		Eigen::Isometry3d noise = Eigen::Isometry3d::Identity();
		noise.linear() =
		    (Eigen::AngleAxisd(-0.02 * kDeg, Eigen::Vector3d::UnitY()) *
		     Eigen::AngleAxisd((i % 2 ? 0.05 : -0.05) * kDeg, Eigen::Vector3d::UnitX()))
		        .toRotationMatrix();
		auto sp = gt[i];
		sp.pose = est.back().pose * dG * noise;
		est.push_back(sp);
	}
	const auto rpe = eval::computeRpe(gt, est, a);
	const double path = eval::trajectoryDistances(gt, a).back();
	const double frames = static_cast<double>(gt.size() - 1);
	EXPECT_NEAR(rpe.rot_drift_deg_per_100m.y(), -0.02 * frames * 100 / path, 1e-4);
	EXPECT_NEAR(rpe.rot_drift_deg_per_100m.x(), 0, 0.05 * 100 / path);
	EXPECT_NEAR(rpe.rot_drift_deg_per_100m.z(), 0, 1e-4);
	EXPECT_GT(rpe.rot_rmse_deg, 0.05);
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
	nlohmann::json j = parseJson(out);
	const double rte1 = number(j, "rel_trans_pct");
	std::printf("official vs SemanticKITTI, step 1: RTE %.3f %%, RRE %.5f deg/m, ATE %.3f m\n",
	            rte1, number(j, "rel_rot_deg_per_m"), number(j, "ate_rmse_m"));
	EXPECT_GE(rte1, 1.5) << out;
	EXPECT_LE(rte1, 2.2) << out;

	// The devkit's own step (10 frames): 37 segments only, so a different figure. Reference
	// values from a line-by-line plain-Python transcription of the devkit (full 4x4 inverses).
	ASSERT_EQ(runCommand(base, out), 0) << base << "\n" << out;
	j = parseJson(out);
	const double rte = number(j, "rel_trans_pct");
	const double ate = number(j, "ate_rmse_m");
	std::printf(
	    "official vs SemanticKITTI, step 10: RTE %.3f %%, RRE %.5f deg/m, ATE %.3f m, path %.2f "
	    "m\n",
	    rte, number(j, "rel_rot_deg_per_m"), ate, number(j, "path_length_m"));
	EXPECT_NEAR(rte, 2.2803, 0.001) << out;
	EXPECT_NEAR(number(j, "rel_rot_deg_per_m"), 0.021481, 1e-5) << out;
	EXPECT_EQ(number(j, "rel_count"), 37) << out;
	EXPECT_EQ(number(j, "n_associated"), 101) << out;
	// The two disagree by 1.1 m over the first 10 frames (data README): ATE is decimetres.
	EXPECT_GT(ate, 0.1);
	EXPECT_LT(ate, 1.0);

	// With the default 100..800 m segments the 84 m clip has none: null, exit 0.
	const std::string cmdLong = evalBin() + " traj --gt " + dir +
	                            "/poses_semantickitti.txt --est " + dir +
	                            "/poses_official.txt --json";
	ASSERT_EQ(runCommand(cmdLong, out), 0) << out;
	j = parseJson(out);
	ASSERT_TRUE(j.contains("rel_trans_pct")) << out;
	EXPECT_TRUE(j["rel_trans_pct"].is_null()) << out;
	ASSERT_TRUE(j.contains("note") && j["note"].is_string()) << out;
	EXPECT_NE(j["note"].get<std::string>().find("try --segments 10:80:10"), std::string::npos)
	    << out;
}

TEST(EvalCli, JsonHasEveryFigureAndNullForNone)
{
	const test::ScopedTempDir dir("evaljson");
	const auto gt = planarDrive(60, 0.8, false, 7);
	io::Trajectory est = gt;
	for (std::size_t i = 0; i < est.size(); ++i)
		est[i].pose.translation().x() += 0.01 * static_cast<double>(i % 3);
	io::saveTrajectoryTum((dir / "gt.tum").string(), gt);
	io::saveTrajectoryTum((dir / "est.tum").string(), est);
	const std::string base = evalBin() + " traj --gt " + (dir / "gt.tum").string() + " --est " +
	                         (dir / "est.tum").string() + " --json";
	std::string out;

	// Segments of 10..50 m fit the 60 m drive; 100 m does not: its figures are null.
	ASSERT_EQ(runCommand(base + " --segments 10,50,100", out), 0) << out;
	EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << "one line:\n" << out;
	nlohmann::json j = parseJson(out);
	for (const char* key : {"gt",
	                        "est",
	                        "n_gt",
	                        "n_est",
	                        "n_associated",
	                        "association",
	                        "path_length_m",
	                        "ate_rmse_m",
	                        "ate_mean_m",
	                        "ate_median_m",
	                        "ate_max_m",
	                        "ate_alignment",
	                        "T_gt_est",
	                        "rpe_pairs",
	                        "rpe_trans_rmse_m",
	                        "rpe_trans_mean_m",
	                        "rpe_rot_rmse_deg",
	                        "rpe_rot_mean_deg",
	                        "segments",
	                        "step",
	                        "rel_count",
	                        "rel_trans_pct",
	                        "rel_rot_deg_per_m",
	                        "per_length",
	                        "note"})
		EXPECT_TRUE(j.contains(key)) << key << " missing in " << out;
	EXPECT_EQ(j.value("gt", ""), (dir / "gt.tum").string());
	EXPECT_EQ(number(j, "n_associated"), static_cast<double>(gt.size())) << out;
	EXPECT_EQ(j.value("association", ""), "stamp") << out;
	EXPECT_EQ(j.value("ate_alignment", ""), "se3") << out;
	EXPECT_GT(number(j, "ate_rmse_m"), 0.0) << out;
	EXPECT_LT(number(j, "ate_rmse_m"), 0.02) << out;
	EXPECT_EQ(j["segments"], nlohmann::json({10, 50, 100})) << out;
	EXPECT_EQ(number(j, "step"), 10) << out;
	EXPECT_TRUE(j["note"].is_null()) << out;  // some segment fits
	ASSERT_TRUE(j["per_length"].is_array() && j["per_length"].size() == 3) << out;
	const auto& fits = j["per_length"][0];
	EXPECT_EQ(number(fits, "length_m"), 10) << out;
	EXPECT_GT(number(fits, "count"), 0) << out;
	EXPECT_TRUE(fits["t_err_pct"].is_number()) << out;
	const auto& none = j["per_length"][2];
	EXPECT_EQ(number(none, "length_m"), 100) << out;
	EXPECT_EQ(number(none, "count"), 0) << out;
	EXPECT_TRUE(none["t_err_pct"].is_null()) << out;
	EXPECT_TRUE(none["r_err_deg_per_m"].is_null()) << out;

	// T_gt_est is a string --align takes back: the same ATE, marked "given".
	ASSERT_TRUE(j["T_gt_est"].is_string()) << out;
	const double ate = number(j, "ate_rmse_m");
	ASSERT_EQ(runCommand(base + " --align " + j["T_gt_est"].get<std::string>(), out), 0) << out;
	j = parseJson(out);
	EXPECT_EQ(j.value("ate_alignment", ""), "given") << out;
	EXPECT_NEAR(number(j, "ate_rmse_m"), ate, 1e-6) << out;
}

TEST(EvalCli, ErrorsGiveNonZeroExitCodes)
{
	const test::ScopedTempDir dir("evalcli");
	std::string out;
	// A file that does not exist is bad input: exit 1, named in the message.
	const std::string missing = (dir / "missing.txt").string();
	EXPECT_EQ(runCommand(evalBin() + " traj --gt " + missing + " --est " + missing + " 2>&1", out),
	          1);
	EXPECT_NE(out.find("rasterslam-eval traj: error: --gt: File does not exist: " + missing),
	          std::string::npos)
	    << out;
	// A file that is no trajectory: exit 1, the file named.
	const std::string bad = (dir / "bad.txt").string();
	io::writeFileAtomically(bad, "not a trajectory\n");
	EXPECT_EQ(runCommand(evalBin() + " traj --gt " + bad + " --est " + bad + " 2>&1", out), 1);
	EXPECT_NE(out.find("rasterslam-eval traj: error: '" + bad + "'"), std::string::npos) << out;
	EXPECT_EQ(runCommand(evalBin() + " nosuchcommand 2>&1", out), 2);
	EXPECT_NE(out.find("rasterslam-eval: unknown command 'nosuchcommand'"), std::string::npos)
	    << out;
	EXPECT_EQ(runCommand(evalBin() + " 2>&1", out), 2);
	EXPECT_NE(out.find("(see rasterslam-eval --help)"), std::string::npos) << out;
}

TEST(EvalCli, HelpAndVersionExitZero)
{
	std::string out;
	EXPECT_EQ(runCommand(evalBin() + " --help", out), 0) << out;
	EXPECT_NE(out.find("rasterslam-eval"), std::string::npos) << out;
	for (const char* cmd : {"traj", "loops", "localmaps", "timings"})
		EXPECT_NE(out.find(std::string("\n  ") + cmd + " "), std::string::npos) << cmd << "\n"
		                                                                        << out;
	EXPECT_NE(out.find("Exit codes"), std::string::npos) << out;
	EXPECT_EQ(runCommand(evalBin() + " help", out), 0) << out;
	EXPECT_NE(out.find("Usage: rasterslam-eval"), std::string::npos) << out;

	EXPECT_EQ(runCommand(evalBin() + " --version", out), 0) << out;
	EXPECT_EQ(out.rfind("rasterslam-eval ", 0), 0u) << out;

	EXPECT_EQ(runCommand(evalBin() + " traj --help", out), 0) << out;
	EXPECT_NE(out.find("Usage: rasterslam-eval traj"), std::string::npos) << out;
	for (const char* opt :
	     {"--gt", "--est", "--calib", "--est-calib", "--gt-format", "--est-format", "--times",
	      "--associate", "--align", "--max-dt", "--segments", "--step", "--json"})
		EXPECT_NE(out.find(std::string("  ") + opt + " "), std::string::npos) << opt << "\n" << out;
	// The defaults are shown.
	EXPECT_NE(out.find("--segments SPEC=100:800:100"), std::string::npos) << out;
	EXPECT_NE(out.find("--step N=10"), std::string::npos) << out;
}

TEST(EvalCli, MissingRequiredOptionIsAUsageError)
{
	const test::ScopedTempDir dir("evalcli");
	const std::string f = (dir / "t.tum").string();
	io::writeFileAtomically(f, "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n");
	std::string out;
	EXPECT_EQ(runCommand(evalBin() + " traj --gt " + f + " 2>&1", out), 2);
	EXPECT_NE(out.find("rasterslam-eval traj: --est is required"), std::string::npos) << out;
	EXPECT_NE(out.find("(see rasterslam-eval traj --help)"), std::string::npos) << out;
	EXPECT_EQ(runCommand(evalBin() + " traj --est " + f + " 2>&1", out), 2);
	EXPECT_NE(out.find("--gt is required"), std::string::npos) << out;
	EXPECT_EQ(runCommand(evalBin() + " traj 2>&1", out), 2);
	EXPECT_NE(out.find("is required"), std::string::npos) << out;
}

TEST(EvalCli, UnknownOptionAndBadValuesAreUsageErrors)
{
	const test::ScopedTempDir dir("evalcli");
	const std::string f = (dir / "t.tum").string();
	io::writeFileAtomically(f, "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n");
	const std::string base = evalBin() + " traj --gt " + f + " --est " + f;
	std::string out;
	EXPECT_EQ(runCommand(base + " --bogus 2>&1", out), 2);
	EXPECT_NE(out.find("rasterslam-eval traj: "), std::string::npos) << out;
	EXPECT_NE(out.find("--bogus"), std::string::npos) << out;
	EXPECT_NE(out.find("(see rasterslam-eval traj --help)"), std::string::npos) << out;
	// Each bad value: exit 2 before any file is read, the option named.
	const std::vector<std::pair<std::string, std::string>> bad = {
	    {"--max-dt -1", "--max-dt"},        {"--max-dt nan", "--max-dt"},
	    {"--max-dt x", "--max-dt"},         {"--step 0", "--step"},
	    {"--step 2.5", "--step"},           {"--segments 1:x", "--segments"},
	    {"--align 1,2,3", "--align"},       {"--align 0,0,0,0,0,0,2", "--align"},
	    {"--gt-format xyz", "--gt-format"}, {"--associate near", "--associate"}};
	for (const auto& [args, opt] : bad)
	{
		EXPECT_EQ(runCommand(base + " " + args + " 2>&1", out), 2) << args << "\n" << out;
		EXPECT_NE(out.find("rasterslam-eval traj: " + opt + ":"), std::string::npos) << args << "\n"
		                                                                             << out;
	}
	// A file that is not there is bad input, not a usage error.
	EXPECT_EQ(runCommand(base + " --times " + (dir / "none").string() + " 2>&1", out), 1) << out;
	EXPECT_NE(out.find("rasterslam-eval traj: error: --times: File does not exist: " +
	                   (dir / "none").string()),
	          std::string::npos)
	    << out;
}
