// The two Velodyne models the project simulates.
#include <rasterslam/sim/lidar_model.h>

#include <algorithm>
#include <stdexcept>

namespace rasterslam::sim
{
LidarModel::LidarModel(std::string name, std::vector<double> elevationsDeg, int azimuthSteps,
                       double minRange_m, double maxRange_m)
    : name_(std::move(name)),
      elevationsDeg_(std::move(elevationsDeg)),
      azimuthSteps_(azimuthSteps),
      minRange_(minRange_m),
      maxRange_(maxRange_m)
{
	if (elevationsDeg_.empty() || azimuthSteps_ < 1 || !(minRange_ >= 0) ||
	    !(maxRange_ > minRange_))
		throw std::invalid_argument("LidarModel '" + name_ +
		                            "': needs beams, azimuth steps "
		                            "and 0 <= min range < max range");
	std::sort(elevationsDeg_.begin(), elevationsDeg_.end());
}

LidarModel LidarModel::hdl64()
{
	std::vector<double> el(64);
	for (int i = 0; i < 64; i++)
		el[i] = -24.8 + i * (2.0 + 24.8) / 63.0;
	return LidarModel("hdl64", el, 2083, 1.0, 120.0);
}

LidarModel LidarModel::vlp16()
{
	std::vector<double> el(16);
	for (int i = 0; i < 16; i++)
		el[i] = -15.0 + 2.0 * i;
	return LidarModel("vlp16", el, 1800, 1.0, 100.0);
}

LidarModel LidarModel::byName(const std::string& name)
{
	if (name == "hdl64")
		return hdl64();
	if (name == "vlp16")
		return vlp16();
	throw std::invalid_argument("unknown lidar '" + name + "' (known: hdl64, vlp16)");
}

}  // namespace rasterslam::sim
