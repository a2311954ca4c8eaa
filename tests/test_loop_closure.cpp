// Loop closure end to end on a simulated drive that revisits its start (rawlogs/town-vlp16.yaml:
// a 199 m block loop closing after 33 s): loops are found at the right places, none where
// there is no revisit, and the optimized trajectory is better than odometry alone.
#include <rasterslam/io/trajectory_io.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <tuple>

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

/** rasterslam-eval's loop scores of a run's loops.txt against its groundtruth.tum: the
 *  "detector" object, as JSON text. */
std::string detectorScores(const fs::path& run)
{
	const auto e = test::runCommand(test::bin("rasterslam-eval") + " loops --loops " +
	                                (run / "loops.txt").string() + " --gt " +
	                                (run / "groundtruth.tum").string() + " --json");
	EXPECT_EQ(e.exitCode, 0) << e.output;
	const auto j = nlohmann::json::parse(e.output, nullptr, false);
	if (!j.is_object() || !j.contains("detector"))
	{
		ADD_FAILURE() << "no loop scores for " << run << ": " << e.output;
		return "{}";
	}
	return j["detector"].dump();
}
/** One line of a run's loops.txt. */
struct LoopLine
{
	double query = 0, candidate = 0, score = 0;
	int inliers = 0;
	bool verified = false, accepted = false;
	std::string reason;
	Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  //!< query in the candidate's frame
};

/** The lines of `run`/loops.txt (a line that does not parse is a test failure). */
std::vector<LoopLine> loopLines(const fs::path& run)
{
	std::vector<LoopLine> out;
	std::ifstream f(run / "loops.txt");
	for (std::string s; std::getline(f, s);)
	{
		if (s.empty() || s[0] == '#')
			continue;
		std::istringstream ss(s);
		LoopLine l;
		double x, y, z, qx, qy, qz, qw;
		int verified = 0, accepted = 0;
		ss >> l.query >> l.candidate >> l.score >> l.inliers >> verified >> accepted >> l.reason >>
		    x >> y >> z >> qx >> qy >> qz >> qw;
		EXPECT_FALSE(ss.fail()) << run << ": " << s;
		l.verified = verified != 0;
		l.accepted = accepted != 0;
		l.T = Eigen::Translation3d(x, y, z) * Eigen::Quaterniond(qw, qx, qy, qz);
		out.push_back(l);
	}
	return out;
}

/** A loop line's registration agrees with the ground truth `gt`: within 0.5 m and 2 deg. */
void expectTrue(const LoopLine& l, const std::vector<io::StampedPose>& gt)
{
	const auto at = [&](double t)
	{
		const io::StampedPose* best = &gt.front();
		for (const auto& p : gt)
			if (std::abs(p.stamp - t) < std::abs(best->stamp - t))
				best = &p;
		EXPECT_LT(std::abs(best->stamp - t), 1e-3);
		return best->pose;
	};
	const Eigen::Isometry3d truth = at(l.candidate).inverse() * at(l.query);
	EXPECT_LT((truth.translation() - l.T.translation()).norm(), 0.5) << l.query;
	EXPECT_LT(Eigen::AngleAxisd(truth.linear().transpose() * l.T.linear()).angle() * 180 / M_PI,
	          2.0)
	    << l.query;
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
	const std::string det = detectorScores(dir / "slam");
	ASSERT_NE(det, "{}");
	// The README's figures (scripts/benchmark-loops.sh, town-vlp16, bow): precision 1, recall
	// 1 (7 of 7 revisiting keyframes). One revisit fewer (6 of 7) fails. The first three
	// revisits (32.9-34.7 s) meet the first local map, whose first keyframes are 30 s old and
	// its last ones not yet: they are found only because recency is judged per keyframe (4 of
	// 7, recall 0.571, when the local map's newest keyframe decided).
	EXPECT_EQ(jsonNumber(det, "fp"), 0) << det;
	EXPECT_GE(jsonNumber(det, "tp"), 7) << det;
	EXPECT_GE(jsonNumber(det, "recall"), 0.99) << det;

	// Each accepted loop's transform agrees with the ground truth, and none is found before
	// the route could have revisited anything.
	const auto gt = io::loadTrajectory((dir / "slam" / "groundtruth.tum").string());
	ASSERT_FALSE(gt.empty());
	int accepted = 0;
	for (const auto& l : loopLines(dir / "slam"))
	{
		if (!l.accepted)
			continue;
		++accepted;
		EXPECT_GT(l.query - gt.front().stamp, 30.0) << l.query;  // the first 30 s revisit nothing
		// The loop links a keyframe older than exclude_recent_s (30 s), also where its local
		// map has younger keyframes.
		EXPECT_LE(l.candidate, l.query - 30.0) << l.query;
		expectTrue(l, gt);
	}
	EXPECT_GE(accepted, 2);

	// Loop closure pays; the README states 0.590 m odometry only, 0.160 m optimized (0.27 of
	// it; goal a third): guarded with a margin.
	auto ate = [&](const fs::path& out)
	{
		const auto r = test::runCommand(test::bin("rasterslam-eval") + " traj --gt " +
		                                (out / "groundtruth.tum").string() + " --est " +
		                                (out / "trajectory.tum").string() + " --json");
		EXPECT_EQ(r.exitCode, 0) << r.output;
		return jsonNumber(r.output, "ate_rmse_m");
	};
	const double odo = ate(dir / "odo"), slam = ate(dir / "slam");
	EXPECT_LT(slam, 0.33 * odo) << "odometry " << odo << " m, with loops " << slam << " m";

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

TEST(LoopClosure, ImageQueriesOfTheLocalMapBeingBuilt)
{
	// map_manager.place_query_keyframes: the loop query is the image of the last keyframes
	// (the local map being built), matched against the database's local-map images: image
	// against image. On the revisit drive it finds the same loops, all right, with other
	// scores than the keyframe's own words give. With place_query_turns the image is also
	// queried turned, and a place scores its best view.
	const auto dir = test::tempDir("loop");
	std::string y = test::shippedConfig("slam.yaml");
	const auto runWith = [&](const std::string& name, int window, int turns = 1)
	{
		const auto cfg = dir / (name + ".yaml");
		std::string c = std::regex_replace(
		    y, std::regex("\n    keyframes_per_map:"),
		    "\n    place_query_keyframes: " + std::to_string(window) +
		        "\n    place_query_turns: " + std::to_string(turns) + "\n    keyframes_per_map:");
		// The drive revisits its places in the same heading: weighed as much as the image as
		// driven, the turned views show in the scores (at the default 0.8 none wins here).
		if (turns > 1)
			c = std::regex_replace(c, std::regex("(\nloop_detector:\n  class: [^\n]*\n  params:)"),
			                       "$1\n    query_turn_weight: 1.0");
		std::ofstream(cfg) << c;
		const auto r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + vlp16Rawlog() +
		                                " --config " + cfg.string() + " --quiet --out " +
		                                (dir / name).string());
		return r;
	};
	// (query stamp, candidate stamp, inliers) -> normalized score, of the verified candidates
	// (consecutive local maps share a keyframe: the inliers tell their candidates apart; the
	// verification's seed is the query's and the local map's, the same in both runs).
	const auto scores = [&](const std::string& name)
	{
		std::map<std::tuple<double, double, int>, double> out;
		for (const auto& r : loopLines(dir / name))
			if (r.verified)
				out[{r.query, r.candidate, r.inliers}] = r.score;
		return out;
	};
	for (const auto& [name, window, turns] :
	     {std::tuple<std::string, int, int>{"keyframe", 0, 1}, {"image", 5, 1}, {"turned", 5, 4}})
	{
		const auto r = runWith(name, window, turns);
		ASSERT_EQ(r.exitCode, 0) << r.output;
	}
	const std::string det = detectorScores(dir / "image");
	ASSERT_NE(det, "{}");
	// As the keyframe queries (README: precision 1, 7 of 7 revisiting keyframes).
	EXPECT_EQ(jsonNumber(det, "fp"), 0) << det;
	EXPECT_GE(jsonNumber(det, "tp"), 7) << det;
	// The words are the image's: the same verified pairs score otherwise.
	const auto a = scores("keyframe"), b = scores("image");
	int common = 0, differ = 0;
	for (const auto& [key, score] : b)
		if (const auto it = a.find(key); it != a.end())
		{
			++common;
			differ += std::abs(it->second - score) > 1e-3;
		}
	EXPECT_GE(common, 4);
	EXPECT_EQ(differ, common);

	// Turned: still no wrong loop and as many right ones; a pair verified in both runs scores
	// at least what the unturned image gives it (its view is one of the four), and some
	// score more (a turned view matched the place better). Compared up to the first query
	// whose accepted loops differ between the runs: after it the optimization moves the poses
	// the query images are made from.
	const std::string detTurned = detectorScores(dir / "turned");
	ASSERT_NE(detTurned, "{}");
	EXPECT_EQ(jsonNumber(detTurned, "fp"), 0) << detTurned;
	EXPECT_GE(jsonNumber(detTurned, "tp"), 7) << detTurned;
	const auto acceptedLoops = [&](const std::string& name)
	{
		std::vector<std::pair<double, double>> out;  // (query, candidate) stamps, in file order
		for (const auto& r : loopLines(dir / name))
			if (r.accepted)
				out.emplace_back(r.query, r.candidate);
		return out;
	};
	const auto la = acceptedLoops("image"), lb = acceptedLoops("turned");
	double sameUntil = std::numeric_limits<double>::infinity();
	for (std::size_t i = 0; i < std::max(la.size(), lb.size()); i++)
		if (i >= la.size() || i >= lb.size() || la[i] != lb[i])
		{
			sameUntil = std::min(i < la.size() ? la[i].first : sameUntil,
			                     i < lb.size() ? lb[i].first : sameUntil);
			break;
		}
	const auto c = scores("turned");
	int both = 0, higher = 0, lower = 0;
	for (const auto& [key, score] : c)
		if (const auto it = b.find(key); it != b.end() && std::get<0>(key) <= sameUntil)
		{
			++both;
			higher += score > it->second + 1e-3;
			lower += score < it->second - 1e-3;
		}
	EXPECT_GE(both, 4);
	EXPECT_GE(higher, 1);
	EXPECT_EQ(lower, 0);

	// A window below 0 is refused, naming the parameter; so are turns of no image.
	const auto bad = runWith("bad", -1);
	EXPECT_EQ(bad.exitCode, 1);
	EXPECT_NE(bad.output.find("place_query_keyframes"), std::string::npos) << bad.output;
	const auto badTurns = runWith("bad-turns", 0, 4);
	EXPECT_EQ(badTurns.exitCode, 1);
	EXPECT_NE(badTurns.output.find("place_query_turns"), std::string::npos) << badTurns.output;
}

TEST(LoopClosure, PolarContextsRankedBesideTheWords)
{
	// map_manager.polar_contexts + loop_detector.polar_fusion: each local map keeps a polar
	// context about each keyframe, the image query one about its keyframe, and the loop
	// detector verifies the two rankings fused. On the revisit drive: no wrong loop, and as
	// many right ones as the image queries alone (README: 7 of 7 revisiting keyframes).
	const auto dir = test::tempDir("loop");
	std::string y = test::shippedConfig("slam.yaml");
	const auto runWith = [&](const std::string& name, const std::string& manager)
	{
		const auto cfg = dir / (name + ".yaml");
		std::string c = std::regex_replace(y, std::regex("\n    keyframes_per_map:"),
		                                   "\n" + manager + "\n    keyframes_per_map:");
		c = std::regex_replace(c, std::regex("(\nloop_detector:\n  class: [^\n]*\n  params:)"),
		                       "$1\n    polar_fusion: true");
		std::ofstream(cfg) << c;
		// --verbose: the loop detector's debug lines say how each candidate was ranked.
		return test::runCommand(test::bin("rasterslam") + " run --rawlog " + vlp16Rawlog() +
		                        " --config " + cfg.string() + " --verbose --out " +
		                        (dir / name).string());
	};
	const auto r = runWith("polar", "    place_query_keyframes: 5\n    polar_contexts: true");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const std::string det = detectorScores(dir / "polar");
	ASSERT_NE(det, "{}");
	EXPECT_EQ(jsonNumber(det, "fp"), 0) << det;
	EXPECT_GE(jsonNumber(det, "tp"), 7) << det;
	// run.yaml counts the loops the contexts alone brought (at most every loop edge).
	std::ifstream ry(dir / "polar/run.yaml");
	const std::string run((std::istreambuf_iterator<char>(ry)), {});
	std::smatch m, e;
	ASSERT_TRUE(std::regex_search(run, m, std::regex("\\bloops_by_context: ([0-9]+)"))) << run;
	ASSERT_TRUE(std::regex_search(run, e, std::regex("\\bloop_edges: ([0-9]+)"))) << run;
	EXPECT_LE(std::stoi(m[1]), std::stoi(e[1]));
	// The contexts ranked the candidates: verified ones carry a polar distance (-1: none).
	EXPECT_TRUE(std::regex_search(r.output, std::regex("polar distance 0\\.[0-9]+")))
	    << "no candidate ranked by its polar context";

	// Contexts of no place query are refused, naming the parameter.
	const auto bad = runWith("bad", "    polar_contexts: true");
	EXPECT_EQ(bad.exitCode, 1);
	EXPECT_NE(bad.output.find("polar_contexts"), std::string::npos) << bad.output;
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

TEST(LoopClosure, AStrongLoopEndsTheCandidateSearch)
{
	// loop_detector.stop_at_inliers (slam.yaml: 50): the candidates ranked below an accepted
	// one with that many inliers are not verified. On a lap and a half of the town loop, where
	// most revisiting keyframes have 5 candidates, it verifies fewer and finds the same
	// revisits, none wrong (README: 2,500 scans, loop stage 2.14 -> 1.52 ms a scan, recall
	// 0.912 -> 0.908).
	const auto dir = test::tempDir("loop-stop");
	const auto rawlog = (dir / "town.rawlog").string();
	const auto sim =
	    test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-loop.yaml") + " --scans 700 -o " + rawlog);
	ASSERT_EQ(sim.exitCode, 0) << sim.output;
	std::string y = test::shippedConfig("slam.yaml");
	ASSERT_TRUE(std::regex_search(y, std::regex("\n    stop_at_inliers: 50 ")));
	const auto runWith = [&](const std::string& name, int stopAt)
	{
		const auto cfg = dir / (name + ".yaml");
		std::ofstream(cfg) << std::regex_replace(
		    y, std::regex("\n    stop_at_inliers: 50 "),
		    "\n    stop_at_inliers: " + std::to_string(stopAt) + " ");
		const auto r =
		    test::runCommand(test::bin("rasterslam") + " run --rawlog " + rawlog + " --config " +
		                     cfg.string() + " --quiet --out " + (dir / name).string());
		EXPECT_EQ(r.exitCode, 0) << r.output;
		return loopLines(dir / name);
	};
	// Queries where a candidate was examined after an accepted one of 50 inliers or more.
	const auto examinedAfterStrong = [](const std::vector<LoopLine>& lines)
	{
		int n = 0;
		for (std::size_t i = 0; i + 1 < lines.size(); i++)
			n +=
			    lines[i].accepted && lines[i].inliers >= 50 && lines[i + 1].query == lines[i].query;
		return n;
	};
	const auto all = runWith("all", 0), stop = runWith("stop", 50);
	ASSERT_FALSE(all.empty());
	ASSERT_FALSE(stop.empty());
	// The drive has what the option is for: strong loops with candidates ranked below them.
	EXPECT_GE(examinedAfterStrong(all), 5);
	EXPECT_EQ(examinedAfterStrong(stop), 0);
	EXPECT_LT(stop.size() + 20, all.size()) << "candidates examined";
	const std::string detAll = detectorScores(dir / "all"), detStop = detectorScores(dir / "stop");
	EXPECT_EQ(jsonNumber(detStop, "fp"), 0) << detStop;
	EXPECT_GE(jsonNumber(detStop, "tp"), jsonNumber(detAll, "tp") - 2) << detStop << detAll;
}

TEST(LoopClosure, ARevisitIsFollowedWhereItsCandidateFallsShort)
{
	// loop_detector.follow_loop_m (slam.yaml: 20): a keyframe that the BOW search closes no
	// loop for, within 20 m of the last one that did, is matched where that loop and the
	// odometry since put it (guided gate). On the VLP-16 drive with tracking-refined.yaml's
	// odometry the revisiting keyframe at 34.7 s has the right candidate at 24 inliers, one
	// short of min_inliers (25): without following it is lost (6 of 7); followed, it is found
	// (with slam.yaml's own odometry every revisit of this drive closes on the BOW search).
	const auto dir = test::tempDir("loop-follow");
	std::string y = test::shippedConfig("slam.yaml");
	const std::regex follow("\n    follow_loop_m: 20 ");
	ASSERT_TRUE(std::regex_search(y, follow));
	const std::string odometry = "\nodometry:\n  class: rasterslam::OrbOdometry\nmap_manager:";
	const auto at = y.find(odometry);
	ASSERT_NE(at, std::string::npos) << "slam.yaml's odometry has parameters now";
	y.insert(at + odometry.size() - std::string("map_manager:").size(),
	         "  params:\n    ground_model: grid\n    refine: rotation\n"
	         "    refine_frames: keyframes\n    refine_keyframes: 10\n");
	const auto runWith = [&](const std::string& name, const std::string& metres)
	{
		const auto cfg = dir / (name + ".yaml");
		std::ofstream(cfg) << std::regex_replace(y, follow, "\n    follow_loop_m: " + metres + " ");
		const auto r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + vlp16Rawlog() +
		                                " --config " + cfg.string() + " --quiet --out " +
		                                (dir / name).string());
		EXPECT_EQ(r.exitCode, 0) << r.output;
		return loopLines(dir / name);
	};
	const auto on = runWith("on", "20"), off = runWith("off", "0");
	ASSERT_FALSE(on.empty());
	ASSERT_FALSE(off.empty());

	const auto gt = io::loadTrajectory((dir / "on" / "groundtruth.tum").string());
	ASSERT_FALSE(gt.empty());
	int followed = 0;
	for (const auto& l : on)
	{
		if (!l.accepted || l.reason != "followed")
			continue;
		++followed;
		// A place of this session's earlier pass, registered where the truth puts it.
		EXPECT_LE(l.candidate, l.query - 30.0) << l.query;
		expectTrue(l, gt);
		// The same keyframe closed no loop unfollowed.
		for (const auto& o : off)
			EXPECT_FALSE(std::abs(o.query - l.query) < 1e-6 && o.accepted) << l.query;
	}
	EXPECT_GE(followed, 1);
	for (const auto& o : off)
		EXPECT_NE(o.reason, "followed");
	// The README's figures (Loop closure, a revisit followed): 7 of 7 revisiting keyframes
	// with this odometry followed, 6 of 7 not; none wrong.
	const std::string det = detectorScores(dir / "on"), detOff = detectorScores(dir / "off");
	EXPECT_EQ(jsonNumber(det, "fp"), 0) << det;
	EXPECT_GE(jsonNumber(det, "tp"), 7) << det;
	EXPECT_LT(jsonNumber(detOff, "tp"), jsonNumber(det, "tp")) << detOff;
}
