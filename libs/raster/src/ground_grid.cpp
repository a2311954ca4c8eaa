#include <rasterslam/raster/ground_grid.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

namespace rasterslam::raster
{
void GroundGrid::clear()
{
	samples_.clear();
	index_.clear();
	centre_.clear();
	half_ = 0;
}

void GroundGrid::build(const std::vector<PointXYZI>& pts, const Plane& plane,
                       const GroundGridParams& p)
{
	clear();
	if (!plane.valid || plane.n.z() < 1e-3f || p.cell_m <= 0 || p.radius_m <= 0)
		return;
	cell_ = static_cast<float>(p.cell_m);
	inv_ = 1.0f / cell_;
	half_ = static_cast<int>(std::ceil(p.radius_m / p.cell_m));
	gx_ = -plane.n.x() / plane.n.z();
	gy_ = -plane.n.y() / plane.n.z();
	const int side = 2 * half_ + 1;
	struct Acc
	{
		double sx = 0, sy = 0, sz = 0;
		float zmin = std::numeric_limits<float>::max(), zmax = -std::numeric_limits<float>::max();
		int n = 0;
	};
	std::vector<Acc> acc(static_cast<std::size_t>(side) * side);
	const float band = static_cast<float>(p.band_m);
	const float rMax2 = static_cast<float>(p.radius_m * p.radius_m);
	const float rMin2 = static_cast<float>(p.minRange_m * p.minRange_m);
	const std::size_t stride = static_cast<std::size_t>(std::max(1, p.stride));
	for (std::size_t i = 0; i < pts.size(); i += stride)
	{
		const auto& q = pts[i];
		const float r2 = q.x * q.x + q.y * q.y;
		if (r2 > rMax2 || r2 < rMin2 || std::abs(plane.height(q)) > band)
			continue;
		const int cx = static_cast<int>(std::lround(q.x * inv_)) + half_;
		const int cy = static_cast<int>(std::lround(q.y * inv_)) + half_;
		if (cx < 0 || cy < 0 || cx >= side || cy >= side)
			continue;
		auto& a = acc[static_cast<std::size_t>(cy) * side + cx];
		a.sx += q.x;
		a.sy += q.y;
		a.sz += q.z;
		a.zmin = std::min(a.zmin, q.z);
		a.zmax = std::max(a.zmax, q.z);
		a.n++;
	}
	// The spread the plane's slope explains across a cell is not a step.
	const float maxSpread =
	    static_cast<float>(p.maxSpread_m) + (std::abs(gx_) + std::abs(gy_)) * cell_;
	index_.assign(acc.size(), -1);
	centre_.assign(acc.size(), std::numeric_limits<float>::quiet_NaN());
	for (std::size_t c = 0; c < acc.size(); c++)
	{
		const auto& a = acc[c];
		if (a.n < p.minPoints)
			continue;
		Sample s;
		s.mean = Eigen::Vector3f(static_cast<float>(a.sx / a.n), static_cast<float>(a.sy / a.n),
		                         static_cast<float>(a.sz / a.n));
		if (a.zmax - a.zmin > maxSpread)
			continue;
		index_[c] = static_cast<int32_t>(samples_.size());
		samples_.push_back(s);
		// The cell's height at its centre, moved there along the plane's slope.
		const float ccx = static_cast<float>(static_cast<int>(c % side) - half_) * cell_;
		const float ccy = static_cast<float>(static_cast<int>(c / side) - half_) * cell_;
		centre_[c] = s.mean.z() + gx_ * (ccx - s.mean.x()) + gy_ * (ccy - s.mean.y());
	}
}

std::optional<float> GroundGrid::heightAt(float x, float y) const
{
	if (samples_.empty())
		return std::nullopt;
	const int side = 2 * half_ + 1;
	// Between the centres of the four cells around (x, y) when all are known (the ground's
	// curvature then shows), else from the cell that holds it along the plane's slope.
	const float fx = x * inv_ + static_cast<float>(half_),
	            fy = y * inv_ + static_cast<float>(half_);
	const int x0 = static_cast<int>(std::floor(fx)), y0 = static_cast<int>(std::floor(fy));
	if (x0 >= 0 && y0 >= 0 && x0 + 1 < side && y0 + 1 < side)
	{
		const float* c = &centre_[static_cast<std::size_t>(y0) * side + x0];
		const float h00 = c[0], h10 = c[1], h01 = c[side], h11 = c[side + 1];
		if (!std::isnan(h00) && !std::isnan(h10) && !std::isnan(h01) && !std::isnan(h11))
		{
			const float ax = fx - static_cast<float>(x0), ay = fy - static_cast<float>(y0);
			return (1 - ay) * ((1 - ax) * h00 + ax * h10) + ay * ((1 - ax) * h01 + ax * h11);
		}
	}
	const int cx = static_cast<int>(std::lround(fx));
	const int cy = static_cast<int>(std::lround(fy));
	if (cx < 0 || cy < 0 || cx >= side || cy >= side)
		return std::nullopt;
	const int32_t k = index_[static_cast<std::size_t>(cy) * side + cx];
	if (k < 0)
		return std::nullopt;
	const auto& m = samples_[static_cast<std::size_t>(k)].mean;
	return m.z() + gx_ * (x - m.x()) + gy_ * (y - m.y());
}

GroundAlignResult alignGroundGrids(const Eigen::Isometry3d& T_ref_cur, const GroundGrid& ref,
                                   const GroundGrid& cur, const GroundAlignParams& p)
{
	GroundAlignResult out;
	out.T = T_ref_cur;
	if (ref.empty() || cur.empty())
	{
		out.why = "no ground grid";
		return out;
	}
	Eigen::Isometry3d T = T_ref_cur;
	Eigen::Matrix3d dRtotal = Eigen::Matrix3d::Identity();
	for (int it = 0; it < std::max(1, p.iterations); it++)
	{
		const Eigen::Isometry3f Tf = T.cast<float>();
		Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
		Eigen::Vector3d g = Eigen::Vector3d::Zero();
		Eigen::Vector2d sxy = Eigen::Vector2d::Zero();
		Eigen::Matrix2d sxx = Eigen::Matrix2d::Zero();
		double sr2 = 0, sw = 0;
		int used = 0;
		for (const auto& s : cur.samples())
		{
			const Eigen::Vector3f q = Tf * s.mean;
			const auto h = ref.heightAt(q.x(), q.y());
			if (!h)
				continue;
			const double r = static_cast<double>(q.z() - *h);
			if (std::abs(r) > p.maxResidual_m)
				continue;
			const double w = std::abs(r) <= p.huber_m ? 1.0 : p.huber_m / std::abs(r);
			// z after a small update: z + tz + wx y - wy x (rotations about the reference
			// frame's x and y axes).
			const Eigen::Vector3d J(1.0, q.y(), -q.x());
			H += w * J * J.transpose();
			g += w * J * r;
			const Eigen::Vector2d xy(q.x(), q.y());
			sxy += xy;
			sxx += xy * xy.transpose();
			sr2 += w * r * r;
			sw += w;
			used++;
		}
		out.used = used;
		if (used < p.minCells)
		{
			out.why = "too few ground cells in common";
			out.T = T_ref_cur;
			return out;
		}
		const Eigen::Vector2d mean = sxy / used;
		const Eigen::Matrix2d cov = sxx / used - mean * mean.transpose();
		const double minVar = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues()(0);
		if (minVar < p.minSpread_m * p.minSpread_m)
		{
			out.why = "the ground cells in common do not spread over the ground";
			out.T = T_ref_cur;
			return out;
		}
		out.rms_m = std::sqrt(sr2 / std::max(sw, 1e-12));
		const Eigen::Vector3d d = H.ldlt().solve(-g);
		Eigen::Isometry3d dT = Eigen::Isometry3d::Identity();
		const Eigen::Matrix3d dR = (Eigen::AngleAxisd(d(1), Eigen::Vector3d::UnitX()) *
		                            Eigen::AngleAxisd(d(2), Eigen::Vector3d::UnitY()))
		                               .toRotationMatrix();
		dT.linear() = dR;
		dT.translation() = Eigen::Vector3d(0, 0, d(0));
		T = dT * T;
		dRtotal = dR * dRtotal;
		if (std::abs(d(0)) < 1e-5 && std::abs(d(1)) < 1e-7 && std::abs(d(2)) < 1e-7)
			break;
	}
	out.correction_deg = Eigen::AngleAxisd(dRtotal).angle() * 180.0 / M_PI;
	if (out.correction_deg > p.maxCorrection_deg)
	{
		out.why = "the ground asks for too large a change of roll and pitch";
		out.T = T_ref_cur;
		return out;
	}
	out.ok = true;
	out.T = T;
	return out;
}

}  // namespace rasterslam::raster
