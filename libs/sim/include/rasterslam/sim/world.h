// The simulated world: a smooth ground height field plus analytic primitives, and a fast
// raycaster over them.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace rasterslam::sim
{
/** What a ray hit; decides the simulated intensity. */
enum class ObjectKind : std::uint8_t
{
	None,
	Ground,
	Building,
	Wall,
	Car,
	Pole,
	TreeTrunk,
	TreeCrown,
	Furniture,
	Person,
	Ceiling
};

const char* kindName(ObjectKind k);
/** Reflectivity in [0,1] before noise: a fixed value per kind, so that a consumer can tell
 *  cars from facades by intensity as on a real sensor. */
float nominalIntensity(ObjectKind k);

/** A bump z += height_m * (1 - r^2/R^2)^2 for r < R: C1-smooth, compact support (so a ray
 *  only evaluates the hills it passes over) and a closed-form gradient. Its steepest slope is
 *  kHillSlopeFactor * |height_m| / radius_m. A negative height makes a dip. */
struct Hill
{
	double x = 0, y = 0, height_m = 0, radius_m = 1;
};
/** max over s of |d/ds (1 - s^2)^2| = 8 / (3 sqrt(3)), reached at s = 1/sqrt(3). */
constexpr double kHillSlopeFactor = 1.5396007178390020;

/** Ground z = h(x,y) = base + tilt . (x,y) + sum of hills. Default: flat z = 0. */
class GroundModel
{
   public:
	GroundModel() = default;
	GroundModel(double base_m, Eigen::Vector2d tilt, std::vector<Hill> hills);

	double height(double x, double y) const;
	Eigen::Vector2d gradient(double x, double y) const;
	/** Upper bound of |grad h| anywhere (tilt plus every hill's steepest slope). */
	double maxSlope() const { return maxSlope_; }
	const std::vector<Hill>& hills() const { return hills_; }

	/** First t in [0, tMax] where origin + t * dir goes below the ground (dir unit), or
	 *  +inf. A ray starting below the ground returns 0. Accurate to about 1e-5 m. */
	double intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double tMax) const;

   private:
	double base_ = 0;
	Eigen::Vector2d tilt_ = Eigen::Vector2d::Zero();
	std::vector<Hill> hills_;
	double maxSlope_ = 0;
};

enum class ShapeType : std::uint8_t
{
	Box,       //!< yaw-rotated box: half extents a (along yaw), b; z in [zmin, zmax]
	Cylinder,  //!< vertical: radius a; z in [zmin, zmax]
	Ellipsoid  //!< vertical axis: horizontal radius a, vertical radius b, centre (cx, cy, cz)
};

struct Shape
{
	ShapeType type = ShapeType::Box;
	ObjectKind kind = ObjectKind::Building;
	double cx = 0, cy = 0, cz = 0;
	double a = 0, b = 0;
	double zmin = 0, zmax = 0;
	double cosYaw = 1, sinYaw = 0;
	/** Radius of the footprint's bounding circle, for the grid registration. */
	double footprintRadius() const;
};

struct RayHit
{
	double range = std::numeric_limits<double>::infinity();
	ObjectKind kind = ObjectKind::None;
	bool hit() const { return kind != ObjectKind::None; }
};

/** Parameters of the procedural town (see rawlogs/README.md for units and defaults). */
struct TownParams
{
	int blocks_x = 3;
	int blocks_y = 2;
	double block_size_m = 50;
	double street_width_m = 14;
	double sidewalk_m = 3;
	double building_height_min_m = 6;
	double building_height_max_m = 24;
	double trees_per_100m = 4;
	double poles_per_100m = 3;
	double cars_per_100m = 5;
	int hills = 4;
	double max_slope = 0.06;
	/** Width of the belt of trees and fences around the town. */
	double outskirts_m = 25;

	// Detail for scenes like real streets (the KITTI sample's): all off by default, and each
	// drawn from its own random stream, so the town's layout is the same with or without it.
	/** Share of a block side's length lined with hedges at the back of the sidewalk. */
	double hedge_share = 0;
	/** Traffic signs (a post and a panel) at the kerb. */
	double signs_per_100m = 0;
	/** Bins, bollards and benches on the sidewalk. */
	double street_furniture_per_100m = 0;
	/** Facades with piers between the windows, entrance steps and some awnings. */
	bool facade_detail = false;
	/** Height of the kerb: the sidewalk stands this much above the street (0: level). */
	double curb_m = 0;
	/** Share of parked vehicles that are vans or SUVs rather than cars. */
	double van_share = 0;
	/** A parked car stands up to this far along the kerb off its 6 m slot's centre. */
	double parking_jitter_m = 0;
	/** Crowns of several lobes rather than one ellipsoid. */
	bool irregular_crowns = false;
	bool detailed() const
	{
		return hedge_share > 0 || signs_per_100m > 0 || street_furniture_per_100m > 0 ||
		       facade_detail || curb_m > 0 || van_share > 0 || irregular_crowns ||
		       parking_jitter_m > 0;
	}

	/** Distance between two parallel street centre lines. */
	double pitch() const { return block_size_m + street_width_m; }
};

/** Parameters of the indoor world (see rawlogs/README.md): a grid of rooms with a door in the
 *  middle of every inner wall, furniture, people standing, under a flat ceiling. */
struct IndoorParams
{
	int rooms_x = 3;
	int rooms_y = 2;
	double room_size_m = 8;
	double ceiling_m = 2.8;
	double wall_m = 0.15;
	double door_m = 1.0;
	int furniture_per_room = 5;
	int people_per_room = 1;
	/** Centre of room (i, j). */
	Eigen::Vector2d roomCentre(int i, int j) const
	{
		return {(i + 0.5) * room_size_m, (j + 0.5) * room_size_m};
	}
};

/** How the world changes between sessions. A session sees the world at its `epoch`: the
 *  world as generated (epoch 0) plus every change of epochs 1..epoch, so a change made at
 *  epoch e appears in every session of epoch >= e (until a later change undoes it) and in
 *  none before. Each rate is the
 *  probability, per epoch, that one object of that kind changes; the draws are a hash of
 *  (seed, object, epoch), apart from the draws that build the world, so epoch 0 is the same
 *  world bit for bit whatever the rates. */
struct ChangeParams
{
	int epoch = 0;
	/** A kerb slot (6 m) changes: its car leaves, or another car parks there, a little further
	 *  along and maybe facing the other way; an empty slot gains a car. */
	double parked_cars = 0.3;
	/** A wall or fence in a gap between buildings is built or pulled down. */
	double walls = 0.05;
	/** A building's front gains or loses an annex (a shop front, scaffolding) on the
	 *  sidewalk. */
	double facades = 0.05;
	/** Tree crowns grow by this fraction per epoch (each tree 0.5..1.5 times it), up to 1.8
	 *  times their first size. */
	double vegetation_growth = 0.04;
	/** Indoors: a piece of furniture is moved to another free spot of its room. */
	double furniture = 0.2;
};

/** One change between sessions, as applied. */
struct ChangeRecord
{
	int epoch = 0;
	/** "car parked", "car left", "car moved", "wall built", "wall removed", "annex built",
	 *  "annex removed", "furniture moved". Vegetation grows everywhere and is not listed. */
	std::string what;
	Eigen::Vector2d where = Eigen::Vector2d::Zero();
};

/** A shape standing on the ground at its centre (see World::addBoxOnGround), not added to any
 *  world: the movers' shapes are built with these. */
Shape boxOnGround(const GroundModel& g, double cx, double cy, double yaw, double halfLength,
                  double halfWidth, double height, ObjectKind kind, double clearance = 0);
Shape cylinderOnGround(const GroundModel& g, double cx, double cy, double radius, double height,
                       ObjectKind kind);

/** Ground plus shapes. Shapes are registered in a uniform XY grid so that a ray only tests
 *  the shapes of the cells it crosses. Adding shapes is not thread-safe; raycast() is. */
class World
{
   public:
	explicit World(GroundModel ground = {}, double cellSize_m = 4.0);

	/** The procedural town; deterministic for (params, seed). Street centre lines lie at
	 *  x = i * pitch (i = 0..blocks_x) and y = j * pitch (j = 0..blocks_y); streets are free
	 *  of obstacles except cars parked at the kerbs. Throws std::invalid_argument on
	 *  nonsensical parameters. */
	static World generate(const TownParams& params, std::uint32_t seed,
	                      const ChangeParams& changes = {});
	/** The indoor world on a flat floor (z = 0): room (i, j) spans [i S, (i+1) S] x
	 *  [j S, (j+1) S] (S = room_size_m); the lanes through the room centres and the doors are
	 *  kept clear. Deterministic for (params, seed); throws std::invalid_argument on
	 *  nonsensical parameters. */
	static World generateIndoor(const IndoorParams& params, std::uint32_t seed,
	                            const ChangeParams& changes = {});

	/** Adds a shape as is (z extents absolute). */
	void add(const Shape& s);
	/** Shapes standing on the ground at their centre: their base is sunk by the ground's
	 *  rise under the footprint, so that no gap shows on a slope. */
	void addBoxOnGround(double cx, double cy, double yaw, double halfLength, double halfWidth,
	                    double height, ObjectKind kind, double clearance = 0);
	void addCylinderOnGround(double cx, double cy, double radius, double height, ObjectKind kind);
	/** An ellipsoid whose lowest point is `bottom` above the ground at (cx, cy). */
	void addEllipsoidOnGround(double cx, double cy, double bottom, double radiusXY, double radiusZ,
	                          ObjectKind kind);

	/** Nearest surface along origin + t * dir (dir unit) with 0 < t <= maxRange. */
	RayHit raycast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
	               double maxRange) const;

	const GroundModel& ground() const { return ground_; }
	const std::vector<Shape>& shapes() const { return shapes_; }
	/** The changes between sessions that made this world (generate() with an epoch > 0), in
	 *  the order they were applied. */
	const std::vector<ChangeRecord>& changes() const { return changes_; }
	void recordChange(ChangeRecord c) { changes_.push_back(std::move(c)); }

   private:
	void rebuildGrid(double xmin, double ymin, double xmax, double ymax);
	void registerShape(std::uint32_t id);

	GroundModel ground_;
	std::vector<Shape> shapes_;
	double cell_;
	double x0_ = 0, y0_ = 0;
	int nx_ = 0, ny_ = 0;
	std::vector<std::vector<std::uint32_t>> cells_;
	std::vector<ChangeRecord> changes_;
};

/** Ray-shape intersection: the first t > 0 on the surface (the exit point when the origin
 *  is inside), or +inf. */
double intersectShape(const Shape& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d);

}  // namespace rasterslam::sim
