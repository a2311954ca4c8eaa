// Cars and people that move during a run, on straight back-and-forth paths.
#include <rasterslam/sim/traffic.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "rng.h"

namespace rasterslam::sim
{
namespace
{
using detail::Rng;

void check(const TrafficParams& p)
{
	if (p.cars < 0 || p.pedestrians < 0 || p.cars > 10000 || p.pedestrians > 10000)
		throw std::invalid_argument("traffic: cars and pedestrians must be in 0..10000");
	if (!(p.car_speed_mps > 0 && p.car_speed_mps <= 40) ||
	    !(p.walk_speed_mps > 0 && p.walk_speed_mps <= 40))
		throw std::invalid_argument("traffic: speeds must be in (0, 40] m/s");
}

Mover person(Rng& rng, const Eigen::Vector2d& a, const Eigen::Vector2d& b, double speed)
{
	Mover m;
	m.kind = ObjectKind::Person;
	m.a = a;
	m.b = b;
	m.speed_mps = speed * rng.uniform(0.8, 1.2);
	m.phase_m = rng.uniform(0, 2 * (b - a).norm());
	m.halfLength = m.halfWidth = rng.uniform(0.22, 0.28);
	m.height = rng.uniform(1.55, 1.9);
	return m;
}
}  // namespace

Traffic Traffic::town(const TownParams& t, const TrafficParams& p, std::uint32_t seed)
{
	check(p);
	// A stream of its own: adding traffic leaves the town as it was.
	Rng rng(static_cast<std::uint32_t>(detail::mix64(seed ^ 0x7261666669630000ull) >> 32));
	const double P = t.pitch(), hw = t.street_width_m / 2;
	// The lanes: clear of the centre line the route drives and of the cars parked at the kerbs.
	const double lane = std::min(3.0, 0.43 * hw);
	std::vector<Mover> movers;
	const int streetsX = t.blocks_y + 1, streetsY = t.blocks_x + 1;
	for (int i = 0; i < p.cars; i++)
	{
		Mover m;
		m.kind = ObjectKind::Car;
		const int street = rng.integer(0, streetsX + streetsY - 1);
		const double side = rng.chance(0.5) ? lane : -lane;
		if (street < streetsX)  // along x, at y = street * P
		{
			const double y = street * P + side;
			m.a = {-hw, y};
			m.b = {t.blocks_x * P + hw, y};
		}
		else
		{
			const double x = (street - streetsX) * P + side;
			m.a = {x, -hw};
			m.b = {x, t.blocks_y * P + hw};
		}
		m.speed_mps = p.car_speed_mps * rng.uniform(0.8, 1.2);
		m.phase_m = rng.uniform(0, 2 * (m.b - m.a).norm());
		m.halfLength = rng.uniform(2.0, 2.4);
		m.halfWidth = rng.uniform(0.85, 0.95);
		m.height = rng.uniform(0.9, 1.1);
		m.cabinHeight = rng.uniform(1.4, 1.6);
		movers.push_back(m);
	}
	const double L = t.block_size_m, depth = std::min(1.2, 0.45 * t.sidewalk_m);
	for (int i = 0; i < p.pedestrians; i++)
	{
		const int bx = rng.integer(0, t.blocks_x - 1), by = rng.integer(0, t.blocks_y - 1);
		const int k = rng.integer(0, 3);
		const double x0 = bx * P + hw, y0 = by * P + hw;
		// The block's sides counter-clockwise, as the town builds them: start, direction, inward.
		const Eigen::Vector2d starts[4] = {{x0, y0}, {x0 + L, y0}, {x0 + L, y0 + L}, {x0, y0 + L}};
		const Eigen::Vector2d dirs[4] = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}};
		const Eigen::Vector2d u = dirs[k], in(-u.y(), u.x());
		movers.push_back(person(rng, starts[k] + 1.0 * u + depth * in,
		                        starts[k] + (L - 1.0) * u + depth * in, p.walk_speed_mps));
	}
	return Traffic(std::move(movers));
}

Traffic Traffic::indoor(const IndoorParams& in, const TrafficParams& p, std::uint32_t seed)
{
	check(p);
	if (p.cars > 0)
		throw std::invalid_argument("traffic: no cars indoors (traffic.cars must be 0)");
	Rng rng(static_cast<std::uint32_t>(detail::mix64(seed ^ 0x7261666669630000ull) >> 32));
	const double S = in.room_size_m;
	std::vector<Mover> movers;
	for (int i = 0; i < p.pedestrians; i++)
	{
		const int rx = rng.integer(0, in.rooms_x - 1), ry = rng.integer(0, in.rooms_y - 1);
		const Eigen::Vector2d c = in.roomCentre(rx, ry);
		const double off = rng.chance(0.5) ? 0.8 : -0.8, half = S / 2 - in.wall_m / 2 - 0.6;
		const bool alongX = rng.chance(0.5);
		const Eigen::Vector2d a = alongX ? Eigen::Vector2d(c.x() - half, c.y() + off)
		                                 : Eigen::Vector2d(c.x() + off, c.y() - half);
		const Eigen::Vector2d b = alongX ? Eigen::Vector2d(c.x() + half, c.y() + off)
		                                 : Eigen::Vector2d(c.x() + off, c.y() + half);
		movers.push_back(person(rng, a, b, p.walk_speed_mps));
	}
	return Traffic(std::move(movers));
}

MoverState Traffic::state(std::size_t i, double t) const
{
	const Mover& m = movers_.at(i);
	const Eigen::Vector2d ab = m.b - m.a;
	const double L = ab.norm();
	MoverState s;
	if (L < 1e-9)
	{
		s.position = m.a;
		return s;
	}
	double u = std::fmod(m.phase_m + m.speed_mps * t, 2 * L);
	if (u < 0)
		u += 2 * L;
	if (u <= L)
	{
		s.position = m.a + (u / L) * ab;
		s.yaw = std::atan2(ab.y(), ab.x());
	}
	else
	{
		s.position = m.b - ((u - L) / L) * ab;
		s.yaw = std::atan2(-ab.y(), -ab.x());
	}
	return s;
}

void Traffic::shapesAt(double t, const GroundModel& ground, const Eigen::Vector3d& sensor,
                       double range, double keepOut, std::vector<Shape>& out) const
{
	for (std::size_t i = 0; i < movers_.size(); i++)
	{
		const Mover& m = movers_[i];
		const MoverState s = state(i, t);
		const Eigen::Vector2d rel = sensor.head<2>() - s.position;
		const double footprint = std::hypot(m.halfLength, m.halfWidth);
		if (rel.norm() > range + footprint)
			continue;
		// The sensor's distance to the mover's footprint (its box, or its circle).
		double gap;
		if (m.kind == ObjectKind::Car)
		{
			const double c = std::cos(s.yaw), sn = std::sin(s.yaw);
			const double lx = std::abs(c * rel.x() + sn * rel.y()) - m.halfLength;
			const double ly = std::abs(-sn * rel.x() + c * rel.y()) - m.halfWidth;
			gap = std::hypot(std::max(lx, 0.0), std::max(ly, 0.0));
		}
		else
			gap = rel.norm() - m.halfLength;
		if (gap < keepOut)
			continue;
		const double x = s.position.x(), y = s.position.y();
		if (m.kind == ObjectKind::Car)
		{
			// Body and a narrower cabin, as the parked cars.
			out.push_back(boxOnGround(ground, x, y, s.yaw, m.halfLength, m.halfWidth, m.height,
			                          ObjectKind::Car, 0.3));
			out.push_back(boxOnGround(ground, x - 0.1 * std::cos(s.yaw), y - 0.1 * std::sin(s.yaw),
			                          s.yaw, 0.56 * m.halfLength, m.halfWidth - 0.1, m.cabinHeight,
			                          ObjectKind::Car, 0.9));
		}
		else
			out.push_back(cylinderOnGround(ground, x, y, m.halfLength, m.height, m.kind));
	}
}

}  // namespace rasterslam::sim
