// rasterslam-eval timings: figures of a synthetic timings.csv, the plot, bad input files.
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <regex>

#include "test_json.h"
#include "test_support.h"

using namespace rasterslam;

using test::number;
using test::parseJson;

namespace
{
const char* kHeader =
    "index,stamp,points,status,inliers,keyframe,late,read_ms,rasterize_ms,odometry_ms,"
    "mapping_ms,loop_ms,total_ms,rss_mb\n";

/** 2000 scans: rss grows 1 MB per 1000 scans from 100 MB; total is 10 ms in the first 10 %,
 *  11 in the middle, 12 in the last 10 %, the difference all in loop closure. */
std::string syntheticCsv()
{
	std::string csv = kHeader;
	char buf[256];
	for (int i = 0; i < 2000; ++i)
	{
		const double loop = i < 200 ? 1 : (i >= 1800 ? 3 : 2);
		std::snprintf(buf, sizeof(buf),
		              "%d,%.6f,120000,ok,80,0,0,4.000,1.000,3.000,1.000,%.3f,%.3f,%.3f\n", i,
		              1700000000.0 + 0.1 * i, loop, 9 + loop, 100 + 0.001 * i);
		csv += buf;
	}
	return csv;
}

std::string writeFile(const std::filesystem::path& p, const std::string& text)
{
	std::filesystem::create_directories(p.parent_path());
	std::ofstream(p) << text;
	return p.string();
}

std::string evalBin()
{
	return test::bin("rasterslam-eval");
}

/** The labels of the runs, in order. */
std::vector<std::string> labels(const nlohmann::json& j)
{
	std::vector<std::string> out;
	for (const auto& run : j.value("runs", nlohmann::json::array()))
		out.push_back(run.value("label", "?"));
	return out;
}
}  // namespace

TEST(TimingsEvalCli, FiguresOfASyntheticRun)
{
	const test::ScopedTempDir dir("timings-eval");
	writeFile(dir / "run1" / "timings.csv", syntheticCsv());
	const auto res = test::runCommand(evalBin() + " timings " + (dir / "run1").string() +
	                                  " --after-scan 950 --json");
	ASSERT_EQ(res.exitCode, 0) << res.output;
	const std::string& out = res.output;
	const nlohmann::json j = parseJson(out);
	ASSERT_EQ(j.value("runs", nlohmann::json::array()).size(), 1u) << out;
	EXPECT_EQ(labels(j), std::vector<std::string>{"run1"}) << out;
	EXPECT_EQ(j["runs"][0].value("file", ""), (dir / "run1" / "timings.csv").string()) << out;
	EXPECT_EQ(number(j, "/runs/0/scans"), 2000) << out;
	EXPECT_EQ(number(j, "/runs/0/tenth_scans"), 200) << out;

	EXPECT_NEAR(number(j, "/runs/0/total_ms/first"), 10.0, 1e-9) << out;
	EXPECT_NEAR(number(j, "/runs/0/total_ms/last"), 12.0, 1e-9) << out;
	EXPECT_NEAR(number(j, "/runs/0/total_ms/ratio"), 1.2, 1e-9) << out;
	EXPECT_NEAR(number(j, "/runs/0/loop_ms/ratio"), 3.0, 1e-9) << out;
	EXPECT_NEAR(number(j, "/runs/0/read_ms/ratio"), 1.0, 1e-9) << out;
	for (const char* stage :
	     {"total_ms", "read_ms", "rasterize_ms", "odometry_ms", "mapping_ms", "loop_ms"})
		EXPECT_TRUE(j["runs"][0].contains(stage)) << stage << " missing in " << out;

	EXPECT_NEAR(number(j, "/runs/0/rss_first_max_mb"), 100.199, 1e-9) << out;
	EXPECT_NEAR(number(j, "/runs/0/rss_last_max_mb"), 101.999, 1e-9) << out;
	EXPECT_NEAR(number(j, "/runs/0/rss_peak_mb"), 101.999, 1e-9) << out;
	EXPECT_NEAR(number(j, "/runs/0/rss_growth_mb_per_1000_scans"), 1.0, 1e-6) << out;
	// --after-scan 950: scans 850..950.
	EXPECT_EQ(number(j, "/runs/0/after_scan/scan"), 950) << out;
	EXPECT_EQ(number(j, "/runs/0/after_scan/from"), 850) << out;
	EXPECT_NEAR(number(j, "/runs/0/after_scan/rss_max_mb"), 100.95, 1e-9) << out;
	EXPECT_NEAR(number(j, "/runs/0/after_scan/last_ratio"), 101.999 / 100.95, 1e-8) << out;
	EXPECT_EQ(number(j, "/window"), 100) << out;
	EXPECT_TRUE(j.contains("plot") && j["plot"].is_null()) << out;

	// Without --after-scan: null.
	const auto plain =
	    test::runCommand(evalBin() + " timings " + (dir / "run1").string() + " --json");
	ASSERT_EQ(plain.exitCode, 0) << plain.output;
	const nlohmann::json p = parseJson(plain.output);
	ASSERT_TRUE(p.contains(nlohmann::json::json_pointer("/runs/0/after_scan"))) << plain.output;
	EXPECT_TRUE(p["runs"][0]["after_scan"].is_null()) << plain.output;

	// The text form carries the same figures.
	const auto text = test::runCommand(evalBin() + " timings " + (dir / "run1").string());
	ASSERT_EQ(text.exitCode, 0) << text.output;
	EXPECT_NE(text.output.find("2000 scans"), std::string::npos) << text.output;
	EXPECT_TRUE(
	    std::regex_search(text.output, std::regex(R"(total\s*:\s*10\.000\s+12\.000\s+1\.200)")))
	    << text.output;
	EXPECT_NE(text.output.find("1.000 MB per 1000 scans"), std::string::npos) << text.output;
}

TEST(TimingsEvalCli, PlotsSeveralRunsWithLabels)
{
	const test::ScopedTempDir dir("timings-eval");
	const std::string a = writeFile(dir / "a" / "timings.csv", syntheticCsv());
	writeFile(dir / "b" / "timings.csv", syntheticCsv());
	const std::string png = (dir / "plot.png").string();
	// A run may be given as its timings.csv too.
	const std::string base =
	    evalBin() + " timings " + a + " " + (dir / "b").string() + " --label first --label second";
	auto res = test::runCommand(base + " --plot " + png + " --window 50 --json");
	ASSERT_EQ(res.exitCode, 0) << res.output;
	nlohmann::json j = parseJson(res.output);
	EXPECT_EQ(labels(j), (std::vector<std::string>{"first", "second"})) << res.output;
	EXPECT_EQ(number(j, "/window"), 50) << res.output;
	EXPECT_EQ(j.value("plot", ""), png) << res.output;
	const cv::Mat img = cv::imread(png);
	ASSERT_FALSE(img.empty()) << png;
	EXPECT_EQ(img.cols, 1200);
	EXPECT_EQ(img.rows, 800);
	// No temporary file is left behind.
	for (const auto& e : std::filesystem::directory_iterator(dir.path()))
		EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();

	// Default labels are the folder names.
	res = test::runCommand(evalBin() + " timings " + a + " --json");
	ASSERT_EQ(res.exitCode, 0) << res.output;
	EXPECT_EQ(labels(parseJson(res.output)), std::vector<std::string>{"a"}) << res.output;
}

TEST(TimingsEvalCli, BadInputNamesTheFileAndLine)
{
	const test::ScopedTempDir dir("timings-eval");
	auto run = [&](const std::string& name, const std::string& csv)
	{
		const std::string file = writeFile(dir / name / "timings.csv", csv);
		return std::make_pair(file,
		                      test::runCommand(evalBin() + " timings " + (dir / name).string()));
	};
	std::string noRss = kHeader;
	noRss.replace(noRss.find(",rss_mb"), 7, "");
	std::string file;
	test::CommandResult res;
	std::tie(file, res) = run("norss", noRss + "0,1.0,1,ok,1,0,0,1,1,1,1,1,5\n");
	EXPECT_EQ(res.exitCode, 1) << res.output;
	EXPECT_NE(res.output.find(file + "' line 1"), std::string::npos) << res.output;
	EXPECT_NE(res.output.find("rss_mb"), std::string::npos) << res.output;

	std::string bad = syntheticCsv();
	bad.replace(bad.find(",12.000,"), 8, ",1x,");  // total_ms of scan 1800, the first 12 ms
	std::tie(file, res) = run("notnumber", bad);
	EXPECT_EQ(res.exitCode, 1) << res.output;
	EXPECT_NE(res.output.find(file + "' line 1802"), std::string::npos) << res.output;
	EXPECT_NE(res.output.find("total_ms"), std::string::npos) << res.output;

	std::tie(file, res) = run("empty", kHeader);
	EXPECT_EQ(res.exitCode, 1) << res.output;
	EXPECT_NE(res.output.find(file), std::string::npos) << res.output;

	// A folder without timings.csv: exit 1, the file named.
	std::filesystem::create_directories(dir / "nocsv");
	res = test::runCommand(evalBin() + " timings " + (dir / "nocsv").string());
	EXPECT_EQ(res.exitCode, 1) << res.output;
	EXPECT_NE(res.output.find((dir / "nocsv" / "timings.csv").string()), std::string::npos)
	    << res.output;
	// A RUN_DIR that does not exist is bad input: exit 1, named in the message.
	res = test::runCommand(evalBin() + " timings " + (dir / "missing").string());
	EXPECT_EQ(res.exitCode, 1) << res.output;
	EXPECT_NE(res.output.find("rasterslam-eval timings: error: RUN_DIR: Path does not exist: " +
	                          (dir / "missing").string()),
	          std::string::npos)
	    << res.output;
}

TEST(TimingsEvalCli, CommandLine)
{
	const test::ScopedTempDir dir("timings-eval");
	const std::string a = writeFile(dir / "a" / "timings.csv", syntheticCsv());
	auto res = test::runCommand(evalBin() + " timings");
	EXPECT_EQ(res.exitCode, 2) << res.output;
	EXPECT_NE(res.output.find("rasterslam-eval timings: RUN_DIR is required"), std::string::npos)
	    << res.output;
	res = test::runCommand(evalBin() + " timings " + a + " --label x --label y");
	EXPECT_EQ(res.exitCode, 2) << res.output;
	EXPECT_NE(res.output.find("rasterslam-eval timings: give --label once per RUN_DIR"),
	          std::string::npos)
	    << res.output;
	EXPECT_NE(res.output.find("(see rasterslam-eval timings --help)"), std::string::npos)
	    << res.output;
	// --label takes one value each time: the folder after it stays a RUN_DIR.
	res = test::runCommand(evalBin() + " timings --label x " + a + " --json");
	EXPECT_EQ(res.exitCode, 0) << res.output;
	EXPECT_EQ(labels(parseJson(res.output)), std::vector<std::string>{"x"}) << res.output;
	for (const std::string bad : {"--window 0", "--window x", "--after-scan -5", "--plot ''"})
	{
		res = test::runCommand(evalBin() + " timings " + a + " " + bad);
		EXPECT_EQ(res.exitCode, 2) << bad << "\n" << res.output;
		EXPECT_NE(res.output.find("rasterslam-eval timings: " + bad.substr(0, bad.find(' ')) + ":"),
		          std::string::npos)
		    << bad << "\n"
		    << res.output;
	}
	// Scan 5000 is past the end of the run.
	res = test::runCommand(evalBin() + " timings " + a + " --after-scan 5000");
	EXPECT_EQ(res.exitCode, 1) << res.output;
	res = test::runCommand(evalBin() + " timings --help");
	EXPECT_EQ(res.exitCode, 0);
	EXPECT_NE(res.output.find("--after-scan"), std::string::npos);
	res = test::runCommand(evalBin() + " --help");
	EXPECT_NE(res.output.find("timings"), std::string::npos);
}
