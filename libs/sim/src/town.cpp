// Procedural town: a grid of blocks lined with buildings, walls, trees and poles, cars parked
// at the kerbs, on gently rolling ground.
#include <rasterslam/sim/world.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>

#include "rng.h"

namespace rasterslam::sim
{
namespace
{
constexpr double kPi = 3.14159265358979323846;

using detail::Rng;

/** Kinds of changeable objects: each numbers its objects in the order the town is built. */
enum Stream : std::uint32_t
{
	kSlot = 1,
	kWall = 2,
	kAnnex = 3,
	kTree = 4,
	kVehicle = 5,
	kSlotOffset = 6
};

/** The changes between sessions, replayed for one world: every object asks, for each epoch
 *  up to the world's, whether it changed then. */
struct Epochs
{
	const ChangeParams& c;
	std::uint32_t seed;
	World& w;
	std::uint64_t slots = 0, walls = 0, buildings = 0, trees = 0;

	bool changes(Stream s, std::uint64_t id, int e, double rate) const
	{
		return rate > 0 && detail::eventDraw(seed, s, id, e) < rate;
	}
	Rng rng(Stream s, std::uint64_t id, int e) const { return detail::eventRng(seed, s, id, e); }
	void record(int e, const char* what, const Eigen::Vector2d& where) const
	{
		w.recordChange({e, what, where});
	}
};

GroundModel makeGround(const TownParams& p, Rng& rng)
{
	// A slight tilt plus hills whose slopes add up to at most max_slope, so every slope bound
	// in the raycaster holds and the vehicle never climbs more than max_slope.
	const double extentX = p.blocks_x * p.pitch(), extentY = p.blocks_y * p.pitch();
	const double tiltSlope = p.hills > 0 ? 0.2 * p.max_slope : p.max_slope;
	const double tiltDir = rng.uniform(0, 2 * kPi);
	const Eigen::Vector2d tilt = tiltSlope * Eigen::Vector2d(std::cos(tiltDir), std::sin(tiltDir));
	std::vector<Hill> hills;
	const double perHill = p.hills > 0 ? (p.max_slope - tiltSlope) / p.hills : 0;
	for (int i = 0; i < p.hills; i++)
	{
		Hill h;
		h.x = rng.uniform(-0.1, 1.1) * extentX;
		h.y = rng.uniform(-0.1, 1.1) * extentY;
		h.radius_m = rng.uniform(0.4, 0.9) * std::max(extentX, extentY);
		const double sign = rng.chance(0.7) ? 1 : -1;
		h.height_m = sign * perHill * h.radius_m / kHillSlopeFactor * rng.uniform(0.6, 1.0);
		hills.push_back(h);
	}
	return GroundModel(0, tilt, hills);
}

/** The detail of a realistic street (TownParams::detailed()): its own random stream, so the
 *  town's layout does not depend on it. Null when the town has none. */
struct Detail
{
	const TownParams& p;
	Rng rng;
};

void addTree(World& w, Rng& rng, Epochs& ep, double x, double y, Detail* detail = nullptr)
{
	const double trunkH = rng.uniform(2.2, 3.5);
	w.addCylinderOnGround(x, y, rng.uniform(0.12, 0.25), trunkH + 0.5, ObjectKind::TreeTrunk);
	const double rz = rng.uniform(1.5, 2.8);
	const double rxy = rng.uniform(1.3, 2.2);
	// Grown since epoch 0: each tree at its own pace, each epoch a little differently.
	const std::uint64_t id = ep.trees++;
	double grown = 1;
	for (int e = 1; e <= ep.c.epoch && ep.c.vegetation_growth > 0; e++)
		grown *= 1 + ep.c.vegetation_growth * (0.5 + detail::eventDraw(ep.seed, kTree, id, e));
	grown = std::min(grown, 1.8);
	w.addEllipsoidOnGround(x, y, trunkH, grown * rxy, grown * rz, ObjectKind::TreeCrown);
	// Lobes: a crown is no ellipsoid; two to four smaller ones around it, some lower.
	if (detail && detail->p.irregular_crowns)
	{
		Rng& d = detail->rng;
		const int lobes = d.integer(2, 4);
		for (int i = 0; i < lobes; i++)
		{
			const double az = d.uniform(0, 2 * kPi), off = grown * rxy * d.uniform(0.4, 0.8);
			const double r = grown * rxy * d.uniform(0.45, 0.7);
			w.addEllipsoidOnGround(x + off * std::cos(az), y + off * std::sin(az),
			                       trunkH + grown * rz * d.uniform(-0.3, 0.6), r,
			                       r * d.uniform(0.7, 1.2), ObjectKind::TreeCrown);
		}
	}
}

struct Car
{
	enum class Type
	{
		Car,
		Suv,
		Van
	};
	Type type = Type::Car;
	bool flip = false;
	double len = 4.4, wid = 1.8, body = 1.0, shift = 0, cabin = 1.5;
};

/** Makes a drawn car a van or an SUV, from the slot's own draw (TownParams::van_share). */
void reshape(Car& c, double u, Rng&& d)
{
	if (u >= 1)
		return;
	if (u < 0.5)
	{
		c.type = Car::Type::Van;
		c.len = d.uniform(4.8, 5.6);
		c.wid = d.uniform(1.9, 2.05);
		c.cabin = d.uniform(1.9, 2.4);
	}
	else
	{
		c.type = Car::Type::Suv;
		c.len = d.uniform(4.3, 4.9);
		c.wid = d.uniform(1.8, 1.95);
		c.body = d.uniform(1.15, 1.3);
		c.cabin = d.uniform(1.65, 1.85);
	}
}

Car drawCar(Rng& rng)
{
	Car c;
	c.flip = !rng.chance(0.5);
	c.len = rng.uniform(4.0, 4.8);
	c.wid = rng.uniform(1.7, 1.9);
	c.body = rng.uniform(0.9, 1.1);
	c.shift = rng.uniform(-0.3, 0.1);
	c.cabin = rng.uniform(1.4, 1.6);
	return c;
}

void addCar(World& w, const Car& c, const Eigen::Vector2d& q, double yaw)
{
	// Body plus a narrower cabin: a box on the ground would hide the wheels' gap and the
	// roof's shape that make cars recognisable in a scan.
	if (c.flip)
		yaw += kPi;
	const double ca = std::cos(yaw), sa = std::sin(yaw);
	if (c.type == Car::Type::Van)
	{
		// A tall box behind a short bonnet.
		const double bonnet = 0.9;
		w.addBoxOnGround(q.x() - bonnet / 2 * ca, q.y() - bonnet / 2 * sa, yaw,
		                 (c.len - bonnet) / 2, c.wid / 2, c.cabin, ObjectKind::Car, 0.3);
		const double f = (c.len - bonnet) / 2;
		w.addBoxOnGround(q.x() + f * ca, q.y() + f * sa, yaw, bonnet / 2, c.wid / 2 - 0.05, 1.05,
		                 ObjectKind::Car, 0.3);
		return;
	}
	w.addBoxOnGround(q.x(), q.y(), yaw, c.len / 2, c.wid / 2, c.body, ObjectKind::Car, 0.3);
	w.addBoxOnGround(q.x() + c.shift * ca, q.y() + c.shift * sa, yaw, c.len * 0.28, c.wid / 2 - 0.1,
	                 c.cabin, ObjectKind::Car, 0.9);
}

/** One side of a block: a frontage line from `a` along unit `u`, of length `len`; `inward`
 *  points into the block. Kerb at the line itself. */
struct Side
{
	Eigen::Vector2d a, u, inward;
	double len;
	Eigen::Vector2d at(double s, double depth) const { return a + s * u + depth * inward; }
	double yaw() const { return std::atan2(u.y(), u.x()); }
};

/** Places objects about every 100 / per100m metres along a side of length `len`, 2 m clear of
 *  its ends: the first at (firstMin..1) spacings, each moved by up to +-jitter spacings. */
template <typename Place>
void scatterAlong(Rng& rng, double len, double per100m, double firstMin, double jitter,
                  Place&& place)
{
	if (per100m <= 0)
		return;
	const double spacing = 100.0 / per100m;
	for (double s = rng.uniform(firstMin, 1.0) * spacing; s < len - 2; s += spacing)
		place(std::clamp(s + rng.uniform(-jitter, jitter) * spacing, 2.0, len - 2));
}

/** Hedges, kerb, signs and street furniture along a side: drawn from the detail stream. */
void detailSide(World& w, Detail& dt, const Side& side)
{
	const TownParams& p = dt.p;
	Rng& d = dt.rng;
	const double yaw = side.yaw();
	// The raised sidewalk, in 2 m slabs so that each follows the ground's slope.
	if (p.curb_m > 0)
		for (double s = 0; s < side.len - 1e-9; s += 2)
		{
			const double len = std::min(2.0, side.len - s);
			const auto q = side.at(s + len / 2, p.sidewalk_m / 2);
			w.addBoxOnGround(q.x(), q.y(), yaw, len / 2, p.sidewalk_m / 2, p.curb_m,
			                 ObjectKind::Ground);
		}
	// Hedges at the back of the sidewalk, in pieces of uneven height and line.
	if (p.hedge_share > 0)
	{
		const double meanHedge = 7.5, meanGap = meanHedge * (1 - p.hedge_share) / p.hedge_share;
		double s = d.uniform(0, 2 * meanGap + 1);
		while (s < side.len - 2)
		{
			const double end = std::min(side.len - 1, s + d.uniform(3, 12));
			const double depth = std::min(p.sidewalk_m, 3.5) - d.uniform(0.5, 0.8);
			const double half = d.uniform(0.3, 0.5), base = d.uniform(0.9, 1.8);
			for (double a = s; a < end; a += 1.5)
			{
				const double len = std::min(1.5, end - a) + 0.1;
				const auto q = side.at(a + len / 2, depth + d.uniform(-0.12, 0.12));
				w.addBoxOnGround(q.x(), q.y(), yaw, len / 2, half, base + d.uniform(-0.25, 0.25),
				                 ObjectKind::TreeCrown);
			}
			s = end + d.uniform(0.3, 1.7) * meanGap + 0.5;
		}
	}
	const auto scatter = [&](double per100m, auto&& place)
	{ scatterAlong(d, side.len, per100m, 0.2, 0.3, place); };
	scatter(p.signs_per_100m,
	        [&](double s)
	        {
		        const auto q = side.at(s, 0.35);
		        const double h = d.uniform(2.2, 2.8);
		        w.addCylinderOnGround(q.x(), q.y(), 0.04, h, ObjectKind::Pole);
		        // The panel faces the street, across the post.
		        const auto f = side.at(s, 0.3);
		        const double size = d.uniform(0.3, 0.45);
		        w.addBoxOnGround(f.x(), f.y(), yaw, size, 0.02, h, ObjectKind::Pole, h - 2 * size);
	        });
	scatter(p.street_furniture_per_100m,
	        [&](double s)
	        {
		        const double u = d.uniform(0, 1);
		        if (u < 0.4)  // a bollard
		        {
			        const auto q = side.at(s, 0.3);
			        w.addCylinderOnGround(q.x(), q.y(), 0.08, d.uniform(0.8, 1.0),
			                              ObjectKind::Pole);
		        }
		        else if (u < 0.75)  // a bin
		        {
			        const auto q = side.at(s, d.uniform(0.5, 1.0));
			        w.addBoxOnGround(q.x(), q.y(), yaw + d.uniform(-0.3, 0.3), 0.35, 0.35,
			                         d.uniform(1.0, 1.3), ObjectKind::Wall);
		        }
		        else  // a bench
		        {
			        const auto q = side.at(s, std::max(1.0, p.sidewalk_m - 1.2));
			        w.addBoxOnGround(q.x(), q.y(), yaw, 0.9, 0.3, 0.8, ObjectKind::Wall, 0.4);
		        }
	        });
}

/** Piers between the windows of a facade (from s0 to s1 along the side, height h), entrance
 *  steps, and now and then an awning over the ground floor. */
void detailFacade(World& w, Detail& dt, const Side& side, double s0, double s1, double h)
{
	Rng& d = dt.rng;
	const double setback = dt.p.sidewalk_m, yaw = side.yaw();
	const double spacing = d.uniform(2.8, 4.5), pier = d.uniform(0.35, 0.6);
	const double out = d.uniform(0.2, 0.45);
	const double pierH = d.chance(0.5) ? h : std::min(h, d.uniform(3.5, 4.5));
	for (double s = s0 + pier / 2; s <= s1 - pier / 2; s += spacing)
	{
		const auto q = side.at(s, setback - out / 2 + 0.05);
		w.addBoxOnGround(q.x(), q.y(), yaw, pier / 2, out / 2 + 0.05, pierH, ObjectKind::Building);
	}
	const double width = s1 - s0;
	const int doors = width > 14 ? 2 : 1;
	for (int i = 0; i < doors; i++)
	{
		const double s = s0 + width * (i + d.uniform(0.25, 0.75)) / doors;
		const auto q = side.at(s, setback - 0.45);
		w.addBoxOnGround(q.x(), q.y(), yaw, d.uniform(0.7, 1.2), 0.45, d.uniform(0.25, 0.6),
		                 ObjectKind::Building);
	}
	if (d.chance(0.3))
	{
		const double frac = d.uniform(0.3, 0.8), depth = d.uniform(0.8, 1.5);
		const auto q = side.at(s0 + width / 2, setback - depth / 2);
		w.addBoxOnGround(q.x(), q.y(), yaw, frac * width / 2, depth / 2, 3.0, ObjectKind::Building,
		                 d.uniform(2.4, 2.8));
	}
}

void fillSide(World& w, Rng& rng, Epochs& ep, const TownParams& p, const Side& side,
              double reserved, Detail* detail)
{
	if (detail)
		detailSide(w, *detail, side);
	// Sidewalk furniture: poles at the kerb, trees a little further in.
	const auto scatter = [&](double per100m, auto&& place)
	{ scatterAlong(rng, side.len, per100m, 0.3, 0.2, place); };
	scatter(p.poles_per_100m,
	        [&](double s)
	        {
		        const auto q = side.at(s, 0.5);
		        w.addCylinderOnGround(q.x(), q.y(), 0.1, rng.uniform(5, 8), ObjectKind::Pole);
	        });
	scatter(p.trees_per_100m,
	        [&](double s)
	        {
		        const auto q = side.at(s, std::min(1.8, 0.6 * p.sidewalk_m));
		        addTree(w, rng, ep, q.x(), q.y(), detail);
	        });

	// Parked cars in the street, 1.1 m off the kerb, never in the intersections, one per 6 m
	// slot. Between sessions a slot's car leaves, or another one parks, up to 0.5 m off.
	if (p.cars_per_100m > 0)
	{
		const double occupancy = std::min(1.0, p.cars_per_100m * 6.0 / 100.0);
		for (double s = 3.5; s < side.len - 3.5; s += 6.0)
		{
			const std::uint64_t id = ep.slots++;
			std::optional<Car> car;
			if (rng.chance(occupancy))
				car = drawCar(rng);
			// Real cars do not park on a 6 m grid: with street detail each slot's car stands up
			// to parking_jitter_m off the slot's centre (its own draw, kept between sessions).
			double along = detail && detail->p.parking_jitter_m > 0
			                   ? (2 * detail::eventDraw(ep.seed, kSlotOffset, id, 0) - 1) *
			                         detail->p.parking_jitter_m
			                   : 0;
			int lastParked = 0;
			for (int e = 1; e <= ep.c.epoch; e++)
			{
				if (!ep.changes(kSlot, id, e, ep.c.parked_cars))
					continue;
				Rng er = ep.rng(kSlot, id, e);
				if (car && er.chance(0.4))
				{
					ep.record(e, "car left", side.at(s + along, -1.1));
					car.reset();
					continue;
				}
				const bool had = car.has_value();
				car = drawCar(er);
				along = er.uniform(-0.5, 0.5);
				lastParked = e;
				ep.record(e, had ? "car moved" : "car parked", side.at(s + along, -1.1));
			}
			if (car)
			{
				// The body type is the slot's own draw: the same car stays a van after the
				// sessions that did not move it.
				if (detail && p.van_share > 0)
				{
					const int e = lastParked;
					const double u = detail::eventDraw(ep.seed, kVehicle, id, e);
					reshape(*car, u < p.van_share ? u / p.van_share : 1,
					        detail::eventRng(ep.seed, kVehicle, id, e));
				}
				// With street detail (longer vans, jitter) a car keeps within its 6 m slot.
				if (detail)
				{
					const double room = std::max(0.0, (6.0 - car->len) / 2);
					along = std::clamp(along, -room, room);
				}
				addCar(w, *car, side.at(s + along, -1.1), side.yaw());
			}
		}
	}

	// Frontage: buildings of random width, sometimes a gap closed by a wall. `reserved` keeps
	// the corners to the sides that span them.
	const double setback = p.sidewalk_m;
	double s = reserved;
	const double end = side.len - reserved;
	const double maxDepth = std::max(4.0, std::min(16.0, p.block_size_m / 2 - setback - 2));
	while (end - s > 4)
	{
		if (rng.chance(0.2))
		{
			const double gap = std::min(rng.uniform(4, 10), end - s);
			const std::uint64_t id = ep.walls++;
			std::optional<double> wallHeight;
			if (rng.chance(0.6))
				wallHeight = rng.uniform(1.8, 2.8);
			const auto q = side.at(s + gap / 2, setback + 0.15);
			for (int e = 1; e <= ep.c.epoch; e++)
			{
				if (!ep.changes(kWall, id, e, ep.c.walls))
					continue;
				if (wallHeight)
					wallHeight.reset();
				else
					wallHeight = ep.rng(kWall, id, e).uniform(1.8, 2.8);
				ep.record(e, wallHeight ? "wall built" : "wall removed", q);
			}
			if (wallHeight)
				w.addBoxOnGround(q.x(), q.y(), side.yaw(), gap / 2, 0.15, *wallHeight,
				                 ObjectKind::Wall);
			s += gap;
			continue;
		}
		double width = rng.uniform(8, 20);
		if (end - s - width < 8)
			width = end - s;
		const double depth = rng.uniform(std::min(8.0, maxDepth), maxDepth);
		const double height = rng.uniform(p.building_height_min_m, p.building_height_max_m);
		const auto q = side.at(s + width / 2, setback + depth / 2);
		w.addBoxOnGround(q.x(), q.y(), side.yaw(), width / 2, depth / 2, height,
		                 ObjectKind::Building);
		if (detail && p.facade_detail)
			detailFacade(w, *detail, side, s, s + width, height);
		// A facade that changes between sessions: an annex on the sidewalk in front of it (a
		// shop front, scaffolding), built or pulled down.
		const std::uint64_t id = ep.buildings++;
		int builtAt = 0;
		for (int e = 1; e <= ep.c.epoch; e++)
		{
			if (!ep.changes(kAnnex, id, e, ep.c.facades))
				continue;
			builtAt = builtAt > 0 ? 0 : e;
			ep.record(e, builtAt > 0 ? "annex built" : "annex removed",
			          side.at(s + width / 2, setback));
		}
		if (builtAt > 0)
		{
			Rng er = ep.rng(kAnnex, id, builtAt);
			const double frac = er.uniform(0.4, 0.8), off = er.uniform(-0.5, 0.5) * (1 - frac);
			const double d = std::min(1.0, 0.35 * setback);
			const auto a = side.at(s + width / 2 + off * width, setback - d / 2);
			w.addBoxOnGround(a.x(), a.y(), side.yaw(), frac * width / 2, d / 2,
			                 er.uniform(2.6, 4.0), ObjectKind::Building);
		}
		s += width;
	}
}

void check(bool ok, const std::string& what)
{
	if (!ok)
		throw std::invalid_argument("town: " + what);
}
}  // namespace

World World::generate(const TownParams& p, std::uint32_t seed, const ChangeParams& changes)
{
	check(p.blocks_x >= 1 && p.blocks_y >= 1, "blocks_x and blocks_y must be >= 1");
	check(p.street_width_m >= 6, "street_width_m must be >= 6 (two lanes and parked cars)");
	check(p.sidewalk_m >= 1, "sidewalk_m must be >= 1");
	check(p.block_size_m >= 2 * p.sidewalk_m + 10, "block_size_m too small for its sidewalks");
	check(p.building_height_min_m > 0 && p.building_height_max_m >= p.building_height_min_m,
	      "building heights must satisfy 0 < min <= max");
	check(p.trees_per_100m >= 0 && p.poles_per_100m >= 0 && p.cars_per_100m >= 0,
	      "densities must be >= 0");
	check(p.hills >= 0 && p.hills <= 32, "hills must be in 0..32");
	check(p.max_slope >= 0 && p.max_slope <= 0.15, "max_slope must be in [0, 0.15]");
	check(p.outskirts_m >= 0, "outskirts_m must be >= 0");
	check(changes.epoch >= 0 && changes.epoch <= 10000, "changes.epoch must be in 0..10000");
	check(changes.parked_cars >= 0 && changes.parked_cars <= 1 && changes.walls >= 0 &&
	          changes.walls <= 1 && changes.facades >= 0 && changes.facades <= 1,
	      "change rates must be in [0, 1]");
	check(changes.vegetation_growth >= 0 && changes.vegetation_growth <= 1,
	      "vegetation_growth must be in [0, 1]");
	check(p.hedge_share >= 0 && p.hedge_share <= 1, "hedge_share must be in [0, 1]");
	check(p.signs_per_100m >= 0 && p.signs_per_100m <= 100 && p.street_furniture_per_100m >= 0 &&
	          p.street_furniture_per_100m <= 100,
	      "signs_per_100m and street_furniture_per_100m must be in [0, 100]");
	check(p.curb_m >= 0 && p.curb_m <= 0.3, "curb_m must be in [0, 0.3]");
	check(p.van_share >= 0 && p.van_share <= 1, "van_share must be in [0, 1]");
	check(p.parking_jitter_m >= 0 && p.parking_jitter_m <= 1, "parking_jitter_m must be in [0, 1]");

	Rng rng(seed);
	World w(makeGround(p, rng), 4.0);
	Epochs ep{changes, seed, w};
	std::optional<Detail> detail;
	if (p.detailed())
		detail.emplace(
		    Detail{p, Rng(static_cast<std::uint32_t>(detail::mix64(seed ^ 0xde7a11ull)))});
	Detail* dt = detail ? &*detail : nullptr;
	const double P = p.pitch(), hw = p.street_width_m / 2;
	for (int bx = 0; bx < p.blocks_x; bx++)
		for (int by = 0; by < p.blocks_y; by++)
		{
			const double x0 = bx * P + hw, y0 = by * P + hw, L = p.block_size_m;
			const double corner = p.sidewalk_m + std::min(16.0, L / 2 - p.sidewalk_m - 2);
			// Counter-clockwise sides: inward = u rotated +90 degrees.
			const Side sides[4] = {{{x0, y0}, {1, 0}, {0, 1}, L},
			                       {{x0 + L, y0}, {0, 1}, {-1, 0}, L},
			                       {{x0 + L, y0 + L}, {-1, 0}, {0, -1}, L},
			                       {{x0, y0 + L}, {0, -1}, {1, 0}, L}};
			for (int k = 0; k < 4; k++)
				fillSide(w, rng, ep, p, sides[k], k % 2 == 0 ? p.sidewalk_m : corner, dt);
			// A courtyard tree or two.
			const int n = rng.chance(0.5) ? 1 : 2;
			for (int i = 0; i < n; i++)
			{
				// Drawn y first: the order GCC gave these draws when they were the arguments of
				// one call (right to left), so the towns stay as they were.
				const double ty = y0 + L * rng.uniform(0.4, 0.6);
				const double tx = x0 + L * rng.uniform(0.45, 0.55);
				addTree(w, rng, ep, tx, ty, dt);
			}
		}

	// Outskirts: a belt of trees and fences beyond the outer streets, so that the outer
	// streets' scans are not empty on one side.
	if (p.outskirts_m > 0)
	{
		const double xmin = -hw, ymin = -hw;
		const double xmax = p.blocks_x * P + hw, ymax = p.blocks_y * P + hw;
		const double perimeter = 2 * (xmax - xmin + ymax - ymin);
		const int nTrees = static_cast<int>(perimeter / 100.0 * 4 * p.outskirts_m / 10.0);
		for (int i = 0; i < nTrees; i++)
		{
			const double s = rng.uniform(0, perimeter);
			const bool fence = rng.chance(0.15);
			// A fence turns freely: keep its whole length out of the street.
			const double halfLen = fence ? rng.uniform(3, 8) : 0;
			const double depth = rng.uniform(3 + halfLen, std::max(3 + halfLen, p.outskirts_m));
			Eigen::Vector2d q;
			if (s < xmax - xmin)
				q = {xmin + s, ymin - depth};
			else if (s < (xmax - xmin) + (ymax - ymin))
				q = {xmax + depth, ymin + s - (xmax - xmin)};
			else if (s < 2 * (xmax - xmin) + (ymax - ymin))
				q = {xmax - (s - (xmax - xmin) - (ymax - ymin)), ymax + depth};
			else
				q = {xmin - depth, ymax - (s - 2 * (xmax - xmin) - (ymax - ymin))};
			if (fence)
			{
				// Height first, then yaw: as GCC drew them as one call's arguments.
				const double height = rng.uniform(1.2, 2.0);
				const double yaw = rng.uniform(0, kPi);
				w.addBoxOnGround(q.x(), q.y(), yaw, halfLen, 0.1, height, ObjectKind::Wall);
			}
			else
				addTree(w, rng, ep, q.x(), q.y(), dt);
		}
	}
	return w;
}

}  // namespace rasterslam::sim
