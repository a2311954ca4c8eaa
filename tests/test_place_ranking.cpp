// The BOW database ranks the true place on top among distractors: rasterslam-bench-places
// over five simulated towns (235 places that look alike: the same generator, other seeds).
#include "test_json.h"
#include "test_support.h"

using namespace rasterslam;

namespace
{
nlohmann::json bench(const std::string& extra)
{
	const auto r = test::runCommand(
	    test::bin("rasterslam-bench-places") + " --json --towns 5 --queries 10 --scenario " +
	    test::sourcePath("rawlogs/town-loop.yaml") + " --vocabulary " +
	    test::sourcePath("share/rasterslam/vocab/elevation-k10l4.vocab") + " " + extra);
	EXPECT_EQ(r.exitCode, 0) << r.output;
	std::printf("%s", r.output.c_str());
	return test::parseJson(r.output);
}
}  // namespace

TEST(PlaceRanking, TruePlaceOnTopAmongDistractors)
{
	// Queries between two places of the route, turned by 90 degrees or driven the other way.
	const auto j = bench("--offset 0 --yaw 90");
	ASSERT_EQ(j["places"].get<int>(), 235);
	ASSERT_EQ(j["queries"].get<int>(), 50);
	// README: recall@1 0.98, recall@5 0.98; a random ranking finds one in 23 at 5.
	EXPECT_GE(j["recall_at_5"].get<double>(), 0.95);
	EXPECT_GE(j["recall_at_1"].get<double>(), 0.9);
	EXPECT_LT(j["random_recall_at_5"].get<double>(), 0.05);
}

TEST(PlaceRanking, TurnedAndAsideQueries)
{
	// 3 m to the side and turned by 20 degrees (or driven the other way): the elevation
	// image's pixel grid no longer lines up, and the ranking suffers (README: recall@5 0.82;
	// 0.68 for the turned ones, 0.96 for those driven the other way).
	const auto j = bench("--offset 3 --yaw 20");
	EXPECT_GE(j["recall_at_5"].get<double>(), 0.8);
	EXPECT_GE(j["recall_at_5_same_way"].get<double>(), 0.6);
}
