// Shapes, the XY grid that indexes them, and the raycaster (ground root find + 2D DDA).
#include <rasterslam/sim/world.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rasterslam::sim
{
namespace
{
constexpr double kInf = std::numeric_limits<double>::infinity();
// Grid margin added when the grid grows, so that adding shapes one by one rarely rebuilds it.
constexpr double kGridMargin = 32;

double intersectBox(const Shape& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d)
{
	// Slab test in the box frame (the yaw rotation only touches x and y).
	const double px = o.x() - s.cx, py = o.y() - s.cy;
	const double lo[3] = {s.cosYaw * px + s.sinYaw * py, -s.sinYaw * px + s.cosYaw * py, o.z()};
	const double ld[3] = {s.cosYaw * d.x() + s.sinYaw * d.y(), -s.sinYaw * d.x() + s.cosYaw * d.y(),
	                      d.z()};
	const double mins[3] = {-s.a, -s.b, s.zmin}, maxs[3] = {s.a, s.b, s.zmax};
	double tNear = -kInf, tFar = kInf;
	for (int k = 0; k < 3; k++)
	{
		if (ld[k] == 0)
		{
			if (lo[k] < mins[k] || lo[k] > maxs[k])
				return kInf;
			continue;
		}
		const double inv = 1.0 / ld[k];
		double t1 = (mins[k] - lo[k]) * inv, t2 = (maxs[k] - lo[k]) * inv;
		if (t1 > t2)
			std::swap(t1, t2);
		tNear = std::max(tNear, t1);
		tFar = std::min(tFar, t2);
		if (tNear > tFar || tFar <= 0)
			return kInf;
	}
	return tNear > 0 ? tNear : tFar;
}

double intersectCylinder(const Shape& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d)
{
	const double mx = o.x() - s.cx, my = o.y() - s.cy, r2 = s.a * s.a;
	const double a = d.x() * d.x() + d.y() * d.y();
	const double b = mx * d.x() + my * d.y();
	const double c = mx * mx + my * my - r2;
	double best = kInf;
	if (a > 0)
	{
		const double disc = b * b - a * c;
		if (disc < 0)
			return kInf;
		const double sq = std::sqrt(disc);
		for (const double t : {(-b - sq) / a, (-b + sq) / a})
		{
			const double z = o.z() + t * d.z();
			if (t > 0 && z >= s.zmin && z <= s.zmax)
			{
				best = t;
				break;
			}
		}
	}
	if (d.z() != 0)
	{
		for (const double zc : {s.zmin, s.zmax})
		{
			const double t = (zc - o.z()) / d.z();
			if (t <= 0 || t >= best)
				continue;
			const double x = mx + t * d.x(), y = my + t * d.y();
			if (x * x + y * y <= r2)
				best = t;
		}
	}
	return best;
}

double intersectEllipsoid(const Shape& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d)
{
	// Scaling z by a/b turns the ellipsoid into a sphere of radius a; t is unchanged.
	const double k = s.a / s.b;
	const double mx = o.x() - s.cx, my = o.y() - s.cy, mz = (o.z() - s.cz) * k;
	const double dz = d.z() * k;
	const double a = d.x() * d.x() + d.y() * d.y() + dz * dz;
	const double b = mx * d.x() + my * d.y() + mz * dz;
	const double c = mx * mx + my * my + mz * mz - s.a * s.a;
	const double disc = b * b - a * c;
	if (disc < 0)
		return kInf;
	const double sq = std::sqrt(disc);
	const double t1 = (-b - sq) / a;
	if (t1 > 0)
		return t1;
	const double t2 = (-b + sq) / a;
	return t2 > 0 ? t2 : kInf;
}
}  // namespace

const char* kindName(ObjectKind k)
{
	switch (k)
	{
		case ObjectKind::None:
			return "none";
		case ObjectKind::Ground:
			return "ground";
		case ObjectKind::Building:
			return "building";
		case ObjectKind::Wall:
			return "wall";
		case ObjectKind::Car:
			return "car";
		case ObjectKind::Pole:
			return "pole";
		case ObjectKind::TreeTrunk:
			return "tree-trunk";
		case ObjectKind::TreeCrown:
			return "tree-crown";
		case ObjectKind::Furniture:
			return "furniture";
		case ObjectKind::Person:
			return "person";
		case ObjectKind::Ceiling:
			return "ceiling";
	}
	return "?";
}

float nominalIntensity(ObjectKind k)
{
	switch (k)
	{
		case ObjectKind::Ground:
			return 0.28f;
		case ObjectKind::Building:
			return 0.34f;
		case ObjectKind::Wall:
			return 0.31f;
		case ObjectKind::Car:
			return 0.22f;
		case ObjectKind::Pole:
			return 0.55f;
		case ObjectKind::TreeTrunk:
			return 0.26f;
		case ObjectKind::TreeCrown:
			return 0.3f;
		case ObjectKind::Furniture:
			return 0.45f;
		case ObjectKind::Person:
			return 0.38f;
		case ObjectKind::Ceiling:
			return 0.5f;
		case ObjectKind::None:
			break;
	}
	return 0.f;
}

double Shape::footprintRadius() const
{
	return type == ShapeType::Box ? std::hypot(a, b) : a;
}

double intersectShape(const Shape& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d)
{
	switch (s.type)
	{
		case ShapeType::Box:
			return intersectBox(s, o, d);
		case ShapeType::Cylinder:
			return intersectCylinder(s, o, d);
		case ShapeType::Ellipsoid:
			return intersectEllipsoid(s, o, d);
	}
	return kInf;
}

World::World(GroundModel ground, double cellSize_m) : ground_(std::move(ground)), cell_(cellSize_m)
{
	if (!(cellSize_m > 0))
		throw std::invalid_argument("World: cell size must be > 0");
}

void World::add(const Shape& s)
{
	if (s.a <= 0 || (s.type != ShapeType::Cylinder && s.b <= 0) ||
	    (s.type != ShapeType::Ellipsoid && !(s.zmax > s.zmin)))
		throw std::invalid_argument("World::add: shape with an empty extent");
	shapes_.push_back(s);
	const double r = s.footprintRadius();
	const bool inside = nx_ > 0 && s.cx - r >= x0_ && s.cy - r >= y0_ &&
	                    s.cx + r < x0_ + nx_ * cell_ && s.cy + r < y0_ + ny_ * cell_;
	if (inside)
	{
		registerShape(static_cast<std::uint32_t>(shapes_.size() - 1));
		return;
	}
	double xmin = s.cx - r, ymin = s.cy - r, xmax = s.cx + r, ymax = s.cy + r;
	if (nx_ > 0)
	{
		xmin = std::min(xmin, x0_);
		ymin = std::min(ymin, y0_);
		xmax = std::max(xmax, x0_ + nx_ * cell_);
		ymax = std::max(ymax, y0_ + ny_ * cell_);
	}
	rebuildGrid(xmin - kGridMargin, ymin - kGridMargin, xmax + kGridMargin, ymax + kGridMargin);
}

Shape boxOnGround(const GroundModel& g, double cx, double cy, double yaw, double halfLength,
                  double halfWidth, double height, ObjectKind kind, double clearance)
{
	Shape s;
	s.type = ShapeType::Box;
	s.kind = kind;
	s.cx = cx;
	s.cy = cy;
	s.a = halfLength;
	s.b = halfWidth;
	s.cosYaw = std::cos(yaw);
	s.sinYaw = std::sin(yaw);
	const double h = g.height(cx, cy);
	const double sink = g.maxSlope() * s.footprintRadius();
	s.zmin = clearance > 0 ? h + clearance : h - sink;
	s.zmax = h + height;
	return s;
}

Shape cylinderOnGround(const GroundModel& g, double cx, double cy, double radius, double height,
                       ObjectKind kind)
{
	Shape s;
	s.type = ShapeType::Cylinder;
	s.kind = kind;
	s.cx = cx;
	s.cy = cy;
	s.a = radius;
	const double h = g.height(cx, cy);
	s.zmin = h - g.maxSlope() * radius;
	s.zmax = h + height;
	return s;
}

void World::addBoxOnGround(double cx, double cy, double yaw, double halfLength, double halfWidth,
                           double height, ObjectKind kind, double clearance)
{
	add(boxOnGround(ground_, cx, cy, yaw, halfLength, halfWidth, height, kind, clearance));
}

void World::addCylinderOnGround(double cx, double cy, double radius, double height, ObjectKind kind)
{
	add(cylinderOnGround(ground_, cx, cy, radius, height, kind));
}

void World::addEllipsoidOnGround(double cx, double cy, double bottom, double radiusXY,
                                 double radiusZ, ObjectKind kind)
{
	Shape s;
	s.type = ShapeType::Ellipsoid;
	s.kind = kind;
	s.cx = cx;
	s.cy = cy;
	s.a = radiusXY;
	s.b = radiusZ;
	s.cz = ground_.height(cx, cy) + bottom + radiusZ;
	s.zmin = s.cz - radiusZ;
	s.zmax = s.cz + radiusZ;
	add(s);
}

void World::rebuildGrid(double xmin, double ymin, double xmax, double ymax)
{
	x0_ = xmin;
	y0_ = ymin;
	nx_ = std::max(1, static_cast<int>(std::ceil((xmax - xmin) / cell_)));
	ny_ = std::max(1, static_cast<int>(std::ceil((ymax - ymin) / cell_)));
	cells_.assign(static_cast<std::size_t>(nx_) * ny_, {});
	for (std::uint32_t i = 0; i < shapes_.size(); i++)
		registerShape(i);
}

void World::registerShape(std::uint32_t id)
{
	// Registered in every cell its footprint's bounding square overlaps: a few extra tests for
	// rotated boxes, never a missed hit.
	const Shape& s = shapes_[id];
	const double r = s.footprintRadius();
	const int ix0 = std::max(0, static_cast<int>(std::floor((s.cx - r - x0_) / cell_)));
	const int iy0 = std::max(0, static_cast<int>(std::floor((s.cy - r - y0_) / cell_)));
	const int ix1 = std::min(nx_ - 1, static_cast<int>(std::floor((s.cx + r - x0_) / cell_)));
	const int iy1 = std::min(ny_ - 1, static_cast<int>(std::floor((s.cy + r - y0_) / cell_)));
	for (int iy = iy0; iy <= iy1; iy++)
		for (int ix = ix0; ix <= ix1; ix++)
			cells_[static_cast<std::size_t>(iy) * nx_ + ix].push_back(id);
}

RayHit World::raycast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double maxRange) const
{
	RayHit best;
	const double tg = ground_.intersect(o, d, maxRange);
	if (tg <= maxRange)
	{
		best.range = tg;
		best.kind = ObjectKind::Ground;
	}
	if (nx_ == 0)
		return best;
	const double tLimit = std::min(maxRange, best.range);

	// Clip the ray's XY shadow to the grid rectangle.
	const double gx1 = x0_ + nx_ * cell_, gy1 = y0_ + ny_ * cell_;
	double tIn = 0, tOut = tLimit;
	const double lo[2] = {x0_, y0_}, hi[2] = {gx1, gy1}, po[2] = {o.x(), o.y()},
	             pd[2] = {d.x(), d.y()};
	for (int k = 0; k < 2; k++)
	{
		if (pd[k] == 0)
		{
			if (po[k] < lo[k] || po[k] >= hi[k])
				return best;
			continue;
		}
		double t1 = (lo[k] - po[k]) / pd[k], t2 = (hi[k] - po[k]) / pd[k];
		if (t1 > t2)
			std::swap(t1, t2);
		tIn = std::max(tIn, t1);
		tOut = std::min(tOut, t2);
	}
	if (tIn > tOut)
		return best;

	// 2D DDA (Amanatides & Woo) over the cells; t is the 3D ray parameter throughout.
	const double sx = o.x() + tIn * d.x(), sy = o.y() + tIn * d.y();
	int ix = std::clamp(static_cast<int>(std::floor((sx - x0_) / cell_)), 0, nx_ - 1);
	int iy = std::clamp(static_cast<int>(std::floor((sy - y0_) / cell_)), 0, ny_ - 1);
	const int stepX = d.x() > 0 ? 1 : -1, stepY = d.y() > 0 ? 1 : -1;
	const double dtX = d.x() != 0 ? cell_ / std::abs(d.x()) : kInf;
	const double dtY = d.y() != 0 ? cell_ / std::abs(d.y()) : kInf;
	double tMaxX = d.x() != 0 ? (x0_ + (ix + (stepX > 0 ? 1 : 0)) * cell_ - o.x()) / d.x() : kInf;
	double tMaxY = d.y() != 0 ? (y0_ + (iy + (stepY > 0 ? 1 : 0)) * cell_ - o.y()) / d.y() : kInf;
	for (;;)
	{
		for (const std::uint32_t id : cells_[static_cast<std::size_t>(iy) * nx_ + ix])
		{
			const Shape& s = shapes_[id];
			const double t = intersectShape(s, o, d);
			if (t < best.range && t <= tLimit)
			{
				best.range = t;
				best.kind = s.kind;
			}
		}
		const double tExit = std::min(tMaxX, tMaxY);
		// Every shape that could be hit before tExit is registered in a visited cell.
		if (best.range <= tExit || tExit >= tOut)
			break;
		if (tMaxX < tMaxY)
		{
			ix += stepX;
			tMaxX += dtX;
			if (ix < 0 || ix >= nx_)
				break;
		}
		else
		{
			iy += stepY;
			tMaxY += dtY;
			if (iy < 0 || iy >= ny_)
				break;
		}
	}
	return best;
}

}  // namespace rasterslam::sim
