// Loop closure end to end on a simulated drive that revisits its start (rawlogs/town-vlp16.yaml:
// a 199 m block loop closing after 33 s): loops are found at the right places, none where
// there is no revisit, and the optimized trajectory is better than odometry alone.
#include <rasterslam/io/trajectory_io.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

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
}  // namespace

TEST(LoopClosure, SimulatedRevisitIsFoundAndCorrectsTheTrajectory)
{
	const auto dir = test::tempDir("loop");
	const auto runWith = [&](const std::string& cfg, const fs::path& out)
	{
		const auto r = test::runCommand(
		    test::bin("rasterslam") + " run --rawlog " + vlp16Rawlog() + " --config " +
		    test::sourcePath("share/rasterslam/config/" + cfg) + " --quiet --out " + out.string());
		EXPECT_EQ(r.exitCode, 0) << r.output;
		return r.output;
	};
	runWith("tracking.yaml", dir / "odo");
	runWith("slam.yaml", dir / "slam");
	ASSERT_TRUE(fs::exists(dir / "slam" / "loops.txt"));
	EXPECT_FALSE(fs::exists(dir / "odo" / "loops.txt"));  // no loop detector configured

	// Precision and recall against the simulator's ground truth (4 m, 30 s).
	const auto e = test::runCommand(test::bin("rasterslam-eval") + " loops --loops " +
	                                (dir / "slam" / "loops.txt").string() + " --gt " +
	                                (dir / "slam" / "groundtruth.tum").string() + " --json");
	ASSERT_EQ(e.exitCode, 0) << e.output;
	const auto j = nlohmann::json::parse(e.output, nullptr, false);
	ASSERT_TRUE(j.is_object() && j.contains("detector")) << e.output;
	const std::string det = j["detector"].dump();
	// The README's figures (scripts/benchmark-loops.sh, town-vlp16, bow): precision 1, recall
	// 0.571 (4 of 7 revisiting keyframes). One revisit fewer (3 of 7) fails.
	EXPECT_EQ(jsonNumber(det, "fp"), 0) << det;
	EXPECT_GE(jsonNumber(det, "tp"), 4) << det;
	EXPECT_GE(jsonNumber(det, "recall"), 0.57) << det;

	// Each accepted loop's transform agrees with the ground truth, and none is found before
	// the route could have revisited anything.
	const auto gt = io::loadTrajectory((dir / "slam" / "groundtruth.tum").string());
	auto gtAt = [&](double t)
	{
		const io::StampedPose* best = &gt.front();
		for (const auto& p : gt)
			if (std::abs(p.stamp - t) < std::abs(best->stamp - t))
				best = &p;
		EXPECT_LT(std::abs(best->stamp - t), 1e-3);
		return best->pose;
	};
	std::ifstream f(dir / "slam" / "loops.txt");
	std::string line;
	int accepted = 0;
	while (std::getline(f, line))
	{
		if (line.empty() || line[0] == '#')
			continue;
		std::istringstream ss(line);
		double qs, cs, score, x, y, z, qx, qy, qz, qw;
		int inl, ver, acc;
		std::string reason;
		ss >> qs >> cs >> score >> inl >> ver >> acc >> reason >> x >> y >> z >> qx >> qy >> qz >>
		    qw;
		ASSERT_FALSE(ss.fail()) << line;
		if (!acc)
			continue;
		++accepted;
		EXPECT_GT(qs - gt.front().stamp, 30.0) << line;  // the first 30 s revisit nothing
		const Eigen::Isometry3d truth = gtAt(cs).inverse() * gtAt(qs);
		EXPECT_NEAR((truth.translation() - Eigen::Vector3d(x, y, z)).norm(), 0, 0.5) << line;
		const Eigen::Quaterniond qe(qw, qx, qy, qz), qt(truth.linear());
		EXPECT_LT(qe.angularDistance(qt) * 180 / M_PI, 2.0) << line;
	}
	EXPECT_GE(accepted, 2);

	// Loop closure pays; the README states 0.575 m odometry only, 0.200 m optimized (0.35 of
	// it): guarded with a margin.
	auto ate = [&](const fs::path& out)
	{
		const auto r = test::runCommand(test::bin("rasterslam-eval") + " traj --gt " +
		                                (out / "groundtruth.tum").string() + " --est " +
		                                (out / "trajectory.tum").string() + " --json");
		EXPECT_EQ(r.exitCode, 0) << r.output;
		return jsonNumber(r.output, "ate_rmse_m");
	};
	const double odo = ate(dir / "odo"), slam = ate(dir / "slam");
	EXPECT_LT(slam, 0.40 * odo) << "odometry " << odo << " m, with loops " << slam << " m";

	// The same input gives the same loops and the same trajectory (batch mode is
	// deterministic), on a drive that has loops.
	runWith("slam.yaml", dir / "slam2");
	for (const auto* file : {"loops.txt", "trajectory.kitti", "pose_graph.graph"})
	{
		std::ifstream fa(dir / "slam" / file), fb(dir / "slam2" / file);
		const std::string a((std::istreambuf_iterator<char>(fa)), {}),
		    b((std::istreambuf_iterator<char>(fb)), {});
		EXPECT_FALSE(a.empty()) << file;
		EXPECT_TRUE(a == b) << file << " differs between two runs";
	}
}

TEST(LoopClosure, ConfigurationErrors)
{
	const auto dir = test::tempDir("loop");
	auto runWith = [&](const std::string& yaml)
	{
		const auto cfg = dir / "cfg.yaml";
		std::ofstream(cfg) << yaml;
		return test::runCommand(test::bin("rasterslam") + " run --rawlog " + vlp16Rawlog() +
		                        " --last 40 --config " + cfg.string() + " --quiet --out " +
		                        (dir / "o").string());
	};
	auto r = runWith(
	    "odometry: {class: rasterslam::OrbOdometry}\nrasterizer: {class: "
	    "rasterslam::ElevationRasterizer}\n"
	    "loop_detector: {class: rasterslam::BowLoopDetector, params: {vocabulary_file: "
	    "nope.vocab}}\n");
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(
	    r.output.find("vocabulary_file: '" + (dir / "nope.vocab").string() + "' does not exist"),
	    std::string::npos)
	    << r.output;  // relative to the config file's folder
	r = runWith(
	    "odometry: {class: rasterslam::GicpOdometry}\nmap_manager: {class: "
	    "rasterslam::LocalMapManager}\n"
	    "loop_detector: {class: rasterslam::BowLoopDetector, params: {vocabulary_file: " +
	    test::sourcePath("share/rasterslam/vocab/elevation-k10l4.vocab") + "}}\n");
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("needs keyframes with features"), std::string::npos) << r.output;
	// The loop detector queries the map manager's map: without one the config is refused.
	r = runWith(
	    "odometry: {class: rasterslam::OrbOdometry}\nrasterizer: {class: "
	    "rasterslam::ElevationRasterizer}\n"
	    "loop_detector: {class: rasterslam::BowLoopDetector, params: {vocabulary_file: " +
	    test::sourcePath("share/rasterslam/vocab/elevation-k10l4.vocab") + "}}\n");
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("'loop_detector' needs a 'map_manager'"), std::string::npos)
	    << r.output;
}
