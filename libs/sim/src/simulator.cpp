// Casting a sweep's rays (in parallel, deterministic) and the scenario -> simulator glue.
#include <rasterslam/sim/simulator.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <thread>

#include "rng.h"

namespace rasterslam::sim
{
namespace
{
constexpr double kDeg = 3.14159265358979323846 / 180.0;
// Azimuth columns per work item: also the unit of random seeding, so it must not depend on
// the thread count.
constexpr int kChunk = 64;

}  // namespace

Simulator::Simulator(std::shared_ptr<const World> world, LidarModel lidar, Route route,
                     SimulatorOptions opt)
    : world_(std::move(world)), lidar_(std::move(lidar)), route_(std::move(route)), opt_(opt)
{
	if (!world_)
		throw std::invalid_argument("Simulator: no world");
	if (!(opt_.rate_hz > 0) || !(opt_.speed_mps >= 0) || opt_.threads < 1 ||
	    !(opt_.point_resolution_m >= 0))
		throw std::invalid_argument(
		    "Simulator: needs rate_hz > 0, speed_mps >= 0, threads >= 1, point_resolution_m >= 0");
	if (!(opt_.corner_accel_mps2 >= 0) || !(opt_.accel_mps2 > 0))
		throw std::invalid_argument("Simulator: needs corner_accel_mps2 >= 0 and accel_mps2 > 0");
	if (opt_.corner_accel_mps2 > 0 && opt_.speed_mps > 0 && !route_.empty())
		buildSpeedProfile();
	// The rays the carrying vehicle blocks: fixed in the sensor frame, so found once.
	for (const EgoBox* b : {&opt_.ego_body, &opt_.ego_cabin})
		if (!b->empty() && !(b->height_m < opt_.sensor_height_m))
			throw std::invalid_argument(
			    "Simulator: a box of the carrying vehicle reaches the sensor (height_m >= "
			    "sensor_height_m): every ray would start inside it");
	if (!opt_.ego_body.empty() || !opt_.ego_cabin.empty())
	{
		const int nBeams = lidar_.beamCount(), nAz = lidar_.azimuthSteps();
		egoBlocked_.assign(static_cast<std::size_t>(nBeams) * static_cast<std::size_t>(nAz), 0);
		// Each box as a shape in the sensor frame, tested by the world's own ray-shape test.
		const auto shapeOf = [&](const EgoBox& box)
		{
			Shape sh;
			sh.type = ShapeType::Box;
			sh.cx = (box.front_m - box.back_m) / 2;
			sh.a = (box.front_m + box.back_m) / 2;
			sh.b = box.half_width_m;
			sh.zmin = -opt_.sensor_height_m;
			sh.zmax = box.height_m - opt_.sensor_height_m;
			return sh;
		};
		std::vector<Shape> boxes;
		for (const EgoBox* box : {&opt_.ego_body, &opt_.ego_cabin})
			if (!box->empty())
				boxes.push_back(shapeOf(*box));
		const auto meets = [&](const Eigen::Vector3d& o, const Eigen::Vector3d& d)
		{
			for (const Shape& sh : boxes)
				if (intersectShape(sh, o, d) <= lidar_.maxRange_m())
					return true;
			return false;
		};
		for (int b = 0; b < nBeams; b++)
		{
			const double el = lidar_.elevationsDeg()[static_cast<std::size_t>(b)] * kDeg;
			const Eigen::Vector3d o(0, 0, lidar_.originHeights_m()[static_cast<std::size_t>(b)]);
			for (int a = 0; a < nAz; a++)
			{
				const double az = 2 * 3.14159265358979323846 * a / nAz;
				const Eigen::Vector3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
				                        std::sin(el));
				egoBlocked_[static_cast<std::size_t>(b) * static_cast<std::size_t>(nAz) +
				            static_cast<std::size_t>(a)] = meets(o, d);
			}
		}
	}
}

void Simulator::buildSpeedProfile()
{
	// The fastest speed at every 5 cm that keeps to the corner bound and to the braking and
	// speeding-up bound v^2 <= v_next^2 + 2 a ds both ways (around the loop twice when it is
	// closed, so that the bound reaches across its start), then the time to each point.
	const double L = route_.length(), a = opt_.accel_mps2;
	const auto n = static_cast<std::size_t>(std::ceil(L / 0.05));
	profileStep_ = L / static_cast<double>(n);
	std::vector<double> v(n + 1);
	for (std::size_t i = 0; i <= n; i++)
	{
		const double k = route_.curvatureAt(std::min(L, static_cast<double>(i) * profileStep_));
		v[i] = k > 0 ? std::min(opt_.speed_mps, std::sqrt(opt_.corner_accel_mps2 / k))
		             : opt_.speed_mps;
	}
	const double dv2 = 2 * a * profileStep_;
	const int rounds = route_.closed() ? 2 : 1;
	for (int r = 0; r < rounds; r++)
	{
		for (std::size_t i = 1; i <= n; i++)
			v[i] = std::min(v[i], std::sqrt(v[i - 1] * v[i - 1] + dv2));
		if (route_.closed())
			v[0] = v[n] = std::min(v[0], v[n]);
		for (std::size_t i = n; i-- > 0;)
			v[i] = std::min(v[i], std::sqrt(v[i + 1] * v[i + 1] + dv2));
		if (route_.closed())
			v[0] = v[n] = std::min(v[0], v[n]);
	}
	profileTime_.assign(n + 1, 0.0);
	for (std::size_t i = 1; i <= n; i++)
		profileTime_[i] = profileTime_[i - 1] + 2 * profileStep_ / (v[i - 1] + v[i]);
}

double Simulator::lapTime() const
{
	if (!profileTime_.empty())
		return profileTime_.back();
	return opt_.speed_mps > 0 ? route_.length() / opt_.speed_mps
	                          : std::numeric_limits<double>::infinity();
}

double Simulator::distanceAt(double t) const
{
	if (profileTime_.empty())
		return opt_.speed_mps * t;
	const double lap = profileTime_.back(), L = route_.length();
	double laps = 0;
	if (t >= lap)
	{
		if (!route_.closed())
			return L + opt_.speed_mps * (t - lap);  // past the end: Route::at stops there
		laps = std::floor(t / lap);
		t -= laps * lap;
	}
	t = std::max(0.0, t);
	const auto it = std::upper_bound(profileTime_.begin(), profileTime_.end(), t);
	const auto i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(1, it - profileTime_.begin()));
	const std::size_t j = std::min(i, profileTime_.size() - 1);
	const double t0 = profileTime_[j - 1], t1 = profileTime_[j];
	const double f = t1 > t0 ? std::clamp((t - t0) / (t1 - t0), 0.0, 1.0) : 0.0;
	return laps * L + (static_cast<double>(j - 1) + f) * profileStep_;
}

Simulator Simulator::fromScenario(const Scenario& sc)
{
	const bool indoor = sc.world == "indoor";
	auto world =
	    std::make_shared<const World>(indoor ? World::generateIndoor(sc.indoor, sc.seed, sc.changes)
	                                         : World::generate(sc.town, sc.seed, sc.changes));
	std::vector<Eigen::Vector2d> wp;
	if (sc.route.pattern == "room_tour")
		wp = Route::roomTour(sc.indoor);
	else if (sc.route.pattern == "block_loop")
		wp = Route::blockLoop(sc.town, sc.route.blocks_x, sc.route.blocks_y);
	else if (sc.route.pattern == "figure_eight")
		wp = Route::figureEight(sc.town);
	else if (sc.route.pattern == "waypoints")
		wp = sc.route.waypoints;
	else
		throw std::invalid_argument(
		    sc.source + ": route.pattern '" + sc.route.pattern +
		    "' unknown (known: block_loop, figure_eight, room_tour, waypoints)");
	SimulatorOptions o;
	o.noise = sc.noise;
	o.seed = sc.seed;
	o.sensor_height_m = sc.sensor_height_m;
	o.rate_hz = sc.rate_hz;
	o.speed_mps = sc.speed_mps;
	o.start_stamp_s = sc.start_stamp_s;
	o.threads = sc.threads;
	o.point_resolution_m = sc.point_resolution_m;
	o.motion_within_sweep = sc.motion_within_sweep;
	o.handheld = sc.handheld;
	o.body_pitch_deg = sc.body_pitch_deg;
	o.body_roll_deg = sc.body_roll_deg;
	o.body_heave_m = sc.body_heave_m;
	o.corner_accel_mps2 = sc.corner_accel_mps2;
	o.accel_mps2 = sc.accel_mps2;
	o.ego_body = sc.ego_body;
	o.ego_cabin = sc.ego_cabin;
	o.sweep.startAzimuth_deg = sc.sweep_start_azimuth_deg;
	o.sweep.clockwise = sc.sweep_clockwise;
	Simulator sim(std::move(world), LidarModel::byName(sc.lidar),
	              Route(wp, sc.route.closed, sc.route.turn_radius_m), o);
	if (sc.traffic.cars > 0 || sc.traffic.pedestrians > 0)
	{
		// Each session its own traffic: the start stamp is mixed into the seed.
		std::uint64_t stampBits = 0;
		std::memcpy(&stampBits, &sc.start_stamp_s, sizeof stampBits);
		const auto seed =
		    static_cast<std::uint32_t>(detail::mix64(sc.seed ^ detail::mix64(stampBits)) >> 32);
		sim.setTraffic(indoor ? Traffic::indoor(sc.indoor, sc.traffic, seed)
		                      : Traffic::town(sc.town, sc.traffic, seed));
	}
	return sim;
}

double Simulator::stamp(std::size_t k) const
{
	return opt_.start_stamp_s + static_cast<double>(k) / opt_.rate_hz;
}

mrpt::poses::CPose3D Simulator::poseAfter(double s, double t) const
{
	auto P = sensorPoseOnGround(world_->ground(), route_.at(s), opt_.sensor_height_m);
	if (opt_.body_pitch_deg > 0 || opt_.body_roll_deg > 0 || opt_.body_heave_m > 0)
	{
		// Three sinusoids per axis, frequencies and phases from the seed.
		constexpr double kTwoPi = 2 * 3.14159265358979323846;
		const auto wave = [&](std::uint64_t axis)
		{
			double v = 0;
			for (std::uint64_t i = 0; i < 3; i++)
			{
				const std::uint64_t h = detail::mix64(detail::mix64(opt_.seed) ^ (axis * 8 + i));
				const double f = 0.6 + 1.9 * static_cast<double>(h >> 40) / 16777216.0;
				const double ph = kTwoPi * static_cast<double>(h & 0xffffff) / 16777216.0;
				v += std::sqrt(2.0 / 3.0) * std::sin(kTwoPi * f * t + ph);
			}
			return v;
		};
		constexpr double kD = kTwoPi / 360;
		P = P + mrpt::poses::CPose3D(0, 0, opt_.body_heave_m * wave(1), 0,
		                             opt_.body_pitch_deg * kD * wave(2),
		                             opt_.body_roll_deg * kD * wave(3));
	}
	if (!opt_.handheld)
		return P;
	constexpr double kTwoPi = 2 * 3.14159265358979323846, kD = kTwoPi / 360;
	const mrpt::poses::CPose3D sway(
	    0, 0, 0.02 * std::sin(kTwoPi * 1.8 * t), 8 * kD * std::sin(kTwoPi * 0.7 * t),
	    3 * kD * std::sin(kTwoPi * 1.1 * t + 1), 3 * kD * std::sin(kTwoPi * 0.9 * t + 2));
	return P + sway;
}

mrpt::poses::CPose3D Simulator::sensorPose(std::size_t k) const
{
	// (The distance as speed * k / rate, not speed * (k / rate): the same bits as before.)
	if (!profileTime_.empty())
		return poseAfter(distanceAt(static_cast<double>(k) / opt_.rate_hz),
		                 static_cast<double>(k) / opt_.rate_hz);
	return poseAfter(opt_.speed_mps * static_cast<double>(k) / opt_.rate_hz,
	                 static_cast<double>(k) / opt_.rate_hz);
}

mrpt::poses::CPose3D Simulator::sensorPoseAt(double stampSec) const
{
	const double t = std::max(0.0, stampSec - opt_.start_stamp_s);
	return poseAfter(distanceAt(t), t);
}

Scan Simulator::scan(std::size_t k) const
{
	if (!opt_.motion_within_sweep)
		return scanFrom(sensorPose(k), k, stamp(k));
	// Each azimuth from the pose of its instant: the sweep ends at the scan's stamp.
	const int nAz = lidar_.azimuthSteps();
	std::vector<mrpt::poses::CPose3D> columnPose(static_cast<std::size_t>(nAz));
	std::vector<double> columnStamp(static_cast<std::size_t>(nAz));
	const double period = 1.0 / opt_.rate_hz, end = stamp(k);
	for (int a = 0; a < nAz; a++)
	{
		const double f = opt_.sweep.fraction(2 * 3.14159265358979323846 * a / nAz);
		columnStamp[static_cast<std::size_t>(a)] = end - (1 - f) * period;
		columnPose[static_cast<std::size_t>(a)] = sensorPoseAt(end - (1 - f) * period);
	}
	return cast(sensorPose(k), columnPose, columnStamp, k, end);
}

Scan Simulator::scanFrom(const mrpt::poses::CPose3D& T_world_sensor, std::size_t index,
                         double stampSec) const
{
	return cast(T_world_sensor, {}, {}, index, stampSec);
}

Scan Simulator::cast(const mrpt::poses::CPose3D& T_world_sensor,
                     const std::vector<mrpt::poses::CPose3D>& columnPose,
                     const std::vector<double>& columnStamp, std::size_t index,
                     double stampSec) const
{
	const int nBeams = lidar_.beamCount(), nAz = lidar_.azimuthSteps();
	const std::vector<double>& lifts = lidar_.originHeights_m();
	// Rotation and origin of each column (one for all without motion within the sweep).
	std::vector<Eigen::Matrix3d> colR;
	std::vector<Eigen::Vector3d> colO;
	const auto addPose = [&](const mrpt::poses::CPose3D& P)
	{
		colR.push_back(P.getRotationMatrix().asEigen());
		colO.emplace_back(P.x(), P.y(), P.z());
	};
	if (columnPose.empty())
		addPose(T_world_sensor);
	else
		for (const auto& P : columnPose)
			addPose(P);
	std::vector<double> ce(nBeams), se(nBeams), ca(nAz), sa(nAz);
	for (int b = 0; b < nBeams; b++)
	{
		ce[b] = std::cos(lidar_.elevationsDeg()[b] * kDeg);
		se[b] = std::sin(lidar_.elevationsDeg()[b] * kDeg);
	}
	for (int a = 0; a < nAz; a++)
	{
		const double az = 2 * 3.14159265358979323846 * a / nAz;
		ca[a] = std::cos(az);
		sa[a] = std::sin(az);
	}

	const int nChunks = (nAz + kChunk - 1) / kChunk;
	std::vector<std::vector<PointXYZI>> out(nChunks);
	std::atomic<int> next{0};
	const double minR = lidar_.minRange_m(), maxR = lidar_.maxRange_m();
	const NoiseParams& nz = opt_.noise;
	const double res = opt_.point_resolution_m;
	const auto quantize = [res](double v)
	{ return static_cast<float>(res > 0 ? std::round(v / res) * res : v); };
	// A mover, as it stands during one block of azimuths, with its bounding sphere.
	struct Placed
	{
		Shape s;
		Eigen::Vector3d centre;
		double radius;
	};
	const auto work = [&]()
	{
		std::vector<Shape> moverShapes;
		std::vector<Placed> movers;
		for (int c = next++; c < nChunks; c = next++)
		{
			movers.clear();
			if (!traffic_.empty())
			{
				const int mid = std::min(nAz - 1, c * kChunk + kChunk / 2);
				const double t =
				    (columnStamp.empty() ? stampSec : columnStamp[static_cast<std::size_t>(mid)]) -
				    opt_.start_stamp_s;
				const Eigen::Vector3d& o =
				    colO[colR.size() == 1 ? 0 : static_cast<std::size_t>(mid)];
				moverShapes.clear();
				traffic_.shapesAt(t, world_->ground(), o, maxR, 1.0, moverShapes);
				for (const Shape& s : moverShapes)
				{
					const double hz = (s.zmax - s.zmin) / 2;
					const double r = s.type == ShapeType::Ellipsoid
					                     ? std::max(s.a, s.b)
					                     : std::hypot(s.footprintRadius(), hz);
					movers.push_back({s, {s.cx, s.cy, s.zmin + hz}, r});
				}
			}
			std::mt19937_64 rng(detail::mix64(detail::mix64(opt_.seed) ^
			                                  detail::mix64(index * 0x100000001B3ull + c)));
			std::normal_distribution<double> rangeNoise(0, 1), intensityNoise(0, 1);
			std::uniform_real_distribution<double> unif(0, 1);
			auto& pts = out[c];
			pts.reserve(static_cast<std::size_t>(kChunk) * nBeams);
			const int aEnd = std::min(nAz, (c + 1) * kChunk);
			// Azimuth-major, all beams at one azimuth in turn, as a Velodyne fires them.
			for (int a = c * kChunk; a < aEnd; a++)
			{
				const std::size_t col = colR.size() == 1 ? 0 : static_cast<std::size_t>(a);
				const Eigen::Matrix3d& R = colR[col];
				const Eigen::Vector3d& sensorOrigin = colO[col];
				for (int b = 0; b < nBeams; b++)
				{
					if (!egoBlocked_.empty() &&
					    egoBlocked_[static_cast<std::size_t>(b) * static_cast<std::size_t>(nAz) +
					                static_cast<std::size_t>(a)])
						continue;
					const Eigen::Vector3d ds(ce[b] * ca[a], ce[b] * sa[a], se[b]);
					const Eigen::Vector3d dw = R * ds;
					// A laser above the frame's origin (a real HDL-64E's sit 0.14-0.22 m up).
					const double lift = lifts[static_cast<std::size_t>(b)];
					const Eigen::Vector3d origin =
					    lift != 0 ? Eigen::Vector3d(sensorOrigin + lift * R.col(2)) : sensorOrigin;
					RayHit hit = world_->raycast(origin, dw, maxR);
					for (const Placed& m : movers)
					{
						const Eigen::Vector3d oc = m.centre - origin;
						const double tc = oc.dot(dw);
						if (tc < -m.radius || oc.squaredNorm() - tc * tc > m.radius * m.radius)
							continue;
						const double tm = intersectShape(m.s, origin, dw);
						if (tm < hit.range && tm <= maxR)
						{
							hit.range = tm;
							hit.kind = m.s.kind;
						}
					}
					if (!hit.hit() || hit.range < minR)
						continue;
					if (nz.range_by_reflectivity &&
					    hit.range > maxR * std::sqrt(nominalIntensity(hit.kind) / 0.8))
						continue;
					if (nz.dropout_prob > 0 && unif(rng) < nz.dropout_prob)
						continue;
					double r = hit.range;
					if (nz.range_sigma_m > 0)
						r += nz.range_sigma_m * rangeNoise(rng);
					if (nz.foliage_depth_m > 0 && hit.kind == ObjectKind::TreeCrown)
						r += std::min(4.0, -std::log(1 - unif(rng))) * nz.foliage_depth_m;
					if (r < minR || r > maxR)
						continue;
					double inten = nominalIntensity(hit.kind);
					if (nz.intensity_sigma > 0)
						inten += nz.intensity_sigma * intensityNoise(rng);
					PointXYZI p;
					p.x = quantize(r * ds.x());
					p.y = quantize(r * ds.y());
					p.z = quantize(lift != 0 ? lift + r * ds.z() : r * ds.z());
					p.intensity =
					    static_cast<float>(std::round(std::clamp(inten, 0.0, 1.0) * 256) / 256);
					pts.push_back(p);
				}
			}
		}
	};
	const int nThreads = std::min(opt_.threads, nChunks);
	std::vector<std::thread> pool;
	for (int t = 1; t < nThreads; t++)
		pool.emplace_back(work);
	work();
	for (auto& th : pool)
		th.join();

	Scan scan;
	scan.index = index;
	scan.stamp = stampSec;
	scan.sensorLabel = "LIDAR";
	std::size_t total = 0;
	for (const auto& v : out)
		total += v.size();
	scan.points.reserve(total);
	for (const auto& v : out)
		scan.points.insert(scan.points.end(), v.begin(), v.end());
	scan.groundTruth = T_world_sensor;
	return scan;
}

}  // namespace rasterslam::sim
