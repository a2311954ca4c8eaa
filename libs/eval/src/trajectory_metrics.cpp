// Association, absolute trajectory error (ATE) and per-frame relative pose error (RPE).
#include <rasterslam/eval/trajectory_metrics.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace rasterslam::eval
{
namespace
{
constexpr double kRadToDeg = 180.0 / M_PI;

double rms(const std::vector<double>& v)
{
	if (v.empty())
		return 0;
	double s = 0;
	for (double x : v)
		s += x * x;
	return std::sqrt(s / static_cast<double>(v.size()));
}
double mean(const std::vector<double>& v)
{
	if (v.empty())
		return 0;
	return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}
double median(std::vector<double> v)
{
	if (v.empty())
		return 0;
	const std::size_t h = v.size() / 2;
	std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h), v.end());
	if (v.size() % 2)
		return v[h];
	const double upper = v[h];
	const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h));
	return 0.5 * (lower + upper);
}

void checkAssociation(const Trajectory& gt, const Trajectory& est, const Association& a)
{
	if (a.gt.size() != a.est.size())
		throw std::invalid_argument("association: gt and est index lists differ in length");
	for (std::size_t k = 0; k < a.gt.size(); ++k)
	{
		if (a.gt[k] >= gt.size() || a.est[k] >= est.size())
			throw std::out_of_range("association: index out of range");
	}
}
}  // namespace

Eigen::Isometry3d fullInverse(const Eigen::Isometry3d& T)
{
	// KITTI's files carry 7 digits, so R^T R = I only to ~1e-7, and acos() near 1 turns that
	// into ~0.03 deg: invert the whole matrix as the devkit does so that the numbers match it.
	return Eigen::Isometry3d(T.inverse(Eigen::Affine).matrix());
}

double rotationAngle(const Eigen::Isometry3d& T)
{
	// KITTI devkit, evaluate_odometry.cpp, rotationError(): the clamp guards acos against
	// round-off just outside [-1, 1].
	const Eigen::Matrix3d R = T.linear();
	const double d = 0.5 * (R(0, 0) + R(1, 1) + R(2, 2) - 1.0);
	return std::acos(std::max(std::min(d, 1.0), -1.0));
}

Association associate(const Trajectory& gt, const Trajectory& est, bool byIndex, double maxDt)
{
	Association a;
	if (byIndex)
	{
		if (gt.size() != est.size())
		{
			std::ostringstream msg;
			msg << "cannot associate by index: the ground truth has " << gt.size()
			    << " poses and the estimate has " << est.size()
			    << " (give time stamps, e.g. TUM files, to associate by time)";
			throw std::runtime_error(msg.str());
		}
		a.gt.resize(gt.size());
		std::iota(a.gt.begin(), a.gt.end(), std::size_t{0});
		a.est = a.gt;
		return a;
	}

	// Nearest stamp, then greedy by increasing |dt| so that no pose is used twice (as TUM's
	// associate.py does).
	std::vector<std::size_t> order(gt.size());
	std::iota(order.begin(), order.end(), std::size_t{0});
	std::sort(order.begin(), order.end(),
	          [&](std::size_t i, std::size_t j) { return gt[i].stamp < gt[j].stamp; });
	struct Candidate
	{
		double dt;
		std::size_t g, e;
	};
	std::vector<Candidate> cands;
	for (std::size_t e = 0; e < est.size(); ++e)
	{
		const double t = est[e].stamp;
		auto it = std::lower_bound(order.begin(), order.end(), t,
		                           [&](std::size_t i, double s) { return gt[i].stamp < s; });
		for (auto jt : {it, it == order.begin() ? order.end() : std::prev(it)})
		{
			if (jt == order.end())
				continue;
			const double dt = std::abs(gt[*jt].stamp - t);
			if (dt <= maxDt)
				cands.push_back({dt, *jt, e});
		}
	}
	std::sort(cands.begin(), cands.end(),
	          [](const Candidate& x, const Candidate& y) {
		          return x.dt < y.dt || (x.dt == y.dt && (x.e < y.e || (x.e == y.e && x.g < y.g)));
	          });
	std::vector<bool> usedG(gt.size(), false), usedE(est.size(), false);
	std::vector<std::pair<std::size_t, std::size_t>> pairs;
	for (const auto& c : cands)
	{
		if (usedG[c.g] || usedE[c.e])
			continue;
		usedG[c.g] = usedE[c.e] = true;
		pairs.emplace_back(c.g, c.e);
	}
	std::sort(pairs.begin(), pairs.end(),
	          [&](const auto& x, const auto& y) { return gt[x.first].stamp < gt[y.first].stamp; });
	for (const auto& [g, e] : pairs)
	{
		a.gt.push_back(g);
		a.est.push_back(e);
	}
	return a;
}

AteResult computeAte(const Trajectory& gt, const Trajectory& est, const Association& a,
                     const std::optional<Eigen::Isometry3d>& fixed)
{
	checkAssociation(gt, est, a);
	AteResult r;
	r.n = a.gt.size();
	if (r.n == 0)
		throw std::runtime_error("ATE: no associated poses");

	Eigen::Matrix3Xd src(3, r.n), dst(3, r.n);
	for (std::size_t k = 0; k < r.n; ++k)
	{
		src.col(static_cast<Eigen::Index>(k)) = est[a.est[k]].pose.translation();
		dst.col(static_cast<Eigen::Index>(k)) = gt[a.gt[k]].pose.translation();
	}
	if (fixed)
		r.T_gt_est = *fixed;
	else if (r.n >= 3)
	{
		// Umeyama (1991), least-squares rigid fit without scale: a monocular-style scale fit
		// would hide the scale drift that a LiDAR odometry must not have.
		r.T_gt_est.matrix() = Eigen::umeyama(src, dst, false);
	}
	else
	{
		// One or two points fix no rotation: align the centroids only.
		r.T_gt_est.translation() = dst.rowwise().mean() - src.rowwise().mean();
	}

	std::vector<double> err(r.n);
	for (std::size_t k = 0; k < r.n; ++k)
	{
		const auto i = static_cast<Eigen::Index>(k);
		err[k] = (dst.col(i) - r.T_gt_est * Eigen::Vector3d(src.col(i))).norm();
	}
	r.rmse_m = rms(err);
	r.mean_m = mean(err);
	r.median_m = median(err);
	r.max_m = *std::max_element(err.begin(), err.end());
	return r;
}

RpeResult computeRpe(const Trajectory& gt, const Trajectory& est, const Association& a)
{
	checkAssociation(gt, est, a);
	RpeResult r;
	if (a.gt.size() < 2)
		return r;
	r.n = a.gt.size() - 1;
	std::vector<double> te(r.n), re(r.n);
	Eigen::Vector3d drift = Eigen::Vector3d::Zero();
	double path = 0;
	for (std::size_t k = 0; k < r.n; ++k)
	{
		const Eigen::Isometry3d dG = fullInverse(gt[a.gt[k]].pose) * gt[a.gt[k + 1]].pose;
		const Eigen::Isometry3d dE = fullInverse(est[a.est[k]].pose) * est[a.est[k + 1]].pose;
		const Eigen::Isometry3d E = fullInverse(dG) * dE;
		te[k] = E.translation().norm();
		re[k] = rotationAngle(E) * kRadToDeg;
		const Eigen::AngleAxisd aa(Eigen::Matrix3d(E.linear()));
		drift += aa.angle() * aa.axis();
		path += dG.translation().norm();
	}
	if (path > 0)
		r.rot_drift_deg_per_100m = drift * kRadToDeg * 100 / path;
	r.trans_rmse_m = rms(te);
	r.trans_mean_m = mean(te);
	r.rot_rmse_deg = rms(re);
	r.rot_mean_deg = mean(re);
	return r;
}

}  // namespace rasterslam::eval
