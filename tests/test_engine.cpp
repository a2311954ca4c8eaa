// The engine with in-process plugins: keyframes and the pose for every scan, the input's own
// odometry as extra graph edges, and the pose-graph optimizer on a graph with a known solution.
#include <mrpt/core/initializer.h>
#include <mrpt/math/wrap2pi.h>
#include <rasterslam/core/engine.h>
#include <rasterslam/core/heap.h>
#include <rasterslam/core/plugin_loader.h>

#include <atomic>
#include <chrono>
#include <deque>
#include <filesystem>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <map>
#include <random>
#include <thread>

#include "test_support.h"

using namespace rasterslam;
using mrpt::containers::yaml;
using mrpt::poses::CPose3D;

namespace rasterslam::test
{
/** An odometry that reports a fixed step per scan and a keyframe every `every` scans. */
class FixedStepOdometry : public Odometry
{
	DEFINE_MRPT_OBJECT(FixedStepOdometry, rasterslam::test)
   public:
	OdometryResult process(const Scan&, const RasterFrame*) override
	{
		OdometryResult r;
		r.status = n_ == 0 ? TrackingStatus::Initializing : TrackingStatus::Ok;
		r.T_prev_curr = n_ == 0 ? CPose3D() : step_;
		r.keyframe = n_ % every_ == 0;
		++n_;
		return r;
	}

   protected:
	void initializeImpl(ParamReader& p) override
	{
		every_ = p.getInt("every", 3);
		step_ = CPose3D(p.getDouble("dx", 1.0), 0, 0, p.getDouble("dyaw", 0.0), 0, 0);
	}

   private:
	int every_ = 3, n_ = 0;
	CPose3D step_;
};

/** A map manager that keeps an empty map: what a loop detector needs to be queried. */
class EmptyMapManager : public MapManager
{
	DEFINE_MRPT_OBJECT(EmptyMapManager, rasterslam::test)
   public:
	MappingUpdate addKeyframe(const KeyframeInfo&, const Scan&, const RasterFrame*,
	                          const PoseView&) override
	{
		return {};
	}
	MappingUpdate finish(const PoseView&) override { return {}; }
	const Map& map() const override { return map_; }
	void loadMap(const std::string&) override {}
	void saveMap(const std::string&, const PoseView&, const std::string&,
	             const std::vector<uint8_t>&) override
	{
	}

   protected:
	void initializeImpl(ParamReader&) override {}

   private:
	Map map_;
};

/** A loop detector that finds nothing and records two decisions a query, numbered. */
class TwoDecisionsLoopDetector : public LoopDetector
{
	DEFINE_MRPT_OBJECT(TwoDecisionsLoopDetector, rasterslam::test)
   public:
	void index(const LocalMap&, const std::vector<uint8_t>&) override {}
	std::vector<LoopConstraint> detect(const KeyframeInfo& kf, const Map&, const PoseView&) override
	{
		for (int k = 0; k < 2; k++)
		{
			LoopDecision d;
			d.queryStamp = kf.stamp;
			d.inliers = made_++;
			d.reason = "inliers";
			decisions_.push_back(d);
		}
		return {};
	}
	RelocalizationResult relocalize(const Scan&, const RasterFrame&, const Map&,
	                                const PoseView&) override
	{
		return {};
	}
	std::vector<uint8_t> savePlaceIndex() override { return {}; }
	void loadPlaceIndex(const Map&) override {}

   protected:
	void initializeImpl(ParamReader&) override {}

   private:
	std::size_t made_ = 0;
};

/** A rasterizer that makes a blank image: enough for the engine to query a loop detector. */
class BlankRasterizer : public Rasterizer
{
	DEFINE_MRPT_OBJECT(BlankRasterizer, rasterslam::test)
   public:
	void rasterize(const Scan&, RasterFrame& out) override
	{
		out.image = mrpt::img::CImage(8, 8, mrpt::img::CH_GRAY);
		out.image.filledRectangle(0, 0, 7, 7, mrpt::img::TColor(0, 0, 0));
	}

   protected:
	void initializeImpl(ParamReader&) override {}
};

/** A loop detector that makes one decision a keyframe and counts the relocalizations asked of
 *  it (the engine asks them holding the map lock), never finding one. */
class CountingLoopDetector : public LoopDetector
{
	DEFINE_MRPT_OBJECT(CountingLoopDetector, rasterslam::test)
   public:
	static inline std::atomic<std::size_t> relocalizations{0};
	void index(const LocalMap&, const std::vector<uint8_t>&) override {}
	std::vector<LoopConstraint> detect(const KeyframeInfo& kf, const Map&, const PoseView&) override
	{
		LoopDecision d;
		d.queryStamp = kf.stamp;
		d.reason = "inliers";
		decisions_.push_back(d);
		return {};
	}
	RelocalizationResult relocalize(const Scan&, const RasterFrame&, const Map&,
	                                const PoseView&) override
	{
		++relocalizations;
		return {};
	}
	std::vector<uint8_t> savePlaceIndex() override { return {}; }
	void loadPlaceIndex(const Map&) override {}

   protected:
	void initializeImpl(ParamReader&) override {}
};

/** The empty map manager with a scan context that names the scan: 2 rings, 3 sectors, the
 *  cells the scan's point count and index. */
class ContextMapManager : public EmptyMapManager
{
	DEFINE_MRPT_OBJECT(ContextMapManager, rasterslam::test)
   public:
	PlaceContext placeContextOf(const Scan& scan, const RasterFrame&) const override
	{
		return contextFor(scan);
	}
	static PlaceContext contextFor(const Scan& scan)
	{
		PlaceContext c;
		c.rings = 2;
		c.sectors = 3;
		c.cells = {static_cast<uint8_t>(scan.points.size() % 256),
		           static_cast<uint8_t>(scan.index % 256),
		           1,
		           2,
		           3,
		           4};
		return c;
	}
};

/** A loop detector that ranks by scan contexts when its params say so (uses_contexts) and
 *  records the context each relocalization is given, never finding one. */
class ContextLoopDetector : public CountingLoopDetector
{
	DEFINE_MRPT_OBJECT(ContextLoopDetector, rasterslam::test)
   public:
	static inline std::vector<std::pair<std::size_t, PlaceContext>> given;
	bool usesScanContexts() const override { return uses_; }
	RelocalizationResult relocalizeScan(const Scan& scan, const RasterFrame&,
	                                    const PlaceContext& context, const Map&,
	                                    const PoseView&) override
	{
		given.emplace_back(scan.index, context);
		return {};
	}

   protected:
	void initializeImpl(ParamReader& p) override { uses_ = p.getBool("uses_contexts", false); }

   private:
	bool uses_ = false;
};
}  // namespace rasterslam::test

IMPLEMENTS_MRPT_OBJECT(ContextMapManager, rasterslam::test::EmptyMapManager, rasterslam::test)
IMPLEMENTS_MRPT_OBJECT(ContextLoopDetector, rasterslam::test::CountingLoopDetector,
                       rasterslam::test)
IMPLEMENTS_MRPT_OBJECT(BlankRasterizer, rasterslam::Rasterizer, rasterslam::test)
IMPLEMENTS_MRPT_OBJECT(CountingLoopDetector, rasterslam::LoopDetector, rasterslam::test)
IMPLEMENTS_MRPT_OBJECT(FixedStepOdometry, rasterslam::Odometry, rasterslam::test)
IMPLEMENTS_MRPT_OBJECT(EmptyMapManager, rasterslam::MapManager, rasterslam::test)
IMPLEMENTS_MRPT_OBJECT(TwoDecisionsLoopDetector, rasterslam::LoopDetector, rasterslam::test)
MRPT_INITIALIZER(register_test_plugins)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::test::FixedStepOdometry));
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::test::EmptyMapManager));
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::test::TwoDecisionsLoopDetector));
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::test::BlankRasterizer));
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::test::CountingLoopDetector));
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::test::ContextMapManager));
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::test::ContextLoopDetector));
}

namespace
{
class VectorSource : public ScanSource
{
   public:
	explicit VectorSource(std::deque<Scan> s) : scans_(std::move(s)) {}
	std::optional<Scan> next() override
	{
		if (scans_.empty())
			return std::nullopt;
		Scan s = std::move(scans_.front());
		scans_.pop_front();
		return s;
	}
	std::string name() const override { return "memory"; }

   private:
	std::deque<Scan> scans_;
};

std::deque<Scan> makeScans(int n, bool withOdometry, const CPose3D& odoStep)
{
	std::deque<Scan> out;
	for (int k = 0; k < n; k++)
	{
		Scan s;
		s.index = k;
		s.stamp = 10 + 0.1 * k;
		for (int i = 0; i < 200; i++)
			s.points.push_back({float(i), 1, 0, 0});
		if (withOdometry && k > 0)
		{
			mrpt::poses::CPose3DPDFGaussian inc(odoStep);
			inc.cov.setIdentity();
			inc.cov *= 1e-4;
			s.odometryIncrement = inc;
		}
		out.push_back(std::move(s));
	}
	return out;
}
}  // namespace

TEST(Engine, LoopDecisionsAreHandedOverAsTheRunGoesWhenAsked)
{
	// A lifelong run keeps no loop decision in memory: with onLoopDecisions set, each
	// keyframe's decisions are handed over once it is processed, in order, and the result
	// keeps none (only their count); without it, the result has them all, as before.
	const auto cfg = yaml::FromText(
	    "odometry: {class: rasterslam::test::FixedStepOdometry, params: {every: 3}}\n"
	    "map_manager: {class: rasterslam::test::EmptyMapManager}\n"
	    "loop_detector: {class: rasterslam::test::TwoDecisionsLoopDetector}\n");
	std::vector<LoopDecision> handed;
	std::vector<std::size_t> scansSeenAtHandover;
	std::size_t scansSeen = 0;
	RunOptions o;
	o.onScan = [&](const ScanRecord&, double) { ++scansSeen; };
	o.onLoopDecisions = [&](std::vector<LoopDecision>&& d)
	{
		scansSeenAtHandover.push_back(scansSeen);
		for (auto& l : d)
			handed.push_back(std::move(l));
	};
	Engine e(cfg, "t.yaml");
	VectorSource src(makeScans(30, false, CPose3D()));
	const auto res = e.run(src, o);
	ASSERT_EQ(res.keyframes, 10u);
	EXPECT_TRUE(res.loopDecisions.empty());
	EXPECT_EQ(res.loopDecisionsMade, 20u);
	ASSERT_EQ(handed.size(), 20u);
	for (std::size_t i = 0; i < handed.size(); i++)
		EXPECT_EQ(handed[i].inliers, i);  // every one, in the order made
	// Handed over during the run, a keyframe at a time, not all at its end.
	ASSERT_FALSE(scansSeenAtHandover.empty());
	EXPECT_LT(scansSeenAtHandover.front(), 5u);
	EXPECT_GE(scansSeenAtHandover.size(), 10u);

	Engine kept(cfg, "t.yaml");
	VectorSource src2(makeScans(30, false, CPose3D()));
	const auto all = kept.run(src2, {});
	EXPECT_EQ(all.loopDecisionsMade, 20u);
	ASSERT_EQ(all.loopDecisions.size(), 20u);
	EXPECT_EQ(all.loopDecisions.back().inliers, 19u);

	// Played at the scans' stamps (ten times faster), where the back end works while the
	// tracking waits: the same decisions, each handed over once.
	Engine paced(cfg, "t.yaml");
	VectorSource src3(makeScans(30, false, CPose3D()));
	std::vector<std::size_t> inliers;
	RunOptions rt;
	rt.realtime = true;
	rt.rate = 10;
	rt.onLoopDecisions = [&](std::vector<LoopDecision>&& d)
	{
		EXPECT_FALSE(d.empty());  // nothing to hand over is not handed over
		for (const auto& l : d)
			inliers.push_back(l.inliers);
	};
	const auto rtRes = paced.run(src3, rt);
	ASSERT_EQ(rtRes.keyframes, 10u);
	EXPECT_TRUE(rtRes.loopDecisions.empty());
	EXPECT_EQ(rtRes.loopDecisionsMade, 20u);
	ASSERT_EQ(inliers.size(), 20u);
	for (std::size_t i = 0; i < inliers.size(); i++)
		EXPECT_EQ(inliers[i], i);
}

TEST(Engine, TheMapIsUnlockedWhileDecisionsAreHandedOver)
{
	// The receiver of the decisions may take its time (rasterslam run writes them to a file):
	// meanwhile the tracking must be able to take the map lock. Here a session seeking its
	// anchor in a prior map asks the loop detector a relocalization under that lock at every
	// scan (anchor_every_scan, the default). The tracking is held after scan 1 until the first
	// hand-over (keyframe 0's decision) has begun, and that hand-over waits for the next
	// request: it can only come if the map is unlocked while the decisions are handed over.
	const auto cfg = yaml::FromText(
	    "rasterizer: {class: rasterslam::test::BlankRasterizer}\n"
	    "odometry: {class: rasterslam::test::FixedStepOdometry, params: {every: 3}}\n"
	    "map_manager: {class: rasterslam::test::EmptyMapManager}\n"
	    "loop_detector: {class: rasterslam::test::CountingLoopDetector}\n");
	auto& asked = test::CountingLoopDetector::relocalizations;
	asked = 0;
	std::atomic<std::size_t> handOvers{0};
	std::size_t askedBefore = 0;
	bool askedDuringHandOver = false;
	bool heldUntilHandOver = false;
	RunOptions o;
	o.relocalizeFirstScan = true;  // never found: it keeps asking
	o.realtime = true;             // the tracking does not wait for the back end
	o.rate = 10;
	o.onScan = [&](const ScanRecord& rec, double)
	{
		if (rec.index != 1)
			return;
		const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
		while (handOvers == 0 && std::chrono::steady_clock::now() < until)
			std::this_thread::sleep_for(std::chrono::milliseconds(1));
		heldUntilHandOver = handOvers > 0;
	};
	o.onLoopDecisions = [&](std::vector<LoopDecision>&&)
	{
		if (handOvers > 0)
		{
			++handOvers;
			return;
		}
		askedBefore = asked.load();
		++handOvers;  // releases the tracking
		const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
		while (asked == askedBefore && std::chrono::steady_clock::now() < until)
			std::this_thread::sleep_for(std::chrono::milliseconds(1));
		askedDuringHandOver = asked > askedBefore;
	};
	Engine e(cfg, "t.yaml");
	VectorSource src(makeScans(30, false, CPose3D()));
	const auto res = e.run(src, o);
	EXPECT_EQ(res.keyframes, 10u);
	EXPECT_FALSE(res.localized);
	EXPECT_GE(asked.load(), 2u);
	ASSERT_GE(handOvers.load(), 1u);
	ASSERT_TRUE(heldUntilHandOver) << "keyframe 0's decision was not handed over within 20 s";
	EXPECT_TRUE(askedDuringHandOver)
	    << "no relocalization could start while the decisions were handed over";
}

TEST(Engine, RelocalizationsGetTheMapManagersScanContextOnlyWhenTheDetectorRanksByIt)
{
	// A session seeking its place (relocalizeFirstScan) asks at every scan: the detector is
	// given the map manager's context of that very scan when it says it ranks by contexts
	// (usesScanContexts), and an empty one otherwise, so that no context is made for nothing.
	for (const bool uses : {true, false})
	{
		SCOPED_TRACE(uses ? "the detector ranks by contexts" : "it does not");
		const auto cfg = yaml::FromText(
		    std::string("rasterizer: {class: rasterslam::test::BlankRasterizer}\n"
		                "odometry: {class: rasterslam::test::FixedStepOdometry}\n"
		                "map_manager: {class: rasterslam::test::ContextMapManager}\n"
		                "loop_detector: {class: rasterslam::test::ContextLoopDetector, params: "
		                "{uses_contexts: ") +
		    (uses ? "true" : "false") + "}}\n");
		auto& given = test::ContextLoopDetector::given;
		given.clear();
		RunOptions o;
		o.relocalizeFirstScan = true;  // never found: it keeps asking
		Engine e(cfg, "t.yaml");
		auto scans = makeScans(6, false, CPose3D());
		for (auto& s : scans)  // scans told apart by their point count too
			s.points.resize(s.points.size() - static_cast<std::size_t>(3 * s.index));
		std::map<std::size_t, Scan> byIndex;
		for (const auto& s : scans)
			byIndex.emplace(s.index, s);
		VectorSource src(scans);
		e.run(src, o);
		ASSERT_GE(given.size(), 2u);
		for (const auto& [index, context] : given)
		{
			ASSERT_EQ(byIndex.count(index), 1u) << "scan " << index;
			const auto expected = test::ContextMapManager::contextFor(byIndex.at(index));
			if (!uses)
			{
				EXPECT_TRUE(context.empty()) << "scan " << index;
				continue;
			}
			EXPECT_EQ(context.rings, expected.rings);
			EXPECT_EQ(context.sectors, expected.sectors);
			EXPECT_EQ(context.cells, expected.cells) << "scan " << index;
		}
		// What rasterslam relocalize asks the engine for: the same rule.
		const Scan& first = byIndex.at(0);
		EXPECT_EQ(e.scanContext(first, RasterFrame{}).cells,
		          uses ? test::ContextMapManager::contextFor(first).cells : std::vector<uint8_t>{});
	}
	// With no loop detector there is nothing to rank by: no context.
	Engine bare(yaml::FromText("rasterizer: {class: rasterslam::test::BlankRasterizer}\n"
	                           "odometry: {class: rasterslam::test::FixedStepOdometry}\n"
	                           "map_manager: {class: rasterslam::test::ContextMapManager}\n"),
	            "t.yaml");
	ASSERT_FALSE(bare.loopDetector());
	EXPECT_TRUE(bare.scanContext(makeScans(1, false, CPose3D()).front(), RasterFrame{}).empty());
}

TEST(Engine, KeyframesAndAPoseForEveryScan)
{
	Engine e(yaml::FromText("odometry: {class: rasterslam::test::FixedStepOdometry, params: "
	                        "{every: 3, dx: 1.0, dyaw: 0.1}}\n"),
	         "t.yaml");
	VectorSource src(makeScans(10, false, CPose3D()));
	const auto res = e.run(src, {});
	ASSERT_EQ(res.scans.size(), 10u);
	ASSERT_EQ(res.poses.size(), 10u);
	EXPECT_EQ(res.keyframes, 4u);  // scans 0, 3, 6, 9
	EXPECT_EQ(res.graph.nodes.size(), 4u);
	EXPECT_EQ(res.graph.edges.size(), 3u);
	// Scan k is k steps of (1 m, 0.1 rad) from the first.
	CPose3D expected;
	for (int k = 0; k < 10; k++)
	{
		EXPECT_NEAR((res.poses[k].asVectorVal() - expected.asVectorVal()).norm(), 0, 1e-9) << k;
		EXPECT_EQ(res.scans[k].keyframe, k % 3 == 0) << k;
		expected = expected + CPose3D(1, 0, 0, 0.1, 0, 0);
	}
	// A non-keyframe scan is placed relative to its keyframe.
	EXPECT_EQ(res.scans[5].kfNode, 1u);
	EXPECT_NEAR(res.scans[5].T_kf_scan.x, 1 + std::cos(0.1), 1e-9);
}

TEST(Engine, SpooledScanRecordsGiveTheSameRun)
{
	// 700 scans: the records cross several writes to the temporary file.
	const auto cfg = yaml::FromText(
	    "odometry: {class: rasterslam::test::FixedStepOdometry, params: "
	    "{every: 3, dx: 1.0, dyaw: 0.01}}\n");
	Engine a(cfg, "t.yaml");
	VectorSource srcA(makeScans(700, false, CPose3D()));
	const auto inMemory = a.run(srcA, {});
	// Scan k is k steps of (1 m, 0.01 rad): on a circle. Composing the steps through each
	// keyframe's rotation and its transpose once let rounding grow to NaN by scan 87.
	ASSERT_EQ(inMemory.poses.size(), 700u);
	for (std::size_t k : {87, 300, 699})
	{
		double x = 0, y = 0;
		for (std::size_t j = 0; j < k; j++)
		{
			x += std::cos(0.01 * static_cast<double>(j));
			y += std::sin(0.01 * static_cast<double>(j));
		}
		EXPECT_NEAR(inMemory.poses[k].x(), x, 1e-6) << k;
		EXPECT_NEAR(inMemory.poses[k].y(), y, 1e-6) << k;
		EXPECT_NEAR(mrpt::math::wrapToPi(inMemory.poses[k].yaw() - 0.01 * static_cast<double>(k)),
		            0, 1e-9)
		    << k;
	}

	const test::ScopedTempDir dir("engine-scan-spool");
	Engine b(cfg, "t.yaml");
	VectorSource srcB(makeScans(700, false, CPose3D()));
	RunOptions o;
	o.spoolScans = true;
	o.scanSpoolDir = dir.path().string();
	std::size_t seen = 0;
	o.onScan = [&](const ScanRecord& r, double)
	{
		EXPECT_EQ(r.index, seen);
		++seen;
	};
	const auto spooled = b.run(srcB, o);
	EXPECT_TRUE(spooled.scans.isSpooled());
	EXPECT_FALSE(inMemory.scans.isSpooled());
	EXPECT_EQ(spooled.error, "");
	EXPECT_EQ(seen, 700u);
	EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
	ASSERT_EQ(spooled.scans.size(), 700u);
	ASSERT_EQ(spooled.poses.size(), inMemory.poses.size());
	for (std::size_t k = 0; k < 700; k += 13)
	{
		EXPECT_EQ(spooled.poses[k], inMemory.poses[k]) << k;
		EXPECT_EQ(spooled.scans[k].kfNode, inMemory.scans[k].kfNode) << k;
		EXPECT_EQ(spooled.scans[k].keyframe, k % 3 == 0) << k;
	}

	// No temporary file can be made: the records stay in memory and the run is the same.
	Engine c(cfg, "t.yaml");
	VectorSource srcC(makeScans(700, false, CPose3D()));
	o.scanSpoolDir = (dir / "no-such-folder").string();
	o.onScan = nullptr;
	const auto fallback = c.run(srcC, o);
	EXPECT_FALSE(fallback.scans.isSpooled());
	EXPECT_EQ(fallback.error, "");
	ASSERT_EQ(fallback.poses.size(), 700u);
	EXPECT_EQ(fallback.poses.back(), inMemory.poses.back());
}

TEST(Engine, FirstLastSelectInputIndices)
{
	Engine e(yaml::FromText("odometry: {class: rasterslam::test::FixedStepOdometry}\n"), "t.yaml");
	VectorSource src(makeScans(10, false, CPose3D()));
	RunOptions o;
	o.first = 2;
	o.last = 6;
	const auto res = e.run(src, o);
	ASSERT_EQ(res.scans.size(), 5u);
	EXPECT_EQ(res.scans.front().index, 2u);
	EXPECT_EQ(res.scans.back().index, 6u);
}

TEST(Engine, RawlogOdometryBecomesExtraEdgesAndIsOptimized)
{
	PluginLoader::instance().load();
	// The LiDAR odometry says 1 m a scan; the wheel odometry says 1.1 m with a much smaller
	// covariance: after optimization the keyframes follow the wheels.
	const std::string cfg =
	    "odometry: {class: rasterslam::test::FixedStepOdometry, params: {every: 2, dx: 1.0}}\n"
	    "optimizer: {class: rasterslam::LevMarqOptimizer}\n"
	    "engine: {use_rawlog_odometry: true}\n";
	Engine e(yaml::FromText(cfg), "t.yaml");
	VectorSource src(makeScans(7, true, CPose3D(1.1, 0, 0, 0, 0, 0)));
	const auto res = e.run(src, {});
	EXPECT_EQ(res.keyframes, 4u);  // 0, 2, 4, 6
	EXPECT_EQ(res.odometryEdges, 3u);
	EXPECT_EQ(res.graph.edges.size(), 6u);  // one LiDAR and one wheel edge a keyframe pair
	bool sawWheelEdge = false;
	for (const auto& [ids, edge] : res.graph.edges)
		if (std::abs(edge.mean.x() - 2.2) < 1e-9)
			sawWheelEdge = true;
	EXPECT_TRUE(sawWheelEdge);
	EXPECT_TRUE(res.optimizer.ran);
	EXPECT_LT(res.optimizer.finalError, res.optimizer.initialError);
	// The LiDAR edges (information 0.5) are far weaker than the wheel edges (400): the
	// optimum spaces keyframes 2.1998 m apart, 6.599 m to keyframe 3; the LiDAR chain alone
	// says 6.0. MRPT's Levenberg-Marquardt stops short of the optimum here (6.45-6.6).
	EXPECT_GT(res.graph.nodes.at(3).x(), 6.4);
	EXPECT_LT(res.graph.nodes.at(3).x(), 6.61);
	EXPECT_NEAR(res.poses[6].x(), res.graph.nodes.at(3).x(), 1e-9);

	// Without the option, the odometry in the input is ignored.
	Engine off(yaml::FromText(
	               "odometry: {class: rasterslam::test::FixedStepOdometry, params: {every: 2}}\n"),
	           "t.yaml");
	VectorSource src2(makeScans(7, true, CPose3D(1.1, 0, 0, 0, 0, 0)));
	EXPECT_EQ(off.run(src2, {}).odometryEdges, 0u);
}

TEST(Optimizer, RecoversAKnownSquare)
{
	PluginLoader::instance().load();
	auto opt = PluginLoader::instance().create<Optimizer>("rasterslam::LevMarqOptimizer");
	opt->initialize(yaml());
	// A square of side 10 driven once: exact edges, a loop edge back to the start, and
	// initial node poses corrupted by seeded noise.
	mrpt::graphs::CNetworkOfPoses3DInf g;
	std::vector<CPose3D> truth;
	CPose3D p;
	for (int i = 0; i < 8; i++)
	{
		truth.push_back(p);
		p = p + CPose3D(5, 0, 0, (i % 2 == 1) ? M_PI / 2 : 0, 0, 0);
	}
	std::mt19937 rng(5);
	std::normal_distribution<double> n(0, 0.3);
	for (int i = 0; i < 8; i++)
		g.nodes[i] = i == 0 ? truth[0]
		                    : truth[i] + CPose3D(n(rng), n(rng), 0.1 * n(rng), 0.1 * n(rng), 0, 0);
	auto addEdge = [&](int a, int b)
	{
		mrpt::graphs::CNetworkOfPoses3DInf::edge_t e;
		e.mean = truth[b] - truth[a];
		e.cov_inv.setIdentity();
		e.cov_inv *= 100;
		g.insertEdge(a, b, e);
	};
	for (int i = 0; i + 1 < 8; i++)
		addEdge(i, i + 1);
	addEdge(7, 0);
	g.root = 0;
	const auto r = opt->optimize(g);
	EXPECT_TRUE(r.ran);
	EXPECT_LT(r.finalError, r.initialError);
	for (int i = 0; i < 8; i++)
		EXPECT_NEAR((g.nodes[i] - truth[i]).asVectorVal().norm(), 0, 1e-4) << i;
}

TEST(Heap, ScanBlocksStayInTheHeapUnlessTheEnvironmentSaysOtherwise)
{
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
	GTEST_SKIP() << "a sanitizer's allocator replaces glibc's heap";
#elif !defined(__GLIBC__)
	GTEST_SKIP() << "the heap policy is glibc's";
#else
	// The user's own settings stand: nothing is changed, and the reason names them.
	ASSERT_EQ(::setenv("MALLOC_TOP_PAD_", "0", 1), 0);
	const auto refused = keepScanBlocksInHeap();
	::unsetenv("MALLOC_TOP_PAD_");
	EXPECT_NE(refused.find("MALLOC_TOP_PAD_"), std::string::npos) << refused;

	// Applied: a scan-sized block (4 MB) comes from the heap, not from a mapping of its own
	// (glibc's default maps a block that size, the first time, and unmaps it when freed).
	ASSERT_EQ(keepScanBlocksInHeap(), "");
	const auto mappedBefore = ::mallinfo2().hblkhd;
	std::vector<char> block(4u << 20, 1);
	EXPECT_EQ(::mallinfo2().hblkhd, mappedBefore);
	// And freeing it keeps it: the heap's free space grows by the block.
	const auto freeBefore = ::mallinfo2().fordblks;
	std::vector<char>().swap(block);
	EXPECT_GE(::mallinfo2().fordblks, freeBefore + (4u << 20));
#endif
}
