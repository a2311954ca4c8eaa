// Ground height field and its ray intersection (bracketing, then safeguarded Newton).
#include <rasterslam/sim/world.h>

#include <algorithm>
#include <cmath>

namespace rasterslam::sim
{
namespace
{
constexpr double kInf = std::numeric_limits<double>::infinity();
// A ray tests at most this many hills individually; beyond, it keeps them all (still correct).
constexpr std::size_t kMaxRayHills = 32;

double hillHeight(const Hill& h, double x, double y)
{
	const double dx = x - h.x, dy = y - h.y;
	const double s = (dx * dx + dy * dy) / (h.radius_m * h.radius_m);
	if (s >= 1)
		return 0;
	return h.height_m * (1 - s) * (1 - s);
}
}  // namespace

GroundModel::GroundModel(double base_m, Eigen::Vector2d tilt, std::vector<Hill> hills)
    : base_(base_m), tilt_(tilt), hills_(std::move(hills))
{
	maxSlope_ = tilt_.norm();
	for (const auto& h : hills_)
		maxSlope_ += kHillSlopeFactor * std::abs(h.height_m) / h.radius_m;
}

double GroundModel::height(double x, double y) const
{
	double z = base_ + tilt_.x() * x + tilt_.y() * y;
	for (const auto& h : hills_)
		z += hillHeight(h, x, y);
	return z;
}

Eigen::Vector2d GroundModel::gradient(double x, double y) const
{
	Eigen::Vector2d g = tilt_;
	for (const auto& h : hills_)
	{
		const double dx = x - h.x, dy = y - h.y, r2 = h.radius_m * h.radius_m;
		const double s = (dx * dx + dy * dy) / r2;
		if (s >= 1)
			continue;
		// d/dx of H (1 - s)^2 with s = r^2/R^2 is -4 H (1 - s) dx / R^2.
		const double k = -4 * h.height_m * (1 - s) / r2;
		g += Eigen::Vector2d(k * dx, k * dy);
	}
	return g;
}

double GroundModel::intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double tMax) const
{
	// Only the hills whose disc the ray's XY shadow crosses can matter for this ray.
	const Hill* near[kMaxRayHills];
	std::size_t nNear = 0;
	bool all = false;
	double slope = tilt_.norm();
	const double dxy2 = d.x() * d.x() + d.y() * d.y();
	for (const auto& h : hills_)
	{
		const double mx = h.x - o.x(), my = h.y - o.y();
		double t = dxy2 > 0 ? (mx * d.x() + my * d.y()) / dxy2 : 0;
		t = std::clamp(t, 0.0, tMax);
		const double ex = mx - t * d.x(), ey = my - t * d.y();
		if (ex * ex + ey * ey >= h.radius_m * h.radius_m)
			continue;
		slope += kHillSlopeFactor * std::abs(h.height_m) / h.radius_m;
		if (nNear < kMaxRayHills)
			near[nNear++] = &h;
		else
			all = true;
	}
	if (all)
	{
		nNear = 0;
		slope = maxSlope_;
	}
	// f(t) = ray height above the ground; fd = df/dt. One pass gives both.
	const auto eval = [&](double t, double& fd)
	{
		const double x = o.x() + t * d.x(), y = o.y() + t * d.y();
		double z = base_ + tilt_.x() * x + tilt_.y() * y;
		double gx = tilt_.x(), gy = tilt_.y();
		const auto addHill = [&](const Hill& h)
		{
			const double dx = x - h.x, dy = y - h.y, r2 = h.radius_m * h.radius_m;
			const double q = (dx * dx + dy * dy) / r2;
			if (q >= 1)
				return;
			z += h.height_m * (1 - q) * (1 - q);
			const double k = -4 * h.height_m * (1 - q) / r2;
			gx += k * dx;
			gy += k * dy;
		};
		if (all)
			for (const auto& h : hills_)
				addHill(h);
		else
			for (std::size_t i = 0; i < nNear; i++)
				addHill(*near[i]);
		fd = d.z() - gx * d.x() - gy * d.y();
		return o.z() + t * d.z() - z;
	};
	double fdIgnored = 0;
	const auto f = [&](double t) { return eval(t, fdIgnored); };

	double fd0 = 0;
	const double f0 = eval(0, fd0);
	if (f0 <= 0)
		return 0;
	const double fdPlane = d.z() - tilt_.x() * d.x() - tilt_.y() * d.y();
	if (!all && nNear == 0)
	{
		// A plane: f is linear, solve it exactly.
		if (fdPlane >= 0)
			return kInf;
		const double t = -f0 / fdPlane;
		return t <= tMax ? t : kInf;
	}

	const double dxy = std::sqrt(dxy2);
	double a = 0, fa = f0, b = tMax;
	if (d.z() + slope * dxy < 0)
	{
		// f' = dz - grad(h).dxy < 0 everywhere: a single crossing, if any, in [0, tMax].
		if (f(tMax) > 0)
			return kInf;
	}
	else
	{
		// f may rise and fall: march with steps f / (fastest possible descent), which cannot
		// jump over a crossing, with a floor of 0.25 m so that grazing rays terminate (a
		// crossing missed by that floor is a sub-millimetre graze).
		const double descent = slope * dxy - d.z();
		if (descent <= 0)
			return kInf;
		for (;;)
		{
			const double tn = std::min(a + std::max(fa / descent, 0.25), tMax);
			const double fn = f(tn);
			if (fn <= 0)
			{
				b = tn;
				break;
			}
			if (tn >= tMax)
				return kInf;
			a = tn;
			fa = fn;
		}
	}

	// Newton's method kept inside the bracket (a bisection whenever a step would leave it):
	// quadratic convergence on this smooth f, and never lost on a flat stretch.
	double t = fd0 < 0 && a == 0 ? -f0 / fd0 : 0.5 * (a + b);
	if (!(t > a && t < b))
		t = 0.5 * (a + b);
	for (int it = 0; it < 60; it++)
	{
		double fd = 0;
		const double ft = eval(t, fd);
		if (std::abs(ft) < 1e-9)
			return t;
		if (ft > 0)
			a = t;
		else
			b = t;
		double tn = fd < 0 ? t - ft / fd : a - 1;
		if (!(tn > a && tn < b))
			tn = 0.5 * (a + b);
		if (std::abs(tn - t) < 1e-6 || b - a < 1e-6)
			return tn;
		t = tn;
	}
	return 0.5 * (a + b);
}

}  // namespace rasterslam::sim
