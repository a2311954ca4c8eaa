#include <rasterslam/eval/trajectory_plot.h>
#include <rasterslam/io/trajectory_io.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace rasterslam::eval
{
double niceStep(double span, double lines)
{
	const double raw = std::max(span, 1e-9) / lines;
	const double mag = std::pow(10.0, std::floor(std::log10(raw)));
	for (const double m : {1.0, 2.0, 5.0})
		if (m * mag >= raw)
			return m * mag;
	return 10 * mag;
}

namespace
{
std::string numberText(double v)
{
	char buf[32];
	std::snprintf(buf, sizeof(buf), "%g", std::abs(v) < 1e-9 ? 0.0 : v);
	return buf;
}
}  // namespace

PlottedTrajectory alignedForPlot(const Trajectory& est, const Association& a,
                                 const Eigen::Isometry3d& T_gt_est, const std::string& label)
{
	PlottedTrajectory out;
	out.label = label;
	for (const std::size_t i : a.est)
	{
		const Eigen::Vector3d p = T_gt_est * est[i].pose.translation();
		out.xy.emplace_back(p.x(), p.y());
	}
	return out;
}

cv::Mat renderTrajectoryPlot(const std::vector<Eigen::Vector2d>& groundTruth,
                             const std::vector<PlottedTrajectory>& estimates,
                             const std::string& title, int width, int height)
{
	width = std::max(width, 400);
	height = std::max(height, 360);
	cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
	const int left = 70, right = 20, top = 50,
	          bottom = 40 + 22 * static_cast<int>(estimates.size() + 1);
	const int pw = width - left - right, ph = height - top - bottom;
	// One scale for x and y, the data centred.
	double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
	const auto extend = [&](const std::vector<Eigen::Vector2d>& v)
	{
		for (const auto& p : v)
			if (std::isfinite(p.x()) && std::isfinite(p.y()))
			{
				x0 = std::min(x0, p.x()), x1 = std::max(x1, p.x());
				y0 = std::min(y0, p.y()), y1 = std::max(y1, p.y());
			}
	};
	extend(groundTruth);
	for (const auto& e : estimates)
		extend(e.xy);
	if (!(x1 >= x0))
		x0 = y0 = -1, x1 = y1 = 1;
	const double margin = 0.05 * std::max({x1 - x0, y1 - y0, 1.0});
	x0 -= margin, x1 += margin, y0 -= margin, y1 += margin;
	const double scale = std::min(pw / (x1 - x0), ph / (y1 - y0));
	const double cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
	const auto px = [&](const Eigen::Vector2d& p)
	{
		return cv::Point(
		    static_cast<int>(std::lround((left + pw / 2.0 + (p.x() - cx) * scale) * 16)),
		    static_cast<int>(std::lround((top + ph / 2.0 - (p.y() - cy) * scale) * 16)));
	};
	const auto font = cv::FONT_HERSHEY_SIMPLEX;
	const cv::Scalar black(0, 0, 0), grid(225, 225, 225);
	// Grid lines every `step` metres over the panel.
	const double vx0 = cx - pw / 2.0 / scale, vx1 = cx + pw / 2.0 / scale;
	const double vy0 = cy - ph / 2.0 / scale, vy1 = cy + ph / 2.0 / scale;
	const double step = niceStep(std::max(vx1 - vx0, vy1 - vy0), 8);
	for (double v = std::ceil(vx0 / step) * step; v <= vx1; v += step)
	{
		cv::line(img, px({v, vy0}), px({v, vy1}), grid, 1, cv::LINE_8, 4);
		const cv::Point at = px({v, vy0});
		cv::putText(img, numberText(v), cv::Point(at.x / 16 - 10, top + ph + 18), font, 0.4, black,
		            1, cv::LINE_AA);
	}
	for (double v = std::ceil(vy0 / step) * step; v <= vy1; v += step)
	{
		cv::line(img, px({vx0, v}), px({vx1, v}), grid, 1, cv::LINE_8, 4);
		const cv::Point at = px({vx0, v});
		cv::putText(img, numberText(v), cv::Point(8, at.y / 16 + 5), font, 0.4, black, 1,
		            cv::LINE_AA);
	}
	cv::rectangle(img, cv::Rect(left, top, pw, ph), black, 1);
	cv::putText(img, title, cv::Point(left, 22), font, 0.55, black, 1, cv::LINE_AA);
	cv::putText(img, "x, y (m); grid " + numberText(step) + " m", cv::Point(left, 42), font, 0.42,
	            black, 1, cv::LINE_AA);

	// Matplotlib's first colours, as BGR.
	const cv::Scalar colours[] = {{180, 119, 31}, {14, 127, 255},  {44, 160, 44},
	                              {40, 39, 214},  {189, 103, 148}, {75, 86, 140}};
	const auto draw = [&](const std::vector<Eigen::Vector2d>& v, cv::Scalar c, int thick)
	{
		std::vector<cv::Point> pts;
		for (const auto& p : v)
			if (std::isfinite(p.x()) && std::isfinite(p.y()))
				pts.push_back(px(p));
		if (pts.size() > 1)
			cv::polylines(img, pts, false, c, thick, cv::LINE_AA, 4);
	};
	draw(groundTruth, black, 3);
	for (std::size_t i = 0; i < estimates.size(); i++)
		draw(estimates[i].xy, colours[i % 6], 2);
	if (!groundTruth.empty())
	{
		const cv::Point s = px(groundTruth.front());
		cv::circle(img, cv::Point(s.x / 16, s.y / 16), 6, black, 2, cv::LINE_AA);
	}
	// Legend under the panel.
	int ly = top + ph + 40;
	const auto legend = [&](const std::string& label, cv::Scalar c, int thick)
	{
		cv::line(img, cv::Point(left, ly), cv::Point(left + 30, ly), c, thick, cv::LINE_AA);
		cv::putText(img, label, cv::Point(left + 40, ly + 5), font, 0.45, black, 1, cv::LINE_AA);
		ly += 22;
	};
	legend("ground truth (circle: start)", black, 3);
	for (std::size_t i = 0; i < estimates.size(); i++)
		legend(estimates[i].label, colours[i % 6], 2);
	return img;
}

void writePng(const std::string& path, const cv::Mat& img)
{
	std::vector<uchar> png;
	bool ok = false;
	try
	{
		ok = cv::imencode(".png", img, png);
	}
	catch (const cv::Exception&)
	{
		ok = false;
	}
	if (!ok)
		throw std::runtime_error("cannot encode the plot '" + path + "'");
	// Through a temporary file: a reader never sees half a PNG.
	io::writeFileAtomically(path, std::string(png.begin(), png.end()));
}

}  // namespace rasterslam::eval
