// Rawlog reading and writing: every observation type we read, both rawlog formats, gz and
// plain, ground-truth association, and damaged files.
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CFileOutputStream.h>
#include <mrpt/maps/CPointsMapXYZI.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement3D.h>
#include <mrpt/obs/CObservation3DRangeScan.h>
#include <mrpt/obs/CObservationPointCloud.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/obs/CObservationRotatingScan.h>
#include <mrpt/obs/CObservationVelodyneScan.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/io/rawlog_source.h>
#include <rasterslam/io/rawlog_writer.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "test_support.h"

using namespace rasterslam;
using namespace mrpt::obs;
namespace fs = std::filesystem;

namespace
{
const mrpt::poses::CPose3D kSensorPose(0.5, -0.2, 1.7, 0.1, 0.02, -0.03);

/** Observations of each type with known points; stamps 100.0, 100.1, ... */
std::vector<CObservation::Ptr> makeObservations(std::vector<std::vector<PointXYZI>>& expected)
{
	std::vector<CObservation::Ptr> out;
	auto stamp = [](int k) { return mrpt::Clock::fromDouble(100.0 + 0.1 * k); };
	auto expect =
	    [&](const std::vector<std::array<float, 4>>& local, const mrpt::poses::CPose3D& sp)
	{
		std::vector<PointXYZI> v;
		for (const auto& p : local)
		{
			double x, y, z;
			sp.composePoint(p[0], p[1], p[2], x, y, z);
			v.push_back({float(x), float(y), float(z), p[3]});
		}
		expected.push_back(v);
	};
	{  // 0: point cloud (XYZI) with a sensor pose
		auto o = CObservationPointCloud::Create();
		o->timestamp = stamp(0);
		o->sensorLabel = "LIDAR";
		o->sensorPose = kSensorPose;
		auto m = mrpt::maps::CPointsMapXYZI::Create();
		std::vector<std::array<float, 4>> pts = {
		    {1, 2, 3, 0.5f}, {-4, 5, -1, 0.25f}, {10, 0, 0, 1}};
		for (const auto& p : pts)
			m->insertPointRGB(p[0], p[1], p[2], p[3], 0, 0);
		o->pointcloud = m;
		out.push_back(o);
		expect(pts, kSensorPose);
	}
	{  // 1: Velodyne scan with its point cloud already generated
		auto o = CObservationVelodyneScan::Create();
		o->timestamp = stamp(1);
		o->sensorLabel = "LIDAR";
		o->sensorPose = kSensorPose;
		std::vector<std::array<float, 4>> pts = {{3, 1, 0.5f, 51 / 255.f},
		                                         {-2, -2, 0, 255 / 255.f}};
		for (const auto& p : pts)
		{
			o->point_cloud.x.push_back(p[0]);
			o->point_cloud.y.push_back(p[1]);
			o->point_cloud.z.push_back(p[2]);
			o->point_cloud.intensity.push_back(static_cast<uint8_t>(std::lround(p[3] * 255)));
		}
		out.push_back(o);
		expect(pts, kSensorPose);
	}
	{  // 2: rotating scan, 16 rows (VLP-16 table: -15..15 deg, row 0 lowest), 3 columns
		auto o = CObservationRotatingScan::Create();
		o->timestamp = stamp(2);
		o->sensorLabel = "LIDAR";
		o->sensorPose = kSensorPose;
		o->rowCount = 16;
		o->columnCount = 3;
		o->rangeResolution = 0.01;
		o->startAzimuth = -M_PI / 2;
		o->azimuthSpan = M_PI;  // columns at -90, 0, +90 deg
		o->rangeImage.setZero(16, 3);
		o->intensityImage.setZero(16, 3);
		o->rangeImage(8, 1) = 1000;  // row 8: +1 deg, 10 m straight ahead
		o->intensityImage(8, 1) = 255;
		o->rangeImage(0, 2) = 500;  // row 0: -15 deg, 5 m to the left
		out.push_back(o);
		const double e8 = 1.0 * M_PI / 180, e0 = -15.0 * M_PI / 180;
		expect({{float(10 * std::cos(e8)), 0, float(10 * std::sin(e8)), 1.0f},
		        {float(5 * std::cos(e0) * std::cos(M_PI / 2)), float(5 * std::cos(e0)),
		         float(5 * std::sin(e0)), 0}},
		       kSensorPose);
		// the rotating scan's points come row by row: row 0 first
		std::swap(expected.back()[0], expected.back()[1]);
	}
	{  // 3: 3D range scan with a point cloud
		auto o = CObservation3DRangeScan::Create();
		o->timestamp = stamp(3);
		o->sensorLabel = "LIDAR";
		o->sensorPose = kSensorPose;
		o->hasPoints3D = true;
		o->points3D_x = {1, 2};
		o->points3D_y = {0, -1};
		o->points3D_z = {4, 5};
		o->points3D_idxs_x = {0, 1};  // pixel coordinates, required by the serializer
		o->points3D_idxs_y = {0, 0};
		out.push_back(o);
		expect({{1, 0, 4, 0}, {2, -1, 5, 0}}, kSensorPose);
	}
	return out;
}

std::vector<Scan> readAll(const std::string& path, std::string* stopReason = nullptr)
{
	io::RawlogSource src(path);
	std::vector<Scan> scans;
	while (auto s = src.next())
		scans.push_back(std::move(*s));
	if (stopReason)
		*stopReason = src.stopReason();
	return scans;
}

void expectScans(const std::vector<Scan>& scans,
                 const std::vector<std::vector<PointXYZI>>& expected)
{
	ASSERT_EQ(scans.size(), expected.size());
	for (size_t k = 0; k < scans.size(); k++)
	{
		EXPECT_EQ(scans[k].index, k);
		EXPECT_NEAR(scans[k].stamp, 100.0 + 0.1 * k, 1e-6);
		ASSERT_EQ(scans[k].points.size(), expected[k].size()) << "scan " << k;
		for (size_t i = 0; i < expected[k].size(); i++)
		{
			EXPECT_NEAR(scans[k].points[i].x, expected[k][i].x, 1e-3) << k << "/" << i;
			EXPECT_NEAR(scans[k].points[i].y, expected[k][i].y, 1e-3) << k << "/" << i;
			EXPECT_NEAR(scans[k].points[i].z, expected[k][i].z, 1e-3) << k << "/" << i;
			EXPECT_NEAR(scans[k].points[i].intensity, expected[k][i].intensity, 1e-3)
			    << k << "/" << i;
		}
	}
}

template <class STREAM>
void writeObjects(const std::string& path,
                  const std::vector<mrpt::serialization::CSerializable::Ptr>& objs)
{
	STREAM f(path);
	auto arch = mrpt::serialization::archiveFrom(f);
	for (const auto& o : objs)
		arch << *o;
}
}  // namespace

TEST(Rawlog, ObservationsFormatEveryScanType)
{
	std::vector<std::vector<PointXYZI>> expected;
	const auto obs = makeObservations(expected);
	const auto dir = test::tempDir("rawlog");
	for (const bool gz : {false, true})
	{
		const auto path = (dir / (gz ? "obs.rawlog.gz" : "obs.rawlog")).string();
		std::vector<mrpt::serialization::CSerializable::Ptr> objs(obs.begin(), obs.end());
		if (gz)
			writeObjects<mrpt::io::CFileGZOutputStream>(path, objs);
		else
			writeObjects<mrpt::io::CFileOutputStream>(path, objs);
		SCOPED_TRACE(path);
		expectScans(readAll(path), expected);
	}
}

TEST(Rawlog, SensoryFrameFormatWithActionsAndGroundTruth)
{
	std::vector<std::vector<PointXYZI>> expected;
	const auto obs = makeObservations(expected);
	std::vector<mrpt::serialization::CSerializable::Ptr> objs;
	for (size_t k = 0; k < obs.size(); k++)
	{
		auto acts = CActionCollection::Create();
		CActionRobotMovement3D mov;
		mov.poseChange.mean = mrpt::poses::CPose3D(1, 0, 0, 0, 0, 0);
		acts->insert(mov);
		objs.push_back(acts);
		auto sf = CSensoryFrame::Create();
		sf->insert(obs[k]);
		if (k % 2 == 0)  // ground truth for every other scan, in the same frame
		{
			auto gt = CObservationRobotPose::Create();
			gt->timestamp = obs[k]->timestamp;
			gt->pose.mean = mrpt::poses::CPose3D(double(k), 2, 0, 0.1 * k, 0, 0);
			sf->insert(gt);
		}
		objs.push_back(sf);
	}
	const auto path = (test::tempDir("rawlog") / "sf.rawlog").string();
	writeObjects<mrpt::io::CFileGZOutputStream>(path, objs);
	const auto scans = readAll(path);
	expectScans(scans, expected);
	for (size_t k = 0; k < scans.size(); k++)
	{
		ASSERT_EQ(scans[k].groundTruth.has_value(), k % 2 == 0) << k;
		if (scans[k].groundTruth)
		{
			EXPECT_NEAR(scans[k].groundTruth->x(), double(k), 1e-9);
		}
	}
}

TEST(Rawlog, WriterRoundTripWithGroundTruthBeforeOrAfter)
{
	const auto dir = test::tempDir("rawlog");
	std::mt19937 rng(7);
	std::uniform_real_distribution<float> u(-50, 50);
	std::vector<Scan> in(5);
	for (size_t k = 0; k < in.size(); k++)
	{
		in[k].stamp = 1.7e9 + 0.1 * k;
		in[k].sensorLabel = "LIDAR";
		for (int i = 0; i < 200; i++)
			in[k].points.push_back({u(rng), u(rng), u(rng), 0.5f});
		in[k].groundTruth = mrpt::poses::CPose3D(k, -double(k), 0.5, 0.01 * k, 0, 0);
	}
	for (const int level : {0, 1})
	{
		const auto path = (dir / ("w" + std::to_string(level) + ".rawlog")).string();
		{
			io::RawlogWriter w(path, level);
			for (const auto& s : in)
				w.writeScan(s);
			EXPECT_FALSE(fs::exists(path));  // only the temporary file until close()
			w.close();
		}
		const auto out = readAll(path);
		ASSERT_EQ(out.size(), in.size());
		for (size_t k = 0; k < in.size(); k++)
		{
			EXPECT_NEAR(out[k].stamp, in[k].stamp, 1e-6);
			ASSERT_TRUE(out[k].groundTruth);
			EXPECT_NEAR(
			    (out[k].groundTruth->asVectorVal() - in[k].groundTruth->asVectorVal()).norm(), 0,
			    1e-9);
			ASSERT_EQ(out[k].points.size(), in[k].points.size());
			EXPECT_FLOAT_EQ(out[k].points[17].y, in[k].points[17].y);
		}
	}
	// Ground truth written before its scan is still attached to it.
	const auto path = (dir / "gtfirst.rawlog").string();
	{
		io::RawlogWriter w(path, 1);
		CObservationRobotPose gt;
		gt.timestamp = mrpt::Clock::fromDouble(in[0].stamp);
		gt.pose.mean = *in[0].groundTruth;
		w.write(gt);
		Scan s = in[0];
		s.groundTruth.reset();
		w.writeScan(s);
		w.close();
	}
	const auto out = readAll(path);
	ASSERT_EQ(out.size(), 1u);
	ASSERT_TRUE(out[0].groundTruth);
	EXPECT_NEAR(out[0].groundTruth->y(), in[0].groundTruth->y(), 1e-9);
}

TEST(Rawlog, UnclosedWriterLeavesNoFileAndKeepsTheOldOne)
{
	const auto dir = test::tempDir("rawlog");
	const auto path = (dir / "keep.rawlog").string();
	std::ofstream(path) << "old contents";
	{
		io::RawlogWriter w(path, 1);
		Scan s;
		s.points.push_back({1, 2, 3, 0});
		w.writeScan(s);
	}  // destroyed without close(): e.g. an exception
	std::ifstream f(path);
	std::string line;
	std::getline(f, line);
	EXPECT_EQ(line, "old contents");
	size_t files = 0;
	for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir))
		++files;
	EXPECT_EQ(files, 1u);  // no temporary left behind
}

TEST(Rawlog, TruncatedFileStopsAtTheDamageWithItsOffset)
{
	const auto dir = test::tempDir("rawlog");
	std::vector<Scan> in(6);
	for (size_t k = 0; k < in.size(); k++)
	{
		in[k].stamp = 10 + 0.1 * k;
		for (int i = 0; i < 1000; i++)
			in[k].points.push_back({float(i), float(k), 0, 0});
	}
	for (const int level : {0, 1})
	{
		const auto full = (dir / ("full" + std::to_string(level) + ".rawlog")).string();
		{
			io::RawlogWriter w(full, level);
			for (const auto& s : in)
				w.writeScan(s);
			w.close();
		}
		const auto size = fs::file_size(full);
		const auto cut = (dir / ("cut" + std::to_string(level) + ".rawlog")).string();
		fs::copy_file(full, cut);
		fs::resize_file(cut, size * 6 / 10);
		std::string reason;
		const auto scans = readAll(cut, &reason);
		SCOPED_TRACE("level " + std::to_string(level));
		EXPECT_GE(scans.size(), 2u);
		EXPECT_LT(scans.size(), in.size());
		EXPECT_NE(reason.find(cut), std::string::npos) << reason;
		EXPECT_NE(reason.find("byte"), std::string::npos) << reason;
		EXPECT_EQ(readAll(full).size(), in.size());
	}
}

TEST(Rawlog, ProgressIsTheShareOfTheFileReadGzipOrPlain)
{
	const test::ScopedTempDir dir("rawlog-progress");
	std::mt19937 rng(2);
	std::uniform_real_distribution<float> u(-30, 30);
	for (const int level : {0, 1})
	{
		SCOPED_TRACE("level " + std::to_string(level));
		const auto path = (dir / ("p" + std::to_string(level) + ".rawlog")).string();
		{
			io::RawlogWriter w(path, level);
			for (int k = 0; k < 120; k++)
			{
				Scan s;
				s.stamp = 1 + 0.1 * k;
				for (int i = 0; i < 5000; i++)
					s.points.push_back({u(rng), u(rng), u(rng), 0});
				w.writeScan(s);
			}
			w.close();
		}
		io::RawlogSource src(path);
		double last = 0;
		std::vector<double> seen;
		while (src.next())
		{
			const double p = src.progress();
			EXPECT_GE(p, last);
			EXPECT_LE(p, 1.0);
			seen.push_back(p);
			last = p;
		}
		ASSERT_EQ(seen.size(), 120u);
		// About proportional to the scans read (equal scans), read-ahead aside (a scan or two
		// and zlib's 256 kB buffer).
		EXPECT_NEAR(seen[59], 0.5, 0.08);
		EXPECT_NEAR(seen[29], 0.25, 0.08);
		EXPECT_NEAR(src.progress(), 1.0, 1e-9);
	}
}

TEST(Rawlog, BadFilesThrowNamingTheFile)
{
	const auto dir = test::tempDir("rawlog");
	auto errorOf = [](const std::string& path) -> std::string
	{
		try
		{
			readAll(path);
		}
		catch (const std::exception& e)
		{
			return e.what();
		}
		return "";
	};
	const auto missing = (dir / "missing.rawlog").string();
	EXPECT_NE(errorOf(missing).find("cannot open rawlog '" + missing + "': no such file"),
	          std::string::npos);
	const auto garbage = (dir / "garbage.rawlog").string();
	{
		std::ofstream f(garbage, std::ios::binary);
		std::mt19937 rng(3);
		for (int i = 0; i < 5000; i++)
			f.put(static_cast<char>(rng()));
	}
	const auto e = errorOf(garbage);
	EXPECT_NE(e.find(garbage + ": not an MRPT rawlog"), std::string::npos) << e;
	const auto empty = (dir / "empty.rawlog").string();
	std::ofstream(empty).close();
	EXPECT_NE(errorOf(empty).find("empty file"), std::string::npos) << errorOf(empty);
}

// A sensory frame (or action collection) whose count is damaged stops the reading at once with
// the count named, before MRPT sizes a container by it (a count of 2^31 asked for gigabytes of
// blocks until the memory cap; this test uses 2^20, harmless even without the check).
TEST(Rawlog, DamagedFrameCountIsRefusedBeforeMrptAllocates)
{
	std::vector<std::vector<PointXYZI>> expected;
	const auto obs = makeObservations(expected);
	const auto dir = test::tempDir("rawlog");
	for (const std::string cls : {"CSensoryFrame", "CActionCollection"})
	{
		std::vector<mrpt::serialization::CSerializable::Ptr> objs;
		for (size_t k = 0; k < 2; k++)
		{
			auto acts = CActionCollection::Create();
			CActionRobotMovement3D mov;
			acts->insert(mov);
			objs.push_back(acts);
			auto sf = CSensoryFrame::Create();
			sf->insert(obs[k]);
			objs.push_back(sf);
		}
		const auto path = (dir / ("count-" + cls + ".rawlog")).string();
		writeObjects<mrpt::io::CFileOutputStream>(path, objs);
		std::string bytes;
		{
			std::ifstream in(path, std::ios::binary);
			bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
		}
		// The second object of that class: its name, one version byte, then the count.
		auto pos = bytes.find(cls);
		pos = bytes.find(cls, pos + 1);
		ASSERT_NE(pos, std::string::npos);
		const std::size_t at = pos + cls.size() + 1;
		uint32_t count = 0;
		std::memcpy(&count, bytes.data() + at, 4);
		ASSERT_EQ(count, 1u) << "the layout this test expects";
		const uint32_t damaged = 1u << 20;
		std::memcpy(bytes.data() + at, &damaged, 4);
		std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;

		io::RawlogSource src(path);
		std::size_t scans = 0;
		while (src.next())
			++scans;
		EXPECT_EQ(scans, 1u) << cls;  // the first frame's scan, then the damaged one
		EXPECT_NE(src.stopReason().find(path), std::string::npos) << src.stopReason();
		EXPECT_NE(src.stopReason().find("a " + cls + " claims 1048576 entries"), std::string::npos)
		    << src.stopReason();
	}
}
