// Route geometry (segments and fillet arcs) and the vehicle's pose on the ground.
#include <rasterslam/sim/route.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rasterslam::sim
{
namespace
{
constexpr double kPi = 3.14159265358979323846;
double wrapPi(double a)
{
	return std::atan2(std::sin(a), std::cos(a));
}
}  // namespace

Route::Route(const std::vector<Eigen::Vector2d>& wp, bool closed, double turnRadius_m)
    : closed_(closed)
{
	if (wp.size() < 2)
		throw std::invalid_argument("Route: needs at least 2 waypoints");
	if (!(turnRadius_m >= 0))
		throw std::invalid_argument("Route: turn radius must be >= 0");
	const std::size_t n = wp.size();
	for (std::size_t i = 0; i < n; i++)
		if ((wp[(i + 1) % n] - wp[i]).norm() < 1e-6 && (closed || i + 1 < n))
			throw std::invalid_argument("Route: two consecutive waypoints coincide");

	// Corners with a fillet: for each, where the arc leaves the incoming segment (A) and
	// joins the outgoing one (B). Tangent length d = R tan(|turn|/2), capped at half of
	// either segment so that neighbouring fillets never overlap.
	struct Corner
	{
		Eigen::Vector2d a, b;
		double yawIn, turn, radius;
	};
	const std::size_t nCorners = closed ? n : n - 2;
	std::vector<Corner> corners;
	for (std::size_t c = 0; c < nCorners; c++)
	{
		const std::size_t i = closed ? c : c + 1;
		const Eigen::Vector2d& prev = wp[(i + n - 1) % n];
		const Eigen::Vector2d& cur = wp[i];
		const Eigen::Vector2d& next = wp[(i + 1) % n];
		const Eigen::Vector2d uIn = (cur - prev).normalized(), uOut = (next - cur).normalized();
		const double yawIn = std::atan2(uIn.y(), uIn.x());
		const double turn = wrapPi(std::atan2(uOut.y(), uOut.x()) - yawIn);
		const double half = std::tan(std::min(std::abs(turn), kPi - 1e-6) / 2);
		double d = turnRadius_m * half;
		d = std::min({d, (cur - prev).norm() / 2, (next - cur).norm() / 2});
		const double r = half > 1e-9 ? d / half : 0;
		corners.push_back({cur - d * uIn, cur + d * uOut, yawIn, turn, r});
	}

	const auto addSegment = [&](const Eigen::Vector2d& p, const Eigen::Vector2d& q)
	{
		const double len = (q - p).norm();
		if (len > 1e-9)
			pieces_.push_back({length_, len, p, std::atan2(q.y() - p.y(), q.x() - p.x()), 0});
		length_ += len;
	};
	const auto addArc = [&](const Corner& c)
	{
		const double len = c.radius * std::abs(c.turn);
		if (len <= 1e-9)
			return;
		pieces_.push_back({length_, len, c.a, c.yawIn, (c.turn > 0 ? 1 : -1) / c.radius});
		length_ += len;
	};

	if (closed)
	{
		// Start halfway along the first segment (wp0 -> wp1), whose end corner is corners[1].
		const Eigen::Vector2d start = 0.5 * (wp[0] + wp[1]);
		Eigen::Vector2d p = start;
		for (std::size_t k = 1; k <= n; k++)
		{
			const Corner& c = corners[k % n];
			addSegment(p, c.a);
			addArc(c);
			p = c.b;
		}
		addSegment(p, start);
	}
	else
	{
		Eigen::Vector2d p = wp[0];
		for (const Corner& c : corners)
		{
			addSegment(p, c.a);
			addArc(c);
			p = c.b;
		}
		addSegment(p, wp[n - 1]);
	}
}

std::vector<Eigen::Vector2d> Route::blockLoop(const TownParams& town, int bx, int by)
{
	if (bx < 1 || by < 1 || bx > town.blocks_x || by > town.blocks_y)
		throw std::invalid_argument("block_loop: the loop's blocks must fit in the town");
	const double P = town.pitch();
	return {{0, 0}, {bx * P, 0}, {bx * P, by * P}, {0, by * P}};
}

std::vector<Eigen::Vector2d> Route::figureEight(const TownParams& town)
{
	if (town.blocks_x < 2)
		throw std::invalid_argument("figure_eight: needs blocks_x >= 2");
	const double P = town.pitch();
	return {{0, 0}, {P, 0}, {P, P}, {2 * P, P}, {2 * P, 0}, {P, 0}, {P, P}, {0, P}};
}

std::vector<Eigen::Vector2d> Route::roomTour(const IndoorParams& p)
{
	std::vector<Eigen::Vector2d> wp;
	for (int j = 0; j < p.rooms_y; j++)
		for (int k = 0; k < p.rooms_x; k++)
			wp.push_back(p.roomCentre(j % 2 == 0 ? k : p.rooms_x - 1 - k, j));
	return wp;
}

const Route::Piece& Route::pieceAt(double& s) const
{
	if (pieces_.empty())
		throw std::logic_error("Route: empty route");
	if (closed_)
	{
		s = std::fmod(s, length_);
		if (s < 0)
			s += length_;
	}
	else
		s = std::clamp(s, 0.0, length_);
	auto it = std::upper_bound(pieces_.begin(), pieces_.end(), s,
	                           [](double v, const Piece& p) { return v < p.s0; });
	return it == pieces_.begin() ? *it : *std::prev(it);
}

double Route::curvatureAt(double s) const
{
	return std::abs(pieceAt(s).curvature);
}

PlanarPose Route::at(double s) const
{
	const Piece& p = pieceAt(s);
	const double u = std::clamp(s - p.s0, 0.0, p.len);
	PlanarPose out;
	if (p.curvature == 0)
	{
		out.x = p.p0.x() + u * std::cos(p.yaw0);
		out.y = p.p0.y() + u * std::sin(p.yaw0);
		out.yaw = p.yaw0;
		return out;
	}
	// On a circle of signed curvature k: p(u) = p0 + (sin(yaw0 + k u) - sin yaw0,
	// cos yaw0 - cos(yaw0 + k u)) / k.
	const double k = p.curvature, yaw = p.yaw0 + k * u;
	out.x = p.p0.x() + (std::sin(yaw) - std::sin(p.yaw0)) / k;
	out.y = p.p0.y() + (std::cos(p.yaw0) - std::cos(yaw)) / k;
	out.yaw = wrapPi(yaw);
	return out;
}

mrpt::poses::CPose3D sensorPoseOnGround(const GroundModel& ground, const PlanarPose& p,
                                        double height_m)
{
	const Eigen::Vector2d g = ground.gradient(p.x, p.y);
	const Eigen::Vector3d zAxis = Eigen::Vector3d(-g.x(), -g.y(), 1).normalized();
	const Eigen::Vector3d fwd(std::cos(p.yaw), std::sin(p.yaw), 0);
	const Eigen::Vector3d xAxis = (fwd - fwd.dot(zAxis) * zAxis).normalized();
	const Eigen::Vector3d yAxis = zAxis.cross(xAxis);
	Eigen::Matrix3d R;
	R << xAxis, yAxis, zAxis;
	const Eigen::Vector3d t = Eigen::Vector3d(p.x, p.y, ground.height(p.x, p.y)) + height_m * zAxis;
	return mrpt::poses::CPose3D(R, t);
}

}  // namespace rasterslam::sim
