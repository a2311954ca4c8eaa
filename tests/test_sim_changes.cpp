// Tests of the simulator's changing world: objects moving during a run, changes between
// sessions (epochs), and the revisit truth between sessions.
#include <rasterslam/sim/revisits.h>
#include <rasterslam/sim/simulator.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include "sim_test_support.h"
#include "test_support.h"

namespace
{
using namespace rasterslam;

/** The intensity a point of this kind has without noise (8-bit, as the simulator rounds). */
float exactIntensity(sim::ObjectKind k)
{
	return static_cast<float>(std::round(sim::nominalIntensity(k) * 256) / 256);
}

/** Points of one kind (told by their exact intensity), in the world frame. */
std::vector<Eigen::Vector3d> pointsOfKind(const Scan& scan, sim::ObjectKind k)
{
	const Eigen::Matrix4d T =
	    scan.groundTruth->getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
	std::vector<Eigen::Vector3d> out;
	for (const auto& p : scan.points)
		if (p.intensity == exactIntensity(k))
			out.push_back((T * Eigen::Vector4d(p.x, p.y, p.z, 1)).head<3>());
	return out;
}

Eigen::Vector3d centroid(const std::vector<Eigen::Vector3d>& v)
{
	Eigen::Vector3d c = Eigen::Vector3d::Zero();
	for (const auto& p : v)
		c += p;
	return c / static_cast<double>(std::max<std::size_t>(1, v.size()));
}

/** Every field of two shapes equal, bit for bit. */
bool sameShape(const sim::Shape& a, const sim::Shape& b)
{
	return a.type == b.type && a.kind == b.kind && a.cx == b.cx && a.cy == b.cy && a.cz == b.cz &&
	       a.a == b.a && a.b == b.b && a.zmin == b.zmin && a.zmax == b.zmax &&
	       a.cosYaw == b.cosYaw && a.sinYaw == b.sinYaw;
}

bool sameShapes(const sim::World& a, const sim::World& b)
{
	if (a.shapes().size() != b.shapes().size())
		return false;
	for (std::size_t i = 0; i < a.shapes().size(); i++)
		if (!sameShape(a.shapes()[i], b.shapes()[i]))
			return false;
	return true;
}

/** Shapes of `a` with no identical shape in `b` (crowns that grew excluded). */
std::vector<sim::Shape> notIn(const sim::World& a, const sim::World& b)
{
	std::vector<sim::Shape> out;
	for (const auto& s : a.shapes())
	{
		if (s.kind == sim::ObjectKind::TreeCrown)
			continue;
		if (std::none_of(b.shapes().begin(), b.shapes().end(),
		                 [&](const sim::Shape& t) { return sameShape(s, t); }))
			out.push_back(s);
	}
	return out;
}

// Fingerprints of the worlds generate() made before the changing world was added (checked:
// the shipped town-loop and town-vlp16 rawlogs, simulated whole, identical byte for byte).
constexpr std::uint64_t kTown42 = 0xb089b9867745a9a3ull;
constexpr std::uint64_t kIndoor7 = 0xed3e7029efa14178ull;

sim::ChangeParams epochOf(int e)
{
	sim::ChangeParams c;
	c.epoch = e;
	c.parked_cars = 0.3;
	c.walls = 0.2;
	c.facades = 0.2;
	c.vegetation_growth = 0.05;
	c.furniture = 0.3;
	return c;
}
}  // namespace

TEST(SimTraffic, MoversMoveAsSpecifiedAndAppearInTheScans)
{
	sim::TownParams town;
	town.cars_per_100m = 0;  // no parked car: every car point is a moving one
	sim::TrafficParams tp;
	tp.cars = 6;
	tp.pedestrians = 12;
	tp.car_speed_mps = 8;
	tp.walk_speed_mps = 1.4;
	const sim::Traffic traffic = sim::Traffic::town(town, tp, 11);
	ASSERT_EQ(traffic.movers().size(), 18u);
	ASSERT_NE(exactIntensity(sim::ObjectKind::Car), exactIntensity(sim::ObjectKind::Person));

	// As specified: on its path, at its speed, back and forth.
	for (std::size_t i = 0; i < traffic.movers().size(); i++)
	{
		const sim::Mover& m = traffic.movers()[i];
		const double nominal =
		    m.kind == sim::ObjectKind::Car ? tp.car_speed_mps : tp.walk_speed_mps;
		EXPECT_GE(m.speed_mps, 0.8 * nominal - 1e-9);
		EXPECT_LE(m.speed_mps, 1.2 * nominal + 1e-9);
		const Eigen::Vector2d ab = m.b - m.a;
		const double L = ab.norm(), period = 2 * L / m.speed_mps;
		ASSERT_GT(L, 10);
		for (const double t : {0.0, 3.7, 41.2, 250.0})
		{
			const auto s = traffic.state(i, t);
			const double along = (s.position - m.a).dot(ab) / L;
			const double off =
			    std::abs(ab.x() * (s.position - m.a).y() - ab.y() * (s.position - m.a).x()) / L;
			EXPECT_NEAR(off, 0, 1e-9) << "mover " << i << " off its path";
			EXPECT_GE(along, -1e-9);
			EXPECT_LE(along, L + 1e-9);
			EXPECT_NEAR((traffic.state(i, t + period).position - s.position).norm(), 0, 1e-6);
			// Away from the turns it covers speed * dt along its heading.
			if (along > 2 && along < L - 2)
			{
				const auto s2 = traffic.state(i, t + 0.1);
				const Eigen::Vector2d step = s2.position - s.position;
				EXPECT_NEAR(step.norm(), 0.1 * m.speed_mps, 1e-9);
				EXPECT_NEAR(std::remainder(std::atan2(step.y(), step.x()) - s.yaw, 2 * M_PI), 0,
				            1e-9);
			}
		}
	}

	// In the scans: each kind's points lie on its movers as they stand at the scan's time, and
	// move with them.
	auto o = test::exactSimOptions();
	sim::Simulator simulator(std::make_shared<const sim::World>(sim::World::generate(town, 11)),
	                         sim::LidarModel::hdl64(), sim::Route(), o);
	for (const std::size_t i : {std::size_t{0}, std::size_t{6}})  // a car, a person
	{
		const sim::Mover& m = traffic.movers()[i];
		// This mover alone in the town: each point of its kind is one of its own.
		simulator.setTraffic(sim::Traffic({m}));
		const Eigen::Vector2d ab = m.b - m.a;
		const double L = ab.norm();
		// The time the mover passes the middle of its path going a -> b.
		const double t0 =
		    (L / 2 - m.phase_m) / m.speed_mps + (m.phase_m > L / 2 ? 2 * L / m.speed_mps : 0);
		const double dt = 3 / m.speed_mps;  // 3 m further
		const Eigen::Vector2d u = ab / L, side(-u.y(), u.x());
		// The sensor on the street: a car seen from the other lane, a person from the centre
		// line.
		const bool alongX = std::abs(u.x()) > std::abs(u.y());
		const double perp = alongX ? m.a.y() : m.a.x();
		const double line = std::round(perp / town.pitch()) * town.pitch();
		const double sensorPerp = std::abs(perp - line) < 4 ? 2 * line - perp : line;
		Eigen::Vector2d at = m.a + (L / 2 + 1.5) * u;
		(alongX ? at.y() : at.x()) = sensorPerp;
		const double z = simulator.world().ground().height(at.x(), at.y()) + 1.73;
		const mrpt::poses::CPose3D sensor(at.x(), at.y(), z, 0, 0, 0);
		const auto kind = m.kind;
		std::vector<Eigen::Vector3d> seen[2];
		for (int k = 0; k < 2; k++)
		{
			const double t = t0 + k * dt;
			const auto st = traffic.state(i, t);
			ASSERT_NEAR((st.position - (m.a + (L / 2 + k * 3) * u)).norm(), 0, 1e-6);
			const Scan scan = simulator.scanFrom(sensor, k, o.start_stamp_s + t);
			for (const auto& p : pointsOfKind(scan, kind))
				if ((p.head<2>() - st.position).norm() < 3)
					seen[k].push_back(p);
			ASSERT_GE(seen[k].size(), kind == sim::ObjectKind::Car ? 200u : 20u)
			    << "mover " << i << " not in the scan at t = " << t;
			// Every such point on that mover's shapes, as they stand at that time.
			std::vector<sim::Shape> shapes;
			sim::Traffic one({m});
			one.shapesAt(t, simulator.world().ground(), {at.x(), at.y(), z}, 120, 1, shapes);
			ASSERT_FALSE(shapes.empty());
			std::size_t onShape = 0;
			for (const auto& p : seen[k])
			{
				const Eigen::Vector3d from(at.x(), at.y(), z);
				const Eigen::Vector3d d = (p - from).normalized();
				for (const auto& s : shapes)
					if (std::abs(sim::intersectShape(s, from, d) - (p - from).norm()) < 1e-3)
					{
						onShape++;
						break;
					}
			}
			EXPECT_EQ(onShape, seen[k].size()) << "mover " << i;
		}
		const Eigen::Vector2d moved = (centroid(seen[1]) - centroid(seen[0])).head<2>();
		EXPECT_NEAR(moved.dot(u), 3, 0.6) << "mover " << i;
		EXPECT_LT(std::abs(moved.dot(side)), 0.4) << "mover " << i;
	}
}

TEST(SimChanges, AChangeAppearsOnlyInTheSessionsAfterIt)
{
	sim::TownParams town;
	const std::uint32_t seed = 5;
	// Epoch 0 is the world as generated, whatever the rates.
	const sim::World base = sim::World::generate(town, seed);
	EXPECT_TRUE(sameShapes(base, sim::World::generate(town, seed, epochOf(0))));
	EXPECT_TRUE(base.changes().empty());

	std::vector<sim::World> worlds;
	for (int e = 0; e <= 4; e++)
		worlds.push_back(sim::World::generate(town, seed, epochOf(e)));
	std::map<std::string, int> kinds;
	for (int e = 1; e <= 4; e++)
	{
		const auto& before = worlds[e - 1];
		const auto& now = worlds[e];
		// The changes so far are the ones before, plus this epoch's.
		std::vector<std::string> earlier, kept;
		std::vector<sim::ChangeRecord> fresh;
		for (const auto& c : before.changes())
			earlier.push_back(std::to_string(c.epoch) + c.what);
		for (const auto& c : now.changes())
		{
			ASSERT_GE(c.epoch, 1);
			ASSERT_LE(c.epoch, e);
			if (c.epoch < e)
				kept.push_back(std::to_string(c.epoch) + c.what);
			else
				fresh.push_back(c);
		}
		EXPECT_EQ(kept, earlier) << "epoch " << e;
		ASSERT_FALSE(fresh.empty()) << "epoch " << e;
		// What differs between the two worlds is where this epoch's changes are, and only there.
		const auto near = [&](const sim::Shape& s)
		{
			return std::any_of(fresh.begin(), fresh.end(),
			                   [&](const sim::ChangeRecord& c)
			                   { return (Eigen::Vector2d(s.cx, s.cy) - c.where).norm() < 12; });
		};
		const auto gone = notIn(before, now), added = notIn(now, before);
		EXPECT_FALSE(gone.empty() && added.empty()) << "epoch " << e;
		for (const auto& s : gone)
			EXPECT_TRUE(near(s)) << "epoch " << e << ": a shape at " << s.cx << " " << s.cy
			                     << " left with no change recorded there";
		for (const auto& s : added)
			EXPECT_TRUE(near(s)) << "epoch " << e << ": a shape at " << s.cx << " " << s.cy
			                     << " came with no change recorded there";
		for (const auto& c : fresh)
			kinds[c.what]++;
	}
	for (const char* k : {"car left", "car parked", "wall built", "annex built"})
		EXPECT_GT(kinds[k], 0) << k;
	// Trees grew, and not beyond 1.8 times.
	double grown = 0;
	std::vector<double> r0, r4;
	for (const auto& s : worlds[0].shapes())
		if (s.kind == sim::ObjectKind::TreeCrown)
			r0.push_back(s.a);
	for (const auto& s : worlds[4].shapes())
		if (s.kind == sim::ObjectKind::TreeCrown)
			r4.push_back(s.a);
	ASSERT_EQ(r0.size(), r4.size());
	ASSERT_GT(r0.size(), 10u);
	for (std::size_t i = 0; i < r0.size(); i++)
	{
		EXPECT_GT(r4[i], r0[i] * 1.05);
		EXPECT_LE(r4[i], r0[i] * 1.8 + 1e-9);
		grown += r4[i] / r0[i];
	}
	EXPECT_NEAR(grown / r0.size(), std::pow(1.05, 4), 0.05);

	// In the scans: a parked car that left at epoch e is seen by the sessions before e, not by
	// session e.
	const sim::ChangeRecord* left = nullptr;
	for (const auto& c : worlds[4].changes())
		if (c.what == "car left" && c.epoch >= 2)
		{
			// Not parked again later.
			const bool back =
			    std::any_of(worlds[4].changes().begin(), worlds[4].changes().end(),
			                [&](const sim::ChangeRecord& d)
			                { return d.epoch > c.epoch && (d.where - c.where).norm() < 1.5; });
			if (!back)
			{
				left = &c;
				break;
			}
		}
	ASSERT_NE(left, nullptr);
	// The street it was parked in: its centre line is the nearest street line to the car.
	const double P = town.pitch();
	const Eigen::Vector2d q = left->where;
	const double dx = std::abs(q.x() - std::round(q.x() / P) * P);
	const double dy = std::abs(q.y() - std::round(q.y() / P) * P);
	const Eigen::Vector2d street = dx < dy ? Eigen::Vector2d(std::round(q.x() / P) * P, q.y())
	                                       : Eigen::Vector2d(q.x(), std::round(q.y() / P) * P);
	auto o = test::exactSimOptions();
	for (int e = 0; e <= 4; e++)
	{
		sim::Simulator simulator(std::make_shared<const sim::World>(worlds[e]),
		                         sim::LidarModel::vlp16(), sim::Route(), o);
		const double z = worlds[e].ground().height(street.x(), street.y()) + 1.73;
		const Scan scan =
		    simulator.scanFrom(mrpt::poses::CPose3D(street.x(), street.y(), z, 0, 0, 0), 0, 0);
		std::size_t there = 0;
		for (const auto& p : pointsOfKind(scan, sim::ObjectKind::Car))
			there += (p.head<2>() - q).norm() < 2.5;
		if (e < left->epoch)
			EXPECT_GT(there, 20u) << "epoch " << e << ": the car at " << q.transpose()
			                      << " should still be parked";
		else
			EXPECT_EQ(there, 0u) << "epoch " << e << ": the car at " << q.transpose()
			                     << " left at epoch " << left->epoch;
	}
}

TEST(SimChanges, FurnitureMovedBetweenIndoorSessions)
{
	sim::IndoorParams in;
	const sim::World base = sim::World::generateIndoor(in, 3);
	EXPECT_TRUE(sameShapes(base, sim::World::generateIndoor(in, 3, epochOf(0))));
	const sim::World w1 = sim::World::generateIndoor(in, 3, epochOf(1));
	const sim::World w2 = sim::World::generateIndoor(in, 3, epochOf(2));
	ASSERT_FALSE(w2.changes().empty());
	ASSERT_EQ(w1.shapes().size(), base.shapes().size());  // moved, none added or lost
	// What moved at epoch 2 is where the records of epoch 2 say, nothing else.
	std::vector<Eigen::Vector2d> to;
	for (const auto& c : w2.changes())
		if (c.epoch == 2)
			to.push_back(c.where);
	ASSERT_FALSE(to.empty());
	const auto added = notIn(w2, w1);
	ASSERT_FALSE(added.empty());
	for (const auto& s : added)
	{
		EXPECT_EQ(s.kind, sim::ObjectKind::Furniture);
		EXPECT_TRUE(std::any_of(to.begin(), to.end(),
		                        [&](const Eigen::Vector2d& p)
		                        { return (p - Eigen::Vector2d(s.cx, s.cy)).norm() < 1e-9; }));
	}
	// Tables, chairs, pillars and plants, moved or not, stay off the lanes the walk takes
	// (through the room centres); cabinets stand against the walls.
	std::size_t checked = 0;
	for (const auto& s : w2.shapes())
		if (s.kind == sim::ObjectKind::Furniture &&
		    (s.type != sim::ShapeType::Box || (s.a == 0.6 && s.b == 0.4) ||
		     (s.a == 0.23 && s.b == 0.23)))
			for (int i = 0; i < in.rooms_x; i++)
				for (int j = 0; j < in.rooms_y; j++)
				{
					const Eigen::Vector2d c = in.roomCentre(i, j);
					if (std::abs(s.cx - c.x()) < in.room_size_m / 2 &&
					    std::abs(s.cy - c.y()) < in.room_size_m / 2)
					{
						EXPECT_TRUE(std::abs(s.cx - c.x()) > 1.2 && std::abs(s.cy - c.y()) > 1.2)
						    << s.cx << " " << s.cy;
						checked++;
					}
				}
	EXPECT_GT(checked, 10u);
}

namespace
{
/** FNV-1a over every field of every shape: the world's fingerprint. */
std::uint64_t fingerprint(const sim::World& w)
{
	std::uint64_t h = 1469598103934665603ull;
	const auto add = [&h](const void* p, std::size_t n)
	{
		for (std::size_t i = 0; i < n; i++)
			h = (h ^ static_cast<const unsigned char*>(p)[i]) * 1099511628211ull;
	};
	for (const auto& s : w.shapes())
	{
		const auto type = static_cast<int>(s.type), kind = static_cast<int>(s.kind);
		add(&type, sizeof type);
		add(&kind, sizeof kind);
		for (const double v : {s.cx, s.cy, s.cz, s.a, s.b, s.zmin, s.zmax, s.cosYaw, s.sinYaw})
			add(&v, sizeof v);
	}
	return h;
}
}  // namespace

TEST(SimChanges, EpochZeroIsTheWorldAsItWasGenerated)
{
	// The shipped scenarios' worlds, pinned: the changes between sessions and the traffic
	// (their own random streams) must not move them. Fingerprints taken before either existed.
	sim::TownParams town;  // the town of rawlogs/town-loop.yaml
	EXPECT_EQ(fingerprint(sim::World::generate(town, 42)), kTown42)
	    << std::hex << fingerprint(sim::World::generate(town, 42));
	sim::IndoorParams indoor;  // the floor of rawlogs/indoor-handheld.yaml
	indoor.furniture_per_room = 6;
	EXPECT_EQ(fingerprint(sim::World::generateIndoor(indoor, 7)), kIndoor7)
	    << std::hex << fingerprint(sim::World::generateIndoor(indoor, 7));
}

TEST(SimRevisits, TruthAgreesWithThePoses)
{
	// Two sessions over one town: a block loop, and a route that drives its first street both
	// ways, one of them the loop's way.
	sim::Scenario a, b;
	a.scans = 400;
	a.route.pattern = "block_loop";
	b.seed = a.seed;
	b.scans = 720;
	b.route.pattern = "waypoints";
	b.route.waypoints = {{0, 0}, {128, 0}, {128, 128}, {64, 128}, {64, 0}, {0, 0}, {0, 64}};
	b.route.closed = false;
	b.start_stamp_s = a.start_stamp_s + 86400;
	const auto trajectory = [](const sim::Scenario& sc)
	{
		const auto s = sim::Simulator::fromScenario(sc);
		io::Trajectory t;
		for (std::size_t k = 0; k < sc.scans; k++)
		{
			io::StampedPose p;
			p.stamp = s.stamp(k);
			p.pose.matrix() =
			    s.sensorPose(k).getHomogeneousMatrixVal<mrpt::math::CMatrixDouble44>().asEigen();
			t.push_back(p);
		}
		return t;
	};
	const io::Trajectory ta = trajectory(a), tb = trajectory(b);
	const double radius = 5;
	const auto rv = sim::findRevisits(tb, {ta}, radius);
	// Brute force: a scan is listed exactly when an earlier pose is within the radius, with the
	// nearest one.
	std::size_t listed = 0, opposite = 0, same = 0;
	for (std::size_t k = 0; k < tb.size(); k++)
	{
		double best = 1e18;
		std::size_t arg = 0;
		for (std::size_t j = 0; j < ta.size(); j++)
		{
			const double d = (ta[j].pose.translation() - tb[k].pose.translation()).norm();
			if (d < best)
			{
				best = d;
				arg = j;
			}
		}
		const auto it =
		    std::find_if(rv.begin(), rv.end(), [k](const sim::Revisit& v) { return v.scan == k; });
		if (best > radius)
		{
			EXPECT_EQ(it, rv.end()) << "scan " << k << " is " << best << " m from session a";
			continue;
		}
		ASSERT_NE(it, rv.end()) << "scan " << k << " is " << best << " m from session a";
		listed++;
		EXPECT_EQ(it->earlierScan, arg);
		EXPECT_NEAR(it->distance_m, best, 1e-9);
		EXPECT_DOUBLE_EQ(it->stamp, tb[k].stamp);
		EXPECT_DOUBLE_EQ(it->earlierStamp, ta[arg].stamp);
		opposite += it->yawDiff_deg > 150;
		same += it->yawDiff_deg < 30;
	}
	EXPECT_EQ(listed, rv.size());
	EXPECT_GT(listed, 200u);
	EXPECT_GT(opposite, 20u);
	EXPECT_GT(same, 20u);
	std::cout << "listed " << listed << ", same way " << same << ", the other way " << opposite
	          << "\n";

	// As text: a header, then one line per revisit that reads back.
	const std::string text = sim::formatRevisits(rv, {"a"}, radius);
	std::istringstream in(text);
	const auto lines = test::parseRevisits(in);
	ASSERT_EQ(lines.size(), rv.size());
	for (std::size_t i = 0; i < lines.size(); i++)
	{
		ASSERT_TRUE(lines[i].parsed) << lines[i].text;
		EXPECT_EQ(lines[i].session, "a");
		EXPECT_EQ(lines[i].scan, rv[i].scan);
		EXPECT_NEAR(lines[i].distance_m, rv[i].distance_m, 1e-3);
	}
	EXPECT_THROW(sim::findRevisits(tb, {ta}, 0), std::invalid_argument);
}

TEST(SimRevisits, WrittenByTheSimulatorForEachSession)
{
	const test::ScopedTempDir dir("simrev");
	const auto write = [&](const std::string& name, const std::string& text)
	{
		std::ofstream(dir / name) << text;
		return (dir / name).string();
	};
	const auto s1 = write("s1.yaml", "lidar: vlp16\nscans: 20\n");
	const auto s2 = write("s2.yaml",
	                      "lidar: vlp16\nscans: 20\nstart_stamp_s: 1700086400\nepoch: 2\n"
	                      "traffic: {cars: 4, pedestrians: 8}\n");
	const std::string sim = test::bin("rasterslam-sim");
	const auto r1 =
	    test::runCommand(sim + " --scenario " + s1 + " --out " + (dir / "s1.rawlog").string() +
	                     " --gt-tum " + (dir / "s1.tum").string());
	ASSERT_EQ(r1.exitCode, 0) << r1.output;
	const auto rev = dir / "s2.revisits.txt";
	const auto r2 = test::runCommand(sim + " --scenario " + s2 + " --out " +
	                                 (dir / "s2.rawlog").string() + " --revisits-of " +
	                                 (dir / "s1.tum").string() + " --revisits " + rev.string());
	ASSERT_EQ(r2.exitCode, 0) << r2.output;
	EXPECT_NE(r2.output.find("epoch 2: "), std::string::npos) << r2.output;
	EXPECT_NE(r2.output.find("moving: 4 cars, 8 people"), std::string::npos) << r2.output;
	EXPECT_NE(r2.output.find("revisits: 20 of 20 scans"), std::string::npos) << r2.output;
	// The same route a day later: every scan at the place of the same scan of session 1.
	std::ifstream in(rev);
	const auto lines = test::parseRevisits(in);
	ASSERT_EQ(lines.size(), 20u);
	for (std::size_t n = 0; n < lines.size(); n++)
	{
		const auto& r = lines[n];
		ASSERT_TRUE(r.parsed) << r.text;
		EXPECT_EQ(r.session, "s1");
		EXPECT_EQ(r.scan, n);
		EXPECT_EQ(r.earlierScan, n);
		EXPECT_NEAR(r.stamp - r.earlierStamp, 86400, 1e-3);
		EXPECT_NEAR(r.distance_m, 0, 1e-3);
		EXPECT_NEAR(r.yaw_deg, 0, 0.01);
	}

	// Misuse: a clear error, nothing written.
	const auto bad =
	    test::runCommand(sim + " --scenario " + s2 + " --out " + (dir / "x.rawlog").string() +
	                     " --revisits " + (dir / "x.txt").string());
	EXPECT_NE(bad.exitCode, 0);
	EXPECT_NE(bad.output.find("--revisits-of"), std::string::npos) << bad.output;
	EXPECT_FALSE(std::filesystem::exists(dir / "x.txt"));
	const auto badTum = write("bad.tum", "1 2 3\n");
	const auto bad2 =
	    test::runCommand(sim + " --scenario " + s2 + " --out " + (dir / "x.rawlog").string() +
	                     " --revisits-of " + badTum + " --revisits " + (dir / "x.txt").string());
	EXPECT_NE(bad2.exitCode, 0);
	EXPECT_NE(bad2.output.find("bad.tum"), std::string::npos) << bad2.output;
	EXPECT_FALSE(std::filesystem::exists(dir / "x.txt"));
	EXPECT_FALSE(std::filesystem::exists(dir / "x.rawlog"));

	// Scenario keys of the changing world are checked like the others.
	for (const auto& [text, key] : std::vector<std::pair<std::string, std::string>>{
	         {"epoch: -1\n", "epoch"},
	         {"changes: {walls: 2}\n", "changes.walls"},
	         {"changes: {trees: 0.1}\n", "changes.trees"},
	         {"traffic: {cars: 2, car_speed_mps: 0}\n", "traffic.car_speed_mps"},
	         {"world: indoor\nroute: room_tour\ntraffic: {cars: 2}\n", "traffic.cars"}})
	{
		const auto path = write("bad.yaml", text);
		try
		{
			sim::loadScenario(path);
			ADD_FAILURE() << "no error for " << text;
		}
		catch (const std::runtime_error& e)
		{
			EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
			EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
		}
	}
	const auto ok = sim::loadScenario(
	    write("ok.yaml", "epoch: 3\nchanges: {parked_cars: 0.5}\ntraffic: {pedestrians: 5}\n"));
	EXPECT_EQ(ok.changes.epoch, 3);
	EXPECT_DOUBLE_EQ(ok.changes.parked_cars, 0.5);
	EXPECT_EQ(ok.traffic.pedestrians, 5);
	EXPECT_EQ(ok.traffic.cars, 0);
}
