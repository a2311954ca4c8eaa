// Scene statistics of LiDAR scans (see scene_stats.h).
#include <rasterslam/eval/scene_stats.h>
#include <rasterslam/raster/ground_plane.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace rasterslam::eval
{
namespace
{
constexpr double kCell_m = 0.2;
constexpr double kStructureRange_m = 40;

template <std::size_t N>
std::size_t bin(const std::array<double, N>& edges, double v)
{
	return static_cast<std::size_t>(std::upper_bound(edges.begin(), edges.end(), v) -
	                                edges.begin());
}
}  // namespace

void SceneStatsAccumulator::add(const std::vector<PointXYZI>& scan)
{
	std::vector<PointXYZI> pts;
	pts.reserve(scan.size());
	for (const auto& p : scan)
		if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) &&
		    std::isfinite(p.intensity))
			pts.push_back(p);
	if (pts.empty())
		return;
	const raster::Plane ground = raster::fitGroundPlane(pts, raster::GroundParams{}, 1);
	if (!ground.valid)
	{
		sum_.scansWithoutGround++;
		return;
	}

	constexpr int kSide = static_cast<int>(2 * kStructureRange_m / kCell_m);
	cv::Mat occupied(kSide, kSide, CV_32F, cv::Scalar(0));
	std::size_t groundPts = 0, nonGround = 0;
	double intensity = 0, bright = 0;
	for (const auto& p : pts)
	{
		const double r = std::hypot(p.x, p.y);
		sum_.rangeShare[bin(SceneStats::kRangeEdges, r)]++;
		intensity += p.intensity;
		bright += p.intensity >= 0.5f;
		const double h = ground.height(p);
		if (h < SceneStats::kGroundBand_m)
		{
			groundPts++;
			continue;
		}
		nonGround++;
		sum_.heightShare[bin(SceneStats::kHeightEdges, h)]++;
		if (r < kStructureRange_m)
		{
			const int u = static_cast<int>((p.x + kStructureRange_m) / kCell_m);
			const int v = static_cast<int>((p.y + kStructureRange_m) / kCell_m);
			if (u >= 0 && u < kSide && v >= 0 && v < kSide)
				occupied.at<float>(v, u) = 1;
		}
	}
	// The structure tensor of the occupancy: gradients across walls, summed over the image.
	cv::Mat gx, gy;
	cv::Sobel(occupied, gx, CV_32F, 1, 0, 3);
	cv::Sobel(occupied, gy, CV_32F, 0, 1, 3);
	const double jxx = gx.dot(gx), jyy = gy.dot(gy), jxy = gx.dot(gy);
	const double tr = jxx + jyy, det = jxx * jyy - jxy * jxy;
	const double disc = std::sqrt(std::max(0.0, tr * tr / 4 - det));
	const double lmax = tr / 2 + disc, lmin = tr / 2 - disc;

	sum_.scans++;
	sum_.points += static_cast<double>(pts.size());
	sum_.groundShare += static_cast<double>(groundPts);
	sum_.isotropy += lmax > 0 ? std::max(0.0, lmin) / lmax : 0;
	sum_.structureCells += cv::countNonZero(occupied);
	sum_.meanIntensity += intensity;
	sum_.brightShare += bright;
	allPoints_ += static_cast<double>(pts.size());
	nonGround_ += static_cast<double>(nonGround);
}

SceneStats SceneStatsAccumulator::finish() const
{
	if (sum_.scans == 0)
		throw std::invalid_argument(sum_.scansWithoutGround > 0
		                                ? "scene statistics: no ground plane found in any of the " +
		                                      std::to_string(sum_.scansWithoutGround) + " scans"
		                                : std::string("scene statistics: no scan with points"));
	SceneStats s = sum_;
	const double n = static_cast<double>(s.scans);
	s.points /= n;
	s.isotropy /= n;
	s.structureCells /= n;
	s.groundShare /= allPoints_;
	s.meanIntensity /= allPoints_;
	s.brightShare /= allPoints_;
	for (auto& v : s.rangeShare)
		v /= allPoints_;
	for (auto& v : s.heightShare)
		v = nonGround_ > 0 ? v / nonGround_ : 0;
	return s;
}

std::string formatSceneStats(const std::vector<std::string>& labels,
                             const std::vector<SceneStats>& stats)
{
	if (labels.size() != stats.size())
		throw std::invalid_argument("formatSceneStats: one label per set of statistics");
	std::string out;
	char buf[128];
	const auto row = [&](const std::string& name, auto&& value)
	{
		std::snprintf(buf, sizeof buf, "%-28s", name.c_str());
		out += buf;
		for (const auto& s : stats)
		{
			std::snprintf(buf, sizeof buf, " %12s", value(s).c_str());
			out += buf;
		}
		out += "\n";
	};
	const auto num = [&](double v, const char* fmt)
	{
		char b[32];
		std::snprintf(b, sizeof b, fmt, v);
		return std::string(b);
	};
	std::snprintf(buf, sizeof buf, "%-28s", "");
	out += buf;
	for (const auto& l : labels)
	{
		std::snprintf(buf, sizeof buf, " %12s", l.c_str());
		out += buf;
	}
	out += "\n";
	row("scans", [&](const SceneStats& s) { return num(static_cast<double>(s.scans), "%.0f"); });
	if (std::any_of(stats.begin(), stats.end(),
	                [](const SceneStats& s) { return s.scansWithoutGround > 0; }))
		row("scans without ground (left out)", [&](const SceneStats& s)
		    { return num(static_cast<double>(s.scansWithoutGround), "%.0f"); });
	row("points a scan", [&](const SceneStats& s) { return num(s.points, "%.0f"); });
	row("ground share", [&](const SceneStats& s) { return num(s.groundShare, "%.3f"); });
	double lo = 0;
	for (std::size_t i = 0; i < 5; i++)
	{
		const std::string name = i < 4 ? "range " + num(lo, "%.0f") + "-" +
		                                     num(SceneStats::kRangeEdges[i], "%.0f") + " m"
		                               : "range >" + num(lo, "%.0f") + " m";
		row(name, [&](const SceneStats& s) { return num(s.rangeShare[i], "%.3f"); });
		if (i < 4)
			lo = SceneStats::kRangeEdges[i];
	}
	lo = SceneStats::kGroundBand_m;
	for (std::size_t i = 0; i < 5; i++)
	{
		const std::string name = i < 4 ? "non-ground at " + num(lo, "%.2g") + "-" +
		                                     num(SceneStats::kHeightEdges[i], "%.0f") + " m"
		                               : "non-ground above " + num(lo, "%.0f") + " m";
		row(name, [&](const SceneStats& s) { return num(s.heightShare[i], "%.3f"); });
		if (i < 4)
			lo = SceneStats::kHeightEdges[i];
	}
	row("upright cells (<40 m)",
	    [&](const SceneStats& s) { return num(s.structureCells, "%.0f"); });
	row("wall isotropy", [&](const SceneStats& s) { return num(s.isotropy, "%.3f"); });
	row("mean intensity", [&](const SceneStats& s) { return num(s.meanIntensity, "%.3f"); });
	row("intensity >= 0.5", [&](const SceneStats& s) { return num(s.brightShare, "%.3f"); });
	return out;
}
}  // namespace rasterslam::eval
