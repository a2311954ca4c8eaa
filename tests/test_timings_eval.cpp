// rasterslam-eval timings: figures of a synthetic timings.csv, the plot, bad input files.
#include <cstdio>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <regex>

#include "test_support.h"

using namespace rasterslam;

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

/** The number after `"key": ` (the first one from `from`); NaN when absent. */
double jsonValue(const std::string& j, const std::string& key, std::size_t from = 0)
{
	std::smatch m;
	const std::string rest = j.substr(std::min(from, j.size()));
	if (!std::regex_search(rest, m, std::regex("\"" + key + "\": (-?[0-9.eE+-]+)")))
		return std::nan("");
	return std::stod(m[1]);
}
}  // namespace

TEST(TimingsEvalCli, FiguresOfASyntheticRun)
{
	const test::ScopedTempDir dir("timings-eval");
	writeFile(dir / "run1" / "timings.csv", syntheticCsv());
	const auto res = test::runCommand(evalBin() + " timings " + (dir / "run1").string() +
	                                  " --after-scan 950 --json");
	ASSERT_EQ(res.exitCode, 0) << res.output;
	const std::string& j = res.output;
	EXPECT_NE(j.find("\"label\": \"run1\""), std::string::npos) << j;
	EXPECT_EQ(jsonValue(j, "scans"), 2000) << j;
	EXPECT_EQ(jsonValue(j, "tenth_scans"), 200) << j;

	const std::size_t total = j.find("\"total_ms\": {");
	ASSERT_NE(total, std::string::npos) << j;
	EXPECT_NEAR(jsonValue(j, "first", total), 10.0, 1e-9) << j;
	EXPECT_NEAR(jsonValue(j, "last", total), 12.0, 1e-9) << j;
	EXPECT_NEAR(jsonValue(j, "ratio", total), 1.2, 1e-9) << j;
	const std::size_t loop = j.find("\"loop_ms\": {");
	ASSERT_NE(loop, std::string::npos) << j;
	EXPECT_NEAR(jsonValue(j, "ratio", loop), 3.0, 1e-9) << j;
	const std::size_t read = j.find("\"read_ms\": {");
	ASSERT_NE(read, std::string::npos) << j;
	EXPECT_NEAR(jsonValue(j, "ratio", read), 1.0, 1e-9) << j;

	EXPECT_NEAR(jsonValue(j, "rss_first_max_mb"), 100.199, 1e-9) << j;
	EXPECT_NEAR(jsonValue(j, "rss_last_max_mb"), 101.999, 1e-9) << j;
	EXPECT_NEAR(jsonValue(j, "rss_peak_mb"), 101.999, 1e-9) << j;
	EXPECT_NEAR(jsonValue(j, "rss_growth_mb_per_1000_scans"), 1.0, 1e-6) << j;
	// --after-scan 950: scans 850..950.
	EXPECT_NEAR(jsonValue(j, "from"), 850, 1e-9) << j;
	EXPECT_NEAR(jsonValue(j, "rss_max_mb"), 100.95, 1e-9) << j;
	EXPECT_NEAR(jsonValue(j, "last_ratio"), 101.999 / 100.95, 1e-8) << j;

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
	EXPECT_NE(res.output.find("\"label\": \"first\""), std::string::npos) << res.output;
	EXPECT_NE(res.output.find("\"label\": \"second\""), std::string::npos) << res.output;
	EXPECT_NE(res.output.find("\"window\": 50"), std::string::npos) << res.output;
	const cv::Mat img = cv::imread(png);
	ASSERT_FALSE(img.empty()) << png;
	EXPECT_EQ(img.cols, 1200);
	EXPECT_EQ(img.rows, 800);
	// No temporary file is left behind.
	for (const auto& e : std::filesystem::directory_iterator(dir.path()))
		EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();

	// Default labels are the folder names.
	res = test::runCommand(evalBin() + " timings " + a + " --json");
	EXPECT_NE(res.output.find("\"label\": \"a\""), std::string::npos) << res.output;
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

	res = test::runCommand(evalBin() + " timings " + (dir / "missing").string());
	EXPECT_EQ(res.exitCode, 1) << res.output;
	EXPECT_NE(res.output.find((dir / "missing" / "timings.csv").string()), std::string::npos)
	    << res.output;
}

TEST(TimingsEvalCli, CommandLine)
{
	const test::ScopedTempDir dir("timings-eval");
	const std::string a = writeFile(dir / "a" / "timings.csv", syntheticCsv());
	auto res = test::runCommand(evalBin() + " timings");
	EXPECT_EQ(res.exitCode, 2) << res.output;
	res = test::runCommand(evalBin() + " timings " + a + " --label x --label y");
	EXPECT_EQ(res.exitCode, 2) << res.output;
	res = test::runCommand(evalBin() + " timings " + a + " --window 0");
	EXPECT_EQ(res.exitCode, 2) << res.output;
	// Scan 5000 is past the end of the run.
	res = test::runCommand(evalBin() + " timings " + a + " --after-scan 5000");
	EXPECT_EQ(res.exitCode, 1) << res.output;
	res = test::runCommand(evalBin() + " timings --help");
	EXPECT_EQ(res.exitCode, 0);
	EXPECT_NE(res.output.find("--after-scan"), std::string::npos);
	res = test::runCommand(evalBin() + " --help");
	EXPECT_NE(res.output.find("timings"), std::string::npos);
}
