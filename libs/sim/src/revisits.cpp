// Revisit truth between sessions: nearest earlier pose of every scan, on a grid of cells.
#include <rasterslam/sim/revisits.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace rasterslam::sim
{
namespace
{
double yawOf(const Eigen::Isometry3d& T)
{
	const Eigen::Vector3d x = T.linear().col(0);
	return std::atan2(x.y(), x.x());
}

std::int64_t cellKey(long long ix, long long iy)
{
	return static_cast<std::int64_t>((static_cast<std::uint64_t>(ix) << 32) ^
	                                 static_cast<std::uint32_t>(iy));
}
}  // namespace

std::vector<Revisit> findRevisits(const io::Trajectory& session,
                                  const std::vector<io::Trajectory>& earlier, double radius_m)
{
	if (!(radius_m > 0) || !std::isfinite(radius_m))
		throw std::invalid_argument("findRevisits: the radius must be > 0");
	// Earlier poses in cells of the radius's size: a query looks at its 3 x 3 cells.
	struct Ref
	{
		std::size_t session, scan;
	};
	std::unordered_map<std::int64_t, std::vector<Ref>> grid;
	const auto cellOf = [radius_m](double v)
	{
		const double c = std::floor(v / radius_m);
		if (!(std::abs(c) < 1e15))
			throw std::invalid_argument("findRevisits: a pose too far out for the radius (" +
			                            std::to_string(v) + " m)");
		return static_cast<long long>(c);
	};
	for (std::size_t s = 0; s < earlier.size(); s++)
		for (std::size_t k = 0; k < earlier[s].size(); k++)
		{
			const Eigen::Vector3d p = earlier[s][k].pose.translation();
			if (!p.allFinite())
				throw std::invalid_argument(
				    "findRevisits: a pose of an earlier session is not finite");
			grid[cellKey(cellOf(p.x()), cellOf(p.y()))].push_back({s, k});
		}
	std::vector<Revisit> out;
	for (std::size_t k = 0; k < session.size(); k++)
	{
		const Eigen::Vector3d p = session[k].pose.translation();
		if (!p.allFinite())
			throw std::invalid_argument("findRevisits: a pose of the session is not finite");
		const long long cx = cellOf(p.x()), cy = cellOf(p.y());
		double best = std::numeric_limits<double>::infinity();
		Ref bestRef{0, 0};
		for (long long dx = -1; dx <= 1; dx++)
			for (long long dy = -1; dy <= 1; dy++)
			{
				const auto it = grid.find(cellKey(cx + dx, cy + dy));
				if (it == grid.end())
					continue;
				for (const Ref& r : it->second)
				{
					const double d = (earlier[r.session][r.scan].pose.translation() - p).norm();
					if (d < best)
					{
						best = d;
						bestRef = r;
					}
				}
			}
		if (!(best <= radius_m))
			continue;
		Revisit v;
		v.scan = k;
		v.stamp = session[k].stamp;
		v.session = bestRef.session;
		v.earlierScan = bestRef.scan;
		const auto& e = earlier[bestRef.session][bestRef.scan];
		v.earlierStamp = e.stamp;
		v.distance_m = best;
		double dyaw = std::abs(yawOf(session[k].pose) - yawOf(e.pose));
		dyaw = std::fmod(dyaw, 2 * M_PI);
		if (dyaw > M_PI)
			dyaw = 2 * M_PI - dyaw;
		v.yawDiff_deg = dyaw * 180 / M_PI;
		out.push_back(v);
	}
	return out;
}

std::string formatRevisits(const std::vector<Revisit>& revisits,
                           const std::vector<std::string>& sessionNames, double radius_m)
{
	std::string out;
	char line[512];
	std::snprintf(line, sizeof line,
	              "# scans of this session within %.2f m of a scan of an earlier session (the "
	              "nearest one)\n# scan stamp session earlier_scan earlier_stamp distance_m "
	              "yaw_diff_deg\n",
	              radius_m);
	out += line;
	for (const Revisit& v : revisits)
	{
		if (v.session >= sessionNames.size())
			throw std::invalid_argument("formatRevisits: no name for an earlier session");
		std::snprintf(line, sizeof line, "%zu %.6f %s %zu %.6f %.3f %.2f\n", v.scan, v.stamp,
		              sessionNames[v.session].c_str(), v.earlierScan, v.earlierStamp, v.distance_m,
		              v.yawDiff_deg);
		out += line;
	}
	return out;
}

}  // namespace rasterslam::sim
