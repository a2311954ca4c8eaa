// Trajectory files (TUM, KITTI), KITTI calibration and times, atomic writes, a run's outputs.
#include <fcntl.h>
#include <rasterslam/core/pose_conversions.h>
#include <rasterslam/io/run_outputs.h>
#include <rasterslam/io/trajectory_io.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>

#include "test_support.h"

using namespace rasterslam;
namespace fs = std::filesystem;

namespace
{
io::Trajectory randomTrajectory(std::size_t n, double stamp0, unsigned seed)
{
	std::mt19937 rng(seed);
	std::uniform_real_distribution<double> u(-1.0, 1.0);
	io::Trajectory t;
	for (std::size_t i = 0; i < n; ++i)
	{
		io::StampedPose sp;
		sp.stamp = stamp0 + 0.1 * static_cast<double>(i) + 1e-4 * u(rng);
		sp.pose.linear() = Eigen::Quaterniond::UnitRandom().toRotationMatrix();
		sp.pose.translation() = Eigen::Vector3d(100 * u(rng), 100 * u(rng), 1e-3 * u(rng));
		t.push_back(sp);
	}
	return t;
}

void writeText(const fs::path& p, const std::string& s)
{
	std::ofstream(p) << s;
}

/** Runs `f`, expects a std::runtime_error whose message contains every string of `parts`. */
template <class F>
void expectErrorWith(F f, const std::vector<std::string>& parts)
{
	try
	{
		f();
		ADD_FAILURE() << "no exception";
	}
	catch (const std::runtime_error& e)
	{
		for (const auto& p : parts)
			EXPECT_NE(std::string(e.what()).find(p), std::string::npos)
			    << "message '" << e.what() << "' lacks '" << p << "'";
	}
}

const std::string kIdentityKitti = "1 0 0 0 0 1 0 0 0 0 1 0\n";
}  // namespace

TEST(TrajectoryIo, TumRoundTripPreservesValues)
{
	// Eigen's UnitRandom draws from std::rand: seed it for a reproducible test.
	std::srand(7);
	const auto dir = test::tempDir("trajio");
	const auto orig = randomTrajectory(50, 1.7e9 + 0.123456, 1);
	const std::string path = (dir / "t.tum").string();
	io::saveTrajectoryTum(path, orig);
	io::TrajectoryFormat fmt = io::TrajectoryFormat::Auto;
	const auto back = io::loadTrajectory(path, io::TrajectoryFormat::Auto, &fmt);
	EXPECT_EQ(fmt, io::TrajectoryFormat::Tum);
	ASSERT_EQ(back.size(), orig.size());
	for (std::size_t i = 0; i < orig.size(); ++i)
	{
		EXPECT_NEAR(back[i].stamp, orig[i].stamp, 1e-9 * std::abs(orig[i].stamp));
		EXPECT_LT((back[i].pose.matrix() - orig[i].pose.matrix()).cwiseAbs().maxCoeff(),
		          1e-9 * 100);
		EXPECT_LT((back[i].pose.linear() - orig[i].pose.linear()).cwiseAbs().maxCoeff(), 1e-12);
	}
	// Nothing but the file itself is left in the folder (the temporary was renamed).
	EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(TrajectoryIo, KittiRoundTripIsExactAndStampsAreIndices)
{
	std::srand(11);
	const auto dir = test::tempDir("trajio");
	const auto orig = randomTrajectory(30, 5.0, 2);
	const std::string path = (dir / "t.kitti").string();
	io::saveTrajectoryKitti(path, orig);
	io::TrajectoryFormat fmt = io::TrajectoryFormat::Auto;
	const auto back = io::loadTrajectory(path, io::TrajectoryFormat::Auto, &fmt);
	EXPECT_EQ(fmt, io::TrajectoryFormat::Kitti);
	ASSERT_EQ(back.size(), orig.size());
	for (std::size_t i = 0; i < orig.size(); ++i)
	{
		EXPECT_EQ(back[i].stamp, static_cast<double>(i));
		// Shortest round-trip formatting: the doubles come back bit for bit.
		EXPECT_EQ(back[i].pose.matrix(), orig[i].pose.matrix()) << "pose " << i;
	}
}

TEST(TrajectoryIo, ParsesCommentsBlankLinesAndFormatOverride)
{
	const auto dir = test::tempDir("trajio");
	const fs::path p = dir / "a.txt";
	writeText(p, "# header\n\n0.5 1 2 3 0 0 0.7071067811865476 0.7071067811865476\n  \n");
	const auto t = io::loadTrajectory(p.string());
	ASSERT_EQ(t.size(), 1u);
	EXPECT_DOUBLE_EQ(t[0].stamp, 0.5);
	EXPECT_DOUBLE_EQ(t[0].pose.translation().y(), 2.0);
	// qz = qw = 1/sqrt(2): 90 degrees about z, so x maps onto y.
	EXPECT_NEAR((t[0].pose.linear() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(),
	            0, 1e-12);
	// Forcing KITTI on a TUM file is an error naming the expected layout.
	expectErrorWith([&] { io::loadTrajectory(p.string(), io::TrajectoryFormat::Kitti); },
	                {p.string(), "line 3", "12 columns", "got 8"});
}

TEST(TrajectoryIo, LoadErrorsNameFileAndLine)
{
	const auto dir = test::tempDir("trajio");
	const fs::path cols = dir / "cols.txt";
	writeText(cols, kIdentityKitti + kIdentityKitti + "1 0 0 0 0 1 0 0 0 0 1\n");
	expectErrorWith([&] { io::loadTrajectory(cols.string()); },
	                {cols.string(), "line 3", "got 11"});

	const fs::path nine = dir / "nine.txt";
	writeText(nine, "1 2 3 4 5 6 7 8 9\n");
	expectErrorWith([&] { io::loadTrajectory(nine.string()); },
	                {nine.string(), "line 1", "8", "12"});

	const fs::path nan = dir / "nan.txt";
	writeText(nan, kIdentityKitti + "1 0 0 nan 0 1 0 0 0 0 1 0\n");
	expectErrorWith([&] { io::loadTrajectory(nan.string()); }, {nan.string(), "line 2", "finite"});

	const fs::path word = dir / "word.txt";
	writeText(word, "0 1 2 3 0 0 x 1\n");
	expectErrorWith([&] { io::loadTrajectory(word.string()); }, {word.string(), "line 1", "'x'"});

	const fs::path skew = dir / "skew.txt";
	writeText(skew, "1 0.1 0 0 0 1 0 0 0 0 1 0\n");
	expectErrorWith([&] { io::loadTrajectory(skew.string()); },
	                {skew.string(), "line 1", "orthonormal"});

	const fs::path mirror = dir / "mirror.txt";
	writeText(mirror, "-1 0 0 0 0 1 0 0 0 0 1 0\n");
	expectErrorWith([&] { io::loadTrajectory(mirror.string()); }, {mirror.string(), "orthonormal"});

	const fs::path quat = dir / "quat.txt";
	writeText(quat, "0 1 2 3 0 0 0 2\n");
	expectErrorWith([&] { io::loadTrajectory(quat.string()); },
	                {quat.string(), "line 1", "quaternion"});

	const std::string missing = (dir / "missing.txt").string();
	expectErrorWith([&] { io::loadTrajectory(missing); }, {missing});
	expectErrorWith([&] { io::loadKittiCalibTr(missing); }, {missing});
	expectErrorWith([&] { io::loadKittiTimes(missing); }, {missing});

	const fs::path noTr = dir / "calib.txt";
	writeText(noTr, "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n");
	expectErrorWith([&] { io::loadKittiCalibTr(noTr.string()); }, {noTr.string(), "Tr:"});
}

TEST(TrajectoryIo, AtomicWriteReplacesAndFailsNamingTheFile)
{
	const auto dir = test::tempDir("trajio");
	const fs::path p = dir / "out.txt";
	io::writeFileAtomically(p.string(), "first\n");
	io::writeFileAtomically(p.string(), "second\n");
	std::ifstream in(p);
	std::string s;
	std::getline(in, s);
	EXPECT_EQ(s, "second");
	EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
	const std::string bad = (dir / "no-such-folder" / "x.txt").string();
	expectErrorWith([&] { io::writeFileAtomically(bad, "x"); }, {bad});
}

TEST(TrajectoryIo, KittiCalibOnRealData)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const std::string dir = test::sharedData("kitti00-0000-0100");
	const Eigen::Isometry3d Tr = io::loadKittiCalibTr(dir + "/calib.txt");
	// Values of the `Tr:` line of sequence 00.
	EXPECT_DOUBLE_EQ(Tr.matrix()(0, 1), -9.999672484946e-01);
	EXPECT_DOUBLE_EQ(Tr.matrix()(2, 0), 9.999738645903e-01);
	EXPECT_DOUBLE_EQ(Tr.translation().z(), -2.921968648686e-01);

	const io::Trajectory id(1);
	const auto conv = io::kittiCameraToVelodyne(id, Tr);
	EXPECT_LT((conv[0].pose.matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-9);

	// From the data README: frames 0 -> 10 are 8.60 m apart (official), 7.49 m (SemanticKITTI).
	for (const auto& [file, expected] : {std::pair<std::string, double>{"poses_official.txt", 8.60},
	                                     {"poses_semantickitti.txt", 7.49}})
	{
		const auto cam = io::loadTrajectory(dir + "/" + file);
		ASSERT_EQ(cam.size(), 101u) << file;
		const auto velo = io::kittiCameraToVelodyne(cam, Tr);
		const double d = (velo[10].pose.translation() - velo[0].pose.translation()).norm();
		EXPECT_NEAR(d, expected, 0.01) << file;
		// A camera 0.27 m behind the Velodyne moves differently when the car turns: the
		// conversion must change the positions, not just relabel axes.
		EXPECT_NEAR(velo[0].pose.translation().norm(), 0, 1e-6) << file;
	}

	const auto times = io::loadKittiTimes(dir + "/times.txt");
	ASSERT_EQ(times.size(), 101u);
	EXPECT_DOUBLE_EQ(times[1], 1.037359e-01);
}

TEST(RunOutputs, LongRunsAreWrittenInChunksAndReadBackExactly)
{
	// 3,000 scans make each trajectory file several times the 64 kB chunk the outputs are
	// streamed in: every line is written once, in order, and reads back to the same values.
	const std::size_t n = 3000;
	const auto est = randomTrajectory(n, 1.7e9, 5), online = randomTrajectory(n, 1.7e9, 6),
	           truth = randomTrajectory(n, 1.7e9, 7);
	RunResult res;
	for (std::size_t i = 0; i < n; i++)
	{
		ScanRecord r;
		r.index = i;
		r.stamp = est[i].stamp;
		r.inliers = i % 97;
		r.onlinePose = toPose(online[i].pose).asTPose();
		r.groundTruth = toPose(truth[i].pose).asTPose();
		res.scans.push_back(r);
		res.poses.push_back(toPose(est[i].pose));
	}
	LoopDecision l;
	l.queryStamp = est[10].stamp;
	l.reason = "ok";
	res.loopDecisions.assign(2000, l);
	const test::ScopedTempDir dir("run-outputs");
	mrpt::containers::yaml info = mrpt::containers::yaml::Map();
	info["scans"] = static_cast<uint64_t>(n);
	io::writeRunOutputs(dir.path().string(), res, info);

	auto expectSame = [&](const io::Trajectory& want, const io::Trajectory& got, double tol)
	{
		ASSERT_EQ(got.size(), want.size());
		for (std::size_t i = 0; i < n; i++)
		{
			EXPECT_EQ(got[i].stamp, est[i].stamp) << i;  // every file has the scans' stamps
			EXPECT_LT((got[i].pose.matrix() - want[i].pose.matrix()).cwiseAbs().maxCoeff(), tol)
			    << i;
		}
	};
	// Through CPose3D (yaw, pitch, roll) and back: equal to rounding.
	expectSame(est, io::loadTrajectory((dir / "trajectory.tum").string()), 1e-9);
	expectSame(online, io::loadTrajectory((dir / "trajectory_online.tum").string()), 1e-9);
	expectSame(truth, io::loadTrajectory((dir / "groundtruth.tum").string()), 1e-9);
	const auto kitti = io::loadTrajectory((dir / "trajectory.kitti").string());
	ASSERT_EQ(kitti.size(), n);
	EXPECT_LT((kitti[n - 1].pose.matrix() - est[n - 1].pose.matrix()).cwiseAbs().maxCoeff(), 1e-9);

	auto lines = [&](const char* name)
	{
		std::ifstream in(dir / name);
		std::vector<std::string> out;
		for (std::string s; std::getline(in, s);)
			out.push_back(s);
		return out;
	};
	const auto csv = lines("timings.csv");
	ASSERT_EQ(csv.size(), n + 1);
	for (std::size_t i = 1; i <= n; i++)
		ASSERT_EQ(csv[i].substr(0, csv[i].find(',')), std::to_string(i - 1)) << i;
	EXPECT_EQ(lines("loops.txt").size(), 2001u);
	// Nothing left under a temporary name.
	for (const auto& e : fs::directory_iterator(dir.path()))
		EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

TEST(RunOutputs, SpooledLoopDecisionsComeFirstInLoopsTxtInTheirOrder)
{
	// A run hands its loop decisions to a spool as it makes them (rasterslam run), and those
	// still in the result come after them: loops.txt has every one, in the order made, each
	// line as appendLoopLine writes it.
	RunResult res;
	for (std::size_t i = 0; i < 3; i++)
	{
		ScanRecord r;
		r.index = i;
		r.stamp = 100.0 + i;
		res.scans.push_back(r);
		res.poses.emplace_back();
	}
	auto decision = [](std::size_t i)
	{
		LoopDecision l;
		l.queryStamp = 1.7e9 + 0.1 * static_cast<double>(i);
		l.candidateStamp = static_cast<double>(i);
		l.inliers = i;
		l.verified = i % 3 == 0;
		l.accepted = i % 6 == 0;
		l.reason = l.verified ? "ok" : "inliers";
		l.T_candidate_query = mrpt::poses::CPose3D(0.01 * i, -2, 0.5, 0.001 * i, 0, 0);
		return l;
	};
	io::LoopDecisionSpool spool;
	std::vector<std::string> want;
	for (std::size_t batch = 0; batch < 40; batch++)  // 40 keyframes of 100: about 8 chunks
	{
		std::vector<LoopDecision> d;
		for (std::size_t k = 0; k < 100; k++)
			d.push_back(decision(100 * batch + k));
		spool.append(d);
	}
	for (std::size_t i = 4000; i < 4005; i++)
		res.loopDecisions.push_back(decision(i));
	for (std::size_t i = 0; i < 4005; i++)
	{
		std::string s;
		io::appendLoopLine(s, decision(i));
		want.push_back(s.substr(0, s.size() - 1));
	}
	EXPECT_EQ(spool.size(), 4000u);
	const test::ScopedTempDir dir("run-outputs-spool");
	const mrpt::containers::yaml info = mrpt::containers::yaml::Map();
	auto loops = [&]
	{
		std::ifstream in(dir / "loops.txt");
		std::vector<std::string> out;
		for (std::string s; std::getline(in, s);)
			out.push_back(s);
		return out;
	};
	io::writeRunOutputs(dir.path().string(), res, info, &spool);
	auto got = loops();
	ASSERT_EQ(got.size(), want.size() + 1);
	EXPECT_EQ(got[0].rfind("# query_stamp", 0), 0u);
	for (std::size_t i = 0; i < want.size(); i++)
		ASSERT_EQ(got[i + 1], want[i]) << i;
	EXPECT_NE(got[7].find(" 1 1 ok "), std::string::npos) << got[7];  // decision 6: accepted
	// Written again (a second write of the same run), the spool gives the same lines: it is
	// read from its start, not consumed.
	io::writeRunOutputs(dir.path().string(), res, info, &spool);
	EXPECT_EQ(loops(), got);
	// Only spooled decisions (none left in the result): loops.txt all the same.
	res.loopDecisions.clear();
	io::writeRunOutputs(dir.path().string(), res, info, &spool);
	EXPECT_EQ(loops().size(), 4001u);
}

TEST(RunOutputs, ASpoolThatLostLinesSaysWhyAndThePreviousOutputsStayWhole)
{
	// A full disk under the spool (/dev/full: every write fails with ENOSPC) must cost
	// loops.txt only: finish() gives the system's reason, writing with that spool fails naming
	// loops.txt and keeps the previous outputs, and the outputs without it can still be written
	// (rasterslam run does so, and reports the error).
	if (!fs::exists("/dev/full"))
		GTEST_SKIP() << "no /dev/full on this system";
	RunResult res;
	for (std::size_t i = 0; i < 4; i++)
	{
		ScanRecord r;
		r.index = i;
		r.stamp = 50.0 + i;
		res.scans.push_back(r);
		res.poses.emplace_back(static_cast<double>(i), 0, 0, 0, 0, 0);
	}
	LoopDecision kept;
	kept.queryStamp = 51;
	kept.reason = "ok";
	res.loopDecisions.push_back(kept);
	const test::ScopedTempDir dir("run-outputs-full-spool");
	const mrpt::containers::yaml info = mrpt::containers::yaml::Map();
	io::writeRunOutputs(dir.path().string(), res, info);
	auto read = [&](const std::string& name)
	{
		std::ifstream in(dir / name);
		return std::string(std::istreambuf_iterator<char>(in), {});
	};
	const std::string trajectoryBefore = read("trajectory.tum");
	const std::string loopsBefore = read("loops.txt");
	ASSERT_FALSE(loopsBefore.empty());

	std::FILE* full = std::fopen("/dev/full", "w+");
	ASSERT_NE(full, nullptr) << std::strerror(errno);
	io::LoopDecisionSpool spool(full);          // owns it from here, whatever fails
	std::vector<LoopDecision> many(200, kept);  // more than the stream's buffer
	spool.append(many);
	const std::string why = spool.finish();
	EXPECT_NE(why.find(std::strerror(ENOSPC)), std::string::npos) << why;
	RunResult next = std::move(res);  // its scan records: a ScanLog moves, never copies
	next.loopDecisions.clear();
	next.poses.assign(4, mrpt::poses::CPose3D(9, 9, 9, 0, 0, 0));
	try
	{
		io::writeRunOutputs(dir.path().string(), next, info, &spool);
		ADD_FAILURE() << "a spool that lost lines was copied into loops.txt";
	}
	catch (const std::exception& e)
	{
		EXPECT_NE(std::string(e.what()).find("loops.txt"), std::string::npos) << e.what();
		EXPECT_NE(std::string(e.what()).find(std::strerror(ENOSPC)), std::string::npos) << e.what();
	}
	EXPECT_EQ(read("trajectory.tum"), trajectoryBefore);
	EXPECT_EQ(read("loops.txt"), loopsBefore);
	for (const auto& e : fs::directory_iterator(dir.path()))
		EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
	// What rasterslam run does then: the other outputs, without loops.txt (none of this run).
	io::writeRunOutputs(dir.path().string(), next, info, nullptr);
	EXPECT_NE(read("trajectory.tum"), trajectoryBefore);
	EXPECT_FALSE(fs::exists(dir / "loops.txt"));
}

TEST(RunOutputs, TheSpoolIsAnUnnamedFileInTheFolderAsked)
{
	// TMPDIR or a folder given: glibc's tmpfile() would use /tmp whatever TMPDIR says.
	const test::ScopedTempDir dir("run-outputs-spool-dir");
	{
		io::LoopDecisionSpool spool(dir.path().string());
		LoopDecision l;
		l.inliers = 17;
		spool.append({l, l});
		EXPECT_TRUE(fs::is_empty(dir.path()));  // no name left behind, even while it is open
		EXPECT_EQ(spool.finish(), "");
		std::string out;
		spool.copyTo(out, [] {});
		std::string line;
		io::appendLoopLine(line, l);
		EXPECT_EQ(out, line + line);
	}
	try
	{
		io::LoopDecisionSpool none((dir / "no-such-folder").string());
		ADD_FAILURE() << "a spool in a folder that does not exist";
	}
	catch (const std::runtime_error& e)
	{
		EXPECT_NE(std::string(e.what()).find("no-such-folder"), std::string::npos) << e.what();
	}
}

TEST(RunOutputs, LostScanRecordsCostThePerScanFilesOnly)
{
	// The scan records' temporary file could not be written (a full disk): the run has no
	// trajectory to give, but loops.txt, the pose graph and run.yaml (with the reason) are
	// still written, and the per-scan files of an earlier run are removed, not left to be
	// taken for this run's.
	if (!fs::exists("/dev/full"))
		GTEST_SKIP() << "no /dev/full on this system";
	const test::ScopedTempDir dir("run-outputs-lost-records");
	const mrpt::containers::yaml info = mrpt::containers::yaml::Map();
	{
		RunResult earlier;
		ScanRecord r;
		earlier.scans.push_back(r);
		earlier.poses.emplace_back();
		io::writeRunOutputs(dir.path().string(), earlier, info);
	}
	ASSERT_TRUE(fs::exists(dir / "trajectory.tum"));
	ASSERT_TRUE(fs::exists(dir / "timings.csv"));

	const int fd = ::open("/dev/full", O_RDWR);
	ASSERT_GE(fd, 0) << std::strerror(errno);
	RunResult res;
	res.scans = ScanLog::onDescriptor(fd);  // owns it from here
	for (std::size_t i = 0; i < 300; i++)
	{
		ScanRecord r;
		r.index = i;
		res.scans.push_back(r);
	}
	ASSERT_NE(res.scans.error(), "");
	LoopDecision l;
	l.inliers = 31;
	res.loopDecisions.push_back(l);
	// Without the run's error saying why, that is a caller's mistake: refused, nothing written.
	EXPECT_THROW(io::writeRunOutputs(dir.path().string(), res, info), std::runtime_error);
	EXPECT_TRUE(fs::exists(dir / "trajectory.tum"));
	EXPECT_FALSE(fs::exists(dir / "loops.txt"));

	res.error = res.scans.error();  // as the engine sets it
	mrpt::containers::yaml failed = mrpt::containers::yaml::Map();
	failed["error"] = res.error;
	io::writeRunOutputs(dir.path().string(), res, failed);
	for (const char* gone :
	     {"trajectory.tum", "trajectory.kitti", "trajectory_online.tum", "timings.csv"})
		EXPECT_FALSE(fs::exists(dir / gone)) << gone;
	for (const char* kept : {"loops.txt", "pose_graph.graph", "run.yaml"})
		EXPECT_TRUE(fs::exists(dir / kept)) << kept;
	std::ifstream y(dir / "run.yaml");
	const std::string yaml(std::istreambuf_iterator<char>(y), {});
	EXPECT_NE(yaml.find("could not be kept in a temporary file"), std::string::npos) << yaml;
	for (const auto& e : fs::directory_iterator(dir.path()))
		EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}
