// The map model (libs/map): every class through MRPT serialization with its version check,
// and the map file: a round trip with poses from a PoseView, damage and old versions refused
// with the file named.
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/map/local_map_store.h>
#include <rasterslam/map/map.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstring>
#include <fstream>
#include <random>
#include <set>
#include <thread>

#include "test_support.h"

using namespace rasterslam;
namespace fs = std::filesystem;

namespace
{
LocalMap::Ptr makeLocalMap(uint64_t id, std::vector<uint64_t> kfs, std::mt19937& rng)
{
	auto lm = std::make_shared<LocalMap>();
	lm->id = id;
	lm->session = 2;
	lm->keyframes = std::move(kfs);
	lm->createdStamp = 100.5 + static_cast<double>(id);
	lm->updatedStamp = lm->createdStamp + 2.25;
	lm->online = true;
	std::uniform_real_distribution<float> u(-30, 30);
	for (int i = 0; i < 50; i++)
	{
		lm->xyz.insert(lm->xyz.end(), {u(rng), u(rng), u(rng) / 10});
		for (int b = 0; b < 32; b++)
			lm->descriptors.push_back(static_cast<uint8_t>(rng()));
		lm->observers.push_back(1u + (static_cast<uint32_t>(rng()) & 6u));
	}
	lm->imagePng = {0x89, 'P', 'N', 'G', 1, 2, 3};
	lm->imageResolution_m = 0.2f;
	lm->imageExtent_m = 60;
	lm->baTracks = 17;
	lm->baInitialRms_m = 0.12f;
	lm->baFinalRms_m = 0.05f;
	std::uniform_int_distribution<int> cm(-3000, 3000);
	for (int i = 0; i < 3 * 40; i++)
		lm->surfaceCm.push_back(static_cast<int16_t>(cm(rng)));
	lm->contextRings = 3;
	lm->contextSectors = 4;
	for (std::size_t i = 0; i < 12 * lm->keyframes.size(); i++)
		lm->contextCells.push_back(static_cast<uint8_t>(rng() % 7 == 0 ? 0 : rng()));
	return lm;
}

template <class T>
std::shared_ptr<T> roundTrip(const T& obj, mrpt::io::CMemoryStream& buf)
{
	auto a = mrpt::serialization::archiveFrom(buf);
	a << obj;
	buf.Seek(0);
	return std::dynamic_pointer_cast<T>(a.ReadObject());
}

/** Sets the version byte after the class name in MRPT's object header. */
void setVersion(mrpt::io::CMemoryStream& buf, const std::string& cls, uint8_t expected, uint8_t v)
{
	auto* bytes = static_cast<uint8_t*>(buf.getRawBufferData());
	const std::string raw(reinterpret_cast<const char*>(bytes), buf.getTotalBytesCount());
	const auto at = raw.find(cls);
	ASSERT_NE(at, std::string::npos);
	ASSERT_EQ(bytes[at + cls.size()], expected);
	bytes[at + cls.size()] = v;
	buf.Seek(0);
}
}  // namespace

TEST(MapModel, LocalMapRoundTripAndVersion)
{
	std::mt19937 rng(7);
	const auto lm = makeLocalMap(4, {10, 11, 12}, rng);
	mrpt::io::CMemoryStream buf;
	const auto back = roundTrip(*lm, buf);
	ASSERT_TRUE(back);
	EXPECT_TRUE(*back == *lm);
	EXPECT_EQ(back->points(), 50u);
	EXPECT_EQ(back->anchor(), 10u);
	EXPECT_EQ(back->keyframeIndex(12), 2);
	EXPECT_EQ(back->keyframeIndex(13), -1);
	LocalMap other = *lm;
	other.online = false;
	EXPECT_FALSE(other == *lm);  // ...and at the online flag
	other = *lm;
	other.observers[3] ^= 8;
	EXPECT_FALSE(other == *lm);  // operator== looks at the observers
	other = *lm;
	other.surfaceCm[5] += 1;
	EXPECT_FALSE(other == *lm);  // ...and at the surface
	other = *lm;
	other.contextCells[7] ^= 1;
	EXPECT_FALSE(other == *lm);  // ...and at the polar contexts
	EXPECT_EQ(back->surfacePoints(), 40u);
	EXPECT_EQ(back->contexts(), 3u);  // one about each keyframe

	setVersion(buf, "rasterslam::LocalMap", 2, 7);
	auto a = mrpt::serialization::archiveFrom(buf);
	EXPECT_ANY_THROW(a.ReadObject());

	// Inconsistent arrays and an empty keyframe label are refused on reading.
	LocalMap bad = *lm;
	bad.descriptors.pop_back();
	mrpt::io::CMemoryStream b2;
	EXPECT_ANY_THROW(roundTrip(bad, b2));
	LocalMap bad2 = *lm;
	bad2.keyframes.clear();
	mrpt::io::CMemoryStream b3;
	EXPECT_ANY_THROW(roundTrip(bad2, b3));
	LocalMap bad3 = *lm;
	bad3.surfaceCm.pop_back();
	mrpt::io::CMemoryStream b4;
	EXPECT_ANY_THROW(roundTrip(bad3, b4));
	// Polar contexts that are not one a keyframe, or cells of no dimensions.
	LocalMap bad4 = *lm;
	bad4.contextCells.resize(24);
	mrpt::io::CMemoryStream b5;
	EXPECT_ANY_THROW(roundTrip(bad4, b5));
	LocalMap bad5 = *lm;
	bad5.contextSectors = 0;
	mrpt::io::CMemoryStream b6;
	EXPECT_ANY_THROW(roundTrip(bad5, b6));
}

TEST(MapModel, LocalMapOfVersion0LoadsWithoutSurface)
{
	// Maps written before the surfaces (version 0) still load: the same stream without the
	// surface's length (the last field, before MRPT's end-of-object byte) and with version 0.
	std::mt19937 rng(8);
	auto lm = makeLocalMap(5, {20, 21}, rng);
	lm->surfaceCm.clear();
	lm->contextRings = lm->contextSectors = 0;
	lm->contextCells.clear();
	mrpt::io::CMemoryStream buf;
	mrpt::serialization::archiveFrom(buf) << *lm;
	setVersion(buf, "rasterslam::LocalMap", 2, 0);
	const auto* p = static_cast<const uint8_t*>(buf.getRawBufferData());
	std::vector<uint8_t> v0(p, p + buf.getTotalBytesCount());
	// The empty surface's length (4 bytes), the contexts' dimensions (2 + 2) and their cells'
	// length (4), all 0, then MRPT's end-of-object byte.
	ASSERT_GE(v0.size(), 13u);
	for (std::size_t i = v0.size() - 13; i + 1 < v0.size(); i++)
		ASSERT_EQ(v0[i], 0u);
	v0.erase(v0.end() - 13, v0.end() - 1);
	mrpt::io::CMemoryStream in;
	in.assignMemoryNotOwn(v0.data(), v0.size());
	const auto back =
	    std::dynamic_pointer_cast<LocalMap>(mrpt::serialization::archiveFrom(in).ReadObject());
	ASSERT_TRUE(back);
	EXPECT_TRUE(*back == *lm);
	EXPECT_EQ(back->surfacePoints(), 0u);

	// Version 1 (surfaces, no polar contexts): the same without the contexts' 8 bytes.
	std::vector<uint8_t> v1(p, p + buf.getTotalBytesCount());
	const std::string raw(v1.begin(), v1.end());
	const auto at = raw.find("rasterslam::LocalMap");
	ASSERT_NE(at, std::string::npos);
	v1[at + std::string("rasterslam::LocalMap").size()] = 1;
	v1.erase(v1.end() - 9, v1.end() - 1);
	mrpt::io::CMemoryStream in1;
	in1.assignMemoryNotOwn(v1.data(), v1.size());
	const auto back1 =
	    std::dynamic_pointer_cast<LocalMap>(mrpt::serialization::archiveFrom(in1).ReadObject());
	ASSERT_TRUE(back1);
	EXPECT_TRUE(*back1 == *lm);
	EXPECT_EQ(back1->contexts(), 0u);
}

TEST(MapModel, DamagedOnlineFlagIsRefusedNotUndefined)
{
	// Found by fuzz_map_store: a bool read from a damaged file held 33 (undefined behaviour).
	std::mt19937 rng(6);
	auto lm = makeLocalMap(3, {1, 2}, rng);
	const auto bytesOf = [&](bool online)
	{
		lm->online = online;
		mrpt::io::CMemoryStream buf;
		mrpt::serialization::archiveFrom(buf) << *lm;
		const auto* p = static_cast<const uint8_t*>(buf.getRawBufferData());
		return std::vector<uint8_t>(p, p + buf.getTotalBytesCount());
	};
	const auto on = bytesOf(true), off = bytesOf(false);
	ASSERT_EQ(on.size(), off.size());
	std::size_t at = on.size();
	for (std::size_t i = 0; i < on.size(); i++)
		if (on[i] != off[i])
		{
			ASSERT_EQ(at, on.size()) << "one byte differs";
			at = i;
		}
	ASSERT_LT(at, on.size());
	auto bad = on;
	bad[at] = 33;
	mrpt::io::CMemoryStream in;
	in.assignMemoryNotOwn(bad.data(), bad.size());
	try
	{
		mrpt::serialization::archiveFrom(in).ReadObject();
		ADD_FAILURE() << "no error";
	}
	catch (const std::exception& e)
	{
		EXPECT_NE(std::string(e.what()).find("online flag 33 is not 0 or 1"), std::string::npos)
		    << e.what();
	}
}

TEST(MapModel, LocalMapGraphRoundTripAndVersion)
{
	LocalMapGraph g;
	g.add(0, 1, LocalMapGraph::EdgeKind::Sequential, 10);
	g.add(1, 2, LocalMapGraph::EdgeKind::Sequential, 12);
	g.add(0, 2, LocalMapGraph::EdgeKind::Loop, 12.5);
	g.add(2, 3, LocalMapGraph::EdgeKind::Relocalization, 20);
	mrpt::io::CMemoryStream buf;
	const auto back = roundTrip(g, buf);
	ASSERT_TRUE(back);
	EXPECT_TRUE(*back == g);
	EXPECT_EQ(back->count(LocalMapGraph::EdgeKind::Sequential), 2u);
	EXPECT_EQ(back->count(LocalMapGraph::EdgeKind::Loop), 1u);
	EXPECT_EQ(back->edges[3].kind, LocalMapGraph::EdgeKind::Relocalization);
	setVersion(buf, "rasterslam::LocalMapGraph", 0, 1);
	auto a = mrpt::serialization::archiveFrom(buf);
	EXPECT_ANY_THROW(a.ReadObject());
}

TEST(MapModel, PoseViewPrefersTheLiveGraph)
{
	std::map<uint64_t, mrpt::poses::CPose3D> live{{5, mrpt::poses::CPose3D(1, 0, 0, 0, 0, 0)}};
	std::map<uint64_t, mrpt::poses::CPose3D> prior{{5, mrpt::poses::CPose3D(9, 0, 0, 0, 0, 0)},
	                                               {2, mrpt::poses::CPose3D(0, 3, 0, 0, 0, 0)}};
	PoseView v;
	v.live = [&](uint64_t id) -> const mrpt::poses::CPose3D*
	{
		const auto it = live.find(id);
		return it == live.end() ? nullptr : &it->second;
	};
	v.prior = &prior;
	EXPECT_DOUBLE_EQ(v.at(5).x(), 1);
	EXPECT_DOUBLE_EQ(v.at(2).y(), 3);
	EXPECT_FALSE(v(8).has_value());
	EXPECT_THROW(v.at(8), std::runtime_error);
}

TEST(MapModel, MapFileRoundTrip)
{
	const test::ScopedTempDir dir("map");
	std::mt19937 rng(11);
	Map m;
	m.sessions = 3;
	std::map<uint64_t, mrpt::poses::CPose3D> live;
	for (uint64_t k = 0; k < 9; k++)
	{
		auto kf = std::make_shared<Keyframe>();
		kf->id = k;
		kf->session = k < 5 ? 1 : 2;
		kf->scanIndex = 3 * k;
		kf->stamp = 100 + static_cast<double>(k);
		m.keyframes[k] = kf;
		live[k] = mrpt::poses::CPose3D(static_cast<double>(k), 0.5 * static_cast<double>(k), 0,
		                               0.1 * static_cast<double>(k), 0, 0);
	}
	m.localMaps[0] = makeLocalMap(0, {0, 1, 2, 3, 4}, rng);
	m.localMaps[1] = makeLocalMap(1, {4, 5, 6, 7, 8}, rng);
	m.graph.add(0, 1, LocalMapGraph::EdgeKind::Sequential, 104);
	m.placeIndexClass = "some::Index";
	m.placeIndex = {1, 2, 3, 4, 5};
	m.sessionRecords[2] = {2, 1.7e9, "2026-11-29T10:00:00Z", "VELODYNE", "/data/drive 2.rawlog"};
	EXPECT_EQ(m.nextKeyframeId(), 9u);
	EXPECT_EQ(m.nextLocalMapId(), 2u);
	EXPECT_EQ(m.localMapsOf(4), (std::vector<uint64_t>{0, 1}));
	PoseView v;
	v.live = [&](uint64_t id) -> const mrpt::poses::CPose3D*
	{
		const auto it = live.find(id);
		return it == live.end() ? nullptr : &it->second;
	};
	saveMap(m, v, dir.path().string());
	EXPECT_TRUE(fs::exists(dir / "localmaps/0001.png"));
	const Map back = loadMap(dir.path().string());
	EXPECT_EQ(back.sessions, 3u);
	ASSERT_EQ(back.keyframes.size(), 9u);
	ASSERT_EQ(back.localMaps.size(), 2u);
	// Labels in memory, points and image read from the map's store when needed.
	EXPECT_FALSE(back.localMaps.at(1)->hasData());
	EXPECT_FALSE(back.localMaps.at(1)->online);
	EXPECT_EQ(back.localMaps.at(1)->keyframes, m.localMaps.at(1)->keyframes);
	EXPECT_EQ(back.saved.at(1).points, 50u);
	EXPECT_TRUE(*back.data(1) == *m.localMaps.at(1));
	EXPECT_TRUE(back.graph == m.graph);
	EXPECT_EQ(back.placeIndexClass, "some::Index");
	EXPECT_EQ(back.placeIndex, m.placeIndex);
	EXPECT_EQ(back.sessionRecords, m.sessionRecords);
	EXPECT_EQ(back.onlineWhenSaved, (std::set<uint64_t>{0, 1}));
	// Poses were taken from the view at saving time and come back as the prior map's.
	for (const auto& [k, p] : live)
	{
		ASSERT_TRUE(back.priorPoses.count(k));
		EXPECT_LT((back.priorPoses.at(k).asVectorVal() - p.asVectorVal()).norm(), 1e-9);
		EXPECT_EQ(back.keyframes.at(k)->session, m.keyframes.at(k)->session);
	}
	// No stray temporary files.
	for (const auto& e : fs::recursive_directory_iterator(dir.path()))
		EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();

	// Saved over itself, a loaded map writes no local map again; one it no longer has leaves
	// the store.
	auto storeFiles = [&]
	{
		std::set<std::string> names;
		for (const auto& e : fs::directory_iterator(dir / "store"))
			names.insert(e.path().filename().string());
		return names;
	};
	const auto files = storeFiles();
	ASSERT_EQ(files.size(), 2u);
	Map again = loadMap(dir.path().string());
	PoseView pv;
	pv.prior = &again.priorPoses;
	saveMap(again, pv, dir.path().string());
	EXPECT_EQ(storeFiles(), files);
	again.localMaps.erase(1);
	saveMap(again, pv, dir.path().string());
	EXPECT_EQ(storeFiles().size(), 1u);
	EXPECT_FALSE(fs::exists(dir / "localmaps/0001.png"));
	saveMap(m, v, dir.path().string());

	// A keyframe without a pose cannot be saved, and the previous map stays loadable.
	live.erase(8);
	EXPECT_THROW(saveMap(m, v, dir.path().string()), std::runtime_error);
	EXPECT_EQ(loadMap(dir.path().string()).keyframes.size(), 9u);
}

TEST(MapModel, ASaveKilledMidwayLeavesThePreviousMapLoadable)
{
	const test::ScopedTempDir dir("map");
	std::mt19937 rng(5);
	// The previous map: 2 local maps. The new one: 60 local maps of 50 points and 241 keyframes
	// with features (a save of a few hundred ms), killed at seeded moments along the way.
	auto makeMap = [&](std::size_t localMaps)
	{
		Map m;
		m.sessions = 3;
		for (uint64_t k = 0; k <= 4 * localMaps; k++)
		{
			auto kf = std::make_shared<Keyframe>();
			kf->id = k;
			kf->stamp = static_cast<double>(k);
			// Features make the file big enough to be caught in the middle.
			const std::size_t n = 1500;
			kf->u.assign(n, 1.f);
			kf->v.assign(n, 2.f);
			kf->angle.assign(n, 0.f);
			kf->response.assign(n, 1.f);
			kf->octave.assign(n, 0);
			kf->xyz.assign(3 * n, 0.5f);
			kf->descriptors.resize(32 * n);
			for (auto& b : kf->descriptors)
				b = static_cast<uint8_t>(rng());
			m.keyframes[k] = kf;
			m.priorPoses[k] = mrpt::poses::CPose3D(static_cast<double>(k), 0, 0, 0, 0, 0);
		}
		for (uint64_t i = 0; i < localMaps; i++)
			m.localMaps[i] = makeLocalMap(i, {4 * i, 4 * i + 1, 4 * i + 4}, rng);
		return m;
	};
	const Map before = makeMap(2), after = makeMap(60);
	PoseView pb, pa;
	pb.prior = &before.priorPoses;
	pa.prior = &after.priorPoses;
	saveMap(before, pb, dir.path().string());
	const auto t0 = std::chrono::steady_clock::now();
	saveMap(after, pa, dir.path().string());
	const double saveMs =
	    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
	saveMap(before, pb, dir.path().string());

	std::uniform_real_distribution<double> when(0.0, 2.5);
	std::size_t sawOld = 0, sawNew = 0;
	for (int trial = 0; trial < 8; trial++)
	{
		const pid_t child = ::fork();
		ASSERT_GE(child, 0);
		if (child == 0)
		{
			try
			{
				saveMap(after, pa, dir.path().string());
			}
			catch (...)
			{
				::_exit(3);
			}
			::_exit(0);
		}
		std::this_thread::sleep_for(
		    std::chrono::microseconds(static_cast<int64_t>(1000 * saveMs * when(rng))));
		::kill(child, SIGKILL);
		int status = 0;
		::waitpid(child, &status, 0);
		// Whatever the moment: a whole map, the old or the new one.
		const Map m = loadMap(dir.path().string());
		ASSERT_TRUE(m.localMaps.size() == 2 || m.localMaps.size() == 60) << m.localMaps.size();
		for (const auto& [id, lm] : m.localMaps)
			EXPECT_EQ(m.data(id)->points(), 50u) << id;
		(m.localMaps.size() == 2 ? sawOld : sawNew)++;
		if (m.localMaps.size() == 60)
			saveMap(before, pb, dir.path().string());
	}
	// Both outcomes happened (the kill times span the save), and the next save cleared what
	// the killed ones left.
	EXPECT_GT(sawOld, 0u);
	saveMap(before, pb, dir.path().string());
	for (const auto& e : fs::directory_iterator(dir.path()))
		EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
	std::printf("save %.0f ms; killed saves left the old map %zu times, the new one %zu times\n",
	            saveMs, sawOld, sawNew);
}

TEST(MapModel, DamagedAndOldMapsAreRefused)
{
	const test::ScopedTempDir dir("map");
	const auto file = mapFilePath(dir.path().string());
	auto expectError = [&](const std::string& what)
	{
		try
		{
			loadMap(dir.path().string());
			ADD_FAILURE() << "no error";
		}
		catch (const std::runtime_error& e)
		{
			const std::string msg = e.what();
			EXPECT_NE(msg.find(what), std::string::npos) << msg;
		}
	};
	expectError("does not exist");
	std::ofstream(file) << "not a map";
	expectError("cannot read map '" + file + "'");
	{
		// A version-0 file, as the loop detector wrote it before the map model.
		mrpt::io::CFileGZOutputStream f(file);
		auto a = mrpt::serialization::archiveFrom(f);
		a << uint32_t(0x504d5352) << uint8_t(0);
	}
	expectError("build the map again");
	fs::remove(file);
	fs::create_directories(file);
	expectError("is not a file");
}

TEST(MapModel, DamagedIndexIsRefusedByItsChecksumLengthOrEnd)
{
	const test::ScopedTempDir dir("map-crc");
	std::mt19937 rng(4);
	Map m;
	m.sessions = 3;  // makeLocalMap's local maps are of session 2
	for (uint64_t k = 0; k < 5; k++)
	{
		auto kf = std::make_shared<Keyframe>();
		kf->id = k;
		m.keyframes[k] = kf;
		m.priorPoses[k] = mrpt::poses::CPose3D(static_cast<double>(k), 0, 0, 0, 0, 0);
	}
	m.localMaps[0] = makeLocalMap(0, {0, 1, 2, 3, 4}, rng);
	PoseView v;
	v.prior = &m.priorPoses;
	const auto d = dir.path().string();
	saveMap(m, v, d);
	ASSERT_NO_THROW(loadMap(d));
	const auto file = mapFilePath(d);
	// The index uncompressed: magic (4), version (1), body length (8), CRC-32 (4), body.
	std::vector<uint8_t> raw;
	{
		mrpt::io::CFileGZInputStream f(file);
		uint8_t buf[4096];
		for (std::size_t n; (n = f.Read(buf, sizeof buf)) > 0;)
			raw.insert(raw.end(), buf, buf + n);
	}
	ASSERT_GT(raw.size(), 17u);
	EXPECT_EQ(raw[4], 4) << "index version";
	uint64_t bodyLength = 0;
	std::memcpy(&bodyLength, raw.data() + 5, 8);
	EXPECT_EQ(bodyLength, raw.size() - 17);
	auto write = [&](const std::vector<uint8_t>& bytes)
	{
		mrpt::io::CFileGZOutputStream f(file);
		f.Write(bytes.data(), bytes.size());
	};
	auto errorOf = [&]() -> std::string
	{
		try
		{
			loadMap(d);
		}
		catch (const std::runtime_error& e)
		{
			return e.what();
		}
		return "";
	};
	// One bit flipped anywhere in the body (seeded positions): refused, the file named.
	std::uniform_int_distribution<std::size_t> pos(17, raw.size() - 1);
	for (int i = 0; i < 20; i++)
	{
		auto bad = raw;
		bad[pos(rng)] ^= static_cast<uint8_t>(1u << (i % 8));
		write(bad);
		const auto msg = errorOf();
		EXPECT_NE(msg.find("cannot read map '" + file + "': checksum mismatch"), std::string::npos)
		    << msg;
	}
	// Cut short, a huge length, and bytes past the end.
	write(std::vector<uint8_t>(raw.begin(), raw.end() - 10));
	EXPECT_NE(errorOf().find("truncated"), std::string::npos) << errorOf();
	auto huge = raw;
	const uint64_t big = uint64_t(1) << 40;
	std::memcpy(huge.data() + 5, &big, 8);
	write(huge);
	EXPECT_NE(errorOf().find("damaged header"), std::string::npos) << errorOf();
	write(raw);
	EXPECT_EQ(errorOf(), "");
}

TEST(MapModel, OfflineStoreRoundTripChecksumAndOnDemandLoading)
{
	const test::ScopedTempDir dir("store");
	std::mt19937 rng(5);
	const LocalMapStore store((dir / "offline").string());
	auto lm = makeLocalMap(12, {40, 41, 42}, rng);
	lm->online = false;
	EXPECT_FALSE(store.contains(12));
	EXPECT_GT(store.save(*lm), 50u * (12 + 32 + 4));
	EXPECT_TRUE(store.contains(12));
	const auto back = store.load(12);
	EXPECT_TRUE(*back == *lm);
	for (const auto& e : fs::directory_iterator(store.dir()))
		EXPECT_EQ(e.path().filename().string(), "000012.rslm");  // no temporary left

	auto expectError = [&](uint64_t id, const std::string& what)
	{
		try
		{
			store.load(id);
			ADD_FAILURE() << "no error";
		}
		catch (const std::runtime_error& e)
		{
			const std::string msg = e.what();
			EXPECT_NE(msg.find(store.pathOf(id)), std::string::npos) << msg;
			EXPECT_NE(msg.find(what), std::string::npos) << msg;
		}
	};
	expectError(13, "no such file");
	// One flipped bit in the payload fails the checksum.
	{
		std::fstream f(store.pathOf(12), std::ios::in | std::ios::out | std::ios::binary);
		f.seekg(100);
		char c = 0;
		f.read(&c, 1);
		c ^= 4;
		f.seekp(100);
		f.write(&c, 1);
	}
	expectError(12, "checksum mismatch");
	// A cut file is refused before anything is allocated from its length.
	store.save(*lm);
	fs::resize_file(store.pathOf(12), fs::file_size(store.pathOf(12)) - 10);
	expectError(12, "does not match the file size");
	// A file renamed to another id holds the wrong map.
	store.save(*lm);
	fs::rename(store.pathOf(12), store.pathOf(14));
	expectError(14, "holds local map 12");

	// The map reads an offline local map from its store on demand, and saves it whole.
	Map m;
	m.sessions = 3;  // the local map is of session 2
	m.offline = std::make_shared<LocalMapStore>(store.dir());
	store.save(*lm);
	auto stub = std::make_shared<LocalMap>();
	stub->id = 12;
	stub->keyframes = lm->keyframes;
	stub->online = false;
	m.localMaps[12] = stub;
	std::map<uint64_t, mrpt::poses::CPose3D> poses;
	for (const auto k : lm->keyframes)
	{
		auto kf = std::make_shared<Keyframe>();
		kf->id = k;
		m.keyframes[k] = kf;
		poses[k] = mrpt::poses::CPose3D(static_cast<double>(k), 0, 0, 0, 0, 0);
	}
	EXPECT_EQ(m.onlineCount(), 0u);
	ASSERT_TRUE(m.data(12));
	EXPECT_EQ(m.data(12)->points(), 50u);
	EXPECT_EQ(m.data(12).get(), m.data(12).get());  // the second read comes from the cache
	PoseView v;
	v.prior = &poses;
	saveMap(m, v, (dir / "map").string());
	const Map back2 = loadMap((dir / "map").string());
	EXPECT_FALSE(back2.localMaps.at(12)->online);
	EXPECT_FALSE(back2.localMaps.at(12)->hasData());  // labels only, until needed
	EXPECT_TRUE(*back2.data(12) == *lm);
}

TEST(MapModel, UseLockOneWriterOrManyReaders)
{
	const test::ScopedTempDir dir("map-lock");
	const auto d = dir.path().string();
	// What a second process gets (a lock of its own: flock conflicts between open files,
	// also within one process).
	auto attempt = [&](MapUseLock::Mode mode) -> std::string
	{
		try
		{
			MapUseLock l(d, mode, "second");
			return "";
		}
		catch (const std::runtime_error& e)
		{
			return e.what();
		}
	};
	{
		const MapUseLock w(d, MapUseLock::Mode::Write, "rasterslam run");
		EXPECT_TRUE(w.held());
		const std::string who = "process " + std::to_string(::getpid()) + " (rasterslam run)";
		const std::string expected =
		    "map folder '" + d + "' is in use: " + who + " is writing it; wait until it ends";
		EXPECT_EQ(attempt(MapUseLock::Mode::Write), expected);
		EXPECT_EQ(attempt(MapUseLock::Mode::Read), expected);
	}
	{
		const MapUseLock r1(d, MapUseLock::Mode::Read, "first reader");
		EXPECT_TRUE(r1.held());
		EXPECT_EQ(attempt(MapUseLock::Mode::Read), "");  // readers together
		EXPECT_EQ(attempt(MapUseLock::Mode::Write),
		          "map folder '" + d +
		              "' is in use: other processes are reading it; wait until they end");
	}
	// Released with the object: a writer again.
	EXPECT_EQ(attempt(MapUseLock::Mode::Write), "");
	// The only file it leaves is the lock file itself.
	std::size_t files = 0;
	for (const auto& e : fs::directory_iterator(d))
	{
		EXPECT_EQ(e.path().filename(), ".use.lock");
		++files;
	}
	EXPECT_EQ(files, 1u);
	// A writer needs a folder it can write in; a reader of a read-only folder (no lock file
	// yet) goes on without a lock. Root ignores permissions: only checked otherwise.
	const auto ro = dir / "read-only";
	fs::create_directories(ro);
	fs::permissions(ro, fs::perms::owner_read | fs::perms::owner_exec);
	if (::geteuid() != 0)
	{
		EXPECT_FALSE(MapUseLock(ro.string(), MapUseLock::Mode::Read, "reader").held());
		EXPECT_THROW(MapUseLock(ro.string(), MapUseLock::Mode::Write, "writer"),
		             std::runtime_error);
	}
	fs::permissions(ro, fs::perms::owner_all);
}
