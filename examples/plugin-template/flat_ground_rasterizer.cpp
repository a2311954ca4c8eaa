// An example rasterslam plugin, built out of tree against the installed package
// (docs/plugins.md): a rasterizer that makes a bird's-eye-view image of each scan without a
// RANSAC plane fit. The ground is a horizontal plane at a low percentile of the heights of
// the points near the vehicle: cheap, and right where the ground under the vehicle is flat.
// Each pixel keeps the point highest above that ground (or the brightest return) and the
// index of that point, so an odometry (rasterslam::OrbOdometry) can back-project what it
// finds in the image to 3D.
#include <mrpt/core/initializer.h>
#include <mrpt/img/CImage.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/map/registration.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace example
{
class FlatGroundRasterizer : public rasterslam::Rasterizer
{
	// The class name in the config is "example::FlatGroundRasterizer".
	DEFINE_MRPT_OBJECT(FlatGroundRasterizer, example)

   public:
	void rasterize(const rasterslam::Scan& scan, rasterslam::RasterFrame& out) override;

   protected:
	void initializeImpl(rasterslam::ParamReader& p) override;

   private:
	// Parameters (README.md): metres unless named otherwise.
	double resolution_m_ = 0.2, minRange_m_ = 2.0, maxRange_m_ = 50.0;
	double groundRadius_m_ = 20.0, groundPercentile_ = 5.0, groundThreshold_m_ = 0.25;
	double maxHeight_m_ = 8.0, sensorHeight_m_ = 1.73;
	bool intensity_ = false;  //!< grey level from the intensity instead of the height
	int size_ = 500;          //!< image side, px
	// State: the last ground height (vehicle frame), for a scan that sees too little ground.
	double groundZ_ = -1.73;
	std::vector<float> key_;  //!< per pixel, the value that picked its point (reused)
};
}  // namespace example

IMPLEMENTS_MRPT_OBJECT(FlatGroundRasterizer, rasterslam::Rasterizer, example)

// Runs when the loader opens the module: the class becomes creatable by its name.
RASTERSLAM_REGISTER_CLASSES(register_example_flat_ground_rasterizer)
{
	mrpt::rtti::registerClass(CLASS_ID(example::FlatGroundRasterizer));
}

namespace example
{
void FlatGroundRasterizer::initializeImpl(rasterslam::ParamReader& p)
{
	// Every key goes through the reader: it records the value in force (run.yaml) and
	// finish(), called after this, rejects keys that were never read.
	resolution_m_ = p.getDouble("resolution_m", resolution_m_);
	minRange_m_ = p.getDouble("min_range_m", minRange_m_);
	maxRange_m_ = p.getDouble("max_range_m", maxRange_m_);
	groundRadius_m_ = p.getDouble("ground_radius_m", groundRadius_m_);
	groundPercentile_ = p.getDouble("ground_percentile", groundPercentile_);
	groundThreshold_m_ = p.getDouble("ground_threshold_m", groundThreshold_m_);
	maxHeight_m_ = p.getDouble("max_height_m", maxHeight_m_);
	sensorHeight_m_ = p.getDouble("sensor_height_m", sensorHeight_m_);
	intensity_ = p.getChoice("value", "height", {"height", "intensity"}) == "intensity";
	p.requirePositive(resolution_m_, "resolution_m");
	p.requirePositive(maxRange_m_ - minRange_m_, "max_range_m - min_range_m");
	p.requirePositive(groundRadius_m_ - minRange_m_, "ground_radius_m - min_range_m");
	p.requirePositive(maxHeight_m_, "max_height_m");
	p.requireRange(groundPercentile_, 0, 100, "ground_percentile");
	if (2 * maxRange_m_ / resolution_m_ > 8192)
		p.reject("resolution_m", "the image would exceed 8192 pixels a side");
	size_ = static_cast<int>(std::ceil(2 * maxRange_m_ / resolution_m_));
	groundZ_ = -sensorHeight_m_;
	MRPT_LOG_INFO_FMT("%d x %d px images, %.2f m a pixel, grey level from the %s", size_, size_,
	                  resolution_m_, intensity_ ? "intensity" : "height above ground");
}

void FlatGroundRasterizer::rasterize(const rasterslam::Scan& scan, rasterslam::RasterFrame& out)
{
	const auto& pts = scan.points;
	const float rmin2 = static_cast<float>(minRange_m_ * minRange_m_);
	const float rmax2 = static_cast<float>(maxRange_m_ * maxRange_m_);

	// Ground: the given percentile of the heights of the points within ground_radius_m.
	std::vector<float> z;
	const float rg2 = static_cast<float>(groundRadius_m_ * groundRadius_m_);
	for (const auto& q : pts)
	{
		const float r2 = q.x * q.x + q.y * q.y;
		if (r2 >= rmin2 && r2 <= rg2)
			z.push_back(q.z);
	}
	const bool groundSeen = z.size() >= 50;
	if (groundSeen)
	{
		const auto k = static_cast<std::size_t>(groundPercentile_ / 100 * (z.size() - 1));
		std::nth_element(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(k), z.end());
		groundZ_ = z[k];
	}
	else
		MRPT_LOG_THROTTLE_WARN_FMT(5.0,
		                           "scan %zu: %zu points near the vehicle; ground kept at z=%.2f m",
		                           scan.index, z.size(), groundZ_);

	// Projection, forward (+x) up and left (+y) left, as rasterslam::ElevationRasterizer's
	// bev: each pixel keeps its highest (or brightest) non-ground point.
	const std::size_t npix = static_cast<std::size_t>(size_) * size_;
	key_.assign(npix, -std::numeric_limits<float>::infinity());
	out.pixelToPoint.assign(npix, -1);
	const float inv = static_cast<float>(1 / resolution_m_), ext = static_cast<float>(maxRange_m_);
	const float g = static_cast<float>(groundZ_), thr = static_cast<float>(groundThreshold_m_);
	std::size_t ground = 0, projected = 0;
	for (std::size_t i = 0; i < pts.size(); i++)
	{
		const auto& q = pts[i];
		const float r2 = q.x * q.x + q.y * q.y;
		if (r2 < rmin2 || r2 > rmax2)
			continue;
		const float h = q.z - g;
		if (h < thr)
		{
			++ground;  // ground, or below it (reflections)
			continue;
		}
		const int col = static_cast<int>(std::floor((ext - q.y) * inv));
		const int row = static_cast<int>(std::floor((ext - q.x) * inv));
		if (col < 0 || row < 0 || col >= size_ || row >= size_)
			continue;
		++projected;
		const std::size_t k = static_cast<std::size_t>(row) * size_ + col;
		const float key = intensity_ ? q.intensity : h;
		if (key > key_[k])
		{
			key_[k] = key;
			out.pixelToPoint[k] = static_cast<int32_t>(i);
		}
	}

	// Grey levels 1..255 (0: an empty pixel). A new image each scan: CImage copies share
	// pixels, so writing into the last one would change it for whoever kept a copy.
	mrpt::img::CImage img(size_, size_, mrpt::img::CH_GRAY);
	const float scale = intensity_ ? 254.0f : static_cast<float>(254 / maxHeight_m_);
	std::size_t pixels = 0;
	for (int row = 0; row < size_; row++)
	{
		auto* line = img.ptrLine<uint8_t>(row);
		for (int col = 0; col < size_; col++)
		{
			const std::size_t k = static_cast<std::size_t>(row) * size_ + col;
			line[col] = 0;
			if (out.pixelToPoint[k] < 0)
				continue;
			line[col] =
			    static_cast<uint8_t>(1 + std::lround(std::clamp(key_[k] * scale, 0.0f, 254.0f)));
			++pixels;
		}
	}
	out.image = std::move(img);
	// The plane n.p + d = height above ground, horizontal in the vehicle frame.
	out.groundValid = groundSeen;
	out.groundNormal[0] = 0;
	out.groundNormal[1] = 0;
	out.groundNormal[2] = 1;
	out.groundD = -g;
	MRPT_LOG_DEBUG_FMT(
	    "scan %zu: ground z=%.2f m, %zu ground points, %zu projected into %zu pixels", scan.index,
	    groundZ_, ground, projected, pixels);
}
}  // namespace example
