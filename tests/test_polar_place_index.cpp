// The loop detector's place index with the local maps' polar contexts (LocalMap::contextCells):
// what a saved map keeps of them, what leaves with a forgotten local map, indexes of maps
// written before them, and places found by the contexts where the words miss them (a local
// map of another map, and a real scan with no pose prior).
#include <gtest/gtest.h>
#include <rasterslam/core/plugin_loader.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/io/kitti.h>
#include <rasterslam/map/map.h>
#include <rasterslam/places/polar_context.h>
#include <rasterslam/raster/elevation_image.h>

#include <random>

#include "test_support.h"

using namespace rasterslam;
using mrpt::containers::yaml;

namespace
{
constexpr const char* kClass = "rasterslam::BowLoopDetector";

std::shared_ptr<LoopDetector> makeDetector(const std::string& params = "polar_fusion: true\n")
{
	PluginLoader::instance().load();
	auto d = PluginLoader::instance().create<LoopDetector>(kClass);
	d->initialize(yaml::FromText(
	    "vocabulary_file: " +
	    test::sourcePath("share/rasterslam/vocab/elevation-localmaps-3m-k10l4.vocab") + "\n" +
	    params));
	return d;
}

/** Points of boxes scattered about the origin (seeded): a place with a context. */
std::vector<PointXYZI> scene(uint32_t seed)
{
	std::mt19937 rng(seed);
	std::uniform_real_distribution<float> xy(-50, 50), h(0.5f, 6.f);
	std::vector<PointXYZI> pts;
	for (int b = 0; b < 30; b++)
	{
		const float cx = xy(rng), cy = xy(rng), top = h(rng);
		for (float z = -1.5f; z < top - 1.73f; z += 0.3f)
			pts.push_back({cx, cy, z, 0});
	}
	return pts;
}

/** A local map of `keyframes` keyframes with a context about each (when `contexts`). */
LocalMap::Ptr localMap(uint64_t id, std::size_t keyframes, bool contexts)
{
	auto lm = std::make_shared<LocalMap>();
	lm->id = id;
	for (std::size_t k = 0; k < keyframes; k++)
		lm->keyframes.push_back(100 * id + k);
	if (contexts)
	{
		lm->contextRings = 10;
		lm->contextSectors = 60;
		for (std::size_t k = 0; k < keyframes; k++)
		{
			const auto c = places::quantizedCells(
			    places::polarContext(scene(static_cast<uint32_t>(10 * id + k))),
			    LocalMap::kContextStep_m);
			lm->contextCells.insert(lm->contextCells.end(), c.begin(), c.end());
		}
	}
	return lm;
}

/** ORB-like descriptors (seeded), 32 bytes each: an image's words. */
std::vector<uint8_t> descriptors(uint32_t seed)
{
	std::mt19937 rng(seed);
	std::vector<uint8_t> d(32 * 200);
	for (auto& b : d)
		b = static_cast<uint8_t>(rng());
	return d;
}

Map mapOf(const std::vector<LocalMap::Ptr>& lms, std::vector<uint8_t> index)
{
	Map m;
	for (const auto& lm : lms)
		m.localMaps[lm->id] = lm;
	m.placeIndexClass = kClass;
	m.placeIndex = std::move(index);
	return m;
}
}  // namespace

TEST(PolarPlaceIndex, ContextsAreSavedWithTheIndexAndLeaveWithTheirLocalMap)
{
	const std::vector<LocalMap::Ptr> lms = {localMap(1, 5, true), localMap(2, 3, true),
	                                        localMap(3, 5, false)};
	auto a = makeDetector();
	for (const auto& lm : lms)
		a->index(*lm, descriptors(static_cast<uint32_t>(lm->id)));
	const auto saved = a->savePlaceIndex();

	// Read back and written again, the index is the same bytes: every context kept as it was.
	auto b = makeDetector();
	b->loadPlaceIndex(mapOf(lms, saved));
	EXPECT_EQ(b->savePlaceIndex(), saved);

	// Without its contexts the index is smaller by 8 of them (5 + 3; local map 3 has none).
	auto plain = makeDetector();
	for (const auto& lm : {localMap(1, 5, false), localMap(2, 3, false), localMap(3, 5, false)})
		plain->index(*lm, descriptors(static_cast<uint32_t>(lm->id)));
	const std::size_t perContext = 8 + 4 + 600;  // local map id, length, 10 x 60 cells
	EXPECT_EQ(saved.size(), plain->savePlaceIndex().size() + 8 * perContext);

	// A forgotten local map's contexts go with its words: the index no longer names it, so a
	// map without it loads (a context left behind would be refused as a missing local map's).
	EXPECT_TRUE(b->forget(1));
	const auto after = b->savePlaceIndex();
	EXPECT_TRUE(plain->forget(1));
	EXPECT_EQ(after.size(), plain->savePlaceIndex().size() + 3 * perContext);  // map 2's 3 left
	auto c = makeDetector();
	EXPECT_NO_THROW(c->loadPlaceIndex(mapOf({lms[1], lms[2]}, after)));
	EXPECT_EQ(c->savePlaceIndex(), after);
	EXPECT_FALSE(c->forget(1));  // nothing of it left
}

TEST(PolarPlaceIndex, AnIndexWrittenBeforeTheContextsLoadsAndDamageIsRefused)
{
	const std::vector<LocalMap::Ptr> lms = {localMap(1, 2, false), localMap(2, 2, false)};
	auto a = makeDetector();
	for (const auto& lm : lms)
		a->index(*lm, descriptors(static_cast<uint32_t>(lm->id)));
	const auto v1 = a->savePlaceIndex();
	// Version 0: the same without the contexts' dimensions (2 + 2 bytes) and count (8).
	ASSERT_GT(v1.size(), 13u);
	ASSERT_EQ(v1[0], 1);
	for (std::size_t i = v1.size() - 12; i < v1.size(); i++)
		ASSERT_EQ(v1[i], 0) << "byte " << i;
	auto v0 = v1;
	v0[0] = 0;
	v0.resize(v0.size() - 12);
	auto b = makeDetector();
	ASSERT_NO_THROW(b->loadPlaceIndex(mapOf(lms, v0)));
	EXPECT_EQ(b->savePlaceIndex(), v1);  // written again in the new version, nothing lost

	// Damaged: a version from the future, a count of contexts the bytes cannot hold, cells of
	// the wrong number.
	auto future = v1;
	future[0] = 9;
	EXPECT_THROW(b->loadPlaceIndex(mapOf(lms, future)), std::runtime_error);
	auto some = v1;
	some[v1.size() - 12] = 10;  // rings
	some[v1.size() - 10] = 60;  // sectors
	some[v1.size() - 8] = 3;    // the count's low byte (little-endian): no cells follow
	EXPECT_ANY_THROW(b->loadPlaceIndex(mapOf(lms, some)));
	auto huge = some;
	huge[v1.size() - 1] = 0x7f;  // its high byte: more contexts than the index has bytes
	EXPECT_THROW(b->loadPlaceIndex(mapOf(lms, huge)), std::runtime_error);

	auto withContexts = makeDetector();
	const auto lm = localMap(1, 1, true);
	withContexts->index(*lm, descriptors(1));
	auto bad = withContexts->savePlaceIndex();
	// The one context's cell count (4 bytes before its 600 cells, at the end) made 599.
	ASSERT_GT(bad.size(), 604u);
	bad[bad.size() - 604] = static_cast<uint8_t>(599 & 0xff);
	bad[bad.size() - 603] = static_cast<uint8_t>(599 >> 8);
	EXPECT_THROW(b->loadPlaceIndex(mapOf({lm}, bad)), std::runtime_error);
}

namespace
{
/** Local map `id` of one keyframe with 200 features: seeded points within 30 m and
 *  descriptors, and (when `context`) the context of scene(10 * id) about the keyframe. */
LocalMap::Ptr featureMap(uint64_t id, bool context)
{
	auto lm = localMap(id, 1, context);
	std::mt19937 rng(static_cast<uint32_t>(id));
	std::uniform_real_distribution<float> u(-30, 30);
	lm->descriptors = descriptors(static_cast<uint32_t>(1000 + id));
	for (std::size_t i = 0; i < lm->descriptors.size() / 32; i++)
	{
		lm->xyz.insert(lm->xyz.end(), {u(rng), u(rng), 0.2f * u(rng)});
		lm->observers.push_back(1);
	}
	return lm;
}

/** `truth` then local maps 2-4: featureMap()s with no contexts. */
std::vector<LocalMap::Ptr> withDistractors(const LocalMap::Ptr& truth)
{
	std::vector<LocalMap::Ptr> lms = {truth};
	for (uint64_t id = 2; id <= 4; id++)
		lms.push_back(featureMap(id, false));
	return lms;
}

/** A map of one session holding `lms`, each with its anchor keyframe at the origin. */
Map mapOfAnchors(const std::vector<LocalMap::Ptr>& lms)
{
	Map map;
	map.sessions = 1;
	for (const auto& lm : lms)
	{
		map.localMaps[lm->id] = lm;
		auto kf = std::make_shared<Keyframe>();
		kf->id = lm->anchor();
		map.keyframes[kf->id] = kf;
		map.priorPoses[kf->id] = mrpt::poses::CPose3D();
	}
	return map;
}
}  // namespace

TEST(PolarPlaceIndex, LocateVerifiesThePlaceTheContextsRankWhereTheWordsMissIt)
{
	// Three local maps (2-4) have an image of the query's own words but other features and no
	// contexts; the true place (local map 1) has the query's features and context, and an
	// image that shares a few of the query's words or none. Only the first max_candidates + 1
	// candidates are verified.
	const auto truth = featureMap(1, true);
	const auto lms = withDistractors(truth);
	const Map map = mapOfAnchors(lms);
	PoseView poses;
	poses.prior = &map.priorPoses;
	// The query: the true place's features and context, as another map's local map.
	LocalMap query = *truth;
	query.id = 99;
	query.keyframes = {9900};

	// A few words: the true place's image holds 30 of the query's 200 descriptors.
	const std::vector<uint8_t> few(truth->descriptors.begin(),
	                               truth->descriptors.begin() + 32 * 30);
	const auto locate = [&](const std::string& params, const std::vector<uint8_t>& truthImage)
	{
		auto d = makeDetector(params);
		for (const auto& lm : lms)
			d->index(*lm, lm->id == 1 ? truthImage : truth->descriptors);
		return d->locate(query, map, poses, 0);
	};
	// The words rank it fourth: 3 verified (max_candidates 2) miss it, 4 find it.
	const std::string anyScore = "min_score: 0\n";
	EXPECT_FALSE(locate(anyScore + "max_candidates: 2\n", few).found);
	const auto fourth = locate(anyScore + "max_candidates: 3\n", few);
	ASSERT_TRUE(fourth.found) << fourth.reason;
	EXPECT_EQ(fourth.localMap, 1u);
	// Fused (its words fourth, its context first: 1/14 + 1/11 against the others' 1/11 at
	// most), it is the first candidate: found with two verified (max_candidates 1, the least),
	// where the words' two miss it.
	EXPECT_FALSE(locate(anyScore + "max_candidates: 1\n", few).found);
	const auto first = locate(anyScore + "max_candidates: 1\npolar_fusion: true\n", few);
	ASSERT_TRUE(first.found) << first.reason;
	EXPECT_EQ(first.localMap, 1u);
	EXPECT_GE(first.inliers, 150u);
	EXPECT_LT(first.pose.norm(), 1e-3);

	// No words at all: only the contexts rank it (second, after the words' first at an equal
	// sum). Its words' score, computed when it is examined, is 0: min_score refuses it
	// unless polar_max_distance takes its context instead.
	const std::string fused = "max_candidates: 1\npolar_fusion: true\n";
	EXPECT_FALSE(locate(fused, {}).found);
	const auto close = locate(fused + "polar_max_distance: 0.05\n", {});
	ASSERT_TRUE(close.found) << close.reason;
	EXPECT_EQ(close.localMap, 1u);
	// A query context of other dimensions than the index's is ranked by its words only.
	query.contextSectors = 30;
	query.contextCells.resize(10 * 30);
	EXPECT_FALSE(locate(fused + "polar_max_distance: 0.05\n", {}).found);
}

namespace
{
/** Tests on a real scan (KITTI-05 frame 540), its elevation image, and the place it was made at:
 *  local map 1 of keyframe 100 holding the features the detector extracts from the image
 *  (its query_features, 3,000) at the points behind them, and the scan's context as
 *  LocalMapManager::placeContextOf makes it. */
class PolarPlaceIndexOnARealScan : public ::testing::Test
{
   protected:
	void SetUp() override;

	Scan scan;
	RasterFrame raster;
	LocalMap::Ptr truth;
	PlaceContext context;
};

void PolarPlaceIndexOnARealScan::SetUp()
{
	RASTERSLAM_REQUIRE_SHARED_DATA();
	scan.index = 540;
	scan.points = io::loadKittiBin(test::sharedData("kitti05-revisit-0540-1319/000540.bin"));
	PluginLoader::instance().load();
	auto rasterizer =
	    PluginLoader::instance().create<Rasterizer>("rasterslam::ElevationRasterizer");
	if (!rasterizer)
		throw std::runtime_error("no rasterslam::ElevationRasterizer plugin");
	rasterizer->initialize(yaml::Map());
	rasterizer->rasterize(scan, raster);

	features::OrbParams orbParams;
	orbParams.numFeatures = 3000;
	features::OrbExtractor orb(orbParams);
	std::vector<cv::KeyPoint> kps;
	cv::Mat desc;
	orb.extract(raster.image.asCvMatRef(), kps, desc);
	truth = std::make_shared<LocalMap>();
	truth->id = 1;
	truth->keyframes = {100};
	for (int i = 0; i < static_cast<int>(kps.size()); i++)
	{
		const int32_t idx = raster::pointAtPixel(raster, kps[i].pt.x, kps[i].pt.y, 1);
		if (idx < 0)
			continue;
		const auto& pt = scan.points[static_cast<std::size_t>(idx)];
		truth->xyz.insert(truth->xyz.end(), {pt.x, pt.y, pt.z});
		truth->observers.push_back(1);
		truth->descriptors.insert(truth->descriptors.end(), desc.ptr<uint8_t>(i),
		                          desc.ptr<uint8_t>(i) + 32);
	}
	std::vector<PointXYZI> imagePts;
	raster::appendImagePoints(raster, scan.points, imagePts);
	context.rings = 10;
	context.sectors = 60;
	context.cells =
	    places::quantizedCells(places::polarContext(imagePts), LocalMap::kContextStep_m);
	truth->contextRings = context.rings;
	truth->contextSectors = context.sectors;
	truth->contextCells = context.cells;
}
}  // namespace

TEST_F(PolarPlaceIndexOnARealScan, RelocalizeScanVerifiesThePlaceTheScanContextRanks)
{
	// The real scan relocalized with no prior, with the map manager's context of it
	// (loop_detector.polar_relocalization): the true place (local map 1) holds the scan's
	// features and context and an image sharing 30 of its words; three distractors hold an
	// image of all its words, other features and no contexts. Only the first
	// max_candidates + 1 candidates are verified.
	ASSERT_GE(truth->points(), 300u) << "too few features on the real scan";
	const auto lms = withDistractors(truth);
	const Map map = mapOfAnchors(lms);
	PoseView poses;
	poses.prior = &map.priorPoses;
	const std::vector<uint8_t> few(truth->descriptors.begin(),
	                               truth->descriptors.begin() + 32 * 30);
	const auto relocalize = [&](const std::string& params, const PlaceContext& c)
	{
		auto d = makeDetector("min_score: 0\n" + params);
		for (const auto& lm : lms)
			d->index(*lm, lm->id == 1 ? few : truth->descriptors);
		EXPECT_EQ(d->usesScanContexts(),
		          params.find("polar_relocalization: true") != std::string::npos);
		return d->relocalizeScan(scan, raster, c, map, poses);
	};
	// The words rank it fourth: with four verified (max_candidates 3) they find it, with two
	// they miss it, as they do when the detector does not relocalize by the contexts or is
	// given none.
	const std::string two = "max_candidates: 1\n", byContext = "polar_relocalization: true\n";
	const auto fourth = relocalize("max_candidates: 3\n", context);
	ASSERT_TRUE(fourth.found) << fourth.reason;
	EXPECT_EQ(fourth.localMap, 1u);
	EXPECT_FALSE(relocalize(two, context).found);
	EXPECT_FALSE(relocalize(two + "polar_fusion: true\n", context).found);
	EXPECT_FALSE(relocalize(two + "polar_fusion: true\n" + byContext, {}).found);
	// By its context too it comes first: found with two verified, at the scan's own pose.
	const auto found = relocalize(two + "polar_fusion: true\n" + byContext, context);
	ASSERT_TRUE(found.found) << found.reason;
	EXPECT_EQ(found.localMap, 1u);
	EXPECT_EQ(found.keyframe, 100u);
	EXPECT_GE(found.inliers, 100u);
	EXPECT_LT(found.pose.norm(), 0.05);
	// A context of other dimensions than the index's is not used.
	PlaceContext other = context;
	other.sectors = 30;
	other.cells.resize(10 * 30);
	EXPECT_FALSE(relocalize(two + "polar_fusion: true\n" + byContext, other).found);
}

TEST_F(PolarPlaceIndexOnARealScan, AFitRefusedOnItsGroundDoesNotHideAPlaceVerifiedAfterIt)
{
	// Two places for the real scan. Local map 2 holds all of the scan's features and an image
	// of all its words (ranked first), but its keyframe's ground plane stands 20 degrees off
	// the scan's: its fit is refused on the ground. Local map 1, the true place, holds two
	// thirds of the features (its fit has fewer inliers) and an image sharing 30 words.
	const LocalMap::Ptr& all = truth;
	ASSERT_TRUE(raster.groundValid);
	ASSERT_GE(all->points(), 300u) << "too few features on the real scan";
	auto decoy = std::make_shared<LocalMap>(*all);
	decoy->id = 2;
	decoy->keyframes = {200};
	auto truth = std::make_shared<LocalMap>(*all);
	const std::size_t kept = all->points() * 2 / 3;
	truth->xyz.resize(3 * kept);
	truth->observers.resize(kept);
	truth->descriptors.resize(32 * kept);
	Map map = mapOfAnchors({truth, decoy});
	auto& decoyFrame = *map.keyframes.at(200);
	const Eigen::Vector3f level(raster.groundNormal[0], raster.groundNormal[1],
	                            raster.groundNormal[2]);
	const auto setGround = [&](const Eigen::Vector3f& n)
	{
		decoyFrame.groundValid = true;
		for (int i = 0; i < 3; i++)
			decoyFrame.groundN[i] = n[i];
		decoyFrame.groundD = raster.groundD;
	};
	setGround(Eigen::AngleAxisf(20.f * static_cast<float>(M_PI) / 180.f, Eigen::Vector3f::UnitX()) *
	          level);
	PoseView poses;
	poses.prior = &map.priorPoses;
	const std::vector<uint8_t> few(all->descriptors.begin(), all->descriptors.begin() + 32 * 30);
	const auto relocalize = [&](bool withTruth)
	{
		auto d = makeDetector("min_score: 0\nmax_candidates: 1\n");
		if (withTruth)
			d->index(*truth, few);
		d->index(*decoy, all->descriptors);
		return d->relocalizeScan(scan, raster, context, map, poses);
	};
	// The decoy alone: refused on its ground, the result naming how far it got.
	const auto decoyOnly = relocalize(false);
	EXPECT_FALSE(decoyOnly.found);
	EXPECT_EQ(decoyOnly.reason, "ground");
	EXPECT_GE(decoyOnly.inliers, 100u);
	// Both: the true place, verified after the refused fit with fewer inliers, is taken at the
	// scan's own pose.
	const auto both = relocalize(true);
	ASSERT_TRUE(both.found) << both.reason;
	EXPECT_EQ(both.reason, "ok");
	EXPECT_EQ(both.localMap, 1u);
	EXPECT_EQ(both.keyframe, 100u);
	EXPECT_LT(both.inliers, decoyOnly.inliers);
	// The decoy is verified first (its words score higher): the refused fit came before.
	EXPECT_GT(decoyOnly.score, both.score);
	EXPECT_LT(both.pose.norm(), 0.05);
	// Its ground level with the scan's, the decoy holds more inliers and is taken.
	setGround(level);
	const auto level2 = relocalize(true);
	ASSERT_TRUE(level2.found) << level2.reason;
	EXPECT_EQ(level2.localMap, 2u);
	EXPECT_GT(level2.inliers, both.inliers);
}
