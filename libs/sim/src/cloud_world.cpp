// Rendering new scans from a cloud of real ones (see cloud_world.h).
#include <rasterslam/sim/cloud_world.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rasterslam::sim
{
namespace
{
constexpr std::int64_t kVoxelBias = 1 << 20;  // 21 bits an axis: +-104 km at 0.1 m

std::int64_t voxelKey(double x, double y, double z, double voxel)
{
	const auto ix = static_cast<std::int64_t>(std::floor(x / voxel)) + kVoxelBias,
	           iy = static_cast<std::int64_t>(std::floor(y / voxel)) + kVoxelBias,
	           iz = static_cast<std::int64_t>(std::floor(z / voxel)) + kVoxelBias;
	constexpr std::int64_t kMax = std::int64_t{1} << 21;
	if (ix < 0 || iy < 0 || iz < 0 || ix >= kMax || iy >= kMax || iz >= kMax)
		throw std::out_of_range("CloudWorld: point (" + std::to_string(x) + ", " +
		                        std::to_string(y) + ", " + std::to_string(z) +
		                        ") is outside the +-100 km the voxel keys cover");
	return (ix << 42) | (iy << 21) | iz;
}

std::int64_t columnKey(std::int64_t cx, std::int64_t cy)
{
	// Unsigned: shifting a negative value left is undefined.
	const auto ux = static_cast<std::uint64_t>(cx), uy = static_cast<std::uint64_t>(cy);
	return static_cast<std::int64_t>((ux << 32) ^ (uy & 0xffffffffULL));
}
}  // namespace

CloudWorld::CloudWorld(CloudWorldParams p) : p_(p)
{
	if (!(p_.voxel_m > 0) || !(p_.maxMergeRange_m > 0) || p_.minScans < 1)
		throw std::invalid_argument(
		    "CloudWorld: voxel_m and maxMergeRange_m must be positive, minScans at least 1");
}

void CloudWorld::add(const std::vector<PointXYZI>& scan, const Eigen::Isometry3d& T_world_sensor)
{
	const double r2max = p_.maxMergeRange_m * p_.maxMergeRange_m;
	for (const auto& q : scan)
	{
		const Eigen::Vector3d s(q.x, q.y, q.z);
		if (!s.allFinite() || s.squaredNorm() > r2max)
			continue;
		const Eigen::Vector3d w = T_world_sensor * s;
		auto& a = voxels_[voxelKey(w.x(), w.y(), w.z(), p_.voxel_m)];
		a.x += w.x();
		a.y += w.y();
		a.z += w.z();
		a.i += q.intensity;
		a.n++;
		if (a.scans == 0 || a.lastScan != added_)
		{
			a.scans++;
			a.lastScan = added_;
		}
	}
	added_++;
	dirty_ = true;
}

void CloudWorld::finalize() const
{
	if (!dirty_)
		return;
	std::vector<std::pair<std::int64_t, PointXYZI>> byColumn;
	byColumn.reserve(voxels_.size());
	for (const auto& [k, a] : voxels_)
	{
		if (a.scans < static_cast<std::uint32_t>(p_.minScans))
			continue;
		PointXYZI p;
		p.x = static_cast<float>(a.x / a.n);
		p.y = static_cast<float>(a.y / a.n);
		p.z = static_cast<float>(a.z / a.n);
		p.intensity = static_cast<float>(a.i / a.n);
		const auto cx = static_cast<std::int64_t>(std::floor(p.x / kColumn_m)),
		           cy = static_cast<std::int64_t>(std::floor(p.y / kColumn_m));
		byColumn.emplace_back(columnKey(cx, cy), p);
	}
	// Sorted by column, then by position: the order (and so the render) does not depend on
	// the hash map's iteration order.
	std::sort(byColumn.begin(), byColumn.end(),
	          [](const auto& a, const auto& b)
	          {
		          if (a.first != b.first)
			          return a.first < b.first;
		          if (a.second.x != b.second.x)
			          return a.second.x < b.second.x;
		          if (a.second.y != b.second.y)
			          return a.second.y < b.second.y;
		          return a.second.z < b.second.z;
	          });
	points_.clear();
	columns_.clear();
	points_.reserve(byColumn.size());
	for (std::size_t i = 0; i < byColumn.size(); i++)
	{
		if (i == 0 || byColumn[i].first != byColumn[i - 1].first)
			columns_[byColumn[i].first] = {i, i};
		columns_[byColumn[i].first].second = i + 1;
		points_.push_back(byColumn[i].second);
	}
	// Normals: the plane of the voxels in the 3 x 3 x 3 block around each one.
	std::unordered_map<std::int64_t, std::uint32_t> index;
	index.reserve(points_.size());
	for (std::size_t i = 0; i < points_.size(); i++)
		index[voxelKey(points_[i].x, points_[i].y, points_[i].z, p_.voxel_m)] =
		    static_cast<std::uint32_t>(i);
	normals_.assign(points_.size(), Eigen::Vector3f::Zero());
	const double v = p_.voxel_m;
	for (std::size_t i = 0; i < points_.size(); i++)
	{
		const auto& c = points_[i];
		Eigen::Vector3f mean = Eigen::Vector3f::Zero();
		Eigen::Matrix3f cov = Eigen::Matrix3f::Zero();
		int n = 0;
		for (int dx = -1; dx <= 1; dx++)
			for (int dy = -1; dy <= 1; dy++)
				for (int dz = -1; dz <= 1; dz++)
				{
					const auto it =
					    index.find(voxelKey(c.x + dx * v, c.y + dy * v, c.z + dz * v, v));
					if (it == index.end())
						continue;
					const auto& q = points_[it->second];
					const Eigen::Vector3f x(q.x, q.y, q.z);
					mean += x;
					cov += x * x.transpose();
					n++;
				}
		if (n < 5)
			continue;
		mean /= static_cast<float>(n);
		cov = cov / static_cast<float>(n) - mean * mean.transpose();
		const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> es(cov);
		// A plane: the smallest spread well below the middle one (not a line, not a blob).
		if (es.eigenvalues()(0) < 0.25f * es.eigenvalues()(1))
			normals_[i] = es.eigenvectors().col(0);
	}
	dirty_ = false;
}

std::vector<PointXYZI> CloudWorld::render(const Eigen::Isometry3d& T_world_sensor,
                                          const LidarModel& lidar, RenderStats* stats) const
{
	finalize();
	RenderStats st;
	const int W = lidar.azimuthSteps(), H = lidar.beamCount();
	const double azStep = 2 * M_PI / W;
	std::vector<double> el(static_cast<std::size_t>(H));
	for (int b = 0; b < H; b++)
		el[static_cast<std::size_t>(b)] =
		    lidar.elevationsDeg()[static_cast<std::size_t>(b)] * M_PI / 180;
	const auto& origin = lidar.originHeights_m();
	double hMean = 0, hSpread = 0;
	for (const double o : origin)
		hMean += o / H;
	for (const double o : origin)
		hSpread = std::max(hSpread, std::abs(o - hMean));
	constexpr float kInf = std::numeric_limits<float>::infinity();
	std::vector<float> range(static_cast<std::size_t>(W * H), kInf), inten(range.size(), 0);
	constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
	std::vector<std::uint32_t> winner(range.size(), kNone);
	const auto cell = [W](int b, int c) { return static_cast<std::size_t>(b * W + c); };

	const Eigen::Isometry3d T_sw = T_world_sensor.inverse();
	const Eigen::Vector3d c = T_world_sensor.translation();
	const double rMin = lidar.minRange_m(), rMax = lidar.maxRange_m();
	const auto c0x = static_cast<std::int64_t>(std::floor((c.x() - rMax) / kColumn_m)),
	           c1x = static_cast<std::int64_t>(std::floor((c.x() + rMax) / kColumn_m)),
	           c0y = static_cast<std::int64_t>(std::floor((c.y() - rMax) / kColumn_m)),
	           c1y = static_cast<std::int64_t>(std::floor((c.y() + rMax) / kColumn_m));
	const Eigen::Matrix3f R = T_sw.linear().cast<float>();
	const Eigen::Vector3f t = T_sw.translation().cast<float>();
	// A voxel covers about its half diagonal around its centre, seen from range r.
	const double footprint = 0.35 * p_.voxel_m;
	for (std::int64_t cx = c0x; cx <= c1x; cx++)
		for (std::int64_t cy = c0y; cy <= c1y; cy++)
		{
			const auto it = columns_.find(columnKey(cx, cy));
			if (it == columns_.end())
				continue;
			for (std::size_t i = it->second.first; i < it->second.second; i++)
			{
				const auto& p = points_[i];
				const Eigen::Vector3f q = R * Eigen::Vector3f(p.x, p.y, p.z) + t;
				const double rxy = std::hypot(q.x(), q.y());
				// The elevation seen from the mean origin, then beam by beam from its own.
				const double e0 = std::atan2(q.z() - hMean, rxy),
				             r0 = std::hypot(rxy, q.z() - hMean);
				if (r0 < rMin || r0 > rMax)
					continue;
				st.candidates++;
				const double h = footprint / r0, spread = hSpread / std::max(rxy, 1e-3);
				const auto lo = std::lower_bound(el.begin(), el.end(), e0 - h - spread),
				           hi = std::upper_bound(el.begin(), el.end(), e0 + h + spread);
				if (lo >= hi)
					continue;  // between two beams: no beam sees this voxel
				const double az = std::atan2(q.y(), q.x());
				const int a0 = static_cast<int>(std::floor((az - h + M_PI) / azStep)),
				          a1 = static_cast<int>(std::floor((az + h + M_PI) / azStep));
				for (auto it2 = lo; it2 < hi; ++it2)
				{
					const auto b = static_cast<std::size_t>(it2 - el.begin());
					const double dz = q.z() - origin[b], rb = std::hypot(rxy, dz);
					if (std::abs(std::atan2(dz, rxy) - el[b]) > footprint / rb)
						continue;
					const auto rf = static_cast<float>(rb);
					for (int a = a0; a <= a1; a++)
					{
						const int col = ((a % W) + W) % W;
						const auto k = cell(static_cast<int>(b), col);
						if (rf < range[k])
						{
							range[k] = rf;
							inten[k] = p.intensity;
							winner[k] = static_cast<std::uint32_t>(i);
						}
					}
				}
			}
		}

	// Gaps: the cloud is sparse (it holds what the real scans' beams hit), so a ray can pass
	// between the voxels of a near surface and return a far one.
	std::vector<float> out = range;
	const auto isGap = [](float r, float n1, float n2)
	{
		const float near = std::max(n1, n2);
		return std::isfinite(near) && near < r - std::max(0.5f, 0.05f * near);
	};
	const auto agree = [](float n1, float n2)
	{ return std::abs(n1 - n2) < 0.2f + 0.05f * std::min(n1, n2); };
	for (int b = 0; b < H; b++)
		for (int a = 0; a < W; a++)
		{
			const float r = range[cell(b, a)];
			// Nearest return within two cells on each side, in the row and in the column.
			const auto side = [&](int db, int da)
			{
				float best = kInf;
				for (int s = 1; s <= 2; s++)
				{
					const int bb = b + s * db, aa = (((a + s * da) % W) + W) % W;
					if (bb < 0 || bb >= H)
						break;
					best = std::min(best, range[cell(bb, aa)]);
				}
				return best;
			};
			const float l = side(0, -1), rr = side(0, 1), u = side(1, 0), d = side(-1, 0);
			const bool rowGap = isGap(r, l, rr), colGap = isGap(r, u, d);
			if (!rowGap && !colGap)
				continue;
			float n1 = rowGap ? l : u, n2 = rowGap ? rr : d;
			if (agree(n1, n2))
			{
				winner[cell(b, a)] = kNone;
				out[cell(b, a)] = 0.5f * (n1 + n2);
				const auto from = rowGap ? cell(b, (a + W - 1) % W) : cell(std::max(b - 1, 0), a);
				if (!std::isfinite(r) || inten[cell(b, a)] == 0)
					inten[cell(b, a)] = inten[from];
				st.filled++;
			}
			else
			{
				out[cell(b, a)] = kInf;
				if (std::isfinite(r))
					st.dropped++;
			}
		}

	std::vector<PointXYZI> scan;
	scan.reserve(static_cast<std::size_t>(W * H / 2));
	for (int b = 0; b < H; b++)
	{
		const double ce = std::cos(el[static_cast<std::size_t>(b)]),
		             se = std::sin(el[static_cast<std::size_t>(b)]);
		for (int a = 0; a < W; a++)
		{
			float r = out[cell(b, a)];
			if (!std::isfinite(r))
				continue;
			const double az = (a + 0.5) * azStep - M_PI;
			if (const auto w = winner[cell(b, a)]; w != kNone && !normals_[w].isZero())
			{
				// Where the ray meets the winner's plane, unless that is far off its range.
				const Eigen::Vector3d d(ce * std::cos(az), ce * std::sin(az), se),
				    o(0, 0, origin[static_cast<std::size_t>(b)]);
				const auto& q = points_[w];
				const Eigen::Vector3d pw(q.x, q.y, q.z);
				const Eigen::Vector3d ps = T_sw * pw,
				                      n = T_sw.linear() * normals_[w].cast<double>();
				const double den = n.dot(d);
				if (std::abs(den) > 0.02)
				{
					const double t = n.dot(ps - o) / den;
					if (t > rMin && std::abs(t - r) < 2.0)
						r = static_cast<float>(t);
				}
			}
			PointXYZI p;
			p.x = static_cast<float>(r * ce * std::cos(az));
			p.y = static_cast<float>(r * ce * std::sin(az));
			p.z = static_cast<float>(origin[static_cast<std::size_t>(b)] + r * se);
			p.intensity = inten[cell(b, a)];
			scan.push_back(p);
		}
	}
	st.rays = scan.size();
	if (stats)
		*stats = st;
	return scan;
}

}  // namespace rasterslam::sim
