// ScanLog: the per-scan records of a run, in memory or in an unnamed temporary file.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <rasterslam/core/scan_log.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>

#include "test_support.h"

namespace fs = std::filesystem;
using namespace rasterslam;

namespace
{
std::vector<ScanRecord> randomRecords(std::size_t n, unsigned seed)
{
	std::mt19937 rng(seed);
	std::uniform_real_distribution<double> u(-100, 100);
	std::vector<ScanRecord> out(n);
	for (std::size_t i = 0; i < n; i++)
	{
		auto& r = out[i];
		r.index = i * 3 + 1;
		r.stamp = 1000 + 0.1 * static_cast<double>(i);
		r.numPoints = static_cast<std::size_t>(rng() % 120000);
		r.status = (i % 7 == 0) ? TrackingStatus::Lost : TrackingStatus::Ok;
		r.inliers = rng() % 500;
		r.keyframe = i % 5 == 0;
		r.kfNode = i / 5;
		r.T_kf_scan = mrpt::math::TPose3D(u(rng), u(rng), u(rng), 0.1, 0.2, 0.3);
		r.onlinePose = mrpt::math::TPose3D(u(rng), u(rng), u(rng), -0.1, 0, 0.3);
		r.ms.total = u(rng);
		r.ms.mapping = u(rng);
		r.rssMb = static_cast<float>(u(rng));
		if (i % 3 != 0)
			r.groundTruth = mrpt::math::TPose3D(u(rng), 0, 0, 0, 0, 0);
	}
	return out;
}

// Field by field: padding bytes are not part of a record's value.
void expectSame(const ScanRecord& a, const ScanRecord& b, std::size_t i)
{
	EXPECT_EQ(a.index, b.index) << i;
	EXPECT_EQ(a.stamp, b.stamp) << i;
	EXPECT_EQ(a.numPoints, b.numPoints) << i;
	EXPECT_EQ(a.status, b.status) << i;
	EXPECT_EQ(a.inliers, b.inliers) << i;
	EXPECT_EQ(a.keyframe, b.keyframe) << i;
	EXPECT_EQ(a.kfNode, b.kfNode) << i;
	EXPECT_EQ(a.T_kf_scan, b.T_kf_scan) << i;
	EXPECT_EQ(a.onlinePose, b.onlinePose) << i;
	EXPECT_EQ(a.ms.total, b.ms.total) << i;
	EXPECT_EQ(a.ms.mapping, b.ms.mapping) << i;
	EXPECT_EQ(a.rssMb, b.rssMb) << i;
	ASSERT_EQ(a.groundTruth.has_value(), b.groundTruth.has_value()) << i;
	if (a.groundTruth)
	{
		EXPECT_EQ(*a.groundTruth, *b.groundTruth) << i;
	}
}
}  // namespace

TEST(ScanLog, ASpooledLogGivesBackWhatAMemoryLogGives)
{
	// 1,000 records: four full writes to the file and 232 still buffered, so reading,
	// changing and iterating cross the boundary between the file and the buffer.
	const auto recs = randomRecords(1000, 7);
	const test::ScopedTempDir dir("scan-log");
	ScanLog mem;
	ScanLog spool = ScanLog::spooled(dir.path().string());
	EXPECT_FALSE(mem.isSpooled());
	EXPECT_TRUE(spool.isSpooled());
	for (const auto& r : recs)
	{
		mem.push_back(r);
		spool.push_back(r);
	}
	EXPECT_TRUE(fs::is_empty(dir.path()));  // no name left behind while it is open
	ASSERT_EQ(spool.size(), recs.size());
	EXPECT_EQ(spool.error(), "");
	for (std::size_t i : {0, 1, 255, 256, 767, 768, 999})
	{
		expectSame(spool[i], recs[i], i);
		expectSame(mem[i], recs[i], i);
	}
	expectSame(spool.front(), recs.front(), 0);
	expectSame(spool.back(), recs.back(), 999);
	EXPECT_THROW(spool[1000], std::out_of_range);

	// Changed in place, in the file (3) and in the buffer (990), as the engine adds the back
	// end's times at the end of a run.
	auto recs2 = recs;
	for (std::size_t i : {3, 990})
	{
		spool.modify(i, [](ScanRecord& r) { r.ms.loop += 2.5; });
		recs2[i].ms.loop += 2.5;
	}
	EXPECT_EQ(spool[3].ms.loop, recs2[3].ms.loop);
	EXPECT_EQ(spool[990].ms.loop, recs2[990].ms.loop);
	EXPECT_EQ(spool[4].ms.loop, recs2[4].ms.loop);  // its neighbour untouched

	// Every record in order, once; and the same after a move.
	ScanLog moved = std::move(spool);
	EXPECT_EQ(spool.size(), 0u);  // NOLINT(bugprone-use-after-move): a moved-from log is empty
	std::size_t n = 0;
	moved.forEach(
	    [&](const ScanRecord& r)
	    {
		    ASSERT_LT(n, recs2.size());
		    expectSame(r, recs2[n], n);
		    EXPECT_EQ(r.ms.loop, recs2[n].ms.loop) << n;
		    ++n;
	    });
	EXPECT_EQ(n, recs2.size());
}

TEST(ScanLog, AWriteThatFailsIsKeptAsTheReasonAndNoLostRecordIsGiven)
{
	// /dev/full: every write fails with ENOSPC, as on a full disk.
	if (!fs::exists("/dev/full"))
		GTEST_SKIP() << "no /dev/full on this system";
	const int fd = ::open("/dev/full", O_RDWR);
	ASSERT_GE(fd, 0) << std::strerror(errno);
	ScanLog log = ScanLog::onDescriptor(fd);  // owns it from here
	const auto recs = randomRecords(300, 3);
	for (const auto& r : recs)
		log.push_back(r);  // the 256th write fails: kept, not thrown
	EXPECT_EQ(log.size(), 300u);
	EXPECT_NE(log.error().find(std::strerror(ENOSPC)), std::string::npos) << log.error();
	EXPECT_NE(log.error().find("256 and any later are lost"), std::string::npos) << log.error();
	EXPECT_THROW(log[0], std::runtime_error);
	EXPECT_THROW(log.forEach([](const ScanRecord&) {}), std::runtime_error);
	expectSame(log[299], recs[299], 299);  // still buffered, not lost
}

TEST(ScanLog, NoTemporaryFileIsAClearError)
{
	const test::ScopedTempDir dir("scan-log-none");
	try
	{
		ScanLog::spooled((dir / "no-such-folder").string());
		ADD_FAILURE() << "a log in a folder that does not exist";
	}
	catch (const std::runtime_error& e)
	{
		EXPECT_NE(std::string(e.what()).find("no-such-folder"), std::string::npos) << e.what();
		EXPECT_NE(std::string(e.what()).find("scan records"), std::string::npos) << e.what();
	}
}

TEST(ScanLog, TheTemporaryFileIsInTmpdirAndHasNoName)
{
	// glibc's tmpfile() would put it in /tmp whatever TMPDIR says (often a RAM disk).
	const test::ScopedTempDir dir("scan-log-tmpdir");
	const char* old = std::getenv("TMPDIR");
	const std::string saved = old ? old : "";
	::setenv("TMPDIR", dir.path().c_str(), 1);
	int fd = -1;
	try
	{
		fd = openUnnamedTempFile("", "a test");
	}
	catch (...)
	{
	}
	if (old)
		::setenv("TMPDIR", saved.c_str(), 1);
	else
		::unsetenv("TMPDIR");
	ASSERT_GE(fd, 0);
	char target[4096] = {0};
	const ssize_t n =
	    ::readlink(("/proc/self/fd/" + std::to_string(fd)).c_str(), target, sizeof target - 1);
	::close(fd);
	ASSERT_GT(n, 0) << std::strerror(errno);
	const std::string where(target, static_cast<std::size_t>(n));
	EXPECT_EQ(where.rfind(dir.path().string() + "/rasterslam-", 0), 0u) << where;
	EXPECT_NE(where.find("(deleted)"), std::string::npos) << where;  // already unnamed
	EXPECT_TRUE(fs::is_empty(dir.path()));
}
