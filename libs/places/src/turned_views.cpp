#include <rasterslam/places/turned_views.h>

#include <cmath>

namespace rasterslam::places
{
std::vector<TurnedView> turnedViews(const std::vector<PointXYZI>& pts, const raster::Plane& ground,
                                    const raster::RasterParams& params, int turns,
                                    const bow::Vocabulary& vocab, features::OrbExtractor& orb)
{
	std::vector<TurnedView> out;
	for (int k = 1; k < turns; k++)
	{
		RasterFrame turned;
		raster::rasterizeElevationTurned(pts, ground, params,
		                                 static_cast<float>(k * (M_PI / 2) / turns), turned);
		std::vector<cv::KeyPoint> kps;
		cv::Mat desc;
		orb.extract(turned.image.asCvMatRef(), kps, desc);
		const auto d =
		    bow::toDescriptors(desc.ptr<uint8_t>(), desc.empty() ? 0 : std::size_t(desc.rows));
		TurnedView v;
		vocab.transform(d, v.words);
		v.selfScore = vocab.selfScore(d);
		out.push_back(std::move(v));
	}
	return out;
}

}  // namespace rasterslam::places
