// The `rasterslam` program's command line: help, version and usage errors of every command,
// the whole system by default, configs by name, and `rasterslam export` round trips.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <rasterslam/core/config.h>
#include <rasterslam/io/trajectory_io.h>
#include <rasterslam/map/map.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "test_support.h"

namespace fs = std::filesystem;
using namespace rasterslam;

namespace
{
std::string rs(const std::string& args)
{
	return test::bin("rasterslam") + " " + args;
}

bool contains(const std::string& text, const std::string& what)
{
	return text.find(what) != std::string::npos;
}

std::string readFile(const fs::path& p)
{
	std::ifstream f(p, std::ios::binary);
	std::stringstream ss;
	ss << f.rdbuf();
	return ss.str();
}

/** The first 30 KITTI scans as a rawlog in `dir`. */
std::string kitti30(const fs::path& dir)
{
	const auto D = test::sharedData("kitti00-0000-0100");
	const auto p = (dir / "kitti30.rawlog").string();
	const auto r = test::runCommand(test::bin("kitti2rawlog") + " --velodyne " + D +
	                                "/velodyne --poses " + D + "/poses_semantickitti.txt --calib " +
	                                D + "/calib.txt --times " + D + "/times.txt --last 29 -o " + p);
	EXPECT_EQ(r.exitCode, 0) << r.output;
	return p;
}
}  // namespace

TEST(RasterslamCli, HelpListsEveryCommandAndVersionNamesTheProgram)
{
	auto r = test::runCommand(rs("--help"));
	ASSERT_EQ(r.exitCode, 0) << r.output;
	for (const auto* cmd : {"run", "relocalize", "export", "map", "list-plugins", "Exit codes"})
		EXPECT_TRUE(contains(r.output, cmd)) << cmd << "\n" << r.output;
	r = test::runCommand(rs("--version"));
	EXPECT_EQ(r.exitCode, 0);
	EXPECT_TRUE(contains(r.output, "rasterslam 0.")) << r.output;
	EXPECT_TRUE(contains(r.output, "MRPT 2.")) << r.output;

	// Each command's own help names its own options.
	const std::vector<std::pair<std::string, std::vector<std::string>>> helps{
	    {"run", {"--rawlog", "--map-out", "--config", "--realtime", "--first"}},
	    {"relocalize", {"--map", "--rawlog", "--out", "--quiet", "--verbose"}},
	    {"export", {"--rawlog", "--format", "--first", "--last", "{bin,pcd,ply}"}},
	    {"map", {"info", "export", "merge", "prune"}},
	    {"map merge", {"--out", "--overwrite", "--config"}},
	    {"map prune", {"--before", "--keep-per-place", "--place-radius", "--dry-run"}},
	    {"map info", {"DIR"}}};
	for (const auto& [cmd, words] : helps)
	{
		r = test::runCommand(rs(cmd + " --help"));
		EXPECT_EQ(r.exitCode, 0) << cmd << "\n" << r.output;
		EXPECT_TRUE(contains(r.output, "Usage: rasterslam " + cmd)) << cmd << "\n" << r.output;
		for (const auto& w : words)
			EXPECT_TRUE(contains(r.output, w)) << cmd << ": " << w << "\n" << r.output;
	}
}

TEST(RasterslamCli, UsageErrorsExitTwoNamingTheCommandAndTheProblem)
{
	test::ScopedTempDir dir("cli-usage");
	const std::string out = (dir / "o").string();
	struct Case
	{
		std::string args, message;
	};
	const std::vector<Case> cases{
	    {"", "A subcommand is required"},
	    {"fly", "fly"},
	    {"run --out " + out, "rasterslam run: --rawlog is required"},
	    {"run --rawlog x --out " + out + " --bogus", "--bogus"},
	    {"run --rawlog x --out " + out + " --first -3", "--first: expects a whole number >= 0"},
	    {"run --rawlog x --out " + out + " --first 5 --last 2", "--first is after --last"},
	    {"run --rawlog x --out " + out + " --quiet --verbose", "--quiet excludes --verbose"},
	    {"run --rawlog x --out " + out + " --rate 2", "--rate requires --realtime"},
	    {"run --rawlog x --out " + out + " --realtime --rate 0", "--rate"},
	    {"run --rawlog x --out " + out + " --overwrite", "--overwrite requires --map-out"},
	    {"relocalize --rawlog x --out " + out, "rasterslam relocalize: --map is required"},
	    {"export --rawlog x --out " + out + " --format xyz", "--format"},
	    {"map", "rasterslam map: A subcommand is required"},
	    {"map info", "DIR is required"},
	    {"map merge a --out c", "B is required"},
	    {"map prune " + out, "give --before WHEN or --keep-per-place N"},
	    {"map prune " + out + " --before 2026-13-01", "is not a valid date"},
	    {"map prune " + out + " --keep-per-place 0", "--keep-per-place"},
	};
	for (const auto& c : cases)
	{
		const auto r = test::runCommand(rs(c.args));
		EXPECT_EQ(r.exitCode, 2) << c.args << "\n" << r.output;
		EXPECT_TRUE(contains(r.output, c.message)) << c.args << "\n" << r.output;
		EXPECT_TRUE(contains(r.output, "--help)")) << c.args << "\n" << r.output;
	}
	// Nothing was made by a usage error.
	EXPECT_FALSE(fs::exists(out));
}

TEST(RasterslamCli, ConfigIsAPathOrAShippedName)
{
	test::ScopedTempDir dir("cli-config");
	auto r =
	    test::runCommand(rs("run --rawlog x --out " + (dir / "o").string() + " --config nonesuch"));
	EXPECT_EQ(r.exitCode, 1) << r.output;
	for (const auto* name : {"--config nonesuch", "slam", "tracking", "gicp-baseline"})
		EXPECT_TRUE(contains(r.output, name)) << name << "\n" << r.output;
	// A folder is not a config.
	r = test::runCommand(
	    rs("run --rawlog x --out " + (dir / "o").string() + " --config " + dir.path().string()));
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_TRUE(contains(r.output, "not a regular file")) << r.output;
}

TEST(RasterslamCli, DefaultRunIsTheWholeSystemAndNamedConfigsWork)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	test::ScopedTempDir dir("cli-default");
	const auto rawlog = kitti30(dir.path());
	// No --config: tracking, map manager, loop closure and optimization; --map-out works.
	auto r = test::runCommand(rs("run --rawlog " + rawlog + " --out " + (dir / "full").string() +
	                             " --map-out " + (dir / "map").string() + " --quiet"));
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_TRUE(fs::exists(dir / "map" / "map.rsmap"));
	const auto full = loadYamlFile((dir / "full" / "run.yaml").string());
	EXPECT_TRUE(contains(full["input"]["config"].as<std::string>(), "config/slam.yaml"));
	const auto& cfg = full["config"];
	EXPECT_EQ(cfg["rasterizer"]["class"].as<std::string>(), "rasterslam::ElevationRasterizer");
	EXPECT_EQ(cfg["odometry"]["class"].as<std::string>(), "rasterslam::OrbOdometry");
	EXPECT_EQ(cfg["map_manager"]["class"].as<std::string>(), "rasterslam::LocalMapManager");
	EXPECT_EQ(cfg["loop_detector"]["class"].as<std::string>(), "rasterslam::BowLoopDetector");
	EXPECT_EQ(cfg["optimizer"]["class"].as<std::string>(), "rasterslam::CeresOptimizer");
	EXPECT_GE(full["counts"]["local_maps"].as<int>(), 1);
	// The allocator the build linked the program with (jemalloc where found: a link that
	// dropped it would leave glibc's); jemalloc returns memory by itself, so no trim runs.
	EXPECT_EQ(full["allocator"].as<std::string>(), std::string(RASTERSLAM_ALLOCATOR));
	if (std::string(RASTERSLAM_ALLOCATOR) == "jemalloc")
	{
		EXPECT_EQ(full["summary"]["memory_trim_ms_total"].as<double>(), 0.0);
	}

	// A shipped config by name: the tracking alone.
	r = test::runCommand(rs("run --rawlog " + rawlog + " --out " + (dir / "trk").string() +
	                        " --config tracking --quiet"));
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto trk = loadYamlFile((dir / "trk" / "run.yaml").string());
	EXPECT_TRUE(contains(trk["input"]["config"].as<std::string>(), "config/tracking.yaml"));
	EXPECT_FALSE(trk["config"].has("loop_detector"));
	EXPECT_FALSE(trk["config"].has("map_manager"));
	EXPECT_EQ(trk["counts"]["local_maps"].as<int>(), 0);

	// The lifelong config: each keyframe's loop query is the image of the local map being
	// built (also what the sanitized run reaches of that code: the loop tests are left out).
	r = test::runCommand(rs("run --rawlog " + rawlog + " --out " + (dir / "life").string() +
	                        " --config lifelong --quiet"));
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto life = loadYamlFile((dir / "life" / "run.yaml").string());
	EXPECT_TRUE(contains(life["input"]["config"].as<std::string>(), "config/lifelong.yaml"));
	EXPECT_EQ(life["config"]["map_manager"]["params"]["place_query_keyframes"].as<int>(), 5);
	EXPECT_GE(life["counts"]["local_maps"].as<int>(), 1);
	EXPECT_GE(life["counts"]["keyframes"].as<int>(), 5);
}

TEST(RasterslamCli, ExportRoundTripGivesTheSameScansAndTrajectory)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	test::ScopedTempDir dir("cli-export");
	const auto D = test::sharedData("kitti00-0000-0100");
	const auto rawlog = kitti30(dir.path());
	auto r = test::runCommand(
	    rs("export --rawlog " + rawlog + " --out " + (dir / "ex").string() + " --quiet"));
	ASSERT_EQ(r.exitCode, 0) << r.output;
	// KITTI's own scans come back byte for byte (their sensorPose is the identity).
	std::size_t n = 0;
	for (; fs::exists(dir / "ex" / "velodyne" / (std::to_string(1000000 + n).substr(1) + ".bin"));
	     n++)
		;
	ASSERT_EQ(n, 30u);
	for (const auto* f : {"000000.bin", "000017.bin", "000029.bin"})
		EXPECT_EQ(readFile(dir / "ex" / "velodyne" / f), readFile(fs::path(D) / "velodyne" / f))
		    << f;
	const auto gt = io::loadTrajectory((dir / "ex" / "poses.txt").string());
	ASSERT_EQ(gt.size(), 30u);
	const auto times = io::loadKittiTimes((dir / "ex" / "times.txt").string());
	ASSERT_EQ(times.size(), 30u);
	EXPECT_DOUBLE_EQ(times.front(), 0.0);
	EXPECT_GT(times.back(), 2.5);  // 10 Hz

	// Converted back, the same trajectory comes out of the same pipeline.
	r = test::runCommand(test::bin("kitti2rawlog") + " --sequence " + (dir / "ex").string() +
	                     " -o " + (dir / "back.rawlog").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	for (const auto& [in, out] : {std::pair{rawlog, std::string("a")},
	                              std::pair{(dir / "back.rawlog").string(), std::string("b")}})
	{
		r = test::runCommand(
		    rs("run --rawlog " + in + " --config tracking --quiet --out " + (dir / out).string()));
		ASSERT_EQ(r.exitCode, 0) << r.output;
	}
	const auto a = io::loadTrajectory((dir / "a" / "trajectory.tum").string());
	const auto b = io::loadTrajectory((dir / "b" / "trajectory.tum").string());
	ASSERT_EQ(a.size(), 30u);
	ASSERT_EQ(b.size(), a.size());
	for (std::size_t i = 0; i < a.size(); i++)
		EXPECT_LT((a[i].pose.matrix() - b[i].pose.matrix()).norm(), 1e-9) << "scan " << i;
	// And the exported ground truth is the rawlog's.
	const auto gtA = io::loadTrajectory((dir / "a" / "groundtruth.tum").string());
	ASSERT_EQ(gtA.size(), gt.size());
	for (std::size_t i = 0; i < gt.size(); i++)
		EXPECT_LT((gtA[i].pose.matrix() - gt[i].pose.matrix()).norm(), 1e-6) << "pose " << i;
}

TEST(RasterslamCli, ExportWritesPcdAndPlyWithTheirPointCountsAndRefusesToClobber)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	test::ScopedTempDir dir("cli-export-fmt");
	const auto D = test::sharedData("kitti00-0000-0100");
	const auto rawlog = kitti30(dir.path());
	const auto binBytes = fs::file_size(fs::path(D) / "velodyne" / "000004.bin");
	for (const std::string fmt : {"pcd", "ply"})
	{
		const auto out = dir / fmt;
		auto r = test::runCommand(rs("export --rawlog " + rawlog + " --out " + out.string() +
		                             " --format " + fmt + " --first 004 --last 5 --quiet"));
		ASSERT_EQ(r.exitCode, 0) << r.output;
		// Scan 4 of the input is file 0 of the export (004 is decimal, not octal).
		const auto text = readFile(out / "velodyne" / ("000000." + fmt));
		ASSERT_FALSE(fs::exists(out / "velodyne" / ("000002." + fmt)));
		const std::string endOfHeader = fmt == "pcd" ? "DATA binary\n" : "end_header\n";
		const auto h = text.find(endOfHeader);
		ASSERT_NE(h, std::string::npos) << fmt;
		const auto header = text.substr(0, h);
		const std::string count = std::to_string(binBytes / 16);
		EXPECT_TRUE(contains(header, fmt == "pcd" ? "POINTS " + count : "element vertex " + count))
		    << header;
		EXPECT_EQ(text.size() - h - endOfHeader.size(), binBytes) << fmt;
		EXPECT_EQ(text.substr(h + endOfHeader.size()),
		          readFile(fs::path(D) / "velodyne" / "000004.bin"))
		    << fmt;

		// A second export into the same folder needs --overwrite; the first stays whole.
		r = test::runCommand(rs("export --rawlog " + rawlog + " --out " + out.string() +
		                        " --format " + fmt + " --last 0 --quiet"));
		EXPECT_EQ(r.exitCode, 1) << r.output;
		EXPECT_TRUE(contains(r.output, "--overwrite")) << r.output;
		EXPECT_EQ(readFile(out / "velodyne" / ("000000." + fmt)), text);
		r = test::runCommand(rs("export --rawlog " + rawlog + " --out " + out.string() +
		                        " --format " + fmt + " --last 0 --quiet --overwrite"));
		EXPECT_EQ(r.exitCode, 0) << r.output;
		EXPECT_FALSE(fs::exists(out / "velodyne" / ("000001." + fmt)));
	}
	// A rawlog that is not there: exit 1 naming it.
	const auto r = test::runCommand(
	    rs("export --rawlog " + (dir / "none.rawlog").string() + " --out " + (dir / "x").string()));
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_TRUE(contains(r.output, (dir / "none.rawlog").string())) << r.output;
}

namespace
{
/** Starts a program with its output in `log`; returns its pid. */
pid_t spawn(const std::vector<std::string>& args, const fs::path& log)
{
	std::vector<char*> argv;
	for (const auto& a : args)
		argv.push_back(const_cast<char*>(a.c_str()));
	argv.push_back(nullptr);
	const pid_t pid = ::fork();
	if (pid == 0)
	{
		const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
		::dup2(fd, 1);
		::dup2(fd, 2);
		::execv(argv[0], argv.data());
		::_exit(127);
	}
	return pid;
}

/** Waits for `pid` (at most `seconds`); its exit code, 128 + signal if a signal ended it, or
 *  -1 on timeout (the process is then killed). */
int waitExit(pid_t pid, double seconds)
{
	const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
	int st = 0;
	while (::waitpid(pid, &st, WNOHANG) == 0)
	{
		if (std::chrono::steady_clock::now() > until)
		{
			::kill(pid, SIGKILL);
			::waitpid(pid, &st, 0);
			return -1;
		}
		std::this_thread::sleep_for(std::chrono::milliseconds(20));
	}
	return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

std::size_t lines(const fs::path& p)
{
	std::ifstream f(p);
	std::size_t n = 0;
	for (std::string l; std::getline(f, l);)
		n += !l.empty() && l[0] != '#';
	return n;
}
}  // namespace

TEST(RasterslamCli, SigintOrSigtermWritesTheOutputsAndTheMapForWhatWasProcessed)
{
	test::ScopedTempDir dir("cli-signal");
	const auto rawlog = (dir / "town.rawlog").string();
	auto r =
	    test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-loop.yaml") + " --scans 300 -o " + rawlog);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	// A temporary output that a killed run left (its process is gone) is removed at the next
	// start; that of a live process is not.
	const pid_t dead = ::fork();
	if (dead == 0)
		::_exit(0);
	::waitpid(dead, nullptr, 0);
	fs::create_directories(dir / "int");
	const auto stale = dir / "int" / ("trajectory.tum.tmp-" + std::to_string(dead));
	const auto live = dir / "int" / ("notes.txt.tmp-" + std::to_string(::getpid()));
	std::ofstream(stale) << "left by a killed run";
	std::ofstream(live) << "another process is writing this";

	for (const auto& [sig, out] :
	     {std::pair{SIGINT, std::string("int")}, std::pair{SIGTERM, std::string("term")}})
	{
		SCOPED_TRACE(out);
		const auto log = dir / (out + ".log");
		// Real time at 3x: 300 scans take 10 s, the signal comes after about one.
		const pid_t pid = spawn(
		    {test::bin("rasterslam"), "run", "--rawlog", rawlog, "--out", (dir / out).string(),
		     "--map-out", (dir / (out + "-map")).string(), "--realtime", "--rate", "3"},
		    log);
		// Started when the first scan is reported.
		const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(60);
		while (readFile(log).find("[rasterslam] 1 scans") == std::string::npos &&
		       std::chrono::steady_clock::now() < until)
			std::this_thread::sleep_for(std::chrono::milliseconds(20));
		std::this_thread::sleep_for(std::chrono::milliseconds(1000));
		::kill(pid, sig);
		const int code = waitExit(pid, 60);
		const auto text = readFile(log);
		EXPECT_EQ(code, 128 + sig) << text;
		const std::string name = sig == SIGINT ? "SIGINT" : "SIGTERM";
		EXPECT_TRUE(contains(text, "interrupted by " + name + " after ")) << text;
		// The outputs cover the scans processed: some, not all.
		const auto n = lines(dir / out / "trajectory.tum");
		EXPECT_GE(n, 5u) << text;
		EXPECT_LT(n, 300u) << text;
		EXPECT_EQ(lines(dir / out / "groundtruth.tum"), n);
		const auto info = loadYamlFile((dir / out / "run.yaml").string());
		EXPECT_EQ(info["summary"]["interrupted_by"].as<std::string>(), name);
		EXPECT_EQ(info["counts"]["scans"].as<std::size_t>(), n);
		// The map is saved and loads.
		r = test::runCommand(rs("map info " + (dir / (out + "-map")).string()));
		EXPECT_EQ(r.exitCode, 0) << r.output;
		EXPECT_TRUE(contains(r.output, "sessions     : 1")) << r.output;
		// No temporary file is left.
		for (const auto* d : {"", "-map", "-map/store"})
			for (const auto& e : fs::directory_iterator(dir / (out + d)))
				if (e.path() != live)
				{
					EXPECT_FALSE(contains(e.path().filename().string(), ".tmp-")) << e.path();
				}
	}
	EXPECT_FALSE(fs::exists(stale));
	EXPECT_TRUE(fs::exists(live));
}

TEST(RasterslamCli, AMapThatCannotBeWrittenIsAnErrorInRunYamlAndLeavesNoDebris)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	test::ScopedTempDir dir("cli-full");
	const auto rawlog = kitti30(dir.path());
	// A file size limit (100 kB, SIGXFSZ ignored) stands in for a full disk: the local maps
	// (hundreds of kB) cannot be written, the trajectory and run.yaml can.
	const auto r =
	    test::runCommand("bash -c \"trap '' XFSZ; ulimit -f 200; " + test::bin("rasterslam") +
	                     " run --rawlog " + rawlog + " --out " + (dir / "o").string() +
	                     " --map-out " + (dir / "m").string() + " --quiet\"");
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_TRUE(contains(r.output, "rasterslam: error: saving the map: cannot write local map '" +
	                                   (dir / "m" / "store").string()))
	    << r.output;
	EXPECT_FALSE(contains(r.output, "Call stack")) << r.output;
	const auto info = loadYamlFile((dir / "o" / "run.yaml").string());
	EXPECT_TRUE(contains(info["summary"]["error"].as<std::string>(), "saving the map")) << r.output;
	EXPECT_EQ(lines(dir / "o" / "trajectory.tum"), 30u);
	// No map, and no temporary file left.
	EXPECT_FALSE(fs::exists(dir / "m" / "map.rsmap"));
	for (const auto& e : fs::recursive_directory_iterator(dir / "m"))
		EXPECT_FALSE(contains(e.path().filename().string(), ".tmp-")) << e.path();
}

TEST(RasterslamCli, ScanRecordsThatCannotBeKeptFailTheRunAndKeepWhatTheyCan)
{
	// The scan records go to a temporary file in $TMPDIR, 256 at a time; a file size limit
	// (40 kB, SIGXFSZ ignored) stands in for a full disk: the first 256 (66 kB) cannot be
	// written. The run has no trajectory then: exit 1, the reason in run.yaml, the pose graph
	// and run.yaml written, an earlier run's trajectory removed rather than left as this one's.
	test::ScopedTempDir dir("cli-records-full");
	fs::create_directories(dir / "tmp");
	fs::create_directories(dir / "o");
	std::ofstream(dir / "o" / "trajectory.tum") << "# an earlier run\n";
	const auto r = test::runCommand(
	    "bash -c \"trap '' XFSZ; ulimit -f 40; TMPDIR=" + (dir / "tmp").string() + " " +
	    rs("run --rawlog " + test::townVlp16Rawlog() + " --last 299 --config tracking --out " +
	       (dir / "o").string() + " --quiet") +
	    "\"");
	EXPECT_EQ(r.exitCode, 1) << r.output;
	const std::string why =
	    "the scan records could not be kept in a temporary file (File too large)";
	EXPECT_TRUE(contains(r.output, "rasterslam: error: " + why)) << r.output;
	EXPECT_TRUE(contains(r.output, "300 scans")) << r.output;  // the summary line is still given
	const auto info = loadYamlFile((dir / "o" / "run.yaml").string());
	EXPECT_TRUE(contains(info["summary"]["error"].as<std::string>(), why)) << r.output;
	EXPECT_EQ(info["counts"]["scans"].as<int>(), 300);
	EXPECT_TRUE(fs::exists(dir / "o" / "pose_graph.graph"));
	EXPECT_FALSE(fs::exists(dir / "o" / "trajectory.tum"));
	EXPECT_FALSE(fs::exists(dir / "o" / "timings.csv"));
	EXPECT_TRUE(fs::is_empty(dir / "tmp"));  // the spools had no names
}

TEST(RasterslamCli, NoTemporaryFileKeepsTheRecordsInMemoryWithOneWarning)
{
	// $TMPDIR names a folder that does not exist: the scan records and the loop decisions stay
	// in memory, the run succeeds, and each is warned of once, with --quiet and without (the
	// engine's log gives the scan records' warning; --quiet silences the log, so the program
	// gives it then).
	test::ScopedTempDir dir("cli-no-tmp");
	const std::string tmp = (dir / "missing").string();
	const std::string records = "the scan records are kept in memory";
	const std::string recordsQuiet =
	    "no temporary file for the scan records in '" + tmp + "'; they were kept in memory";
	const std::string decisions = "loop decisions kept in memory";
	auto count = [](const std::string& text, const std::string& what)
	{
		std::size_t n = 0;
		for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1))
			n++;
		return n;
	};
	for (const bool quiet : {false, true})
	{
		const auto out = dir / (quiet ? "quiet" : "loud");
		const auto r = test::runCommand("env TMPDIR=" + tmp + " " +
		                                rs("run --rawlog " + test::townVlp16Rawlog() +
		                                   " --last 59 --config tracking --out " + out.string() +
		                                   (quiet ? " --quiet" : "")));
		EXPECT_EQ(r.exitCode, 0) << r.output;
		EXPECT_EQ(count(r.output, records) + count(r.output, recordsQuiet), 1u) << r.output;
		EXPECT_EQ(count(r.output, quiet ? recordsQuiet : records), 1u) << r.output;
		EXPECT_TRUE(contains(r.output, "no temporary file for the scan records in '" + tmp + "'"))
		    << r.output;  // the folder is named
		EXPECT_EQ(count(r.output, decisions), 1u) << r.output;
		// Nothing is lost: every scan's pose and time.
		EXPECT_EQ(lines(out / "trajectory.tum"), 60u);
		EXPECT_TRUE(fs::exists(out / "timings.csv"));
		EXPECT_FALSE(fs::exists(tmp));
	}
}

TEST(RasterslamCli, AMapInUseByAnotherProcessIsRefusedAndLeftAsItWas)
{
	test::ScopedTempDir dir("cli-lock");
	const auto rawlog = test::townVlp16Rawlog();
	const auto map = (dir / "m").string();
	auto r = test::runCommand(rs("run --rawlog " + rawlog + " --last 150 --out " +
	                             (dir / "o1").string() + " --map-out " + map + " --quiet"));
	ASSERT_EQ(r.exitCode, 0) << r.output;
	// What map info says, but for the size on disk (the lock file's content varies).
	const auto info = [&]
	{
		auto out = test::runCommand(rs("map info " + map)).output;
		out.erase(0, out.find('\n'));
		return out;
	};
	const auto before = test::runCommand(rs("map info " + map));
	ASSERT_EQ(before.exitCode, 0) << before.output;
	const std::string update =
	    rs("run --rawlog " + rawlog + " --last 60 --out " + (dir / "o2").string() + " --map-in " +
	       map + " --map-out " + map + " --quiet");
	const std::string prune = rs("map prune " + map + " --keep-per-place 1 --quiet");
	{
		// Another process writes the map (this one, holding the lock as a run does).
		const MapUseLock writer(map, MapUseLock::Mode::Write, "rasterslam run");
		const std::string inUse = "rasterslam: error: map folder '" + map +
		                          "' is in use: process " + std::to_string(::getpid()) +
		                          " (rasterslam run) is writing it; wait until it ends";
		r = test::runCommand(update);
		EXPECT_EQ(r.exitCode, 1) << r.output;
		EXPECT_TRUE(contains(r.output, inUse)) << r.output;
		r = test::runCommand(prune);
		EXPECT_EQ(r.exitCode, 1) << r.output;
		EXPECT_TRUE(contains(r.output, inUse)) << r.output;
		// Reading the index alone needs no lock.
		EXPECT_EQ(test::runCommand(rs("map info " + map)).exitCode, 0);
	}
	{
		// Another process reads it: other readers go on, a writer is refused.
		const MapUseLock reader(map, MapUseLock::Mode::Read, "rasterslam relocalize");
		r = test::runCommand(prune);
		EXPECT_EQ(r.exitCode, 1) << r.output;
		EXPECT_TRUE(contains(r.output,
		                     "map folder '" + map + "' is in use: other processes are reading it"))
		    << r.output;
		r = test::runCommand(rs("run --rawlog " + rawlog + " --last 60 --out " +
		                        (dir / "o3").string() + " --map-in " + map + " --quiet"));
		EXPECT_EQ(r.exitCode, 0) << r.output;
	}
	// Nothing the refused commands did reached the map.
	auto expected = before.output;
	expected.erase(0, expected.find('\n'));
	EXPECT_EQ(info(), expected);
	// Free again: the update runs.
	r = test::runCommand(update);
	EXPECT_EQ(r.exitCode, 0) << r.output;
	EXPECT_TRUE(contains(test::runCommand(rs("map info " + map)).output, "sessions     : 2"));
}

TEST(RasterslamCli, OfflineLocalMapsAKilledRunLeftAreRemovedByTheNextRun)
{
	test::ScopedTempDir dir("cli-offline");
	// The run's temporary folder: a killed run's offline local maps (its process is gone) and
	// a live process's.
	const auto tmp = dir / "tmp";
	const pid_t dead = ::fork();
	if (dead == 0)
		::_exit(0);
	::waitpid(dead, nullptr, 0);
	const auto stale = tmp / ("rasterslam-offline-" + std::to_string(dead) + "-0");
	const auto live = tmp / ("rasterslam-offline-" + std::to_string(::getpid()) + "-0");
	fs::create_directories(stale);
	fs::create_directories(live);
	std::ofstream(stale / "000003.rslm") << "left by a killed run";
	// The drive puts local maps offline (run.yaml: local_maps_offline > 0).
	const auto r = test::runCommand("TMPDIR=" + tmp.string() + " " +
	                                rs("run --rawlog " + test::townVlp16Rawlog() + " --out " +
	                                   (dir / "o").string() + " --quiet"));
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto info = loadYamlFile((dir / "o" / "run.yaml").string());
	EXPECT_GT(info["counts"]["local_maps_offline"].as<int>(), 0);
	EXPECT_FALSE(fs::exists(stale));
	EXPECT_TRUE(fs::exists(live));
	// The run removed its own.
	std::size_t left = 0;
	for (const auto& e : fs::directory_iterator(tmp))
		left += e.path() != live;
	EXPECT_EQ(left, 0u);
}
