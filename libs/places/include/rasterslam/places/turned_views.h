// Turned query images (loop_detector.query_turns, rasterslam-bench-places --query-turns): the
// pixel grid of an elevation image is fixed to the sensor's heading, so a place seen turned
// by an angle that is not a multiple of 90 degrees gives other ORB features. The query is
// rasterized again turned by k * 90 / N degrees (k = 1..N-1); one of the N images then lies
// within 45 / N degrees of any place's grid.
#pragma once

#include <rasterslam/bow/vocabulary.h>
#include <rasterslam/features/orb_extractor.h>
#include <rasterslam/raster/elevation_image.h>

#include <vector>

namespace rasterslam::places
{
struct TurnedView
{
	bow::BowVector words;
	/** The vocabulary's selfScore of the view's descriptors (0 under 40 of them): its
	 *  normalizer in bow::Database::queryViews. */
	double selfScore = 0;
};

/** The N - 1 turned views of `pts` (rasterized above `ground` with `params`), in the order of
 *  k; none for turns < 2. */
std::vector<TurnedView> turnedViews(const std::vector<PointXYZI>& pts, const raster::Plane& ground,
                                    const raster::RasterParams& params, int turns,
                                    const bow::Vocabulary& vocab, features::OrbExtractor& orb);

}  // namespace rasterslam::places
