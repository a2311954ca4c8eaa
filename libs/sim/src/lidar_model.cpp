// The two Velodyne models the project simulates.
#include <rasterslam/sim/lidar_model.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
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
	originHeights_.assign(elevationsDeg_.size(), 0.0);
}

LidarModel LidarModel::fromRingOrderedScan(const std::string& name,
                                           const std::vector<PointXYZI>& scan, int azimuthSteps,
                                           double minRange_m, double maxRange_m)
{
	// Rings: a ring ends where the azimuth falls back by more than half a turn. A few points
	// out of order (noise near the wrap) would start a ring of their own: a piece of fewer
	// than kMinRing points stays with the ring before it.
	constexpr std::size_t kMinRing = 100;
	std::vector<std::vector<Eigen::Vector2d>> rings(1);  // (r_xy, z)
	double prevAz = 0;
	std::size_t fallsSeen = 0;
	for (std::size_t i = 0; i < scan.size(); i++)
	{
		const auto& p = scan[i];
		if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
			continue;
		const double az = std::atan2(p.y, p.x);
		const bool falls = i > 0 && az - prevAz < -M_PI;
		fallsSeen += falls;
		if (falls && rings.back().size() >= kMinRing)
			rings.emplace_back();
		prevAz = az;
		const double rxy = std::hypot(p.x, p.y);
		if (rxy >= 2.5 && rxy <= 80)
			rings.back().emplace_back(rxy, p.z);
	}
	if (rings.size() < 4 || fallsSeen > 4 * rings.size())
		throw std::invalid_argument("LidarModel '" + name + "': the scan has " +
		                            std::to_string(rings.size()) +
		                            " ring(s): its points are not stored ring after ring");
	// The beams' common origin height, from the rings that see a spread of ranges (facades,
	// not only the ground circle): z = h + r tan(elevation), least squares, twice, the second
	// time without the points 0.1 m off the first line.
	std::vector<double> heights;
	for (const auto& ring : rings)
	{
		double n = 0, sr = 0, srr = 0;
		for (const auto& q : ring)
		{
			n++;
			sr += q.x();
			srr += q.x() * q.x();
		}
		if (n < kMinRing || srr / n - (sr / n) * (sr / n) < 25)  // range spread under 5 m
			continue;
		double slope = 0, h = 0;
		for (int round = 0; round < 2; round++)
		{
			double m = 0, a = 0, z = 0, aa = 0, az = 0;
			for (const auto& q : ring)
			{
				if (round > 0 && std::abs(q.y() - h - slope * q.x()) > 0.1)
					continue;
				m++;
				a += q.x();
				z += q.y();
				aa += q.x() * q.x();
				az += q.x() * q.y();
			}
			const double det = m * aa - a * a;
			if (m < 10 || det <= 0)
				break;
			slope = (m * az - a * z) / det;
			h = (z - slope * a) / m;
		}
		heights.push_back(h);
	}
	double h0 = 0;
	if (!heights.empty())
	{
		std::nth_element(heights.begin(), heights.begin() + heights.size() / 2, heights.end());
		h0 = heights[heights.size() / 2];
	}
	// Each ring's elevation seen from that origin: the median over its points.
	std::vector<double> el;
	for (const auto& ring : rings)
	{
		if (ring.size() < kMinRing)
			continue;  // a stub at the scan's start or end
		// Far points where the ring has enough of them: an error in the origin height tilts
		// the elevation of near ones most.
		std::vector<double> e, eFar;
		for (const auto& q : ring)
		{
			e.push_back(std::atan2(q.y() - h0, q.x()) * 180 / M_PI);
			if (q.x() > 8)
				eFar.push_back(e.back());
		}
		if (eFar.size() >= kMinRing)
			e.swap(eFar);
		std::nth_element(e.begin(), e.begin() + e.size() / 2, e.end());
		el.push_back(e[e.size() / 2]);
	}
	// A beam cut in two by the scan's start and end gives two rings: one elevation.
	std::sort(el.begin(), el.end());
	std::vector<double> beams;
	for (const double e : el)
		if (beams.empty() || e - beams.back() > 0.08)
			beams.push_back(e);
	LidarModel m(name, beams, azimuthSteps, minRange_m, maxRange_m);
	m.originHeights_.assign(beams.size(), h0);
	return m;
}

LidarModel LidarModel::hdl64()
{
	std::vector<double> el(64);
	for (int i = 0; i < 64; i++)
		el[i] = -24.8 + i * (2.0 + 24.8) / 63.0;
	return LidarModel("hdl64", el, 2083, 1.0, 120.0);
}

LidarModel LidarModel::hdl64e()
{
	// MRPT's default HDL-64 calibration, vert_correction of lasers 0..63 in degrees, sorted.
	std::vector<double> el = {
	    -24.5551, -24.1468, -23.5492, -22.9659, -22.3575, -21.9758, -21.4907, -21.0636,
	    -20.4286, -19.8919, -19.2472, -18.9229, -18.4289, -17.9638, -17.3684, -16.8012,
	    -16.2738, -15.9062, -15.3849, -14.9266, -14.2905, -13.8056, -13.1632, -12.8296,
	    -12.2940, -11.9133, -11.2952, -10.7536, -10.1760, -9.7443,  -9.3000,  -8.7745,
	    -8.5626,  -8.2187,  -7.9432,  -7.5522,  -7.2297,  -6.8490,  -6.5602,  -6.1900,
	    -5.8889,  -5.4830,  -5.1346,  -4.8091,  -4.5299,  -4.1573,  -3.8193,  -3.4693,
	    -3.1191,  -2.7921,  -2.4882,  -2.0906,  -1.8098,  -1.4588,  -1.1427,  -0.7563,
	    -0.4518,  -0.0888,  0.2040,   0.5905,   0.8950,   1.2931,   1.5623,   1.9601};
	LidarModel m("hdl64e", el, 2083, 1.0, 120.0);
	// Their vert_offset_correction: each laser's height above the frame's origin, in the
	// same order (the lower block's lasers sit 0.14-0.16 m up, the upper block's 0.20-0.22).
	m.originHeights_ = {
	    0.1625, 0.1620, 0.1612, 0.1605, 0.1597, 0.1592, 0.1586, 0.1581, 0.1573, 0.1566, 0.1558,
	    0.1555, 0.1549, 0.1543, 0.1536, 0.1529, 0.1523, 0.1519, 0.1512, 0.1507, 0.1500, 0.1494,
	    0.1487, 0.1483, 0.1477, 0.1473, 0.1466, 0.1460, 0.1453, 0.1448, 0.1443, 0.1437, 0.2174,
	    0.2170, 0.2166, 0.2161, 0.2157, 0.2152, 0.2148, 0.2144, 0.2140, 0.2135, 0.2130, 0.2126,
	    0.2123, 0.2118, 0.2114, 0.2109, 0.2105, 0.2101, 0.2097, 0.2092, 0.2088, 0.2084, 0.2080,
	    0.2075, 0.2071, 0.2067, 0.2063, 0.2058, 0.2054, 0.2050, 0.2046, 0.2041};
	return m;
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
	if (name == "hdl64e")
		return hdl64e();
	if (name == "vlp16")
		return vlp16();
	throw std::invalid_argument("unknown lidar '" + name + "' (known: hdl64, hdl64e, vlp16)");
}

}  // namespace rasterslam::sim
