// kitti2rawlog on the real KITTI sample: the rawlog holds the scans and the Velodyne-frame
// ground truth inv(Tr) * P_i * Tr.
#include <rasterslam/io/kitti.h>
#include <rasterslam/io/rawlog_source.h>
#include <rasterslam/io/trajectory_io.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>

#include "test_json.h"
#include "test_support.h"

using namespace rasterslam;
namespace fs = std::filesystem;

namespace
{
std::vector<Scan> readAll(const std::string& path)
{
	io::RawlogSource src(path);
	std::vector<Scan> v;
	while (auto s = src.next())
		v.push_back(std::move(*s));
	EXPECT_EQ(src.stopReason(), "");
	return v;
}
}  // namespace

TEST(Kitti, ConverterEmbedsScansAndGroundTruth)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto D = test::sharedData("kitti00-0000-0100");
	const auto out = (test::tempDir("kitti") / "k.rawlog").string();
	const auto r =
	    test::runCommand(test::bin("kitti2rawlog") + " --velodyne " + D + "/velodyne --poses " + D +
	                     "/poses_semantickitti.txt --calib " + D + "/calib.txt --times " + D +
	                     "/times.txt --first 5 --last 14 -o " + out);
	ASSERT_EQ(r.exitCode, 0) << r.output;

	const auto scans = readAll(out);
	ASSERT_EQ(scans.size(), 10u);
	const auto bins = io::listKittiBins(D + "/velodyne");
	const auto times = io::loadKittiTimes(D + "/times.txt");
	const auto gt = io::kittiCameraToVelodyne(io::loadTrajectory(D + "/poses_semantickitti.txt"),
	                                          io::loadKittiCalibTr(D + "/calib.txt"));
	for (size_t k = 0; k < scans.size(); k++)
	{
		const size_t frame = 5 + k;
		const auto pts = io::loadKittiBin(bins[frame]);
		ASSERT_EQ(scans[k].points.size(), pts.size()) << frame;
		EXPECT_EQ(scans[k].points[123].x, pts[123].x);
		EXPECT_EQ(scans[k].points.back().intensity, pts.back().intensity);
		EXPECT_NEAR(scans[k].stamp, times[frame], 1e-6);
		ASSERT_TRUE(scans[k].groundTruth) << frame;
		const auto& g = gt[frame].pose;
		EXPECT_NEAR(scans[k].groundTruth->x(), g.translation().x(), 1e-9);
		EXPECT_NEAR(scans[k].groundTruth->y(), g.translation().y(), 1e-9);
		EXPECT_NEAR(scans[k].groundTruth->z(), g.translation().z(), 1e-9);
		const auto R = scans[k].groundTruth->getRotationMatrix();
		for (int i = 0; i < 3; i++)
			for (int j = 0; j < 3; j++)
				EXPECT_NEAR(R(i, j), g.linear()(i, j), 1e-9);
	}
	// Velodyne frame: the car drives along +x, so x grows and the height barely changes.
	EXPECT_GT(scans.back().groundTruth->x() - scans.front().groundTruth->x(), 5.0);
	EXPECT_LT(std::abs(scans.back().groundTruth->z() - scans.front().groundTruth->z()), 0.5);

	// MRPT's own tool opens it.
	const auto info = test::runCommand("rawlog-edit --info -i " + out);
	ASSERT_EQ(info.exitCode, 0) << info.output;
	EXPECT_NE(info.output.find("GROUND_TRUTH /     10"), std::string::npos) << info.output;
	EXPECT_NE(info.output.find("LIDAR /     10"), std::string::npos) << info.output;
}

TEST(Kitti, ExternalStorageAndSequenceLayout)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto D = test::sharedData("kitti00-0000-0100");
	const auto dir = test::tempDir("kitti");
	// A KITTI-layout copy of three scans: dataset/sequences/00/{velodyne,calib,times},
	// dataset/poses/00.txt
	const auto seq = dir / "dataset" / "sequences" / "00";
	fs::create_directories(seq / "velodyne");
	fs::create_directories(dir / "dataset" / "poses");
	const auto bins = io::listKittiBins(D + "/velodyne");
	for (int i = 0; i < 3; i++)
		fs::create_symlink(bins[i], seq / "velodyne" / fs::path(bins[i]).filename());
	fs::copy_file(D + "/calib.txt", seq / "calib.txt");
	fs::copy_file(D + "/times.txt", seq / "times.txt");
	fs::copy_file(D + "/poses_official.txt", dir / "dataset" / "poses" / "00.txt");

	const auto ext = (dir / "ext.rawlog").string(), emb = (dir / "emb.rawlog").string();
	auto r = test::runCommand(test::bin("kitti2rawlog") + " --sequence " + seq.string() +
	                          " --external -o " + ext);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	r = test::runCommand(test::bin("kitti2rawlog") + " --sequence " + seq.string() + " -o " + emb);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	EXPECT_LT(fs::file_size(ext), fs::file_size(emb) / 100);  // references, not points

	const auto a = readAll(ext), b = readAll(emb);
	ASSERT_EQ(a.size(), 3u);
	ASSERT_EQ(b.size(), 3u);
	for (size_t k = 0; k < 3; k++)
	{
		ASSERT_EQ(a[k].points.size(), b[k].points.size());
		EXPECT_EQ(a[k].points[1000].z, b[k].points[1000].z);
		ASSERT_TRUE(a[k].groundTruth);  // poses found in dataset/poses/00.txt
		EXPECT_NEAR(a[k].groundTruth->x(), b[k].groundTruth->x(), 1e-12);
	}
}

TEST(Kitti, BadInputIsReported)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto D = test::sharedData("kitti00-0000-0100");
	const auto dir = test::tempDir("kitti");
	fs::create_directories(dir / "velo");
	std::ofstream(dir / "velo" / "000000.bin", std::ios::binary) << "0123456789";  // 10 bytes
	auto r = test::runCommand(test::bin("kitti2rawlog") + " --velodyne " + (dir / "velo").string() +
	                          " -o " + (dir / "x.rawlog").string());
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("000000.bin': size 10 bytes is not a multiple of 16"),
	          std::string::npos)
	    << r.output;
	EXPECT_FALSE(fs::exists(dir / "x.rawlog"));

	r = test::runCommand(test::bin("kitti2rawlog") + " --velodyne " + D + "/velodyne --poses " + D +
	                     "/poses_official.txt -o " + (dir / "y.rawlog").string());
	EXPECT_EQ(r.exitCode, 2);
	EXPECT_NE(r.output.find("--poses needs --calib"), std::string::npos) << r.output;

	// A folder that is not there is bad input: exit 1, named.
	r = test::runCommand(test::bin("kitti2rawlog") + " --velodyne " + (dir / "nothere").string() +
	                     " -o " + (dir / "z.rawlog").string());
	EXPECT_EQ(r.exitCode, 1);
	EXPECT_NE(r.output.find("--velodyne: Directory does not exist: " + (dir / "nothere").string()),
	          std::string::npos)
	    << r.output;
	EXPECT_FALSE(fs::exists(dir / "z.rawlog"));
}

TEST(Kitti, VerticalCorrectionRaisesEveryElevation)
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto D = test::sharedData("kitti00-0000-0100");
	const auto dir = test::tempDir("kitti");
	const auto plain = (dir / "p.rawlog").string(), corr = (dir / "c.rawlog").string();
	const auto base = test::bin("kitti2rawlog") + " --velodyne " + D + "/velodyne --last 0 -o ";
	ASSERT_EQ(test::runCommand(base + plain).exitCode, 0);
	ASSERT_EQ(test::runCommand(base + corr + " --vertical-correction-deg 0.205").exitCode, 0);
	const auto a = readAll(plain), b = readAll(corr);
	ASSERT_EQ(a.size(), 1u);
	ASSERT_EQ(b.size(), 1u);
	ASSERT_EQ(a[0].points.size(), b[0].points.size());
	for (size_t i = 0; i < a[0].points.size(); i += 997)
	{
		const auto &p = a[0].points[i], &q = b[0].points[i];
		const double rp = std::hypot(p.x, p.y), rq = std::hypot(q.x, q.y);
		if (rp < 1)
			continue;
		EXPECT_NEAR(std::atan2(q.z, rq) - std::atan2(p.z, rp), 0.205 * M_PI / 180, 1e-5) << i;
		EXPECT_NEAR(std::hypot(rq, q.z), std::hypot(rp, p.z), 1e-4) << i;    // range kept
		EXPECT_NEAR(std::atan2(q.y, q.x), std::atan2(p.y, p.x), 1e-5) << i;  // azimuth kept
	}
	const auto r = test::runCommand(base + (dir / "x.rawlog").string() +
	                                " --external --vertical-correction-deg 0.2");
	EXPECT_EQ(r.exitCode, 2) << r.output;
}

TEST(Kitti, GroundPatchesLowerTheRotationDrift)
{
	// The KITTI sample as recorded, tracked as tracking.yaml does with the engine's 0.205 deg
	// beam correction and ground_model: grid (the heights of the same ground patches matched),
	// against tracking.yaml's ground_model: plane (the two scans' RANSAC planes made parallel)
	// and against the grid without the correction. Measured (scripts/benchmark.sh, relative errors
	// on 10..80 m segments): plane 0.376 %, 0.0138 deg/m; grid 0.379 %, 0.0088 deg/m (KISS-ICP on
	// the corrected scans: 0.57-0.59 %, 0.0086-0.0088); grid without the correction 0.765 %, 0.0199
	// deg/m (the ground's cone reads as pitch).
	RASTERSLAM_REQUIRE_SHARED_DATA();
	const auto D = test::sharedData("kitti00-0000-0100");
	const test::ScopedTempDir dir("kitti");
	const auto rawlog = (dir / "as-recorded.rawlog").string();
	auto r = test::runCommand(test::bin("kitti2rawlog") + " --velodyne " + D +
	                          "/velodyne --poses " + D + "/poses_semantickitti.txt --calib " + D +
	                          "/calib.txt --times " + D + "/times.txt --compress 0 -o " + rawlog);
	ASSERT_EQ(r.exitCode, 0) << r.output;
	std::ifstream in(test::sourcePath("share/rasterslam/config/tracking.yaml"));
	const std::string base((std::istreambuf_iterator<char>(in)), {});
	auto with = [&](const std::string& from, const std::string& to)
	{
		std::string y = base;
		const auto at = y.find(from);
		EXPECT_NE(at, std::string::npos) << from;
		if (at != std::string::npos)
			y.replace(at, from.size(), to);
		return y;
	};
	const std::string planes =
	    with("vertical_correction_deg: 0 ", "vertical_correction_deg: 0.205 ");
	const std::string corrected =
	    std::regex_replace(planes, std::regex("ground_model: plane "), "ground_model: grid ");
	ASSERT_NE(planes, corrected);
	// And the shipped tracking-refined.yaml: the grid, and the rotation refined by ICP on the
	// last 10 keyframes' points, keyframes only (the goal on this sample: RTE under
	// 0.57 % and RRE under 0.0086 deg/m at once). Measured: 0.371 %, 0.0066 deg/m (0.370 %,
	// 0.0068 before refit_cauchy_m).
	std::ifstream inRefined(test::sourcePath("share/rasterslam/config/tracking-refined.yaml"));
	const std::string refinedBase((std::istreambuf_iterator<char>(inRefined)), {});
	const std::string refined = std::regex_replace(
	    refinedBase, std::regex("vertical_correction_deg: 0 "), "vertical_correction_deg: 0.205 ");
	ASSERT_NE(refined, refinedBase);
	const std::string uncorrected =
	    std::regex_replace(base, std::regex("ground_model: plane "), "ground_model: grid ");
	std::map<std::string, std::string> results;
	for (const auto& [name, text] :
	     std::vector<std::pair<std::string, std::string>>{{"grid", corrected},
	                                                      {"plane", planes},
	                                                      {"uncorrected", uncorrected},
	                                                      {"refined", refined}})
	{
		const auto cfg = dir / (name + ".yaml");
		std::ofstream(cfg) << text;
		r = test::runCommand(test::bin("rasterslam") + " run --rawlog " + rawlog + " --config " +
		                     cfg.string() + " --quiet --out " + (dir / name).string());
		ASSERT_EQ(r.exitCode, 0) << r.output;
		r = test::runCommand(test::bin("rasterslam-eval") + " traj --gt " + D +
		                     "/poses_semantickitti.txt --calib " + D + "/calib.txt --est " +
		                     (dir / name / "trajectory.kitti").string() +
		                     " --segments 10:80:10 --json");
		ASSERT_EQ(r.exitCode, 0) << r.output;
		results[name] = r.output;
	}
	const double rre = test::jsonNumber(results["grid"], "rel_rot_deg_per_m");
	EXPECT_LT(rre, 0.0095) << results["grid"];
	EXPECT_LT(test::jsonNumber(results["grid"], "rel_trans_pct"), 0.57) << results["grid"];
	EXPECT_LT(test::jsonNumber(results["grid"], "ate_rmse_m"), 0.05) << results["grid"];
	EXPECT_LT(rre, 0.75 * test::jsonNumber(results["plane"], "rel_rot_deg_per_m"))
	    << results["plane"];
	const double refinedRre = test::jsonNumber(results["refined"], "rel_rot_deg_per_m");
	EXPECT_LT(refinedRre, 0.0086) << results["refined"];
	EXPECT_LT(test::jsonNumber(results["refined"], "rel_trans_pct"), 0.57) << results["refined"];
	EXPECT_LT(refinedRre, rre) << results["refined"];
	// Without the correction the same tracking is worse: the correction is what it needs.
	EXPECT_GT(test::jsonNumber(results["uncorrected"], "rel_rot_deg_per_m"), 1.5 * rre)
	    << results["uncorrected"];
}
