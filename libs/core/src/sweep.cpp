#include <rasterslam/core/sweep.h>

#include <algorithm>
#include <cmath>

namespace rasterslam
{
namespace
{
/** atan2 within about 0.0015 rad (a cubic in the ratio of the smaller to the larger
 *  coordinate, folded into the right octant), several times faster than std::atan2: de-skewing
 *  a scan asks it for every point, and the bins it picks are 0.35 deg wide. */
inline float fastAtan2(float y, float x)
{
	constexpr float kPi = 3.14159265358979f, kPi2 = kPi / 2, kPi4 = kPi / 4;
	const float ax = std::abs(x), ay = std::abs(y);
	const float mx = std::max(ax, ay), mn = std::min(ax, ay);
	const float z = mn / (mx + 1e-30f);  // in [0, 1]; 0 at the origin
	float a = kPi4 * z - z * (z - 1) * (0.2447f + 0.0663f * z);
	a = ay > ax ? kPi2 - a : a;
	a = x < 0 ? kPi - a : a;
	return y < 0 ? -a : a;
}
}  // namespace

Eigen::Isometry3d scaleMotion(const Eigen::Isometry3d& motion, double s)
{
	const Eigen::AngleAxisd aa(motion.linear());
	Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
	out.linear() = Eigen::AngleAxisd(aa.angle() * s, aa.axis()).toRotationMatrix();
	out.translation() = motion.translation() * s;
	return out;
}

void deskewSweep(std::vector<PointXYZI>& points, const Eigen::Isometry3d& T_start_end,
                 const SweepModel& model)
{
	// The correction for each of kBins azimuth bins, from the end frame back to the instant of
	// the bin's middle: T_end_at(f) = T_start_end^-1 * T_start_at(f). A bin is 0.35 deg of
	// the sweep: the sensor moves 0.8 mm in it at 8 m/s.
	constexpr int kBins = 1024;
	std::vector<Eigen::Matrix<float, 3, 4>> fix(kBins);
	const Eigen::Isometry3d endInv = T_start_end.inverse();
	const Eigen::AngleAxisd aa(T_start_end.linear());  // once: scaleMotion would per bin
	for (int b = 0; b < kBins; b++)
	{
		const double f = (b + 0.5) / kBins;
		Eigen::Isometry3d at = Eigen::Isometry3d::Identity();
		at.linear() = Eigen::AngleAxisd(aa.angle() * f, aa.axis()).toRotationMatrix();
		at.translation() = T_start_end.translation() * f;
		fix[static_cast<std::size_t>(b)] = (endInv * at).matrix().topRows<3>().cast<float>();
	}
	constexpr float kTwoPi = 6.28318530717959f;
	// The start azimuth as a fraction of a turn in [0, 1), so that d below is in (-1.5, 1.5).
	float a0 = static_cast<float>(model.startAzimuth_deg / 360.0);
	a0 -= std::floor(a0);
	const float sign = model.clockwise ? 1.f : -1.f;
	for (auto& p : points)
	{
		// The same as SweepModel::fraction, in floats and with the fast atan2 (no floor call:
		// one or two wraps are enough).
		float d = sign * (a0 - fastAtan2(p.y, p.x) * (1 / kTwoPi));
		d += d < 0 ? 1.f : 0.f;
		d += d < 0 ? 1.f : 0.f;
		d -= d >= 1 ? 1.f : 0.f;
		const float q = d * kBins;
		// A non-finite point (NaN compares false) takes bin 0 and stays non-finite.
		const int b = (q >= 0 && q < kBins) ? static_cast<int>(q) : 0;
		const auto& M = fix[static_cast<std::size_t>(b)];
		const float x = p.x, y = p.y, z = p.z;
		p.x = M(0, 0) * x + M(0, 1) * y + M(0, 2) * z + M(0, 3);
		p.y = M(1, 0) * x + M(1, 1) * y + M(1, 2) * z + M(1, 3);
		p.z = M(2, 0) * x + M(2, 1) * y + M(2, 2) * z + M(2, 3);
	}
}

void correctElevation(std::vector<PointXYZI>& points, double deg)
{
	const double a = deg * M_PI / 180, ca = std::cos(a), sa = std::sin(a);
	for (auto& p : points)
	{
		const double rh = std::hypot(p.x, p.y);
		if (rh < 1e-9)
			continue;
		// In the vertical plane of the point: (rh, z) rotated by a.
		const double rh2 = ca * rh - sa * p.z, z2 = sa * rh + ca * p.z;
		p.x = static_cast<float>(p.x * rh2 / rh);
		p.y = static_cast<float>(p.y * rh2 / rh);
		p.z = static_cast<float>(z2);
	}
}

}  // namespace rasterslam
