// Saving a map and relocalizing in it with no pose prior: a simulated revisit, and the real
// KITTI-05 pair (frames 540 and 1319, 8.9 m and 28 deg apart) with the 540 local map among
// the KITTI-00 distractors.
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/rawlog_source.h>
#include <rasterslam/io/rawlog_writer.h>
#include <rasterslam/io/trajectory_io.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <regex>
#include <sstream>

#include "test_json.h"
#include "test_support.h"

using namespace rasterslam;
namespace fs = std::filesystem;

namespace
{
struct RelocLine
{
	double stamp = 0;
	bool found = false;
	std::string reason;
	double kfStamp = 0;
	std::size_t inliers = 0;
	double score = 0;
	Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

std::vector<RelocLine> readReloc(const fs::path& p)
{
	std::vector<RelocLine> out;
	std::ifstream f(p);
	std::string line;
	while (std::getline(f, line))
	{
		if (line.empty() || line[0] == '#')
			continue;
		std::istringstream ss(line);
		RelocLine r;
		std::string status;
		unsigned long long lm, kf;
		double x, y, z, qx, qy, qz, qw;
		ss >> r.stamp >> status >> r.reason >> lm >> kf >> r.kfStamp >> r.score >> r.inliers >> x >>
		    y >> z >> qx >> qy >> qz >> qw;
		EXPECT_FALSE(ss.fail()) << line;
		r.found = status == "found";
		r.pose.linear() = Eigen::Quaterniond(qw, qx, qy, qz).toRotationMatrix();
		r.pose.translation() = Eigen::Vector3d(x, y, z);
		out.push_back(r);
	}
	return out;
}

Eigen::Isometry3d poseAt(const io::Trajectory& t, double stamp)
{
	for (const auto& p : t)
		if (std::abs(p.stamp - stamp) < 1e-4)
			return p.pose;
	ADD_FAILURE() << "no pose at " << stamp;
	return Eigen::Isometry3d::Identity();
}
}  // namespace

TEST(Relocalization, Kitti05RevisitAmongDistractors)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto D00 = test::sharedData("kitti00-0000-0100"),
	           D05 = test::sharedData("kitti05-revisit-0540-1319");
	const auto dir = test::tempDir("reloc");
	// Map input: KITTI 00 scans 0-100, then KITTI 05 frame 540 (a jump: tracking restarts).
	const auto mapRawlog = (dir / "map.rawlog").string(), query = (dir / "query.rawlog").string();
	{
		io::RawlogWriter w(mapRawlog, 1);
		const auto bins = io::listKittiBins(D00 + "/velodyne");
		const auto times = io::loadKittiTimes(D00 + "/times.txt");
		for (std::size_t i = 0; i < bins.size(); i++)
		{
			Scan s;
			s.stamp = 100 + times[i];
			s.points = io::loadKittiBin(bins[i]);
			w.writeScan(s);
		}
		Scan s;
		s.stamp = 200;
		s.points = io::loadKittiBin(D05 + "/000540.bin");
		w.writeScan(s);
		w.close();
		io::RawlogWriter q(query, 1);
		Scan s2;
		s2.stamp = 300;
		s2.points = io::loadKittiBin(D05 + "/001319.bin");
		q.writeScan(s2);
		q.close();
	}
	const auto slam = test::sourcePath("share/rasterslam/config/slam.yaml");
	auto r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + mapRawlog +
	                          " --config " + slam + " --quiet --out " + (dir / "run").string() +
	                          " --map-out " + (dir / "map").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	ASSERT_TRUE(fs::exists(dir / "map" / "map.rsmap"));
	EXPECT_TRUE(fs::exists(dir / "map" / "localmaps" / "0000.png"));

	r = test::runCommand(test::bin("rasterslam") + " relocalize --map " + (dir / "map").string() +
	                     " --rawlog " + query + " --out " + (dir / "reloc").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto lines = readReloc(dir / "reloc" / "relocalization.txt");
	ASSERT_EQ(lines.size(), 1u);
	ASSERT_TRUE(lines[0].found) << lines[0].reason;
	EXPECT_NEAR(lines[0].kfStamp, 200, 1e-6);  // matched the 540 keyframe, not a distractor

	// Ground truth (data README, official poses): pose of 1319 in the frame of 540.
	Eigen::Matrix4d M;
	M << 0.883776, -0.466986, -0.0294015, 7.34227, 0.467908, 0.882265, 0.051687, 4.89425,
	    0.00180279, -0.0594369, 0.99823, 0.0543196, 0, 0, 0, 1;
	const Eigen::Isometry3d truth(M);
	const auto est = io::loadTrajectory((dir / "run" / "trajectory.tum").string());
	const Eigen::Isometry3d rel = poseAt(est, 200).inverse() * lines[0].pose;
	const double dt = (rel.translation() - truth.translation()).norm();
	const double da =
	    Eigen::AngleAxisd(rel.linear().transpose() * truth.linear()).angle() * 180 / M_PI;
	std::cout << "KITTI-05 1319 in 540: " << dt << " m, " << da << " deg, " << lines[0].inliers
	          << " inliers\n";
	EXPECT_LT(dt, 0.3);
	EXPECT_LT(da, 1.0);
}

TEST(Relocalization, BadMapIsReported)
{
	const auto dir = test::tempDir("reloc");
	fs::create_directories(dir / "map");
	std::ofstream(dir / "map" / "map.rsmap") << "not a map";
	const auto r =
	    test::runCommand(test::bin("rasterslam") + " relocalize --map " + (dir / "map").string() +
	                     " --rawlog x.rawlog --out " + (dir / "o").string());
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("cannot read map '" + (dir / "map" / "map.rsmap").string() + "'"),
	          std::string::npos)
	    << r.output;
	const auto r2 =
	    test::runCommand(test::bin("rasterslam") + " relocalize --map " + (dir / "none").string() +
	                     " --rawlog x.rawlog --out " + (dir / "o").string());
	EXPECT_EQ(r2.exitCode, 1);
	EXPECT_NE(r2.output.find("does not exist"), std::string::npos) << r2.output;
}

namespace
{
/** The simulated VLP-16 drive (a 199 m loop), read once per test program. */
const std::vector<Scan>& vlp16Scans()
{
	static const std::vector<Scan> scans = []
	{
		const auto& p = test::townVlp16Rawlog();
		std::vector<Scan> v;
		io::RawlogSource src(p);
		while (auto s = src.next())
			v.push_back(std::move(*s));
		return v;
	}();
	return scans;
}

std::string writeScans(const fs::path& path,
                       const std::vector<std::pair<std::size_t, double>>& which)
{
	io::RawlogWriter w(path.string(), 1);
	for (const auto& [k, stamp] : which)
	{
		Scan s = vlp16Scans().at(k);
		s.stamp = stamp;
		w.writeScan(s);
	}
	w.close();
	return path.string();
}

/** Largest distance between the run's poses and the ground truth expressed in the frame of
 *  the simulator's first scan (the map frame), over the scans of `out` whose stamps map to
 *  simulator scans through `stampToScan`. */
std::vector<double> errorsInMapFrame(const fs::path& out,
                                     const std::map<long, std::size_t>& stampToScan)
{
	const auto est = io::loadTrajectory((out / "trajectory.tum").string());
	const auto& scans = vlp16Scans();
	const auto g0inv =
	    scans.front().groundTruth->getInverseHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>();
	std::vector<double> errs;
	for (const auto& p : est)
	{
		const auto it = stampToScan.find(std::lround(p.stamp * 10));
		if (it == stampToScan.end())
			continue;
		const auto g =
		    scans[it->second].groundTruth->getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>();
		const auto rel = g0inv * g;
		errs.push_back(
		    (p.pose.translation() - Eigen::Vector3d(rel(0, 3), rel(1, 3), rel(2, 3))).norm());
	}
	std::sort(errs.begin(), errs.end());
	return errs;
}
}  // namespace

TEST(Relocalization, SessionInAPriorMap)
{
	const auto dir = test::tempDir("reloc");
	std::vector<std::pair<std::size_t, double>> first, second;
	std::map<long, std::size_t> stampToScan;
	for (std::size_t k = 0; k < 300; k++)
		first.emplace_back(k, 10 + 0.1 * k);
	for (std::size_t k = 320; k < 400; k++)
	{
		second.emplace_back(k, 1000 + 0.1 * k);  // another day
		stampToScan[std::lround((1000 + 0.1 * k) * 10)] = k;
	}
	const auto slam = test::sourcePath("share/rasterslam/config/slam.yaml");
	auto r = test::runCommand(test::bin("rasterslam") + " run --rawlog " +
	                          writeScans(dir / "a.rawlog", first) + " --config " + slam +
	                          " --quiet --out " + (dir / "a").string() + " --map-out " +
	                          (dir / "map").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " run --rawlog " +
	                     writeScans(dir / "b.rawlog", second) + " --config " + slam + " --out " +
	                     (dir / "b").string() + " --map-in " + (dir / "map").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_NE(r.output.find("located in the prior map"), std::string::npos) << r.output;
	// The second session's poses are in the first session's frame. Measured: median 0.45 m,
	// largest 0.63 m (the first session's own drift included).
	const auto errs = errorsInMapFrame(dir / "b", stampToScan);
	ASSERT_EQ(errs.size(), 80u);
	EXPECT_LT(errs[errs.size() / 2], 1.0);
	EXPECT_LT(errs.back(), 1.5);
}

TEST(Relocalization, AJumpInTheRawlogIsRelocalized)
{
	const auto dir = test::tempDir("reloc");
	// Two recordings one after the other: the drive, then the first 60 scans again.
	std::vector<std::pair<std::size_t, double>> scans;
	std::map<long, std::size_t> stampToScan;
	for (std::size_t k = 0; k < 300; k++)
		scans.emplace_back(k, 10 + 0.1 * k);
	for (std::size_t k = 0; k < 60; k++)
	{
		scans.emplace_back(k, 500 + 0.1 * k);
		stampToScan[std::lround((500 + 0.1 * k) * 10)] = k;
	}
	const auto r = test::runCommand(test::bin("rasterslam") + " run --rawlog " +
	                                writeScans(dir / "j.rawlog", scans) + " --config " +
	                                test::sourcePath("share/rasterslam/config/slam.yaml") +
	                                " --out " + (dir / "j").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_NE(r.output.find("relocalized in local map"), std::string::npos) << r.output;
	const auto errs = errorsInMapFrame(dir / "j", stampToScan);
	ASSERT_EQ(errs.size(), 60u);
	EXPECT_LT(errs[errs.size() / 2], 1.0);  // back where it started, not at the motion prior
}

namespace
{
/** The KITTI sample as a plain rawlog (dir/k.rawlog), mapped with slam.yaml: dir/run (its
 *  outputs) and dir/map; with `last` >= 0, from scans 0..last only. */
void mapKittiStreet(const std::string& D, const fs::path& dir, int last = -1)
{
	const auto rawlog = (dir / "k.rawlog").string();
	auto r = test::runCommand(test::bin("kitti2rawlog") + " --velodyne " + D +
	                          "/velodyne --poses " + D + "/poses_semantickitti.txt --calib " + D +
	                          "/calib.txt --times " + D + "/times.txt --compress 0 -o " + rawlog);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + rawlog +
	                     " --config slam --quiet --out " + (dir / "run").string() + " --map-out " +
	                     (dir / "map").string() +
	                     (last >= 0 ? " --last " + std::to_string(last) : std::string()));
	ASSERT_EQ(r.exitCode, 0) << r.output;
}

/** `rasterslam relocalize` of `rawlog` in dir/map with config `cfg` into dir/out, evaluated
 *  against dir/q.tum and the map run's trajectories (dir/run): the evaluator's JSON. */
nlohmann::json relocalizeAndEvaluate(const fs::path& dir, const fs::path& cfg,
                                     const std::string& rawlog, const std::string& out)
{
	const auto rr = test::runCommand(test::bin("rasterslam") + " relocalize --quiet --map " +
	                                 (dir / "map").string() + " --config " + cfg.string() +
	                                 " --rawlog " + rawlog + " --out " + (dir / out).string());
	EXPECT_EQ(rr.exitCode, 0) << rr.output;
	const auto e = test::runCommand(test::bin("rasterslam-eval") + " reloc --json --reloc " +
	                                (dir / out / "relocalization.txt").string() + " --gt " +
	                                (dir / "q.tum").string() + " --map-gt " +
	                                (dir / "run" / "groundtruth.tum").string() + " --map-est " +
	                                (dir / "run" / "trajectory.tum").string());
	EXPECT_EQ(e.exitCode, 0) << e.output;
	std::printf("%s: %s\n", out.c_str(), e.output.c_str());
	return test::parseJson(e.output);
}
}  // namespace

// Revisits on real street geometry: the KITTI-00 sample mapped from its real scans, then
// queried with HDL-64E scans rendered from those scans at other poses (rasterslam-sim
// --kitti): every 10 m of the street, 0, 3 and 6 m to either side, driven both ways.
TEST(Relocalization, KittiStreetRevisitsRenderedFromRealScans)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto D = test::sharedData("kitti00-0000-0100");
	test::ScopedTempDir tmp("reloc-render");
	const auto dir = tmp.path();
	const auto query = (dir / "q.rawlog").string();
	ASSERT_NO_FATAL_FAILURE(mapKittiStreet(D, dir));
	test::CommandResult r;
	r = test::runCommand(test::bin("rasterslam-sim") + " --kitti " + D +
	                     " --every 10 --compress 0 -o " + query + " --gt-tum " +
	                     (dir / "q.tum").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " relocalize --quiet --map " +
	                     (dir / "map").string() + " --rawlog " + query + " --out " +
	                     (dir / "reloc").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam-eval") + " reloc --json --reloc " +
	                     (dir / "reloc" / "relocalization.txt").string() + " --gt " +
	                     (dir / "q.tum").string() + " --map-gt " +
	                     (dir / "run" / "groundtruth.tum").string() + " --map-est " +
	                     (dir / "run" / "trajectory.tum").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto j = test::parseJson(r.output);
	std::printf("%s\n", r.output.c_str());
	const auto queries = j["queries"].get<std::size_t>();
	ASSERT_EQ(queries, 80u);  // 8 places (82.8 m) x 5 offsets x 2 directions
	// README: 80 of these 80 revisits relocalized within 0.3 m and 1 degree, none wrong
	// (goal: 90 %); the height from the ground planes, median error 0.03 m.
	EXPECT_GE(j["correct"].get<double>(), 0.9 * static_cast<double>(queries));
	EXPECT_EQ(j["wrong"].get<std::size_t>(), 0u);
	EXPECT_LT(j["median_height_m"].get<double>(), 0.06);
	// The opposite direction is there and is found too.
	std::size_t opposite = 0, oppositeCorrect = 0;
	for (const auto& [k, g] : j["groups"].items())
		if (k.rfind("opposite", 0) == 0)
		{
			opposite += g["queries"].get<std::size_t>();
			oppositeCorrect += g["correct"].get<std::size_t>();
		}
	EXPECT_EQ(opposite, queries / 2);
	EXPECT_GE(oppositeCorrect, opposite * 8 / 10);
	// Refined on the local map's surfaces (icp_refine): driven the other way the features are
	// other points of the objects, and their fit alone was 0.21-0.24 m off along the road
	// (median of each group); refined, 0.02-0.05 m (README, 160 revisits).
	for (const auto& [k, g] : j["groups"].items())
		EXPECT_LT(g["median_trans_m"].get<double>(), 0.1) << k;
	EXPECT_LT(j["median_trans_m"].get<double>(), 0.06);

	// Every found line names a local map and a keyframe of this map, with a normalized score
	// at or over min_score (0.3).
	for (const auto& l : readReloc(dir / "reloc" / "relocalization.txt"))
		if (l.found)
		{
			EXPECT_GE(l.score, 0.3);
		}

	// Scans of another (simulated) town, same sensor: none is placed in the KITTI street.
	const auto other = (dir / "town.rawlog").string();
	r = test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-loop.yaml") + " --scans 60 -o " + other);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " relocalize --quiet --map " +
	                     (dir / "map").string() + " --rawlog " + other + " --out " +
	                     (dir / "other").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto lines = readReloc(dir / "other" / "relocalization.txt");
	ASSERT_EQ(lines.size(), 60u);
	for (const auto& l : lines)
		EXPECT_FALSE(l.found) << l.stamp << " placed with " << l.inliers << " inliers";
}

// loop_detector.query_turns: scans of the KITTI street rendered turned by 25 degrees off the
// route (left and right in turn), relocalized with the turned images of each query ranking the
// places and one candidate verified, so that the ranking decides; and scans of another town
// still placed nowhere with the extra images.
TEST(Relocalization, TurnedQueryImagesOnTheKittiStreet)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto D = test::sharedData("kitti00-0000-0100");
	test::ScopedTempDir tmp("reloc-turns");
	const auto dir = tmp.path();
	ASSERT_NO_FATAL_FAILURE(mapKittiStreet(D, dir));
	test::CommandResult r;
	// The revisit grid's poses (every 10 m, 0, 3 and 6 m aside, both ways), each turned.
	r = test::runCommand(test::bin("rasterslam-sim") + " --kitti " + D +
	                     " --every 10 --across 0,3,-6 --compress 0 -o " +
	                     (dir / "grid.rawlog").string() + " --gt-tum " +
	                     (dir / "grid.tum").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	{
		std::ifstream in(dir / "grid.tum");
		std::ofstream out(dir / "at.tum");
		std::string line;
		int i = 0;
		while (std::getline(in, line))
		{
			if (line.empty() || line[0] == '#')
				continue;
			std::istringstream ls(line);
			double t, x, y, z, qx, qy, qz, qw;
			ASSERT_TRUE(static_cast<bool>(ls >> t >> x >> y >> z >> qx >> qy >> qz >> qw)) << line;
			const Eigen::Quaterniond q =
			    Eigen::Quaterniond(qw, qx, qy, qz) *
			    Eigen::Quaterniond(Eigen::AngleAxisd((i++ % 2 ? -25.0 : 25.0) * M_PI / 180,
			                                         Eigen::Vector3d::UnitZ()));
			out << std::setprecision(12) << t << " " << x << " " << y << " " << z << " " << q.x()
			    << " " << q.y() << " " << q.z() << " " << q.w() << "\n";
		}
		ASSERT_EQ(i, 48);  // 8 places x 3 offsets x 2 directions
	}
	const auto query = (dir / "q.rawlog").string();
	r = test::runCommand(test::bin("rasterslam-sim") + " --kitti " + D + " --at " +
	                     (dir / "at.tum").string() + " --compress 0 -o " + query + " --gt-tum " +
	                     (dir / "q.tum").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;

	const std::string y = std::regex_replace(
	    test::shippedConfig("slam.yaml"), std::regex("max_candidates: 5 "), "max_candidates: 1 ");
	const auto plainCfg = dir / "one.yaml", turnsCfg = dir / "turns.yaml";
	std::ofstream(plainCfg) << y;
	std::ofstream(turnsCfg) << std::regex_replace(y, std::regex("\n    min_score:"),
	                                              "\n    query_turns: 4\n    min_score:");
	const auto plain = relocalizeAndEvaluate(dir, plainCfg, query, "plain");
	const auto turned = relocalizeAndEvaluate(dir, turnsCfg, query, "turned");
	ASSERT_EQ(turned["queries"].get<std::size_t>(), 48u);
	// README: 47 of 48 within 0.3 m and 1 degree with the turned images and without, none
	// wrong: on a street of 5 local maps the ranking has little to decide (with the turned
	// images' scores not weighed, 48). The ranking's gain is PlaceRanking's.
	EXPECT_GE(turned["correct"].get<std::size_t>(), 44u);
	EXPECT_GE(turned["correct"].get<std::size_t>(), plain["correct"].get<std::size_t>());
	EXPECT_EQ(turned["wrong"].get<std::size_t>(), 0u);
	for (const auto& l : readReloc(dir / "turned" / "relocalization.txt"))
		if (l.found)
		{
			EXPECT_GE(l.score, 0.3);  // the turned images' scores on the query's own scale
		}

	// Another town's scans, with four images each: still placed nowhere.
	const auto other = (dir / "town.rawlog").string();
	r = test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-loop.yaml") + " --scans 40 -o " + other);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " relocalize --quiet --map " +
	                     (dir / "map").string() + " --config " + turnsCfg.string() + " --rawlog " +
	                     other + " --out " + (dir / "other").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto lines = readReloc(dir / "other" / "relocalization.txt");
	ASSERT_EQ(lines.size(), 40u);
	for (const auto& l : lines)
		EXPECT_FALSE(l.found) << l.stamp << " placed with " << l.inliers << " inliers";
}

// loop_detector.relocalization_surface_search: revisits 15-30 m beyond the mapped part of the
// KITTI street (the first 51 scans mapped, the grid rendered over the whole street) match too
// few ORB descriptors to verify; their surfaces are searched with no prior (planarSearch, then
// ICP), the features matched again only near where the surfaces put them, and found, none
// wrong; another town's scans are still placed nowhere.
TEST(Relocalization, FarRevisitsFoundOnTheSurfacesOfTheKittiStreet)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto D = test::sharedData("kitti00-0000-0100");
	test::ScopedTempDir tmp("reloc-far");
	const auto dir = tmp.path();
	ASSERT_NO_FATAL_FAILURE(mapKittiStreet(D, dir, 50));
	const auto query = (dir / "q.rawlog").string();
	auto r = test::runCommand(test::bin("rasterslam-sim") + " --kitti " + D +
	                          " --every 10 --compress 0 -o " + query + " --gt-tum " +
	                          (dir / "q.tum").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const std::string y = test::shippedConfig("slam.yaml");
	const auto plainCfg = dir / "plain.yaml", surfaceCfg = dir / "surface.yaml";
	std::ofstream(plainCfg) << y;
	std::ofstream(surfaceCfg) << std::regex_replace(
	    y, std::regex("\n    min_score:"),
	    "\n    relocalization_surface_search: true\n    min_score:");
	const auto plain = relocalizeAndEvaluate(dir, plainCfg, query, "plain");
	const auto surface = relocalizeAndEvaluate(dir, surfaceCfg, query, "surface");
	ASSERT_EQ(surface["queries"].get<std::size_t>(), 80u);
	const auto far = [](const nlohmann::json& j, const char* what)
	{
		std::size_t n = 0;
		for (const auto& [k, g] : j["groups"].items())
			if (k.find("15-30m") != std::string::npos)
				n += g[what].get<std::size_t>();
		return n;
	};
	ASSERT_EQ(far(surface, "queries"), 18u);  // 9 each way
	// README: 7 -> 10 of these 18 within 0.3 m and 1 degree, none wrong (on the 160-pose
	// grid 10 -> 22 found, 9 -> 21 correct of 30); every query found before is still found.
	EXPECT_GE(far(surface, "correct"), 9u);
	EXPECT_GE(far(surface, "correct"), far(plain, "correct") + 2);
	EXPECT_GE(surface["correct"].get<std::size_t>(), plain["correct"].get<std::size_t>());
	EXPECT_EQ(surface["wrong"].get<std::size_t>(), 0u);
	std::size_t bySurface = 0;
	for (const auto& l : readReloc(dir / "surface" / "relocalization.txt"))
		if (l.found && l.reason == "surface")
		{
			bySurface++;
			// Matched only near where the surfaces put them, the features held the pose:
			// surface_search_min_inliers (30).
			EXPECT_GE(l.inliers, 30u);
			EXPECT_GE(l.score, 0.3);  // min_score holds for it too
		}
	EXPECT_GE(bySurface, 2u);

	// Another town's scans, searched on their surfaces too: placed nowhere.
	const auto other = (dir / "town.rawlog").string();
	r = test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-loop.yaml") + " --scans 40 -o " + other);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " relocalize --quiet --map " +
	                     (dir / "map").string() + " --config " + surfaceCfg.string() +
	                     " --rawlog " + other + " --out " + (dir / "other").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	const auto lines = readReloc(dir / "other" / "relocalization.txt");
	ASSERT_EQ(lines.size(), 40u);
	for (const auto& l : lines)
		EXPECT_FALSE(l.found) << l.stamp << " placed (" << l.reason << ")";
}

// surface_search_max_conflicts: another simulated town's streets look like the mapped town's
// (same generator): two scans of the town of seed 1001 pass the surface search's inlier, ratio
// and agreement checks against the town-loop drive's map (30-35 guided inliers, the right
// KITTI ones 32-69). Scan 17's alignment stands walls and poles where the map saw bare ground
// (0.6 of the compared cells; right alignments, also in a town 9 epochs later, at most 0.015):
// refused. Scan 9's tall structure agrees with the map's (1 of 92 cells): still placed.
// relocalization_max_conflicts: the same check for places found on the features. With the
// verification made lax (relocalization_min_inliers 12 instead of 18), scans 9 and 17 are
// placed on the features too; scan 17's fit is refused on its free space.
TEST(Relocalization, AnotherTownPassingEveryOtherCheckIsRefusedOnItsFreeSpace)
{
	test::ScopedTempDir tmp("reloc-free-space");
	const auto dir = tmp.path();
	const auto town = (dir / "town.rawlog").string(), other = (dir / "other.rawlog").string();
	auto r =
	    test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-loop.yaml") + " --compress 0 -o " + town);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam") + " run --quiet --config slam --rawlog " + town +
	                     " --out " + (dir / "run").string() + " --map-out " +
	                     (dir / "map").string());
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("rasterslam-sim") + " --scenario " +
	                     test::sourcePath("rawlogs/town-loop.yaml") +
	                     " --seed 1001 --scans 18 --compress 0 -o " + other);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	std::string lastOutput;  // of the last relocalize
	const auto relocalize =
	    [&](const std::string& extra, const std::string& out, bool surface = true)
	{
		const auto cfg = dir / (out + ".yaml");
		auto yaml = test::shippedConfig("slam.yaml");
		if (!surface)  // lax verification on the features instead
		{
			const std::regex lax("relocalization_min_inliers: 18 ");
			EXPECT_TRUE(std::regex_search(yaml, lax));
			yaml = std::regex_replace(yaml, lax, "relocalization_min_inliers: 12 ");
		}
		std::ofstream(cfg) << std::regex_replace(
		    yaml, std::regex("\n    min_score:"),
		    std::string(surface ? "\n    relocalization_surface_search: true" : "") + extra +
		        "\n    min_score:");
		lastOutput.clear();
		const auto rr = test::runCommand(test::bin("rasterslam") +
		                                 " relocalize --quiet --first 9 --last 17 --map " +
		                                 (dir / "map").string() + " --config " + cfg.string() +
		                                 " --rawlog " + other + " --out " + (dir / out).string());
		EXPECT_EQ(rr.exitCode, 0) << rr.output;
		lastOutput = rr.output;
		return readReloc(dir / out / "relocalization.txt");
	};
	// Without the free-space check (any share taken): scans 9 and 17 are placed, on the
	// surfaces, in a town they are not in. This is what the check is for; should a change
	// stop placing them, the test needs other scans that pass every other check.
	const auto unchecked = relocalize("\n    surface_search_max_conflicts: 1", "unchecked");
	ASSERT_EQ(unchecked.size(), 9u);
	for (const auto& l : unchecked)
		if (l.found)
		{
			EXPECT_EQ(l.reason, "surface");
			EXPECT_GE(l.inliers, 30u);  // surface_search_min_inliers: the features held it
		}
	EXPECT_TRUE(unchecked[0].found);  // scan 9
	EXPECT_TRUE(unchecked[8].found);  // scan 17
	// With the shipped bound (0.05) scan 17 is refused, and nothing else is placed that was
	// not before.
	const auto checked = relocalize("", "checked");
	ASSERT_EQ(checked.size(), 9u);
	EXPECT_FALSE(checked[8].found) << "scan 17 placed (" << checked[8].reason << ")";
	for (std::size_t i = 0; i < checked.size(); i++)
		EXPECT_TRUE(!checked[i].found || unchecked[i].found) << "scan " << 9 + i;

	// On the features, with 12 inliers enough: without the check (any share kept) scans 9
	// and 17 are placed; with the shipped bound (0.05) scan 17 is refused, naming why.
	const auto laxUnchecked = relocalize("\n    relocalization_max_conflicts: 1", "lax1", false);
	ASSERT_EQ(laxUnchecked.size(), 9u);
	for (const auto& l : laxUnchecked)
		if (l.found)
		{
			EXPECT_EQ(l.reason, "ok");
			EXPECT_GE(l.inliers, 12u);
		}
	EXPECT_TRUE(laxUnchecked[0].found);  // scan 9
	EXPECT_TRUE(laxUnchecked[8].found);  // scan 17
	const auto laxChecked = relocalize("", "lax", false);
	ASSERT_EQ(laxChecked.size(), 9u);
	EXPECT_FALSE(laxChecked[8].found);
	EXPECT_EQ(laxChecked[8].reason, "free-space");
	// The summary counts the scans not placed by reason.
	EXPECT_NE(lastOutput.find("rasterslam: relocalized 1 of 9 scans (not placed: "),
	          std::string::npos)
	    << lastOutput;
	EXPECT_TRUE(std::regex_search(lastOutput, std::regex("(: |, )1 free-space(, |\\))")))
	    << lastOutput;
	for (std::size_t i = 0; i < laxChecked.size(); i++)
		EXPECT_TRUE(!laxChecked[i].found || laxUnchecked[i].found) << "scan " << 9 + i;
}

TEST(Relocalization, EvalRefusesAMalformedFileNamingIt)
{
	test::ScopedTempDir tmp("reloc-eval");
	const auto bad = (tmp / "relocalization.txt").string(), gt = (tmp / "gt.tum").string();
	{
		std::ofstream(bad) << "# header\n1.0 found ok 0 0 0.0 0.5 30 1 2\n";  // cut short
		std::ofstream(gt) << "1.0 0 0 0 0 0 0 1\n";
	}
	const auto r = test::runCommand(test::bin("rasterslam-eval") + " reloc --reloc " + bad +
	                                " --gt " + gt + " --map-gt " + gt + " --map-est " + gt);
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_NE(r.output.find(bad + ":2: not a relocalization line"), std::string::npos) << r.output;
}
