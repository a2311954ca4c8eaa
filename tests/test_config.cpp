// Strict config files: syntax errors, duplicate keys, anchors and out-of-range values are
// errors naming the file, the line and the key; every shipped config still loads as before.
#include <rasterslam/core/config.h>
#include <rasterslam/core/engine.h>

#include <fstream>
#include <sstream>

#include "test_support.h"

using namespace rasterslam;
using mrpt::containers::yaml;
namespace fs = std::filesystem;

namespace
{
/** The ConfigError's message; "" when none; another exception is reported as such. */
std::string configError(const std::function<void()>& f)
{
	try
	{
		f();
	}
	catch (const ConfigError& e)
	{
		return e.what();
	}
	catch (const std::exception& e)
	{
		return std::string("not a ConfigError: ") + e.what();
	}
	return "";
}

std::string write(const fs::path& p, const std::string& text)
{
	std::ofstream(p) << text;
	return p.string();
}

std::string readText(const std::string& path)
{
	std::ifstream f(path);
	std::stringstream ss;
	ss << f.rdbuf();
	return ss.str();
}

/** Loads the file strictly and constructs an Engine from it, as `rasterslam run` does. */
std::string engineError(const std::string& path)
{
	return configError([&] { Engine e(loadYamlFile(path), path); });
}

/** 1-based line of the first occurrence of `s` in `text`. */
int lineOf(const std::string& text, const std::string& s)
{
	const auto pos = text.find(s);
	EXPECT_NE(pos, std::string::npos) << s;
	return 1 + static_cast<int>(std::count(text.begin(), text.begin() + pos, '\n'));
}

std::string shipped(const std::string& rel)
{
	return test::sourcePath(rel);
}

const char* kShipped[] = {"share/rasterslam/config/slam.yaml",
                          "share/rasterslam/config/lifelong.yaml",
                          "share/rasterslam/config/indoor.yaml",
                          "share/rasterslam/config/gicp-indoor.yaml",
                          "share/rasterslam/config/tracking.yaml",
                          "share/rasterslam/config/tracking-refined.yaml",
                          "share/rasterslam/config/gicp-baseline.yaml",
                          "examples/plugin-template/config/flat-ground.yaml"};

/** The tree without comments or layout: null ~, scalars quoted, [seq], {key: value}. */
std::string tree(const yaml::node_t& n)
{
	if (n.isNullNode())
		return "~";
	if (n.isScalar())
		return "'" + n.as<std::string>() + "'";
	std::string s;
	if (n.isSequence())
	{
		for (const auto& e : n.asSequence())
			s += (s.empty() ? "" : ", ") + tree(e);
		return "[" + s + "]";
	}
	for (const auto& kv : n.asMap())
		s += (s.empty() ? "" : ", ") + tree(kv.first) + ": " + tree(kv.second);
	return "{" + s + "}";
}

std::string tree(const yaml& y)
{
	return tree(y.node());
}

std::string printed(const yaml& y)
{
	std::stringstream ss;
	y.printAsYAML(ss);
	return ss.str();
}
}  // namespace

TEST(StrictConfig, SyntaxErrorsNameFileAndLine)
{
	test::ScopedTempDir dir("config");
	// An unclosed '{': MRPT's parser alone printed a diagnostic and returned a map.
	const auto unclosed = write(dir / "unclosed.yaml",
	                            "odometry: {class: rasterslam::GicpOdometry\n"
	                            "engine:\n"
	                            "  min_points: 10\n");
	auto e = engineError(unclosed);
	EXPECT_EQ(e.rfind(unclosed + ":2:", 0), 0u) << e;
	EXPECT_NE(e.find("YAML syntax error"), std::string::npos) << e;
	EXPECT_NE(e.find("'{' opened at line 1, column 11"), std::string::npos) << e;

	const auto indent = write(dir / "indent.yaml",
	                          "odometry:\n"
	                          "  class: rasterslam::GicpOdometry\n"
	                          "  params:\n"
	                          "    voxel_m: 0.5\n"
	                          "   max_iterations: 3\n");
	e = engineError(indent);
	EXPECT_EQ(e.rfind(indent + ":5:", 0), 0u) << e;
	EXPECT_NE(e.find("YAML syntax error"), std::string::npos) << e;
	EXPECT_NE(e.find("check the indentation"), std::string::npos) << e;

	const auto unclosedList = write(
	    dir / "list.yaml", "plugins: [a.so, b.so\nodometry: {class: rasterslam::GicpOdometry}\n");
	e = engineError(unclosedList);
	EXPECT_EQ(e.rfind(unclosedList + ":", 0), 0u) << e;
	EXPECT_NE(e.find("'[' opened at line 1, column 10"), std::string::npos) << e;

	const auto twoDocs = write(dir / "two.yaml",
	                           "odometry: {class: rasterslam::GicpOdometry}\n---\n"
	                           "odometry: {class: rasterslam::OrbOdometry}\n");
	e = engineError(twoDocs);
	EXPECT_EQ(e.rfind(twoDocs + ":2:1: a second YAML document", 0), 0u) << e;

	// Not a map at the top level, and an empty file: as before.
	EXPECT_NE(engineError(write(dir / "scalar.yaml", "hello\n"))
	              .find("expected a YAML map of sections at the top level"),
	          std::string::npos);
	EXPECT_NE(engineError(write(dir / "empty.yaml", "# nothing\n"))
	              .find("expected a YAML map of sections at the top level"),
	          std::string::npos);
}

TEST(StrictConfig, DuplicateTopLevelSection)
{
	test::ScopedTempDir dir("config");
	// The measured case: a second engine section silently dropped optimize_at_end.
	const std::string text = readText(shipped("share/rasterslam/config/slam.yaml"));
	const std::string dup = text + "engine:\n  optimize_online: false\n";
	const auto path = write(dir / "slam.yaml", dup);
	const auto e = engineError(path);
	const int first = lineOf(dup, "\nengine:") + 1;
	const int second = static_cast<int>(std::count(dup.begin(), dup.end(), '\n')) - 1;
	EXPECT_EQ(e, path + ":" + std::to_string(second) +
	                 ":1: duplicate key 'engine' (first at line " + std::to_string(first) + ")");
}

TEST(StrictConfig, DuplicateKeyInParams)
{
	test::ScopedTempDir dir("config");
	const auto block = write(dir / "block.yaml",
	                         "odometry:\n"
	                         "  class: rasterslam::GicpOdometry\n"
	                         "  params:\n"
	                         "    voxel_m: 0.5\n"
	                         "    max_iterations: 3\n"
	                         "    voxel_m: 0.7\n");
	EXPECT_EQ(engineError(block),
	          block + ":6:5: duplicate key 'odometry.params.voxel_m' (first at line 4)");
	const auto flow = write(dir / "flow.yaml",
	                        "odometry: {class: rasterslam::GicpOdometry,\n"
	                        "           params: {voxel_m: 0.5, voxel_m: 1}}\n");
	EXPECT_EQ(engineError(flow),
	          flow + ":2:35: duplicate key 'odometry.params.voxel_m' (first at line 2)");
}

TEST(StrictConfig, DuplicateKeyInNestedMaps)
{
	test::ScopedTempDir dir("config");
	// In a section (class twice: which plugin would run?).
	const auto section = write(dir / "section.yaml",
	                           "odometry:\n"
	                           "  class: rasterslam::GicpOdometry\n"
	                           "  class: rasterslam::OrbOdometry\n");
	EXPECT_EQ(engineError(section),
	          section + ":3:3: duplicate key 'odometry.class' (first at line 2)");
	// Deeper, and in a map inside a list.
	const auto deep = write(dir / "deep.yaml",
	                        "odometry:\n"
	                        "  params:\n"
	                        "    a:\n"
	                        "      b: 1\n"
	                        "      b: 2\n");
	EXPECT_EQ(engineError(deep),
	          deep + ":5:7: duplicate key 'odometry.params.a.b' (first at line 4)");
	const auto inList = write(dir / "list.yaml", "plugins: [{x: 1}, {x: 1, x: 2}]\n");
	EXPECT_EQ(engineError(inList),
	          inList + ":1:26: duplicate key 'plugins[1].x' (first at line 1)");
	// The same key in two maps is not a duplicate.
	EXPECT_EQ(configError(
	              [&] {
		              checkYamlText(
		                  "odometry: {params: {min_points: 1}}\nengine: {min_points: 1}\n",
		                  "ok.yaml");
	              }),
	          "");
}

TEST(StrictConfig, AnchorsAliasesAndMergeKeysAreRejected)
{
	// MRPT's parser cannot read them (an assertion fails); a merge key makes duplicates
	// ambiguous (which value wins?).
	auto e = configError(
	    []
	    { checkYamlText("base: &b {class: rasterslam::GicpOdometry}\nodometry: *b\n", "a.yaml"); });
	EXPECT_EQ(e.rfind("a.yaml:1:7: anchor '&b': anchors and aliases are not supported", 0), 0u)
	    << e;
	e = configError(
	    [] {
		    checkYamlText("odometry:\n  <<: {class: rasterslam::GicpOdometry}\n  class: x\n",
		                  "m.yaml");
	    });
	EXPECT_EQ(e.rfind("m.yaml:2:3: merge key '<<' in 'odometry'", 0), 0u) << e;
	e = configError([] { checkYamlText("? [a, b]\n: 1\n", "k.yaml"); });
	EXPECT_EQ(e.rfind("k.yaml:1:3: a list or a map as a key", 0), 0u) << e;
}

TEST(StrictConfig, OutOfRangeValuesNameFileLineAndKey)
{
	test::ScopedTempDir dir("config");
	struct Case
	{
		std::string section, className, key, value, expected;
	};
	const std::vector<Case> cases = {
	    {"loop_detector", "rasterslam::BowLoopDetector", "min_inliers", "-5",
	     "must be >= 3, got -5"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "min_score", "-0.1",
	     "must be >= 0, got -0.1"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "max_hamming", "300",
	     "must be in [0, 256], got 300"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "query_turns", "0",
	     "must be in [1, 16], got 0"},
	    {"rasterizer", "rasterslam::ElevationRasterizer", "resolution_m", "0",
	     "must be > 0, got 0"},
	    {"rasterizer", "rasterslam::ElevationRasterizer", "ground_max_tilt_deg", "95",
	     "must be in [0, 90], got 95"},
	    {"odometry", "rasterslam::OrbOdometry", "min_inliers", "2", "must be >= 3, got 2"},
	    {"odometry", "rasterslam::OrbOdometry", "ratio", "1.5",
	     "must be in (0, 1] (1 disables the test), got 1.5"},
	    {"odometry", "rasterslam::OrbOdometry", "ransac_confidence", "1",
	     "must be in (0, 1), got 1"},
	    {"odometry", "rasterslam::OrbOdometry", "max_step_m", "0", "must be > 0, got 0"},
	    {"odometry", "rasterslam::OrbOdometry", "refine_keyframes", "0",
	     "must be in [1, 50], got 0"},
	    {"odometry", "rasterslam::OrbOdometry", "refine_min_overlap", "1.5",
	     "must be in [0, 1], got 1.5"},
	    {"odometry", "rasterslam::GicpOdometry", "max_fitness_m2", "-1", "must be > 0, got -1"},
	    {"odometry", "rasterslam::GicpOdometry", "min_range_m", "-2", "must be >= 0, got -2"},
	    {"map_manager", "rasterslam::LocalMapManager", "keyframes_per_map", "0",
	     "must be in [1, 32], got 0"},
	    {"map_manager", "rasterslam::LocalMapManager", "map_features", "0",
	     "must be in [1, 100000], got 0"},
	    // fuzz_config found these overflow an int count (num_features * 3) before the bound.
	    {"odometry", "rasterslam::OrbOdometry", "num_features", "0001000000000",
	     "must be in [1, 100000], got 1000000000"},
	    {"odometry", "rasterslam::OrbOdometry", "scale_levels", "1000",
	     "must be in [1, 32], got 1000"},
	    {"odometry", "rasterslam::OrbOdometry", "scale_factor", "1e300",
	     "must be in (1, 2], got 1e+300"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "query_features", "2147483647",
	     "must be in [1, 100000], got 2147483647"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "surface_search_hypotheses", "0",
	     "must be in [1, 64], got 0"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "surface_search_inlier_ratio", "0.5",
	     "must be >= 1, got 0.5"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "surface_search_yaw_step_deg", "0",
	     "must be in [0.1, 90], got 0"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "surface_search_max_conflicts", "1.5",
	     "must be in [0, 1], got 1.5"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "free_space_min_top_m", "-1",
	     "must be in [0, 100], got -1"},
	    {"loop_detector", "rasterslam::BowLoopDetector", "relocalization_max_conflicts", "-0.1",
	     "must be in [0, 1], got -0.1"},
	    {"optimizer", "rasterslam::LevMarqOptimizer", "tau", "-1", "must be > 0, got -1"},
	    {"optimizer", "rasterslam::CeresOptimizer", "max_iterations", "0", "must be >= 1, got 0"},
	};
	for (const auto& c : cases)
	{
		// A full config (every role) with the bad value in its own section's params.
		const std::vector<std::pair<std::string, std::string>> roles = {
		    {"rasterizer", "rasterslam::ElevationRasterizer"},
		    {"odometry", "rasterslam::OrbOdometry"},
		    {"map_manager", "rasterslam::LocalMapManager"},
		    {"loop_detector", "rasterslam::BowLoopDetector"},
		    {"optimizer", "rasterslam::LevMarqOptimizer"}};
		std::string text = "# a comment line\n";
		for (const auto& [role, cls] : roles)
		{
			text += role + ":\n  class: " + (role == c.section ? c.className : cls) + "\n";
			if (role == c.section)
				text += "  params:\n    " + c.key + ": " + c.value + "\n";
		}
		const auto path = write(dir / "range.yaml", text);
		const std::string where = path + ":" + std::to_string(lineOf(text, "    " + c.key)) +
		                          ":5: " + c.section + ".params." + c.key + ": ";
		EXPECT_EQ(engineError(path), where + c.expected) << text;
	}
	// The engine's own keys.
	for (const auto& [key, value, expected] :
	     std::vector<std::tuple<std::string, std::string, std::string>>{
	         {"min_points", "0", "must be >= 1, got 0"},
	         {"test_corrupt_loops", "2", "must be in [0, 1], got 2"},
	         {"anchor_agree_m", "0", "must be > 0, got 0"},
	         {"optimize_every_keyframes", "-3", "must be >= 1, got -3"}})
	{
		const auto path =
		    write(dir / "engine.yaml", "odometry: {class: rasterslam::GicpOdometry}\nengine:\n  " +
		                                   key + ": " + value + "\n");
		EXPECT_EQ(engineError(path), path + ":3:3: engine." + key + ": " + expected);
	}
	// Without a file (a config built in memory): the key, no position.
	const auto e = configError(
	    []
	    {
		    Engine en(yaml::FromText("odometry: {class: rasterslam::OrbOdometry, params: "
		                             "{min_inliers: -5}}\n"),
		              "mem.yaml");
	    });
	EXPECT_EQ(e, "mem.yaml: odometry.params.min_inliers: must be >= 3, got -5");
}

/** A config of the ORB pipeline whose loop detector has these params lines. */
std::string withLoopDetectorParams(const std::string& params)
{
	return "odometry: {class: rasterslam::OrbOdometry}\n"
	       "rasterizer: {class: rasterslam::ElevationRasterizer}\n"
	       "map_manager: {class: rasterslam::LocalMapManager}\n"
	       "loop_detector:\n  class: rasterslam::BowLoopDetector\n  params:\n" +
	       params;
}

TEST(StrictConfig, QueryTurnsAndCanonicalYawAreOneOrTheOther)
{
	// Both turn the loop detector's query image: asking for both is a mistake, not a choice.
	test::ScopedTempDir dir("config");
	const std::string text =
	    withLoopDetectorParams("    canonical_yaw: true\n    query_turns: 4\n");
	const auto path = write(dir / "turns.yaml", text);
	EXPECT_EQ(engineError(path), path + ":" + std::to_string(lineOf(text, "    query_turns")) +
	                                 ":5: loop_detector.params.query_turns: and canonical_yaw "
	                                 "both turn the query's image: use one");
}

TEST(StrictConfig, SurfaceSearchNeedsTheQuerysSurface)
{
	// The surface search aligns the query's surface, which icp_refine makes: without it the
	// option would do nothing, so it is refused rather than ignored.
	test::ScopedTempDir dir("config");
	const std::string text = withLoopDetectorParams("    relocalization_surface_search: true\n");
	const auto path = write(dir / "surface.yaml", text);
	EXPECT_EQ(engineError(path),
	          path + ":" + std::to_string(lineOf(text, "    relocalization_surface_search")) +
	              ":5: loop_detector.params.relocalization_surface_search: needs icp_refine "
	              "(the query's surface)");
}

TEST(StrictConfig, ShippedConfigsLoadToTheSameValues)
{
	for (const auto* rel : kShipped)
	{
		const auto path = shipped(rel);
		yaml strict;
		ASSERT_EQ(configError([&] { strict = loadYamlFile(path); }), "") << path;
		// The tree is built from yaml-cpp's parse: the same as MRPT's parse of the same text
		// (comments are not kept).
		EXPECT_EQ(tree(strict), tree(yaml::FromText(readText(path)))) << path;
		EXPECT_EQ(printed(strict).find('#'), std::string::npos) << path;
		// The example's rasterizer is built out of tree (tests/sdk runs it).
		if (std::string(rel).rfind("share/", 0) != 0)
			continue;
		std::unique_ptr<Engine> engine;
		ASSERT_EQ(configError([&] { engine = std::make_unique<Engine>(strict, path); }), "")
		    << path;
		// What run.yaml records loads strictly again, to the same engine.
		test::ScopedTempDir dir("config");
		std::stringstream ss;
		engine->configInForce().printAsYAML(ss);
		const auto again = write(dir / "in-force.yaml", ss.str());
		std::unique_ptr<Engine> engine2;
		ASSERT_EQ(
		    configError([&] { engine2 = std::make_unique<Engine>(loadYamlFile(again), path); }), "")
		    << ss.str();
		EXPECT_EQ(printed(engine2->configInForce()), ss.str()) << path;
	}
}

TEST(StrictConfig, RefinedTrackingIsTrackingWithTheGridTheRefinementAndTheRobustRefit)
{
	// tracking-refined.yaml is what the benchmark's tracking+grid+refine rows run
	// (scripts/benchmark.sh makes them from tracking.yaml): the same tree but for these keys.
	auto refined = loadYamlFile(shipped("share/rasterslam/config/tracking-refined.yaml"));
	auto base = loadYamlFile(shipped("share/rasterslam/config/tracking.yaml"));
	EXPECT_NE(tree(refined), tree(base));
	EXPECT_EQ(base["odometry"]["params"]["ground_model"].as<std::string>(), "plane");
	base["odometry"]["params"]["ground_model"] = "grid";
	base["odometry"]["params"]["refine"] = "rotation";
	base["odometry"]["params"]["refine_frames"] = "keyframes";
	base["odometry"]["params"]["refine_keyframes"] = "10";
	base["odometry"]["params"]["refit_cauchy_m"] = "0.1";
	// (MRPT's maps are ordered by key: the trees do not depend on where a key is written.)
	EXPECT_EQ(tree(refined), tree(base));
}

TEST(StrictConfig, TreeMatchesMrptParserOnEveryForm)
{
	// Block and flow maps and sequences, quoted and plain scalars, numbers in every notation,
	// nulls, comments, nesting: loadYamlFile builds the tree MRPT's parser builds.
	const std::string text =
	    "# a comment\n"
	    "engine: {max_scans: 10, quiet: true}   # flow map\n"
	    "odometry:\n"
	    "  class: rasterslam::OrbOdometry\n"
	    "  params:\n"
	    "    a: 1.5e-3\n"
	    "    b: -7\n"
	    "    c: [1, 2.5, x]\n"
	    "    d: 'quoted: yes'\n"
	    "    e: \"double \\\"q\\\"\"\n"
	    "    f: ~\n"
	    "    g: null\n"
	    "    h:\n"
	    "      - {k: 1}\n"
	    "      - [2, 3]\n"
	    "      - plain text\n"
	    "    i: .inf\n"
	    "    j: 0x1F\n"
	    "    l: 'null'\n";
	test::ScopedTempDir dir("config");
	const auto path = write(dir / "forms.yaml", text);
	yaml y;
	ASSERT_EQ(configError([&] { y = loadYamlFile(path); }), "");
	// One difference: MRPT's parser reads a quoted 'null' as null, YAML (and yaml-cpp) as the
	// string "null".
	std::string mrptTree = tree(yaml::FromText(text));
	const std::string quotedNull = "'l': ~";
	ASSERT_NE(mrptTree.find(quotedNull), std::string::npos) << mrptTree;
	mrptTree.replace(mrptTree.find(quotedNull), quotedNull.size(), "'l': 'null'");
	EXPECT_EQ(tree(y), mrptTree);
	EXPECT_EQ(y["odometry"]["params"]["l"].as<std::string>(), "null");
	const auto& p = y["odometry"]["params"];
	EXPECT_DOUBLE_EQ(p["a"].as<double>(), 1.5e-3);
	EXPECT_EQ(p["b"].as<int>(), -7);
	EXPECT_EQ(p["c"].asSequence().size(), 3u);
	EXPECT_EQ(p["d"].as<std::string>(), "quoted: yes");
	EXPECT_EQ(p["e"].as<std::string>(), "double \"q\"");
	EXPECT_TRUE(p["f"].isNullNode());
	EXPECT_TRUE(p["g"].isNullNode());
	EXPECT_EQ(p["h"].asSequence().size(), 3u);
	EXPECT_TRUE(y["engine"]["quiet"].as<bool>());
	// A key with nothing after it is a null value (MRPT's parser throws "empty scalar"); a
	// parameter without a value is an error (StrictConfig.OutOfRangeValuesNameFileLineAndKey).
	const auto empty = write(dir / "empty.yaml", "engine:\n  max_scans:\n");
	ASSERT_EQ(configError([&] { y = loadYamlFile(empty); }), "");
	EXPECT_TRUE(y["engine"]["max_scans"].isNullNode());
	const auto noValue = write(dir / "no-value.yaml",
	                           "odometry:\n  class: rasterslam::OrbOdometry\n  params:\n"
	                           "    num_features:\n");
	EXPECT_EQ(engineError(noValue), noValue +
	                                    ":4:5: key 'odometry.params.num_features': has no value "
	                                    "(write one, or leave the key out for the default)");
	// An empty file is not a map of sections.
	const auto none = write(dir / "none.yaml", "# nothing\n");
	EXPECT_NE(configError([&] { (void)loadYamlFile(none); }).find("expected a YAML map"),
	          std::string::npos);
}

TEST(StrictConfig, ParamReaderRangeHelpers)
{
	ParamReader p(yaml::FromText("a: 5\nb: 0.5\n"), "odometry.params", "");
	const double a = p.getDouble("a", 0), b = p.getDouble("b", 0);
	EXPECT_EQ(configError([&] { p.requireAtLeast(a, 5, "a"); }), "");
	EXPECT_EQ(configError([&] { p.requireRange(b, 0, 1, "b"); }), "");
	EXPECT_EQ(configError([&] { p.requireAtLeast(a, 6, "a"); }),
	          "odometry.params.a: must be >= 6, got 5");
	EXPECT_EQ(configError([&] { p.requireRange(b, 0.6, 1, "b"); }),
	          "odometry.params.b: must be in [0.6, 1], got 0.5");
	EXPECT_EQ(configError([&] { p.require(b > 1, b, "b", "must be > 1"); }),
	          "odometry.params.b: must be > 1, got 0.5");
	EXPECT_EQ(configError([&] { p.reject("a", "too odd"); }), "odometry.params.a: too odd");
	EXPECT_EQ(configLocation("/nonexistent/x.yaml", "a"), "/nonexistent/x.yaml");
}

TEST(StrictConfig, ProgramExitsOneWithTheMessage)
{
	test::ScopedTempDir dir("config");
	const auto run = [&](const std::string& config)
	{
		return test::runCommand(test::bin("rasterslam") + " run --config " + config + " --rawlog " +
		                        (dir / "x.rawlog").string() + " --out " + (dir / "out").string());
	};
	const auto bad = write(dir / "bad.yaml", "odometry: {class: rasterslam::GicpOdometry\n");
	auto r = run(bad);
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_NE(r.output.find("rasterslam: error: " + bad + ":2:1: YAML syntax error"),
	          std::string::npos)
	    << r.output;

	const auto dup = write(dir / "dup.yaml",
	                       "odometry: {class: rasterslam::GicpOdometry}\n"
	                       "engine: {optimize_at_end: false}\n"
	                       "engine: {min_points: 10}\n");
	r = run(dup);
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_NE(r.output.find(dup + ":3:1: duplicate key 'engine' (first at line 2)"),
	          std::string::npos)
	    << r.output;

	const auto range = write(dir / "range.yaml",
	                         "odometry:\n  class: rasterslam::GicpOdometry\n"
	                         "  params:\n    voxel_m: 0\n");
	r = run(range);
	EXPECT_EQ(r.exitCode, 1) << r.output;
	EXPECT_NE(r.output.find(range + ":4:5: odometry.params.voxel_m: must be > 0, got 0"),
	          std::string::npos)
	    << r.output;
}
