#include <mrpt/img/CImage.h>
#include <rasterslam/raster/elevation_image.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace rasterslam::raster
{
namespace
{
int imageSize(const RasterParams& p)
{
	if (p.mode == ProjectionMode::Pinhole)
		return p.pinholeSize_px;
	return static_cast<int>(std::ceil(2 * p.maxRange_m / p.resolution_m));
}
}  // namespace

bool projectPoint(const RasterParams& p, float x, float y, float z, float& u, float& v)
{
	const float size = static_cast<float>(imageSize(p));
	if (p.mode == ProjectionMode::Bev)
	{
		// Forward (+x) is up in the image, left (+y) is left.
		const float inv = static_cast<float>(1.0 / p.resolution_m),
		            ext = static_cast<float>(p.maxRange_m);
		u = (ext - y) * inv;
		v = (ext - x) * inv;
		return true;
	}
	// Equation (1): p_cam = R (p_l + t), t = (0, 0, -H): x_cam = -y, y_cam = -x, z_cam = H - z;
	// then K: u = f x_cam / z_cam + c, v = f y_cam / z_cam + c.
	const float H = static_cast<float>(p.cameraHeight_m);
	const float zc = H - z;
	if (zc < 0.5f)
		return false;  // at or above the camera
	const float f =
	    static_cast<float>(0.5 * size * (p.cameraHeight_m + p.sensorHeight_m) / p.maxRange_m);
	const float c = 0.5f * size;
	u = f * (-y) / zc + c;
	v = f * (-x) / zc + c;
	return true;
}

double dominantEdgeAngle(const cv::Mat& img)
{
	cv::Mat gx, gy;
	cv::Sobel(img, gx, CV_32F, 1, 0);
	cv::Sobel(img, gy, CV_32F, 0, 1);
	std::array<double, 90> hist{};
	for (int r = 0; r < img.rows; r++)
	{
		const float* x = gx.ptr<float>(r);
		const float* y = gy.ptr<float>(r);
		for (int c = 0; c < img.cols; c++)
		{
			const double m = std::hypot(x[c], y[c]);
			if (m < 1)
				continue;
			const double a = std::fmod(std::atan2(y[c], x[c]) * 180 / M_PI + 360.0, 90.0);
			hist[static_cast<std::size_t>(a) % 90] += m;
		}
	}
	std::array<double, 90> sm{};
	for (std::size_t i = 0; i < 90; i++)
		sm[i] = hist[(i + 89) % 90] + 2 * hist[i] + hist[(i + 1) % 90];
	const auto best = static_cast<std::size_t>(std::max_element(sm.begin(), sm.end()) - sm.begin());
	// The vertex of the parabola through the peak bin and its neighbours. (Tried and worse on
	// a thin-walled street turned by 20 degrees: the weighted mean of the orientations near
	// the peak, and a structure tensor; this one is good to about a degree there.)
	const double l = sm[(best + 89) % 90], c = sm[best], r = sm[(best + 1) % 90];
	const double den = l - 2 * c + r;
	const double off = std::abs(den) > 1e-12 ? 0.5 * (l - r) / den : 0.0;
	const double deg = std::fmod(static_cast<double>(best) + 0.5 + off + 90.0, 90.0);
	return deg * M_PI / 180;
}

namespace
{
RasterStats rasterizeOnce(const std::vector<PointXYZI>& pts, const Plane& ground,
                          const RasterParams& p, float yaw, RasterFrame& out);
}  // namespace

RasterStats rasterizeElevation(const std::vector<PointXYZI>& pts, const Plane& ground,
                               const RasterParams& p, RasterFrame& out)
{
	if (!p.canonicalYaw || p.mode != ProjectionMode::Bev)
		return rasterizeOnce(pts, ground, p, 0, out);
	rasterizeOnce(pts, ground, p, 0, out);
	// The image's axes: u runs along -y, v along -x, so an edge at angle a in the image lies
	// at -a in the sensor's x-y plane; turning the scan by +a lines it up with the axes.
	const auto yaw = static_cast<float>(dominantEdgeAngle(out.image.asCvMatRef()));
	return rasterizeOnce(pts, ground, p, yaw, out);
}

RasterStats rasterizeElevationTurned(const std::vector<PointXYZI>& pts, const Plane& ground,
                                     const RasterParams& p, float yaw, RasterFrame& out)
{
	return rasterizeOnce(pts, ground, p, yaw, out);
}

namespace
{
RasterStats rasterizeOnce(const std::vector<PointXYZI>& pts, const Plane& ground,
                          const RasterParams& p, float yaw, RasterFrame& out)
{
	RasterStats st;
	st.input = pts.size();
	st.plane = ground;
	const int size = imageSize(p);
	const std::size_t npix = static_cast<std::size_t>(size) * size;
	std::vector<float> top(npix, -std::numeric_limits<float>::infinity());
	out.pixelToPoint.assign(npix, -1);

	const float rmin2 = static_cast<float>(p.minRange_m * p.minRange_m);
	const float rmax2 = static_cast<float>(p.maxRange_m * p.maxRange_m);
	const float gthr = static_cast<float>(p.groundThreshold_m),
	            below = static_cast<float>(-p.belowGround_m);
	const float h0 = static_cast<float>(p.sensorHeight_m);
	const float above = static_cast<float>(p.maxHeight_m);
	const float cy = std::cos(yaw), sy = std::sin(yaw);
	out.imageYaw = yaw;
	for (std::size_t i = 0; i < pts.size(); i++)
	{
		const auto& q = pts[i];
		const float r2 = q.x * q.x + q.y * q.y;
		if (r2 < rmin2 || r2 > rmax2)
		{
			++st.outliers;
			continue;
		}
		const float h = ground.valid ? ground.height(q) : q.z + h0;
		if (h < below || (above > 0 && h > above))
		{
			++st.outliers;
			continue;
		}
		if (p.removeGround && h < gthr)
		{
			++st.ground;
			continue;
		}
		float u, v;
		const float x = cy * q.x - sy * q.y, y = sy * q.x + cy * q.y;  // turned by yaw
		if (!projectPoint(p, x, y, q.z, u, v))
			continue;
		const int col = static_cast<int>(std::floor(u)), row = static_cast<int>(std::floor(v));
		if (col < 0 || row < 0 || col >= size || row >= size)
			continue;
		++st.projected;
		const std::size_t k = static_cast<std::size_t>(row) * size + col;
		if (h > top[k])
		{
			top[k] = h;
			out.pixelToPoint[k] = static_cast<int32_t>(i);
		}
	}

	cv::Mat img(size, size, CV_8UC1, cv::Scalar(0));
	const float g0 = static_cast<float>(p.greyMin_m),
	            gscale = static_cast<float>(254.0 / (p.greyMax_m - p.greyMin_m));
	std::array<int, 256> hist{};
	for (std::size_t k = 0; k < npix; k++)
	{
		if (out.pixelToPoint[k] < 0)
			continue;
		const float g = std::clamp((top[k] - g0) * gscale, 0.0f, 254.0f);
		const auto level = static_cast<uint8_t>(1 + std::lround(g));
		img.data[k] = level;
		++hist[level];
		++st.pixels;
	}
	if (p.equalize && st.pixels > 0)
	{
		// Histogram equalization over the occupied pixels only: empty pixels stay 0.
		std::array<uint8_t, 256> lut{};
		int cum = 0;
		for (int l = 1; l < 256; l++)
		{
			cum += hist[l];
			lut[l] = static_cast<uint8_t>(1 + (254LL * cum) / static_cast<long long>(st.pixels));
		}
		for (std::size_t k = 0; k < npix; k++)
			if (img.data[k])
				img.data[k] = lut[img.data[k]];
	}
	out.image = mrpt::img::CImage(img, mrpt::img::SHALLOW_COPY);
	return st;
}
}  // namespace

int32_t pointAtPixel(const RasterFrame& f, float u, float v, int radius_px)
{
	const int w = static_cast<int>(f.image.getWidth()), h = static_cast<int>(f.image.getHeight());
	const int cu = static_cast<int>(std::floor(u)), cv_ = static_cast<int>(std::floor(v));
	int32_t best = -1;
	float bestD = std::numeric_limits<float>::max();
	for (int dv = -radius_px; dv <= radius_px; dv++)
		for (int du = -radius_px; du <= radius_px; du++)
		{
			const int c = cu + du, r = cv_ + dv;
			if (c < 0 || r < 0 || c >= w || r >= h)
				continue;
			const int32_t idx = f.pixelToPoint[static_cast<std::size_t>(r) * w + c];
			if (idx < 0)
				continue;
			const float d = (c + 0.5f - u) * (c + 0.5f - u) + (r + 0.5f - v) * (r + 0.5f - v);
			if (d < bestD)
			{
				bestD = d;
				best = idx;
			}
		}
	return best;
}

void appendMoved(const std::vector<PointXYZI>& pts, const Eigen::Isometry3f& T,
                 std::vector<PointXYZI>& out)
{
	out.reserve(out.size() + pts.size());
	for (const auto& q : pts)
	{
		const Eigen::Vector3f w = T * Eigen::Vector3f(q.x, q.y, q.z);
		out.push_back({w.x(), w.y(), w.z(), q.intensity});
	}
}

void appendImagePoints(const RasterFrame& f, const std::vector<PointXYZI>& pts,
                       std::vector<PointXYZI>& out)
{
	for (const auto idx : f.pixelToPoint)
		if (idx >= 0 && static_cast<std::size_t>(idx) < pts.size())
			out.push_back(pts[static_cast<std::size_t>(idx)]);
}

}  // namespace rasterslam::raster
