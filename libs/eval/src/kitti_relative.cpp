// The KITTI odometry devkit's relative errors (evaluate_odometry.cpp), and segment specs.
#include <rasterslam/eval/trajectory_metrics.h>

#include <cmath>
#include <cstdlib>
#include <stdexcept>

namespace rasterslam::eval
{
namespace
{
constexpr double kRadToDeg = 180.0 / M_PI;

double parsePositive(const std::string& tok, const std::string& spec)
{
	char* end = nullptr;
	const double v = std::strtod(tok.c_str(), &end);
	if (tok.empty() || end == tok.c_str() || *end != '\0' || !std::isfinite(v) || v <= 0)
	{
		throw std::invalid_argument(
		    "segment spec '" + spec + "': expected a positive number of metres, got '" + tok +
		    "' (use start:end:step, e.g. 10:80:10, or a list like 100,200,400)");
	}
	return v;
}

std::vector<std::string> split(const std::string& s, char sep)
{
	std::vector<std::string> out;
	std::size_t b = 0;
	for (;;)
	{
		const auto e = s.find(sep, b);
		out.push_back(s.substr(b, e == std::string::npos ? std::string::npos : e - b));
		if (e == std::string::npos)
			return out;
		b = e + 1;
	}
}
}  // namespace

std::vector<double> trajectoryDistances(const Trajectory& gt, const Association& a)
{
	// Devkit trajectoryDistances(): cumulative Euclidean distance between consecutive poses.
	std::vector<double> dist;
	dist.reserve(a.gt.size());
	for (std::size_t k = 0; k < a.gt.size(); ++k)
	{
		if (k == 0)
			dist.push_back(0);
		else
			dist.push_back(
			    dist.back() +
			    (gt[a.gt[k]].pose.translation() - gt[a.gt[k - 1]].pose.translation()).norm());
	}
	return dist;
}

KittiRelativeResult computeKittiRelative(const Trajectory& gt, const Trajectory& est,
                                         const Association& a, const std::vector<double>& lengths_m,
                                         std::size_t step)
{
	if (a.gt.size() != a.est.size())
		throw std::invalid_argument("association: gt and est index lists differ in length");
	if (step == 0)
		throw std::invalid_argument("KITTI relative errors: step must be >= 1");

	KittiRelativeResult r;
	r.perLength.resize(lengths_m.size());
	for (std::size_t l = 0; l < lengths_m.size(); ++l)
		r.perLength[l].length_m = lengths_m[l];

	const std::vector<double> dist = trajectoryDistances(gt, a);
	const std::size_t n = dist.size();
	double tSum = 0, rSum = 0;
	// Devkit calcSequenceErrors(): first frames every `step_size` (10, i.e. one second).
	for (std::size_t first = 0; first < n; first += step)
	{
		for (std::size_t l = 0; l < lengths_m.size(); ++l)
		{
			const double len = lengths_m[l];
			// Devkit lastFrameFromSegmentLength(): the first frame strictly beyond len.
			std::size_t last = first;
			while (last < n && !(dist[last] > dist[first] + len))
				++last;
			if (last == n)
				continue;

			const Eigen::Isometry3d dG = fullInverse(gt[a.gt[first]].pose) * gt[a.gt[last]].pose;
			const Eigen::Isometry3d dE =
			    fullInverse(est[a.est[first]].pose) * est[a.est[last]].pose;
			// Devkit: pose_error = inv(pose_delta_result) * pose_delta_gt; errors divided by len.
			const Eigen::Isometry3d err = fullInverse(dE) * dG;
			const double tErr = err.translation().norm() / len;
			const double rErr = rotationAngle(err) / len;

			auto& pl = r.perLength[l];
			pl.t_err_pct += tErr;
			pl.r_err_deg_per_m += rErr;
			++pl.count;
			tSum += tErr;
			rSum += rErr;
			++r.count;
		}
	}
	// Sums -> means in the units reported by the devkit tables (% and deg/m).
	for (auto& pl : r.perLength)
	{
		if (pl.count == 0)
			continue;
		pl.t_err_pct = 100.0 * pl.t_err_pct / static_cast<double>(pl.count);
		pl.r_err_deg_per_m = kRadToDeg * pl.r_err_deg_per_m / static_cast<double>(pl.count);
	}
	if (r.count > 0)
	{
		r.t_err_pct = 100.0 * tSum / static_cast<double>(r.count);
		r.r_err_deg_per_m = kRadToDeg * rSum / static_cast<double>(r.count);
	}
	return r;
}

std::vector<double> parseSegmentSpec(const std::string& spec)
{
	if (spec.find_first_not_of(" \t") == std::string::npos)
		throw std::invalid_argument("segment spec is empty (expected e.g. 10:80:10)");

	std::vector<double> out;
	if (spec.find(':') != std::string::npos)
	{
		const auto parts = split(spec, ':');
		if (parts.size() != 3)
		{
			throw std::invalid_argument("segment spec '" + spec +
			                            "': expected start:end:step, e.g. 10:80:10");
		}
		const double start = parsePositive(parts[0], spec);
		const double end = parsePositive(parts[1], spec);
		const double inc = parsePositive(parts[2], spec);
		if (end < start)
			throw std::invalid_argument("segment spec '" + spec + "': end is before start");
		// Integer count so that 0.1-metre steps do not lose the last length to round-off.
		const double steps = std::floor((end - start) / inc + 1e-9);
		if (steps > 10000)
			throw std::invalid_argument("segment spec '" + spec + "': more than 10000 lengths");
		for (int k = 0; k <= static_cast<int>(steps); ++k)
			out.push_back(start + k * inc);
	}
	else
	{
		for (const auto& tok : split(spec, ','))
			out.push_back(parsePositive(tok, spec));
	}
	return out;
}

}  // namespace rasterslam::eval
