// The command lines of the smaller programs (kitti2rawlog, rasterslam-sim, rasterslam-vocab,
// rasterslam-map-export, rasterslam-bench-map-store) follow the project's conventions
// (apps/common/include/rasterslam/cli/app.h): --help and --version exit 0; usage errors print
// "PROG: what" and "(see PROG --help)" on stderr and exit 2; bad input found while running
// exits 1 with a message naming the file.
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <regex>
#include <string>
#include <utility>
#include <vector>

#include "test_support.h"

namespace fs = std::filesystem;
using namespace rasterslam;

namespace
{
/** Runs `bin/prog args`; only its standard output is captured. */
test::CommandResult stdoutOf(const std::string& prog, const std::string& args)
{
	return test::runCommand("(" + test::bin(prog) + " " + args + " 2>/dev/null)");
}

/** Runs `bin/prog args`; only its standard error is captured. */
test::CommandResult stderrOf(const std::string& prog, const std::string& args)
{
	return test::runCommand("(" + test::bin(prog) + " " + args + " 2>&1 >/dev/null)");
}

bool contains(const std::string& text, const std::string& what)
{
	return text.find(what) != std::string::npos;
}

/** A usage error of `command` ("rasterslam-vocab train"): exit 2, "command: <what>" and
 *  "(see command --help)" on stderr, `what` holding `mentions`. */
void expectUsageError(const test::CommandResult& r, const std::string& command,
                      const std::string& mentions)
{
	EXPECT_EQ(r.exitCode, 2) << r.output;
	EXPECT_EQ(r.output.rfind(command + ": ", 0), 0u) << r.output;
	EXPECT_TRUE(contains(r.output, "(see " + command + " --help)")) << r.output;
	EXPECT_TRUE(contains(r.output, mentions)) << "expected '" << mentions << "' in: " << r.output;
}

struct Program
{
	std::string name;
	std::vector<std::string> options;  //!< some of the options --help must list
};

const std::vector<Program> kPrograms = {
    {"kitti2rawlog",
     {"--velodyne", "--sequence", "--out", "--poses", "--calib", "--times", "--first", "--last",
      "--external", "--compress", "--vertical-correction-deg"}},
    {"rasterslam-sim",
     {"--scenario", "--out", "--scans", "--seed", "--lidar", "--sensor-height", "--compress",
      "--gt-tum"}},
    {"rasterslam-vocab", {"train", "info", "bench"}},
    {"rasterslam-map-export", {"DIR", "--out"}},
    {"rasterslam-bench-map-store", {"--local-maps", "--points"}},
    {"rasterslam-bench-read", {"--bin", "--rawlog", "--passes"}},
};
}  // namespace

TEST(Cli, HelpExitsZeroAndListsTheOptions)
{
	for (const auto& p : kPrograms)
	{
		for (const std::string flag : {"--help", "-h"})
		{
			const auto r = stdoutOf(p.name, flag);
			EXPECT_EQ(r.exitCode, 0) << p.name << " " << flag << ": " << r.output;
			EXPECT_TRUE(contains(r.output, "Usage: " + p.name)) << p.name << ": " << r.output;
			for (const auto& o : p.options)
				EXPECT_TRUE(contains(r.output, o)) << p.name << " --help lacks " << o;
			EXPECT_TRUE(contains(r.output, "Exit codes")) << p.name << ": " << r.output;
		}
	}
}

TEST(Cli, HelpKeepsTheExplanationsBeyondTheOptions)
{
	EXPECT_TRUE(contains(stdoutOf("kitti2rawlog", "--help").output, "GROUND_TRUTH"));
	EXPECT_TRUE(
	    contains(stdoutOf("rasterslam-vocab", "--help").output, "rasterslam-vocab info vocab.bin"));
	EXPECT_TRUE(contains(stdoutOf("rasterslam-map-export", "--help").output, "points.pcd"));
}

TEST(Cli, SubcommandHelpListsItsOptions)
{
	const std::vector<std::pair<std::string, std::vector<std::string>>> subs = {
	    {"train", {"--images", "--output", "--branching", "--levels", "--seed", "--features"}},
	    {"info", {"vocab"}},
	    {"bench", {"--vocab", "--entries", "--seed"}}};
	for (const auto& [sub, options] : subs)
	{
		const auto r = stdoutOf("rasterslam-vocab", sub + " --help");
		EXPECT_EQ(r.exitCode, 0) << sub << ": " << r.output;
		EXPECT_TRUE(contains(r.output, "Usage: rasterslam-vocab " + sub)) << r.output;
		for (const auto& o : options)
			EXPECT_TRUE(contains(r.output, o))
			    << "rasterslam-vocab " << sub << " --help lacks " << o;
	}
}

TEST(Cli, VersionExitsZeroAndNamesTheProgram)
{
	for (const auto& p : kPrograms)
	{
		const auto r = stdoutOf(p.name, "--version");
		EXPECT_EQ(r.exitCode, 0) << p.name << ": " << r.output;
		EXPECT_TRUE(std::regex_search(r.output, std::regex("^" + p.name + " [0-9]+\\.[0-9]+")))
		    << p.name << ": " << r.output;
	}
}

TEST(Cli, UnknownOptionIsAUsageError)
{
	// The required options are given, so that the unknown one is what is wrong.
	const test::ScopedTempDir dir("cli");
	const auto d = dir.path().string();
	std::ofstream(dir / "scenario.yaml") << "scans: 1\n";
	const std::vector<std::pair<std::string, std::string>> cases = {
	    {"kitti2rawlog", "--velodyne " + d + " -o " + d + "/x.rawlog"},
	    {"rasterslam-sim", "--scenario " + d + "/scenario.yaml -o " + d + "/x.rawlog"},
	    {"rasterslam-map-export", d + " --out " + d + "/exp"},
	    {"rasterslam-bench-map-store", "--local-maps 1 --points 1"},
	    {"rasterslam-bench-read", "--bin " + d},
	};
	for (const auto& [prog, args] : cases)
		expectUsageError(stderrOf(prog, args + " --no-such-option"), prog, "--no-such-option");
	expectUsageError(
	    stderrOf("rasterslam-vocab", "bench --vocab " + d + "/scenario.yaml --no-such-option"),
	    "rasterslam-vocab bench", "--no-such-option");
	// A word where the subcommand goes that is none.
	expectUsageError(stderrOf("rasterslam-vocab", "no-such-command"), "rasterslam-vocab",
	                 "no-such-command");
	EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

TEST(Cli, MissingRequiredOptionIsNamed)
{
	const test::ScopedTempDir dir("cli");
	const auto d = dir.path().string();
	std::ofstream(dir / "scenario.yaml") << "scans: 1\n";
	expectUsageError(stderrOf("kitti2rawlog", "--velodyne " + d), "kitti2rawlog", "--out");
	expectUsageError(stderrOf("kitti2rawlog", "-o " + d + "/x.rawlog"), "kitti2rawlog",
	                 "--velodyne");
	expectUsageError(
	    stderrOf("kitti2rawlog", "-o " + d + "/x.rawlog --velodyne " + d + " --sequence " + d),
	    "kitti2rawlog", "--sequence");
	expectUsageError(stderrOf("rasterslam-sim", "-o " + d + "/x.rawlog"), "rasterslam-sim",
	                 "--scenario");
	expectUsageError(stderrOf("rasterslam-sim", "--scenario " + d + "/scenario.yaml"),
	                 "rasterslam-sim", "--out");
	expectUsageError(stderrOf("rasterslam-vocab", ""), "rasterslam-vocab", "subcommand");
	expectUsageError(stderrOf("rasterslam-vocab", "train -o " + d + "/v.bin"),
	                 "rasterslam-vocab train", "--images");
	expectUsageError(stderrOf("rasterslam-vocab", "train --images " + d), "rasterslam-vocab train",
	                 "--output");
	expectUsageError(stderrOf("rasterslam-vocab", "info"), "rasterslam-vocab info", "vocab");
	expectUsageError(stderrOf("rasterslam-vocab", "bench"), "rasterslam-vocab bench", "--vocab");
	expectUsageError(stderrOf("rasterslam-map-export", "--out " + d + "/exp"),
	                 "rasterslam-map-export", "DIR");
	expectUsageError(stderrOf("rasterslam-map-export", d), "rasterslam-map-export", "--out");
	EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 1);
}

TEST(Cli, BadValuesAreUsageErrors)
{
	const test::ScopedTempDir dir("cli");
	const auto d = dir.path().string();
	std::ofstream(dir / "scenario.yaml") << "scans: 1\n";
	std::ofstream(dir / "poses.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n";
	const auto kitti = "--velodyne " + d + " -o " + d + "/x.rawlog ";
	expectUsageError(stderrOf("kitti2rawlog", kitti + "--compress 10"), "kitti2rawlog",
	                 "--compress");
	expectUsageError(stderrOf("kitti2rawlog", kitti + "--first -1"), "kitti2rawlog", "--first");
	expectUsageError(stderrOf("kitti2rawlog", kitti + "--last x"), "kitti2rawlog", "--last");
	expectUsageError(stderrOf("kitti2rawlog", kitti + "--vertical-correction-deg 6"),
	                 "kitti2rawlog", "--vertical-correction-deg");
	expectUsageError(stderrOf("kitti2rawlog", kitti + "--vertical-correction-deg nan"),
	                 "kitti2rawlog", "--vertical-correction-deg");
	expectUsageError(stderrOf("kitti2rawlog", kitti + "--external --vertical-correction-deg 0.2"),
	                 "kitti2rawlog", "--external");
	expectUsageError(stderrOf("kitti2rawlog", kitti + "--poses " + d + "/poses.txt"),
	                 "kitti2rawlog", "--poses needs --calib");

	const auto sim = "--scenario " + d + "/scenario.yaml -o " + d + "/x.rawlog ";
	expectUsageError(stderrOf("rasterslam-sim", sim + "--lidar hdl32"), "rasterslam-sim", "vlp16");
	expectUsageError(stderrOf("rasterslam-sim", sim + "--scans 0"), "rasterslam-sim", "--scans");
	expectUsageError(stderrOf("rasterslam-sim", sim + "--seed 4294967296"), "rasterslam-sim",
	                 "--seed");
	expectUsageError(stderrOf("rasterslam-sim", sim + "--compress x"), "rasterslam-sim",
	                 "--compress");
	expectUsageError(stderrOf("rasterslam-sim", sim + "--sensor-height 0"), "rasterslam-sim",
	                 "--sensor-height");
	expectUsageError(stderrOf("rasterslam-sim", sim + "--sensor-height nan"), "rasterslam-sim",
	                 "--sensor-height");
	// The shared number check (cli::numberIn) names the interval, open or closed, and reads
	// the whole text as one finite number.
	expectUsageError(stderrOf("rasterslam-sim", sim + "--sensor-height 10"), "rasterslam-sim",
	                 "expects a height in metres in (0, 10), got '10'");
	expectUsageError(stderrOf("rasterslam-sim", sim + "--sensor-height 1.5m"), "rasterslam-sim",
	                 "got '1.5m'");
	expectUsageError(stderrOf("rasterslam-sim", sim + "--sensor-height 1e400"), "rasterslam-sim",
	                 "got '1e400'");
	expectUsageError(stderrOf("kitti2rawlog", kitti + "--vertical-correction-deg -5.5"),
	                 "kitti2rawlog", "expects a number of degrees in [-5, 5], got '-5.5'");
	expectUsageError(stderrOf("rasterslam-eval", "traj --gt " + d + "/scenario.yaml --est " + d +
	                                                 "/scenario.yaml --max-dt -0.5"),
	                 "rasterslam-eval traj", "expects a number >= 0, got '-0.5'");
	// A closed interval holds its ends: past the check, each run fails on its input (no
	// .bin files; a scenario that is no trajectory), exit 1, not on the value.
	for (const auto& [prog, args] : std::vector<std::pair<std::string, std::string>>{
	         {"kitti2rawlog", kitti + "--vertical-correction-deg 5"},
	         {"kitti2rawlog", kitti + "--vertical-correction-deg -5"},
	         {"rasterslam-eval",
	          "traj --gt " + d + "/scenario.yaml --est " + d + "/scenario.yaml --max-dt 0"}})
	{
		const auto r = stderrOf(prog, args);
		EXPECT_EQ(r.exitCode, 1) << args << "\n" << r.output;
		EXPECT_FALSE(contains(r.output, "expects")) << args << "\n" << r.output;
	}

	const auto train = "train --images " + d + " -o " + d + "/v.bin ";
	expectUsageError(stderrOf("rasterslam-vocab", train + "--branching 1"),
	                 "rasterslam-vocab train", "--branching");
	expectUsageError(stderrOf("rasterslam-vocab", train + "--levels 9"), "rasterslam-vocab train",
	                 "--levels");
	expectUsageError(stderrOf("rasterslam-vocab", train + "--seed -1"), "rasterslam-vocab train",
	                 "--seed");
	expectUsageError(stderrOf("rasterslam-vocab", train + "--features 0"), "rasterslam-vocab train",
	                 "--features");
	expectUsageError(
	    stderrOf("rasterslam-vocab", "bench --vocab " + d + "/scenario.yaml " + "--entries 100,0"),
	    "rasterslam-vocab bench", "--entries");
	expectUsageError(stderrOf("rasterslam-vocab", "info " + d + "/scenario.yaml b"),
	                 "rasterslam-vocab info", "b");

	expectUsageError(stderrOf("rasterslam-bench-map-store", "--local-maps 0"),
	                 "rasterslam-bench-map-store", "--local-maps");
	expectUsageError(stderrOf("rasterslam-bench-map-store", "--points -5"),
	                 "rasterslam-bench-map-store", "--points");
	// Nothing was written.
	EXPECT_EQ(std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator()), 2);
}

TEST(Cli, BadInputFoundWhileRunningExitsOneNamingTheFile)
{
	const test::ScopedTempDir dir("cli");
	const auto d = dir.path().string();
	fs::create_directories(dir / "empty");
	std::ofstream(dir / "bad.yaml") << "scans: [1, 2\n";
	std::ofstream(dir / "text.bin") << "not a vocabulary\n";

	auto r = test::runCommand(test::bin("kitti2rawlog") + " --velodyne " + d + "/empty -o " + d +
	                          "/x.rawlog");
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_TRUE(contains(r.output, d + "/empty")) << r.output;

	r = test::runCommand(test::bin("rasterslam-sim") + " --scenario " + d + "/bad.yaml -o " + d +
	                     "/x.rawlog");
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_TRUE(contains(r.output, "bad.yaml")) << r.output;

	r = test::runCommand(test::bin("rasterslam-vocab") + " info " + d + "/text.bin");
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_TRUE(contains(r.output, "text.bin")) << r.output;

	r = test::runCommand(test::bin("rasterslam-vocab") + " train --images " + d + "/empty -o " + d +
	                     "/v.bin");
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_TRUE(contains(r.output, d + "/empty: no *.png images")) << r.output;

	// A named input that is not there: exit 1, named (CLI11's existence checks).
	for (const auto& [prog, args, named] :
	     std::vector<std::tuple<std::string, std::string, std::string>>{
	         {"kitti2rawlog",
	          "--velodyne " + d + " -o " + d + "/x.rawlog --times " + d + "/nothere.txt",
	          d + "/nothere.txt"},
	         {"kitti2rawlog", "--velodyne " + d + "/nothere -o " + d + "/x.rawlog", d + "/nothere"},
	         {"rasterslam-sim", "--scenario " + d + "/nothere.yaml -o " + d + "/x.rawlog",
	          d + "/nothere.yaml"},
	         {"rasterslam-vocab", "info " + d + "/nothere.bin", d + "/nothere.bin"}})
	{
		r = test::runCommand(test::bin(prog) + " " + args);
		EXPECT_EQ(r.exitCode, 1) << args << "\n" << r.output;
		EXPECT_TRUE(contains(r.output, "error: ")) << r.output;
		EXPECT_TRUE(contains(r.output, "does not exist: " + named)) << r.output;
	}

	r = test::runCommand(test::bin("rasterslam-map-export") + " " + d + "/empty --out " + d +
	                     "/exp");
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_TRUE(contains(r.output, d + "/empty/map.rsmap' does not exist")) << r.output;

	for (const auto* left : {"x.rawlog", "v.bin", "v.bin.tmp", "exp"})
		EXPECT_FALSE(fs::exists(dir / left)) << left;
}

// kitti2rawlog writes a plain rawlog unless asked for gzip (plain reads ~25x faster), and
// rasterslam-bench-read reads the same scans, point for point in count, from the .bin files
// and from both rawlogs.
TEST(Cli, DefaultRawlogIsPlainAndBenchReadReadsEveryFormat)
{
	const test::ScopedTempDir dir("cli");
	const auto d = dir.path().string();
	fs::create_directories(dir / "velodyne");
	for (int s = 0; s < 3; s++)
	{
		std::vector<float> rec;
		for (int k = 0; k < 500 + 100 * s; k++)
			for (float v : {static_cast<float>(k) * 0.01f + 3.f, -2.f, 0.5f, 0.25f})
				rec.push_back(v);
		std::ofstream(dir / "velodyne" / ("00000" + std::to_string(s) + ".bin"), std::ios::binary)
		    .write(reinterpret_cast<const char*>(rec.data()),
		           static_cast<std::streamsize>(rec.size() * sizeof(float)));
	}
	for (const std::string compress : {"", " --compress 1"})
	{
		const auto r =
		    test::runCommand(test::bin("kitti2rawlog") + " --velodyne " + d + "/velodyne -o " + d +
		                     (compress.empty() ? "/plain" : "/gz") + ".rawlog" + compress);
		ASSERT_EQ(r.exitCode, 0) << r.output;
	}
	const auto magic = [&](const std::string& name)
	{
		unsigned char m[2] = {0, 0};
		std::ifstream(dir / name, std::ios::binary).read(reinterpret_cast<char*>(m), 2);
		return m[0] == 0x1f && m[1] == 0x8b;
	};
	EXPECT_FALSE(magic("plain.rawlog")) << "the default rawlog is gzip";
	EXPECT_TRUE(magic("gz.rawlog")) << "--compress 1 did not write gzip";

	const auto r = stdoutOf("rasterslam-bench-read", "--bin " + d + "/velodyne --rawlog " + d +
	                                                     "/plain.rawlog --rawlog " + d +
	                                                     "/gz.rawlog --passes 2");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	// One row per input: format, MB, scans, points a scan (mean), ...
	const std::regex row("(bin|rawlog) +[0-9]+ +([0-9]+) +([0-9]+) ");
	int rows = 0;
	for (auto it = std::sregex_iterator(r.output.begin(), r.output.end(), row);
	     it != std::sregex_iterator(); ++it, ++rows)
	{
		EXPECT_EQ((*it)[2].str(), "3") << r.output;
		EXPECT_EQ((*it)[3].str(), "600") << r.output;  // (500 + 600 + 700) / 3
	}
	EXPECT_EQ(rows, 3) << r.output;
}

// `make bench-quick` and `make bench` write bench/results/REPORT.md through
// scripts/bench-report.sh; its smoke mode (40-scan drives, no KITTI, no KISS-ICP) checks that a
// report is made whole: the commit, each drive's table, and every plot it names, readable.
TEST(BenchReport, SmokeReportIsComplete)
{
	const test::ScopedTempDir dir("bench-report");
	const std::string build = fs::path(RASTERSLAM_BIN_DIR).parent_path().string();
	const auto r = test::runCommand("OUT=" + dir.path().string() + " BUILD=" + build + " bash " +
	                                test::sourcePath("scripts/bench-report.sh") + " --smoke");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	std::ifstream in(dir / "REPORT.md");
	ASSERT_TRUE(in.good()) << r.output;
	const std::string md((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
	EXPECT_TRUE(std::regex_search(md, std::regex("commit: `[0-9a-f]{7,}")));
	EXPECT_TRUE(contains(md, "## Tracking")) << md;
	EXPECT_FALSE(contains(md, "FAILED")) << md;
	for (const std::string scen :
	     {"town-loop", "town-vlp16", "town-sweep", "indoor-handheld", "town-kitti"})
		EXPECT_TRUE(contains(md, "rawlogs/" + scen + ".yaml, 40 ")) << scen;
	for (const std::string cfg :
	     {"tracking ", "gicp-baseline ", "tracking+deskew ", "indoor ", "gicp-indoor "})
		EXPECT_TRUE(std::regex_search(
		    md, std::regex("\n" + std::regex_replace(cfg, std::regex("\\+"), "\\+") +
		                   " +[0-9]+\\.[0-9] ")))
		    << cfg;
	// Every plot the report names is there and decodes.
	int plots = 0;
	const std::regex img("!\\[[^\\]]*\\]\\(([^)]+\\.png)\\)");
	for (auto it = std::sregex_iterator(md.begin(), md.end(), img); it != std::sregex_iterator();
	     ++it, ++plots)
	{
		const cv::Mat m = cv::imread((dir / (*it)[1].str()).string());
		EXPECT_FALSE(m.empty()) << (*it)[1].str();
	}
	EXPECT_GE(plots, 6);  // five drives from above, the cost over a run
	// Nothing left half-written.
	for (const auto& e : fs::directory_iterator(dir.path()))
		EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

// The README's benchmark tables are the committed report's (scripts/readme-figures.sh): they
// match it, and the check catches a README that drifted from it.
TEST(ReadmeFigures, MatchTheReport)
{
	const std::string script = test::sourcePath("scripts/readme-figures.sh");
	const auto ok = test::runCommand("bash " + script + " --check");
	EXPECT_EQ(ok.exitCode, 0) << ok.output;

	const test::ScopedTempDir dir("readme-figures");
	const auto readme = dir / "README.md", report = dir / "REPORT.md";
	std::ofstream(report)
	    << "# report\n\n- commit: `abc1234`; made today by `x quick`\n\n"
	       "## Tables\n\n`cmd`\n\n```\nrow 1.00\n```\n\n### Plots\n\n![p](p.png)\n";
	std::ofstream(readme)
	    << "intro\n<!-- report: Tables -->\nstale 9.99\n<!-- end report -->\nend\n";
	const std::string env = "README=" + readme.string() + " REPORT=" + report.string() + " ";
	const auto stale = test::runCommand(env + "bash " + script + " --check");
	EXPECT_EQ(stale.exitCode, 1) << stale.output;
	EXPECT_NE(stale.output.find("differ"), std::string::npos) << stale.output;
	const auto update = test::runCommand(env + "bash " + script);
	ASSERT_EQ(update.exitCode, 0) << update.output;
	std::ifstream in(readme);
	const std::string md((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
	EXPECT_EQ(md,
	          "intro\n<!-- report: Tables -->\nFrom `bench/results/REPORT.md` (commit: `abc1234`; "
	          "made today by `x quick`), section \"Tables\":\n\n`cmd`\n\n```\nrow 1.00\n```\n"
	          "<!-- end report -->\nend\n");
	EXPECT_EQ(test::runCommand(env + "bash " + script + " --check").exitCode, 0);
	// A section the report lacks is an error, and the README is left as it was.
	std::ofstream(readme) << "<!-- report: Missing -->\n<!-- end report -->\n";
	const auto missing = test::runCommand(env + "bash " + script);
	EXPECT_NE(missing.exitCode, 0);
	EXPECT_NE(missing.output.find("no section \"Missing\""), std::string::npos) << missing.output;
	std::ifstream again(readme);
	const std::string kept((std::istreambuf_iterator<char>(again)),
	                       std::istreambuf_iterator<char>());
	EXPECT_EQ(kept, "<!-- report: Missing -->\n<!-- end report -->\n");
	for (const auto& e : fs::directory_iterator(dir.path()))
		EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

// scripts/bench-repro.sh (make bench-repro) makes the report twice and compares every result
// file and the report's accuracy columns: two runs give the same figures, timings aside.
TEST(BenchReport, SmokeReportIsReproducible)
{
	const test::ScopedTempDir dir("bench-repro");
	const std::string build = fs::path(RASTERSLAM_BIN_DIR).parent_path().string();
	const auto r = test::runCommand("WORK=" + dir.path().string() + " BUILD=" + build + " bash " +
	                                test::sourcePath("scripts/bench-repro.sh") + " --smoke");
	ASSERT_EQ(r.exitCode, 0) << r.output;
	std::smatch m;
	ASSERT_TRUE(std::regex_search(
	    r.output, m, std::regex("reproducible \\(smoke\\): ([0-9]+) result files identical")))
	    << r.output;
	// Five drives, two or more systems each: their trajectories are among the files compared.
	EXPECT_GE(std::stoi(m[1].str()), 25) << r.output;
	// The comparison catches a difference: one trajectory of the first run changed.
	fs::path changed;
	for (const auto& e : fs::recursive_directory_iterator(dir / "a/work"))
		if (e.path().filename() == "trajectory.tum")
		{
			changed = e.path();
			break;
		}
	ASSERT_FALSE(changed.empty());
	std::ofstream(changed, std::ios::app) << "2000000000 0 0 0 0 0 0 1\n";
	const auto again = test::runCommand("COMPARE_ONLY=1 WORK=" + dir.path().string() + " bash " +
	                                    test::sourcePath("scripts/bench-repro.sh") + " --smoke");
	EXPECT_EQ(again.exitCode, 1) << again.output;
	EXPECT_NE(again.output.find("NOT reproducible"), std::string::npos) << again.output;
	EXPECT_NE(again.output.find(fs::relative(changed, dir / "a/work").string()), std::string::npos)
	    << again.output;
}
