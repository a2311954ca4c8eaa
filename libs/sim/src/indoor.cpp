// The indoor world: rooms on a grid joined by doors, furniture and people, a flat ceiling, as
// a building walked through with a handheld LiDAR (the paper's indoor dataset is such a place).
#include <rasterslam/sim/world.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>

#include "rng.h"

namespace rasterslam::sim
{
namespace
{
using detail::Rng;
constexpr std::uint32_t kFurnitureStream = 5;

void need(bool ok, const std::string& what)
{
	if (!ok)
		throw std::invalid_argument("indoor world: " + what);
}

/** A wall along x (horizontal) or y, from a to b at c, with a door gap centred at `door`
 *  (NaN: none). */
void addWall(World& w, const IndoorParams& p, bool alongX, double c, double a, double b,
             double door)
{
	const auto piece = [&](double lo, double hi)
	{
		if (hi - lo < 1e-6)
			return;
		const double mid = (lo + hi) / 2, half = (hi - lo) / 2;
		if (alongX)
			w.addBoxOnGround(mid, c, 0, half, p.wall_m / 2, p.ceiling_m, ObjectKind::Wall);
		else
			w.addBoxOnGround(c, mid, 0, p.wall_m / 2, half, p.ceiling_m, ObjectKind::Wall);
	};
	if (std::isnan(door))
		piece(a, b);
	else
	{
		piece(a, door - p.door_m / 2);
		piece(door + p.door_m / 2, b);
	}
}
}  // namespace

World World::generateIndoor(const IndoorParams& p, std::uint32_t seed, const ChangeParams& changes)
{
	need(p.rooms_x >= 1 && p.rooms_y >= 1, "rooms_x and rooms_y must be >= 1");
	need(p.room_size_m >= 4 && p.room_size_m <= 50, "room_size_m must be in [4, 50]");
	need(p.ceiling_m >= 2 && p.ceiling_m <= 10, "ceiling_m must be in [2, 10]");
	need(p.wall_m > 0 && p.wall_m <= 1, "wall_m must be in (0, 1]");
	need(p.door_m >= 0.6 && p.door_m <= p.room_size_m / 2,
	     "door_m must be in [0.6, room_size_m/2]");
	need(p.furniture_per_room >= 0 && p.furniture_per_room <= 30,
	     "furniture_per_room must be in 0..30");
	need(p.people_per_room >= 0 && p.people_per_room <= 10, "people_per_room must be in 0..10");
	need(changes.epoch >= 0 && changes.epoch <= 10000, "changes.epoch must be in 0..10000");
	need(changes.furniture >= 0 && changes.furniture <= 1, "changes.furniture must be in [0, 1]");
	Rng rng(seed);
	World w(GroundModel(), 4.0);
	std::uint64_t furnitureIds = 0;
	const double S = p.room_size_m, W = p.rooms_x * S, H = p.rooms_y * S;
	const double nan = std::numeric_limits<double>::quiet_NaN();
	// Outer walls, closed; inner walls with a door in the middle of each room's side.
	addWall(w, p, true, 0, 0, W, nan);
	addWall(w, p, true, H, 0, W, nan);
	addWall(w, p, false, 0, 0, H, nan);
	addWall(w, p, false, W, 0, H, nan);
	for (int i = 1; i < p.rooms_x; i++)
		for (int j = 0; j < p.rooms_y; j++)
			addWall(w, p, false, i * S, j * S, (j + 1) * S, (j + 0.5) * S);
	for (int j = 1; j < p.rooms_y; j++)
		for (int i = 0; i < p.rooms_x; i++)
			addWall(w, p, true, j * S, i * S, (i + 1) * S, (i + 0.5) * S);
	// The ceiling: one slab over the whole floor.
	Shape ceiling;
	ceiling.type = ShapeType::Box;
	ceiling.kind = ObjectKind::Ceiling;
	ceiling.cx = W / 2;
	ceiling.cy = H / 2;
	ceiling.a = W / 2 + p.wall_m;
	ceiling.b = H / 2 + p.wall_m;
	ceiling.zmin = p.ceiling_m;
	ceiling.zmax = p.ceiling_m + 0.3;
	w.add(ceiling);

	// Furniture and people off the lanes through the room centres (where the walk goes).
	const double lane = 1.2, margin = p.wall_m / 2 + 0.35;
	for (int i = 0; i < p.rooms_x; i++)
		for (int j = 0; j < p.rooms_y; j++)
		{
			const Eigen::Vector2d c = p.roomCentre(i, j);
			const auto spot = [&](Rng& r, double halfExtent, double& x, double& y)
			{
				for (int tries = 0; tries < 50; tries++)
				{
					x = r.uniform(i * S + margin + halfExtent, (i + 1) * S - margin - halfExtent);
					y = r.uniform(j * S + margin + halfExtent, (j + 1) * S - margin - halfExtent);
					if (std::abs(x - c.x()) > lane + halfExtent &&
					    std::abs(y - c.y()) > lane + halfExtent)
						return true;
				}
				return false;
			};
			for (int k = 0; k < p.furniture_per_room; k++)
			{
				// Between sessions a piece may be moved to another free spot of its room (its
				// size kept): `moves` replays those epochs.
				const std::uint64_t id = furnitureIds++;
				const auto moves = [&](auto&& move)
				{
					for (int e = 1; e <= changes.epoch && changes.furniture > 0; e++)
						if (detail::eventDraw(seed, kFurnitureStream, id, e) < changes.furniture)
						{
							Rng er = detail::eventRng(seed, kFurnitureStream, id, e);
							if (const std::optional<Eigen::Vector2d> to = move(er))
								w.recordChange({e, "furniture moved", *to});
						}
				};
				using Moved = std::optional<Eigen::Vector2d>;
				double x, y;
				const int type = rng.integer(0, 3);
				if (type <= 1)  // a table or a chair
				{
					const double half = type == 0 ? 0.75 : 0.35;
					if (!spot(rng, half, x, y))
						continue;
					double yaw = rng.uniform(0, 3.14159);
					moves(
					    [&](Rng& er)
					    {
						    double nx, ny;
						    if (!spot(er, half, nx, ny))
							    return Moved();
						    x = nx;
						    y = ny;
						    yaw = er.uniform(0, 3.14159);
						    return Moved(Eigen::Vector2d(x, y));
					    });
					if (type == 0)
						w.addBoxOnGround(x, y, yaw, 0.6, 0.4, 0.75, ObjectKind::Furniture);
					else
						w.addBoxOnGround(x, y, yaw, 0.23, 0.23, 0.9, ObjectKind::Furniture);
				}
				else if (type == 2)  // a cabinet against a wall, turned to face the room
				{
					int side = rng.integer(0, 3);
					double along = rng.uniform(-S / 2 + 1.0, S / 2 - 1.0);
					// Not in front of a door (the middle of the side), and inside the room (a
					// small room with a wide door has no place for one).
					const double edge = S / 2 - p.wall_m / 2 - 0.55;
					if (edge <= p.door_m / 2 + 0.6)
						continue;
					const double h = rng.uniform(1.2, 2.1);
					const double off = S / 2 - p.wall_m / 2 - 0.25;
					// Its centre, and whether it stands along x, for a side and a place along it.
					const auto at = [&](int sd, double al, double& cx, double& cy)
					{
						const double a = std::clamp(
						    std::abs(al) < p.door_m / 2 + 0.6 ? al + (al < 0 ? -1.5 : 1.5) : al,
						    -edge, edge);
						cx = sd <= 1 ? c.x() + a : c.x() + (sd == 2 ? -off : off);
						cy = sd <= 1 ? c.y() + (sd == 0 ? -off : off) : c.y() + a;
						return sd <= 1;
					};
					moves(
					    [&](Rng& er)
					    {
						    side = er.integer(0, 3);
						    along = er.uniform(-S / 2 + 1.0, S / 2 - 1.0);
						    double cx, cy;
						    at(side, along, cx, cy);
						    return Moved(Eigen::Vector2d(cx, cy));
					    });
					const bool alongX = at(side, along, x, y);
					if (alongX)
						w.addBoxOnGround(x, y, 0, 0.5, 0.23, h, ObjectKind::Furniture);
					else
						w.addBoxOnGround(x, y, 0, 0.23, 0.5, h, ObjectKind::Furniture);
				}
				else  // a pillar or a plant
				{
					if (!spot(rng, 0.3, x, y))
						continue;
					// (In this order: the world's draws as before, when they were the arguments of
					// one call, which GCC evaluates right to left.)
					const double height = rng.uniform(1.0, p.ceiling_m);
					const double radius = rng.uniform(0.12, 0.3);
					moves(
					    [&](Rng& er)
					    {
						    double nx, ny;
						    if (!spot(er, 0.3, nx, ny))
							    return Moved();
						    x = nx;
						    y = ny;
						    return Moved(Eigen::Vector2d(x, y));
					    });
					w.addCylinderOnGround(x, y, radius, height, ObjectKind::Furniture);
				}
			}
			for (int k = 0; k < p.people_per_room; k++)
			{
				double x, y;
				if (spot(rng, 0.25, x, y))
					w.addCylinderOnGround(x, y, 0.22, rng.uniform(1.55, 1.9), ObjectKind::Person);
			}
		}
	return w;
}

}  // namespace rasterslam::sim
