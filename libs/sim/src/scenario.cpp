// Strict reading of scenario files: every key known, every value of the expected type.
#include <mrpt/containers/yaml.h>
#include <rasterslam/sim/scenario.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <stdexcept>

namespace rasterslam::sim
{
namespace
{
using Node = mrpt::containers::yaml::node_t;

class Reader
{
   public:
	explicit Reader(std::string file) : file_(std::move(file)) {}

	[[noreturn]] void fail(const std::string& key, const std::string& what) const
	{
		throw std::runtime_error(file_ + ": key '" + key + "': " + what);
	}

	std::string text(const Node& n, const std::string& key) const
	{
		if (!n.isScalar())
			fail(key, "expected a scalar value, found a " + n.typeName());
		std::string s = n.as<std::string>();
		// MRPT prints strings back as YAML, quoting some: undo it.
		if (s.size() >= 2 && (s.front() == '"' || s.front() == '\'') && s.back() == s.front())
			s = s.substr(1, s.size() - 2);
		return s;
	}
	double number(const Node& n, const std::string& key) const
	{
		const std::string s = text(n, key);
		char* end = nullptr;
		errno = 0;
		const double v = std::strtod(s.c_str(), &end);
		if (s.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v))
			fail(key, "expected a number, found '" + s + "'");
		return v;
	}
	long long integer(const Node& n, const std::string& key, long long lo, long long hi) const
	{
		const std::string s = text(n, key);
		char* end = nullptr;
		errno = 0;
		const long long v = std::strtoll(s.c_str(), &end, 10);
		if (s.empty() || *end != '\0' || errno == ERANGE)
			fail(key, "expected an integer, found '" + s + "'");
		if (v < lo || v > hi)
			fail(key, "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) +
			              "], found " + s);
		return v;
	}
	bool boolean(const Node& n, const std::string& key) const
	{
		const std::string s = text(n, key);
		if (s == "true" || s == "True" || s == "yes")
			return true;
		if (s == "false" || s == "False" || s == "no")
			return false;
		fail(key, "expected true or false, found '" + s + "'");
	}

	using Handler = std::function<void(const Node&, const std::string&)>;
	/** Calls the handler of every key of map node `n`; an unknown key is an error. */
	void forEachKey(const Node& n, const std::string& prefix,
	                const std::map<std::string, Handler>& handlers) const
	{
		const std::string where = prefix.empty() ? "(top level)" : prefix;
		if (!n.isMap())
			fail(where, "expected a map of keys, found a " + n.typeName());
		for (const auto& [k, v] : n.asMap())
		{
			const std::string key = k.isScalar() ? k.as<std::string>() : "?";
			const std::string full = prefix.empty() ? key : prefix + "." + key;
			const auto it = handlers.find(key);
			if (it == handlers.end())
			{
				std::string known;
				for (const auto& h : handlers)
					known += (known.empty() ? "" : ", ") + h.first;
				fail(full, "unknown key (known here: " + known + ")");
			}
			it->second(v, full);
		}
	}

   private:
	std::string file_;
};

Eigen::Vector2d point2(const Reader& r, const Node& n, const std::string& key)
{
	if (!n.isSequence() || n.asSequence().size() != 2)
		r.fail(key, "expected a waypoint [x, y]");
	return {r.number(n.asSequence()[0], key), r.number(n.asSequence()[1], key)};
}
}  // namespace

Scenario loadScenario(const std::string& path)
{
	if (!std::filesystem::is_regular_file(path))
		throw std::runtime_error(path + ": scenario file not found");
	mrpt::containers::yaml doc;
	try
	{
		doc = mrpt::containers::yaml::FromFile(path);
	}
	catch (const std::exception& e)
	{
		// MRPT's message carries a call stack: keep its "Message:" line only (the parser has
		// already printed the line and column).
		std::string msg = e.what();
		if (const auto p = msg.find("Message:"); p != std::string::npos)
			msg = msg.substr(p + 9, msg.find('\n', p) - p - 9);
		throw std::runtime_error(path + ": not a valid YAML file (" + msg + ")");
	}
	Scenario sc;
	sc.source = path;
	const Reader r(path);
	constexpr long long kMaxInt = std::numeric_limits<int>::max();
	const auto num = [&](double& dst)
	{ return [&r, &dst](const Node& n, const std::string& k) { dst = r.number(n, k); }; };
	const auto intIn = [&](int& dst, long long lo, long long hi)
	{
		return [&r, &dst, lo, hi](const Node& n, const std::string& k)
		{ dst = static_cast<int>(r.integer(n, k, lo, hi)); };
	};

	TownParams& t = sc.town;
	const std::map<std::string, Reader::Handler> townKeys = {
	    {"blocks_x", intIn(t.blocks_x, 1, 100)},
	    {"blocks_y", intIn(t.blocks_y, 1, 100)},
	    {"block_size_m", num(t.block_size_m)},
	    {"street_width_m", num(t.street_width_m)},
	    {"sidewalk_m", num(t.sidewalk_m)},
	    {"building_height_min_m", num(t.building_height_min_m)},
	    {"building_height_max_m", num(t.building_height_max_m)},
	    {"trees_per_100m", num(t.trees_per_100m)},
	    {"poles_per_100m", num(t.poles_per_100m)},
	    {"cars_per_100m", num(t.cars_per_100m)},
	    {"hills", intIn(t.hills, 0, 32)},
	    {"max_slope", num(t.max_slope)},
	    {"outskirts_m", num(t.outskirts_m)},
	    {"hedge_share", num(t.hedge_share)},
	    {"signs_per_100m", num(t.signs_per_100m)},
	    {"street_furniture_per_100m", num(t.street_furniture_per_100m)},
	    {"facade_detail",
	     [&](const Node& n, const std::string& k) { t.facade_detail = r.boolean(n, k); }},
	    {"curb_m", num(t.curb_m)},
	    {"van_share", num(t.van_share)},
	    {"parking_jitter_m", num(t.parking_jitter_m)},
	    {"irregular_crowns",
	     [&](const Node& n, const std::string& k) { t.irregular_crowns = r.boolean(n, k); }}};
	IndoorParams& in = sc.indoor;
	const std::map<std::string, Reader::Handler> indoorKeys = {
	    {"rooms_x", intIn(in.rooms_x, 1, 20)},
	    {"rooms_y", intIn(in.rooms_y, 1, 20)},
	    {"room_size_m", num(in.room_size_m)},
	    {"ceiling_m", num(in.ceiling_m)},
	    {"wall_m", num(in.wall_m)},
	    {"door_m", num(in.door_m)},
	    {"furniture_per_room", intIn(in.furniture_per_room, 0, 30)},
	    {"people_per_room", intIn(in.people_per_room, 0, 10)}};
	RouteParams& rt = sc.route;
	bool patternGiven = false;
	const std::map<std::string, Reader::Handler> routeKeys = {
	    {"pattern",
	     [&](const Node& n, const std::string& k)
	     {
		     rt.pattern = r.text(n, k);
		     patternGiven = true;
	     }},
	    {"blocks_x", intIn(rt.blocks_x, 1, 100)},
	    {"blocks_y", intIn(rt.blocks_y, 1, 100)},
	    {"waypoints",
	     [&](const Node& n, const std::string& k)
	     {
		     if (!n.isSequence())
			     r.fail(k, "expected a list of [x, y] waypoints");
		     rt.waypoints.clear();
		     for (const auto& p : n.asSequence())
			     rt.waypoints.push_back(point2(r, p, k));
	     }},
	    {"closed", [&](const Node& n, const std::string& k) { rt.closed = r.boolean(n, k); }},
	    {"turn_radius_m", num(rt.turn_radius_m)}};
	NoiseParams& nz = sc.noise;
	const std::map<std::string, Reader::Handler> noiseKeys = {
	    {"range_sigma_m", num(nz.range_sigma_m)},
	    {"dropout_prob", num(nz.dropout_prob)},
	    {"intensity_sigma", num(nz.intensity_sigma)},
	    {"foliage_depth_m", num(nz.foliage_depth_m)},
	    {"range_by_reflectivity",
	     [&](const Node& n, const std::string& k) { nz.range_by_reflectivity = r.boolean(n, k); }}};

	const std::map<std::string, Reader::Handler> bodyKeys = {{"pitch_deg", num(sc.body_pitch_deg)},
	                                                         {"roll_deg", num(sc.body_roll_deg)},
	                                                         {"heave_m", num(sc.body_heave_m)}};

	const auto egoKeys = [&](EgoBox& b)
	{
		return std::map<std::string, Reader::Handler>{{"front_m", num(b.front_m)},
		                                              {"back_m", num(b.back_m)},
		                                              {"half_width_m", num(b.half_width_m)},
		                                              {"height_m", num(b.height_m)}};
	};
	const auto bodyBox = egoKeys(sc.ego_body), cabinBox = egoKeys(sc.ego_cabin);
	const std::map<std::string, Reader::Handler> egoParts = {
	    {"body", [&](const Node& n, const std::string& k) { r.forEachKey(n, k, bodyBox); }},
	    {"cabin", [&](const Node& n, const std::string& k) { r.forEachKey(n, k, cabinBox); }}};

	TrafficParams& tr = sc.traffic;
	const std::map<std::string, Reader::Handler> trafficKeys = {
	    {"cars", intIn(tr.cars, 0, 10000)},
	    {"pedestrians", intIn(tr.pedestrians, 0, 10000)},
	    {"car_speed_mps", num(tr.car_speed_mps)},
	    {"walk_speed_mps", num(tr.walk_speed_mps)}};
	ChangeParams& ch = sc.changes;
	const std::map<std::string, Reader::Handler> changeKeys = {
	    {"parked_cars", num(ch.parked_cars)},
	    {"walls", num(ch.walls)},
	    {"facades", num(ch.facades)},
	    {"vegetation_growth", num(ch.vegetation_growth)},
	    {"furniture", num(ch.furniture)}};

	const std::map<std::string, Reader::Handler> topKeys = {
	    {"seed", [&](const Node& n, const std::string& k)
	     { sc.seed = static_cast<std::uint32_t>(r.integer(n, k, 0, 0xFFFFFFFFll)); }},
	    {"lidar", [&](const Node& n, const std::string& k) { sc.lidar = r.text(n, k); }},
	    {"scans", [&](const Node& n, const std::string& k)
	     { sc.scans = static_cast<std::size_t>(r.integer(n, k, 1, kMaxInt)); }},
	    {"rate_hz", num(sc.rate_hz)},
	    {"speed_mps", num(sc.speed_mps)},
	    {"corner_accel_mps2", num(sc.corner_accel_mps2)},
	    {"accel_mps2", num(sc.accel_mps2)},
	    {"sensor_height_m", num(sc.sensor_height_m)},
	    {"start_stamp_s", num(sc.start_stamp_s)},
	    {"threads", intIn(sc.threads, 1, 64)},
	    {"point_resolution_m", num(sc.point_resolution_m)},
	    {"motion_within_sweep",
	     [&](const Node& n, const std::string& k) { sc.motion_within_sweep = r.boolean(n, k); }},
	    {"sweep_start_azimuth_deg", num(sc.sweep_start_azimuth_deg)},
	    {"sweep_clockwise",
	     [&](const Node& n, const std::string& k) { sc.sweep_clockwise = r.boolean(n, k); }},
	    {"route",
	     [&](const Node& n, const std::string& k)
	     {
		     // Shorthands: a pattern name, or the list of waypoints itself.
		     if (n.isScalar())
		     {
			     rt.pattern = r.text(n, k);
			     patternGiven = true;
		     }
		     else if (n.isSequence())
			     routeKeys.at("waypoints")(n, k);
		     else
			     r.forEachKey(n, k, routeKeys);
	     }},
	    {"town", [&](const Node& n, const std::string& k) { r.forEachKey(n, k, townKeys); }},
	    {"world", [&](const Node& n, const std::string& k) { sc.world = r.text(n, k); }},
	    {"indoor", [&](const Node& n, const std::string& k) { r.forEachKey(n, k, indoorKeys); }},
	    {"handheld", [&](const Node& n, const std::string& k) { sc.handheld = r.boolean(n, k); }},
	    {"body", [&](const Node& n, const std::string& k) { r.forEachKey(n, k, bodyKeys); }},
	    {"ego", [&](const Node& n, const std::string& k) { r.forEachKey(n, k, egoParts); }},
	    {"noise", [&](const Node& n, const std::string& k) { r.forEachKey(n, k, noiseKeys); }},
	    {"traffic", [&](const Node& n, const std::string& k) { r.forEachKey(n, k, trafficKeys); }},
	    {"epoch", intIn(ch.epoch, 0, 10000)},
	    {"changes", [&](const Node& n, const std::string& k) { r.forEachKey(n, k, changeKeys); }}};

	if (!doc.isNullNode())
		r.forEachKey(doc.node(), "", topKeys);
	if (!rt.waypoints.empty() && !patternGiven)
		rt.pattern = "waypoints";
	if (rt.pattern == "waypoints" && rt.waypoints.size() < 2)
		r.fail("route.waypoints", "pattern 'waypoints' needs at least 2 waypoints");
	validateScenario(sc);
	return sc;
}

void validateScenario(const Scenario& sc)
{
	const Reader r(sc.source.empty() ? "(scenario)" : sc.source);
	const auto need = [&](bool ok, const char* key, const char* what)
	{
		if (!ok)
			r.fail(key, what);
	};
	need(sc.lidar == "hdl64" || sc.lidar == "hdl64e" || sc.lidar == "vlp16", "lidar",
	     "expected hdl64, hdl64e or vlp16");
	need(sc.scans >= 1, "scans", "expected >= 1");
	need(sc.rate_hz > 0 && sc.rate_hz <= 100, "rate_hz", "expected in (0, 100]");
	need(sc.speed_mps >= 0 && sc.speed_mps <= 50, "speed_mps", "expected in [0, 50]");
	need(sc.corner_accel_mps2 >= 0 && sc.corner_accel_mps2 <= 10, "corner_accel_mps2",
	     "expected in [0, 10]");
	need(sc.accel_mps2 > 0 && sc.accel_mps2 <= 10, "accel_mps2", "expected in (0, 10]");
	need(sc.sensor_height_m > 0 && sc.sensor_height_m < 10, "sensor_height_m",
	     "expected in (0, 10)");
	need(sc.start_stamp_s >= 0, "start_stamp_s", "expected >= 0");
	need(sc.threads >= 1, "threads", "expected >= 1");
	need(sc.point_resolution_m >= 0 && sc.point_resolution_m <= 0.05, "point_resolution_m",
	     "expected in [0, 0.05]");
	need(sc.sweep_start_azimuth_deg >= -360 && sc.sweep_start_azimuth_deg <= 360,
	     "sweep_start_azimuth_deg", "expected in [-360, 360]");
	need(sc.world == "town" || sc.world == "indoor", "world", "expected town or indoor");
	need(sc.route.pattern == "block_loop" || sc.route.pattern == "figure_eight" ||
	         sc.route.pattern == "room_tour" || sc.route.pattern == "waypoints",
	     "route.pattern", "expected block_loop, figure_eight, room_tour or waypoints");
	need(sc.route.pattern != "room_tour" || sc.indoor.rooms_x * sc.indoor.rooms_y >= 2,
	     "indoor.rooms_x", "room_tour needs at least 2 rooms");
	// A closed tour returns to the first room through a door only when it ends beside it: an
	// even number of rows, or one column.
	need(sc.route.pattern != "room_tour" || !sc.route.closed || sc.indoor.rooms_y % 2 == 0 ||
	         sc.indoor.rooms_x == 1,
	     "indoor.rooms_y",
	     "a closed room_tour needs an even rooms_y (or rooms_x 1): it would cross walls to return");
	need((sc.route.pattern == "room_tour") == (sc.world == "indoor") ||
	         sc.route.pattern == "waypoints",
	     "route.pattern",
	     "room_tour goes with world: indoor, block_loop and figure_eight with town");
	need(sc.route.turn_radius_m >= 0, "route.turn_radius_m", "expected >= 0");
	need(sc.route.blocks_x <= sc.town.blocks_x && sc.route.blocks_y <= sc.town.blocks_y,
	     "route.blocks_x",
	     "the block loop must fit in the town (route.blocks_x/y <= town.blocks_x/y)");
	need(sc.route.pattern != "figure_eight" || sc.town.blocks_x >= 2, "route.pattern",
	     "figure_eight needs town.blocks_x >= 2");
	need(sc.noise.range_sigma_m >= 0 && sc.noise.range_sigma_m < 1, "noise.range_sigma_m",
	     "expected in [0, 1)");
	need(sc.noise.dropout_prob >= 0 && sc.noise.dropout_prob <= 1, "noise.dropout_prob",
	     "expected in [0, 1]");
	need(sc.noise.intensity_sigma >= 0 && sc.noise.intensity_sigma <= 1, "noise.intensity_sigma",
	     "expected in [0, 1]");
	need(sc.noise.foliage_depth_m >= 0 && sc.noise.foliage_depth_m <= 2, "noise.foliage_depth_m",
	     "expected in [0, 2]");
	need(sc.body_pitch_deg >= 0 && sc.body_pitch_deg <= 5, "body.pitch_deg", "expected in [0, 5]");
	need(sc.body_roll_deg >= 0 && sc.body_roll_deg <= 5, "body.roll_deg", "expected in [0, 5]");
	need(sc.body_heave_m >= 0 && sc.body_heave_m <= 0.2, "body.heave_m", "expected in [0, 0.2]");
	for (const auto& [name, b] : {std::pair<const char*, const EgoBox&>{"ego.body", sc.ego_body},
	                              std::pair<const char*, const EgoBox&>{"ego.cabin", sc.ego_cabin}})
	{
		need(b.front_m >= 0 && b.back_m >= 0 && b.half_width_m >= 0 && b.height_m >= 0 &&
		         b.front_m <= 10 && b.back_m <= 10 && b.half_width_m <= 5 && b.height_m <= 5,
		     name,
		     "expected front_m, back_m <= 10, half_width_m <= 5, height_m <= 5, none negative");
		const bool any = b.front_m > 0 || b.back_m > 0 || b.half_width_m > 0 || b.height_m > 0;
		need(!any || !b.empty(), name,
		     "expected front_m + back_m, half_width_m and height_m all above 0 (a box)");
		need(b.height_m < sc.sensor_height_m, name,
		     "expected height_m below sensor_height_m: the lasers would sit inside the box");
	}
	const TownParams& t = sc.town;
	need(t.block_size_m >= 2 * t.sidewalk_m + 10, "town.block_size_m",
	     "expected >= 2 * sidewalk_m + 10");
	need(t.street_width_m >= 6, "town.street_width_m", "expected >= 6");
	need(t.sidewalk_m >= 1, "town.sidewalk_m", "expected >= 1");
	need(t.building_height_min_m > 0 && t.building_height_max_m >= t.building_height_min_m,
	     "town.building_height_min_m",
	     "expected 0 < building_height_min_m <= building_height_max_m");
	need(t.trees_per_100m >= 0, "town.trees_per_100m", "expected >= 0");
	need(t.poles_per_100m >= 0, "town.poles_per_100m", "expected >= 0");
	need(t.cars_per_100m >= 0, "town.cars_per_100m", "expected >= 0");
	need(t.max_slope >= 0 && t.max_slope <= 0.15, "town.max_slope", "expected in [0, 0.15]");
	need(t.outskirts_m >= 0, "town.outskirts_m", "expected >= 0");
	need(t.hedge_share >= 0 && t.hedge_share <= 1, "town.hedge_share", "expected in [0, 1]");
	need(t.signs_per_100m >= 0 && t.signs_per_100m <= 100, "town.signs_per_100m",
	     "expected in [0, 100]");
	need(t.street_furniture_per_100m >= 0 && t.street_furniture_per_100m <= 100,
	     "town.street_furniture_per_100m", "expected in [0, 100]");
	need(t.curb_m >= 0 && t.curb_m <= 0.3, "town.curb_m", "expected in [0, 0.3]");
	need(t.van_share >= 0 && t.van_share <= 1, "town.van_share", "expected in [0, 1]");
	need(t.parking_jitter_m >= 0 && t.parking_jitter_m <= 1, "town.parking_jitter_m",
	     "expected in [0, 1]");
	const TrafficParams& tr = sc.traffic;
	need(tr.cars >= 0 && tr.cars <= 10000, "traffic.cars", "expected in 0..10000");
	need(tr.pedestrians >= 0 && tr.pedestrians <= 10000, "traffic.pedestrians",
	     "expected in 0..10000");
	need(tr.cars == 0 || sc.world == "town", "traffic.cars", "cars drive in the town only");
	need(tr.car_speed_mps > 0 && tr.car_speed_mps <= 40, "traffic.car_speed_mps",
	     "expected in (0, 40]");
	need(tr.walk_speed_mps > 0 && tr.walk_speed_mps <= 40, "traffic.walk_speed_mps",
	     "expected in (0, 40]");
	const ChangeParams& ch = sc.changes;
	need(ch.epoch >= 0 && ch.epoch <= 10000, "epoch", "expected in 0..10000");
	need(ch.parked_cars >= 0 && ch.parked_cars <= 1, "changes.parked_cars", "expected in [0, 1]");
	need(ch.walls >= 0 && ch.walls <= 1, "changes.walls", "expected in [0, 1]");
	need(ch.facades >= 0 && ch.facades <= 1, "changes.facades", "expected in [0, 1]");
	need(ch.vegetation_growth >= 0 && ch.vegetation_growth <= 1, "changes.vegetation_growth",
	     "expected in [0, 1]");
	need(ch.furniture >= 0 && ch.furniture <= 1, "changes.furniture", "expected in [0, 1]");
}

}  // namespace rasterslam::sim
