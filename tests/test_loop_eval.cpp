// Loop-closure evaluation: positives, precision/recall, the threshold sweep, F1 max, the CLI.
#include <rasterslam/eval/loop_metrics.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <regex>
#include <sstream>

#include "test_json.h"
#include "test_support.h"

using namespace rasterslam;

using test::parseJson;

namespace
{
constexpr double kT0 = 1000.0;  // first ground-truth stamp
constexpr double kLap = 40.0;   // a 100 m square at 10 m/s

/** Position after `t` seconds on the square (0,0) -> (100,0) -> (100,100) -> (0,100). */
Eigen::Vector3d squareAt(double t)
{
	const double d = std::fmod(10.0 * t, 400.0);
	if (d < 100)
		return {d, 0, 0};
	if (d < 200)
		return {100, d - 100, 0};
	if (d < 300)
		return {300 - d, 100, 0};
	return {0, 400 - d, 0};
}

/** Two laps at 10 Hz: 801 poses, stamps kT0 + 0.1 i. */
io::Trajectory twoLaps()
{
	io::Trajectory gt;
	for (int i = 0; i <= 800; ++i)
	{
		io::StampedPose sp;
		sp.stamp = kT0 + 0.1 * i;
		sp.pose.translation() = squareAt(0.1 * i);
		gt.push_back(sp);
	}
	return gt;
}

struct Line
{
	double query, candidate;  // seconds since the start; candidate < 0: none
	double score;
	bool verified, accepted;
};

std::string loopsText(const std::vector<Line>& lines)
{
	std::string out =
	    "# query_stamp candidate_stamp score inliers verified accepted reason x y z qx qy qz qw\n";
	char buf[256];
	for (const auto& l : lines)
	{
		std::snprintf(buf, sizeof(buf), "%.6f %.6f %.6f %d %d %d %s 0 0 0 0 0 0 1\n", kT0 + l.query,
		              l.candidate < 0 ? -1.0 : kT0 + l.candidate, l.score, l.verified ? 40 : 5,
		              l.verified ? 1 : 0, l.accepted ? 1 : 0,
		              l.accepted ? "ok" : (l.verified ? "score" : "inliers"));
		out += buf;
	}
	return out;
}

eval::LoopLog logOf(const std::vector<Line>& lines)
{
	std::istringstream in(loopsText(lines));
	return eval::parseLoopLog(in, "mem/loops.txt");
}

/** Queries once a second over both laps; the first lap finds nothing (candidate -1). */
std::vector<Line> firstLapMisses()
{
	std::vector<Line> v;
	for (int t = 0; t < 40; ++t)
		v.push_back({double(t), -1, 0.0, false, false});
	return v;
}

/** All 40 second-lap queries find the same place one lap earlier, scores 0.50 .. 0.89. */
std::vector<Line> allCorrect()
{
	auto v = firstLapMisses();
	for (int k = 0; k < 40; ++k)
		v.push_back({40.0 + k, k + 0.0, 0.5 + 0.01 * k, true, true});
	return v;
}

const eval::PrPoint& rowAt(const eval::LoopEvalResult& r, double thr)
{
	for (const auto& p : r.sweep)
	{
		if (std::abs(p.threshold - thr) < 1e-9)
			return p;
	}
	ADD_FAILURE() << "no sweep row at threshold " << thr;
	return r.sweep.back();
}

std::string writeFile(const std::filesystem::path& p, const std::string& text)
{
	std::ofstream(p) << text;
	return p.string();
}

std::string evalBin()
{
	return test::bin("rasterslam-eval");
}

}  // namespace

TEST(LoopEval, SquareHasPositivesOnlyOnTheSecondLap)
{
	// The route sanity the other tests rely on: lap 2 revisits lap 1, 40 s apart.
	EXPECT_NEAR((squareAt(53) - squareAt(13)).norm(), 0, 1e-9);
	EXPECT_NEAR((squareAt(35) - squareAt(0)).norm(), 50, 1e-9);
	const auto r = eval::evaluateLoops(logOf(allCorrect()), twoLaps());
	EXPECT_EQ(r.lines, 80u);
	EXPECT_EQ(r.queries, 80u);
	// t = 39 s is 10 m short of the start: no place 30 s older within 4 m, so not positive.
	EXPECT_EQ(r.positives, 40u);
}

TEST(LoopEval, AllCorrectDetectionsGivePerfectScores)
{
	const auto r = eval::evaluateLoops(logOf(allCorrect()), twoLaps());
	EXPECT_EQ(r.detector.tp, 40u);
	EXPECT_EQ(r.detector.fp, 0u);
	EXPECT_EQ(r.detector.fn, 0u);
	EXPECT_DOUBLE_EQ(r.detector.precision, 1.0);
	EXPECT_DOUBLE_EQ(r.detector.recall, 1.0);
	EXPECT_EQ(r.acceptedLines, 40u);
	EXPECT_EQ(r.acceptedWrong, 0u);
	// 0 (the misses), 40 correct scores and +inf.
	ASSERT_EQ(r.sweep.size(), 42u);
	ASSERT_NE(r.best, eval::LoopEvalResult::npos);
	const auto& b = r.sweep[r.best];
	EXPECT_DOUBLE_EQ(b.f1, 1.0);
	// 0 and 0.5 both reach F1 = 1: the tie goes to the higher threshold.
	EXPECT_NEAR(b.threshold, 0.5, 1e-9);
	const auto& above = rowAt(r, 0.51);
	EXPECT_EQ(above.tp, 39u);
	EXPECT_EQ(above.fn, 1u);
	EXPECT_DOUBLE_EQ(above.precision, 1.0);
	EXPECT_NEAR(above.recall, 39.0 / 40.0, 1e-12);
	const auto& last = r.sweep.back();
	EXPECT_TRUE(std::isinf(last.threshold));
	EXPECT_EQ(last.tp + last.fp, 0u);
	EXPECT_DOUBLE_EQ(last.precision, 1.0);
	EXPECT_DOUBLE_EQ(last.recall, 0.0);
}

TEST(LoopEval, WrongHighScoreDetectionLowersPrecisionAtLowThresholds)
{
	auto lines = allCorrect();
	// t = 35 s at (0, 50) matched with t = 0 at (0, 0): 50 m away, old enough, wrong.
	lines.push_back({35, 0, 0.95, true, false});
	const auto r = eval::evaluateLoops(logOf(lines), twoLaps());
	EXPECT_EQ(r.positives, 40u);
	const auto& low = rowAt(r, 0.5);
	EXPECT_EQ(low.tp, 40u);
	EXPECT_EQ(low.fp, 1u);
	EXPECT_NEAR(low.precision, 40.0 / 41.0, 1e-12);
	EXPECT_DOUBLE_EQ(low.recall, 1.0);
	const auto& high = rowAt(r, 0.95);
	EXPECT_EQ(high.tp, 0u);
	EXPECT_EQ(high.fp, 1u);
	EXPECT_DOUBLE_EQ(high.precision, 0.0);
	EXPECT_DOUBLE_EQ(high.f1, 0.0);
	// Above every correct score, below the wrong one.
	EXPECT_DOUBLE_EQ(rowAt(r, 0.89).precision, 0.5);
	// Not accepted: the detector's own decisions stay clean.
	EXPECT_EQ(r.detector.fp, 0u);
	EXPECT_DOUBLE_EQ(r.detector.precision, 1.0);
	EXPECT_NEAR(r.sweep[r.best].threshold, 0.5, 1e-9);
	EXPECT_NEAR(r.sweep[r.best].f1, 80.0 / 81.0, 1e-12);

	// Accepted, the same line is a false positive of the detector and a wrong edge.
	lines.back().accepted = true;
	const auto r2 = eval::evaluateLoops(logOf(lines), twoLaps());
	EXPECT_EQ(r2.detector.tp, 40u);
	EXPECT_EQ(r2.detector.fp, 1u);
	EXPECT_NEAR(r2.detector.precision, 40.0 / 41.0, 1e-12);
	EXPECT_EQ(r2.acceptedWrong, 1u);
}

TEST(LoopEval, UnverifiedAndMissingCandidatesAreNoDetections)
{
	auto lines = allCorrect();
	// Query 45 s: a wrong, unverified candidate outscores the right one; a -1 line too.
	lines.push_back({45, 20, 0.99, false, false});
	lines.push_back({45, -1, 0.98, false, false});
	const auto r = eval::evaluateLoops(logOf(lines), twoLaps());
	EXPECT_EQ(rowAt(r, 0.5).fp, 0u);
	EXPECT_EQ(rowAt(r, 0.5).tp, 40u);
	EXPECT_EQ(rowAt(r, 0.99).tp + rowAt(r, 0.99).fp, 0u);
	EXPECT_EQ(r.queries, 80u);
}

TEST(LoopEval, RecentCandidatesAreNeitherPositiveNorDetections)
{
	// Matches 0.2 s back (2 m away: right by distance) and one 20 s back (100 m away: wrong);
	// all are younger than 30 s.
	std::vector<Line> lines;
	for (int t = 1; t < 30; ++t)
		lines.push_back({double(t), t - 0.2, 0.9, true, t == 5});
	lines.push_back({25, 5, 0.8, true, false});
	const auto r = eval::evaluateLoops(logOf(lines), twoLaps());
	EXPECT_EQ(r.positives, 0u);
	EXPECT_EQ(r.recentLines, 30u);
	EXPECT_EQ(r.acceptedRecent, 1u);
	EXPECT_EQ(r.detector.tp + r.detector.fp, 0u);
	for (const auto& p : r.sweep)
	{
		EXPECT_EQ(p.tp + p.fp, 0u) << p.threshold;
		EXPECT_FALSE(p.valid);
	}
	EXPECT_EQ(r.best, eval::LoopEvalResult::npos);

	// With --exclude-s 0.1 the 0.2 s-old matches count: correct by distance, and the queries
	// become positives (the pose 0.2 s back is within 4 m).
	eval::LoopEvalParams p;
	p.exclude_s = 0.1;
	p.registration_m = 0;  // by distance: these lines carry no registration (identity)
	const auto r2 = eval::evaluateLoops(logOf(lines), twoLaps(), p);
	EXPECT_EQ(r2.recentLines, 0u);
	EXPECT_EQ(r2.positives, 29u);
	EXPECT_EQ(rowAt(r2, 0.9).tp, 29u);
	// Query 25 keeps its best line (0.9, correct) and never uses the 0.8 one (wrong).
	EXPECT_EQ(rowAt(r2, 0.8).fp, 0u);
}

TEST(LoopEval, F1MaxPicksTheThresholdThatDropsTheWrongDetections)
{
	auto lines = firstLapMisses();
	for (int k = 0; k < 20; ++k)  // correct, scores 0.60 .. 0.79
		lines.push_back({40.0 + k, k + 0.0, 0.6 + 0.01 * k, true, k % 2 == 0});
	for (int k = 20; k < 40; ++k)  // wrong (50 m further along the path), 0.20 .. 0.39
		lines.push_back({40.0 + k, k + 5.0, 0.2 + 0.01 * (k - 20), true, false});
	const auto r = eval::evaluateLoops(logOf(lines), twoLaps());
	ASSERT_NE(r.best, eval::LoopEvalResult::npos);
	const auto& b = r.sweep[r.best];
	EXPECT_NEAR(b.threshold, 0.6, 1e-9);
	EXPECT_EQ(b.tp, 20u);
	EXPECT_EQ(b.fp, 0u);
	EXPECT_EQ(b.fn, 20u);
	EXPECT_NEAR(b.f1, 2.0 / 3.0, 1e-12);
	const auto& all = rowAt(r, 0.2);
	EXPECT_NEAR(all.f1, 0.5, 1e-12);
	EXPECT_EQ(all.fp, 20u);
	// The detector accepted every other correct one.
	EXPECT_EQ(r.detector.tp, 10u);
	EXPECT_EQ(r.detector.fn, 30u);
	EXPECT_NEAR(r.detector.recall, 0.25, 1e-12);
}

TEST(LoopEval, SweepMatchesBruteForceAndIsMonotone)
{
	// Several candidates a query, random scores and verdicts, right and wrong places.
	std::mt19937 rng(7);
	std::uniform_real_distribution<double> score(0, 1);
	std::bernoulli_distribution coin(0.5);
	std::vector<Line> lines;
	for (int t = 0; t < 80; ++t)
	{
		for (int c = 0; c < 4; ++c)
		{
			const double cand = coin(rng) && t >= 40 ? t - 40.0 : std::fmod(t * 7.0 + c, 40.0);
			lines.push_back(
			    {double(t), cand, std::round(score(rng) * 100) / 100, coin(rng), false});
		}
	}
	const auto r = eval::evaluateLoops(logOf(lines), twoLaps());
	auto at = [&](double t) { return squareAt(t); };
	EXPECT_EQ(r.positives, 40u);
	for (std::size_t i = 0; i < r.sweep.size(); ++i)
	{
		const auto& p = r.sweep[i];
		if (i)
		{
			const auto& q = r.sweep[i - 1];
			EXPECT_GT(p.threshold, q.threshold);
			EXPECT_LE(p.tp + p.fp, q.tp + q.fp);
			EXPECT_LE(p.tp, q.tp);
			EXPECT_LE(p.recall, q.recall);
			EXPECT_GE(p.fn, q.fn);
		}
		// The definition, query by query.
		std::size_t tp = 0, fp = 0;
		for (int t = 0; t < 80; ++t)
		{
			const Line* best = nullptr;
			for (const auto& l : lines)
			{
				if (l.query == t && l.verified && l.score >= p.threshold && t - l.candidate >= 30 &&
				    (!best || l.score > best->score))
					best = &l;
			}
			if (best)
				++((at(t) - at(best->candidate)).norm() <= 4 ? tp : fp);
		}
		EXPECT_EQ(p.tp, tp) << p.threshold;
		EXPECT_EQ(p.fp, fp) << p.threshold;
	}
	EXPECT_GT(r.sweep.front().tp, 0u);
	EXPECT_GT(r.sweep.front().fp, 0u);
	double bestF1 = 0;
	for (const auto& p : r.sweep)
		bestF1 = std::max(bestF1, p.f1);
	EXPECT_DOUBLE_EQ(r.sweep[r.best].f1, bestF1);

	// The CSV says the same, row by row.
	std::istringstream csv(eval::loopSweepCsv(r));
	std::string row;
	std::getline(csv, row);
	EXPECT_EQ(row, "threshold,precision,recall,f1,tp,fp,fn");
	std::size_t n = 0;
	std::string last;
	while (std::getline(csv, row))
	{
		last = row;
		ASSERT_LT(n, r.sweep.size());
		std::smatch m;
		ASSERT_TRUE(std::regex_match(
		    row, m, std::regex(R"(([^,]+),([^,]+),([^,]+),([^,]+),(\d+),(\d+),(\d+))")))
		    << row;
		EXPECT_EQ(std::stoul(m[5]), r.sweep[n].tp);
		EXPECT_EQ(std::stoul(m[6]), r.sweep[n].fp);
		EXPECT_NEAR(std::stod(m[2]), r.sweep[n].precision, 1e-6);
		++n;
	}
	EXPECT_EQ(n, r.sweep.size());
	EXPECT_EQ(last.rfind("inf,", 0), 0u) << last;
}

TEST(LoopEval, BadLinesNameTheFileAndLine)
{
	const auto dir = test::tempDir("loopeval");
	const std::string good = loopsText({{40, 0, 0.5, true, true}});
	// Comment line 1, a good line 2, then the bad one on line 3.
	const std::vector<std::pair<std::string, std::string>> bad = {
	    {"1040.000000 1000.000000 0.5 40 1 1 ok 0 0 0 0 0 0\n", "columns"},
	    {"1040.000000 1000.000000 abc 40 1 1 ok 0 0 0 0 0 0 1\n", "score"},
	    {"1040.000000 1000.000000 0.5 40 2 1 ok 0 0 0 0 0 0 1\n", "verified"},
	    {"1040.000000 1000.000000 0.5 -3 1 1 ok 0 0 0 0 0 0 1\n", "inliers"},
	};
	for (const auto& [text, what] : bad)
	{
		const std::string path = writeFile(dir / "loops.txt", good + text);
		try
		{
			eval::loadLoopLog(path);
			ADD_FAILURE() << "no error for: " << text;
		}
		catch (const std::runtime_error& e)
		{
			const std::string msg = e.what();
			EXPECT_NE(msg.find(path), std::string::npos) << msg;
			EXPECT_NE(msg.find("line 3"), std::string::npos) << msg;
			EXPECT_NE(msg.find(what), std::string::npos) << msg;
		}
	}
	EXPECT_EQ(eval::loadLoopLog(writeFile(dir / "ok.txt", good + "\n# c\n")).candidates.size(), 1u);
}

TEST(LoopEval, UnknownStampsNameTheStampFileAndLine)
{
	// 1000.05 is halfway between two 10 Hz stamps: farther than 0.02 s from both.
	const std::vector<std::pair<Line, std::string>> cases = {
	    {{4000, 0, 0.5, true, true}, "5000.000000"},
	    {{40, 0.05, 0.5, true, true}, "1000.050000"},
	};
	for (const auto& [l, stamp] : cases)
	{
		try
		{
			eval::evaluateLoops(logOf({{40, 0, 0.5, true, true}, l}), twoLaps());
			ADD_FAILURE() << "no error for " << stamp;
		}
		catch (const std::runtime_error& e)
		{
			const std::string msg = e.what();
			EXPECT_NE(msg.find("mem/loops.txt"), std::string::npos) << msg;
			EXPECT_NE(msg.find("line 3"), std::string::npos) << msg;
			EXPECT_NE(msg.find(stamp), std::string::npos) << msg;
		}
	}
	// Within max-dt the nearest stamp is used.
	EXPECT_NO_THROW(eval::evaluateLoops(logOf({{40.01, 0.01, 0.5, true, true}}), twoLaps()));
}

TEST(LoopEval, PlotMarksTheOperatingPoint)
{
	const auto r = eval::evaluateLoops(logOf(allCorrect()), twoLaps());
	const cv::Mat img = eval::renderLoopPrPlot(r, "test");
	ASSERT_FALSE(img.empty());
	EXPECT_EQ(img.type(), CV_8UC3);
	// The detector's mark is the only red ink: it sits at recall 1, precision 1 (top right).
	int red = 0, redRight = 0;
	for (int y = 0; y < img.rows; ++y)
	{
		for (int x = 0; x < img.cols; ++x)
		{
			const auto& px = img.at<cv::Vec3b>(y, x);
			if (px[2] > 150 && px[1] < 80 && px[0] < 80)
			{
				++red;
				if (x > img.cols * 3 / 4 && y < img.rows / 4)
					++redRight;
			}
		}
	}
	EXPECT_GT(redRight, 20);
	EXPECT_GT(red, redRight);  // and the legend
}

TEST(LoopEvalCli, WritesCsvPlotAndJson)
{
	const auto dir = test::tempDir("loopeval-cli");
	const std::string gt = (dir / "groundtruth.tum").string();
	io::saveTrajectoryTum(gt, twoLaps());
	auto lines = firstLapMisses();
	for (int k = 0; k < 20; ++k)
		lines.push_back({40.0 + k, k + 0.0, 0.6 + 0.01 * k, true, k % 2 == 0});
	for (int k = 20; k < 40; ++k)
		lines.push_back({40.0 + k, k + 5.0, 0.2 + 0.01 * (k - 20), true, false});
	const std::string loops = writeFile(dir / "loops.txt", loopsText(lines));
	const std::string csv = (dir / "pr.csv").string(), png = (dir / "pr.png").string();
	// By distance: the lines carry no registration (identity poses).
	const std::string base = evalBin() + " loops --registration 0 --loops " + loops + " --gt " + gt;

	auto res = test::runCommand(base + " --csv " + csv + " --plot " + png);
	ASSERT_EQ(res.exitCode, 0) << res.output;
	EXPECT_NE(res.output.find("positives    : 40 of 80"), std::string::npos) << res.output;
	EXPECT_NE(res.output.find("score >= 0.6:"), std::string::npos) << res.output;
	std::ifstream c(csv);
	std::string header;
	std::getline(c, header);
	EXPECT_EQ(header, "threshold,precision,recall,f1,tp,fp,fn");
	std::size_t rows = 0;
	for (std::string l; std::getline(c, l);)
		++rows;
	EXPECT_EQ(rows, 42u);  // 0, 40 scores, inf
	const cv::Mat img = cv::imread(png);
	ASSERT_FALSE(img.empty()) << png;
	EXPECT_EQ(img.cols, 800);
	EXPECT_EQ(img.rows, 600);
	// No temporary file is left behind.
	std::size_t files = 0;
	for (const auto& e : std::filesystem::directory_iterator(dir))
		files += e.path().filename().string().find(".tmp") != std::string::npos;
	EXPECT_EQ(files, 0u);

	res = test::runCommand(base + " --json");
	ASSERT_EQ(res.exitCode, 0) << res.output;
	// One object on one line.
	EXPECT_EQ(std::count(res.output.begin(), res.output.end(), '\n'), 1) << res.output;
	nlohmann::json j = parseJson(res.output);
	EXPECT_EQ(j.value("queries", -1), 80) << res.output;
	EXPECT_EQ(j.value("positives", -1), 40) << res.output;
	EXPECT_EQ(j.value("lines", -1), static_cast<int>(lines.size())) << res.output;
	EXPECT_TRUE(j.value("csv", nlohmann::json()).is_null()) << res.output;
	EXPECT_TRUE(j.value("plot", nlohmann::json()).is_null()) << res.output;
	const nlohmann::json det = j.value("detector", nlohmann::json::object());
	EXPECT_FALSE(det.contains("threshold")) << res.output;
	EXPECT_DOUBLE_EQ(det.value("precision", -1.0), 1.0) << res.output;
	EXPECT_DOUBLE_EQ(det.value("recall", -1.0), 0.25) << res.output;
	EXPECT_TRUE(det.value("f1", nlohmann::json()).is_number()) << res.output;
	EXPECT_EQ(det.value("tp", -1), 10) << res.output;
	EXPECT_EQ(det.value("fp", -1), 0) << res.output;
	EXPECT_EQ(det.value("fn", -1), 30) << res.output;
	nlohmann::json best = j.value("f1_max", nlohmann::json::object());
	EXPECT_NEAR(best.value("threshold", -1.0), 0.6, 1e-9) << res.output;
	EXPECT_DOUBLE_EQ(best.value("precision", -1.0), 1.0) << res.output;
	EXPECT_DOUBLE_EQ(best.value("recall", -1.0), 0.5) << res.output;

	// --distance 60 makes the 50 m matches correct, and first-lap queries from t = 34 s on
	// (60 m or less from the start) positives: 40 + 6.
	res = test::runCommand(base + " --distance 60 --json");
	ASSERT_EQ(res.exitCode, 0) << res.output;
	j = parseJson(res.output);
	EXPECT_EQ(j.value("positives", -1), 46) << res.output;
	EXPECT_DOUBLE_EQ(j.value("distance_m", -1.0), 60.0) << res.output;
	best = j.value("f1_max", nlohmann::json::object());
	EXPECT_NEAR(best.value("threshold", -1.0), 0.2, 1e-9) << res.output;
	EXPECT_EQ(best.value("tp", -1), 40) << res.output;
	EXPECT_EQ(best.value("fp", -1), 0) << res.output;
	EXPECT_EQ(best.value("fn", -1), 6) << res.output;
}

TEST(LoopEvalCli, ExitCodes)
{
	const auto dir = test::tempDir("loopeval-cli");
	const std::string gt = (dir / "groundtruth.tum").string();
	io::saveTrajectoryTum(gt, twoLaps());
	const std::string loops =
	    writeFile(dir / "loops.txt",
	              loopsText({{40, 0, 0.5, true, true}}) + "1040 1000 x 1 1 1 ok 0 0 0 0 0 0 1\n");
	auto res = test::runCommand(evalBin() + " loops --gt " + gt);
	EXPECT_EQ(res.exitCode, 2) << res.output;
	EXPECT_NE(res.output.find("rasterslam-eval loops: --loops is required"), std::string::npos)
	    << res.output;
	res =
	    test::runCommand(evalBin() + " loops --loops " + loops + " --gt " + gt + " --distance -1");
	EXPECT_EQ(res.exitCode, 2) << res.output;
	EXPECT_NE(res.output.find("rasterslam-eval loops: --distance: "), std::string::npos)
	    << res.output;
	res = test::runCommand(evalBin() + " loops --loops " + loops + " --gt " + gt + " --csv ''");
	EXPECT_EQ(res.exitCode, 2) << res.output;
	EXPECT_NE(res.output.find("--csv: empty file name"), std::string::npos) << res.output;
	res = test::runCommand(evalBin() + " loops --loops " + loops + " --gt " + gt);
	EXPECT_EQ(res.exitCode, 1) << res.output;
	EXPECT_NE(res.output.find(loops + "' line 3"), std::string::npos) << res.output;
	res = test::runCommand(evalBin() + " loops --help");
	EXPECT_EQ(res.exitCode, 0);
	EXPECT_NE(res.output.find("--exclude-s"), std::string::npos);
	// The table lists the new command and traj still works as before.
	res = test::runCommand(evalBin() + " --help");
	EXPECT_NE(res.output.find("loops"), std::string::npos);
	EXPECT_NE(res.output.find("traj"), std::string::npos);
}

// The truth of a verified line is its registration: right 8 m away is a correct loop (and a
// positive), wrong 1 m away is a wrong one.
TEST(LoopEval, RegistrationDecidesVerifiedLines)
{
	const auto gt = twoLaps();
	const auto at = [&](double t)
	{ return gt[static_cast<std::size_t>(std::lround(t * 10))].pose; };
	std::string text =
	    "# query_stamp candidate_stamp score inliers verified accepted reason x y z qx qy qz qw\n";
	const auto line = [&](double q, double c, const Eigen::Isometry3d& T, bool accepted)
	{
		const Eigen::Quaterniond r(T.linear());
		char buf[256];
		std::snprintf(buf, sizeof(buf),
		              "%.6f %.6f 0.7 40 1 %d ok %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", kT0 + q,
		              kT0 + c, accepted ? 1 : 0, T.translation().x(), T.translation().y(),
		              T.translation().z(), r.x(), r.y(), r.z(), r.w());
		text += buf;
	};
	// Query at 41 s (1 lap + 1 s: 10 m along the square), candidate at 0.2 s: 8 m apart.
	line(41, 0.2, at(0.2).inverse() * at(41), true);
	// Query at 50 s, candidate at 10 s (the same place), registered 1.5 m off.
	Eigen::Isometry3d off = at(10).inverse() * at(50);
	off.translation().x() += 1.5;
	line(50, 10, off, true);
	// Query at 39.2 s, candidate at 0 s: 8 m apart, no place within 4 m 30 s older.
	line(39.2, 0, at(0).inverse() * at(39.2), true);
	std::istringstream in(text);
	const auto log = eval::parseLoopLog(in, "mem/loops.txt");

	const auto r = eval::evaluateLoops(log, gt);
	EXPECT_EQ(r.registeredLines, 3u);
	EXPECT_EQ(r.registeredFar, 2u);
	EXPECT_EQ(r.acceptedWrong, 1u);
	EXPECT_EQ(r.detector.tp, 2u);
	EXPECT_EQ(r.detector.fp, 1u);
	EXPECT_EQ(r.positives, 3u);  // 39.2 s by its registration
	// By distance (4 m) they are judged the other way round.
	eval::LoopEvalParams byDistance;
	byDistance.registration_m = 0;
	const auto d = eval::evaluateLoops(log, gt, byDistance);
	EXPECT_EQ(d.registeredLines, 0u);
	EXPECT_EQ(d.acceptedWrong, 2u);
	EXPECT_EQ(d.detector.tp, 1u);
	EXPECT_EQ(d.detector.fp, 2u);
	EXPECT_EQ(d.positives, 2u);
}
