#include <rasterslam/features/planar_search.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <unordered_map>

namespace rasterslam::features
{
namespace
{
struct Span
{
	float lo = std::numeric_limits<float>::max();
	float hi = std::numeric_limits<float>::lowest();
};

/** Centres (x, y) of the cells whose points span at least minSpan_m in height. */
std::vector<Eigen::Vector2f> structureCells(const std::vector<Eigen::Vector3f>& pts,
                                            const PlanarSearchParams& p, double range_m)
{
	// Cells within +-2^20 of the origin, packed as non-negative (cx + h) * 2h + (cy + h).
	constexpr int64_t kHalf = int64_t(1) << 20;
	std::unordered_map<int64_t, Span> cells;
	const double inv = 1.0 / p.cell_m;
	const double r2 = range_m * range_m;
	for (const auto& q : pts)
	{
		if (!q.allFinite() || double(q.x()) * q.x() + double(q.y()) * q.y() > r2)
			continue;
		const double fx = std::floor(q.x() * inv), fy = std::floor(q.y() * inv);
		if (std::abs(fx) >= double(kHalf) || std::abs(fy) >= double(kHalf))
			continue;
		const auto cx = static_cast<int64_t>(fx), cy = static_cast<int64_t>(fy);
		auto& s = cells[(cx + kHalf) * (2 * kHalf) + (cy + kHalf)];
		s.lo = std::min(s.lo, q.z());
		s.hi = std::max(s.hi, q.z());
	}
	std::vector<Eigen::Vector2f> out;
	for (const auto& [key, s] : cells)
		if (s.hi - s.lo >= p.minSpan_m)
		{
			const int64_t cx = key / (2 * kHalf) - kHalf, cy = key % (2 * kHalf) - kHalf;
			out.emplace_back(static_cast<float>((cx + 0.5) * p.cell_m),
			                 static_cast<float>((cy + 0.5) * p.cell_m));
		}
	std::sort(out.begin(), out.end(),
	          [](const auto& a, const auto& b)
	          { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
	return out;
}

struct Peak
{
	double yaw = 0, x = 0, y = 0, score = 0;
};

double yawGap_deg(double a, double b)
{
	double d = std::fmod(std::abs(a - b), 2 * M_PI);
	return std::min(d, 2 * M_PI - d) * 180.0 / M_PI;
}
}  // namespace

std::vector<PlanarHypothesis> planarSearch(const std::vector<Eigen::Vector3f>& source,
                                           const std::vector<Eigen::Vector3f>& target,
                                           const PlanarSearchParams& p)
{
	std::vector<PlanarHypothesis> out;
	if (!(p.cell_m > 0) || !(p.yawStep_deg > 0) || p.hypotheses < 1)
		return out;
	const auto src = structureCells(source, p, p.range_m);
	const auto tgt = structureCells(target, p, std::numeric_limits<double>::max());
	if (src.empty() || tgt.empty())
		return out;

	// The target's view, each structure cell spread over its neighbours (1, 1/2 beside,
	// 1/4 diagonally) so that a turn between two yaw steps still meets it.
	Eigen::Vector2f lo = tgt.front(), hi = tgt.front();
	for (const auto& c : tgt)
	{
		lo = lo.cwiseMin(c);
		hi = hi.cwiseMax(c);
	}
	const double cell = p.cell_m;
	const float x0 = lo.x() - static_cast<float>(cell), y0 = lo.y() - static_cast<float>(cell);
	const int wt = static_cast<int>(std::ceil((hi.x() - x0) / cell)) + 2;
	const int ht = static_cast<int>(std::ceil((hi.y() - y0) / cell)) + 2;
	const int half = static_cast<int>(std::ceil(p.range_m / cell)) + 1;
	const int ws = 2 * half + 1;  // the source's view: its origin in the middle
	const int rows = cv::getOptimalDFTSize(ht + ws - 1);
	const int cols = cv::getOptimalDFTSize(wt + ws - 1);
	cv::Mat T = cv::Mat::zeros(rows, cols, CV_32F);
	for (const auto& c : tgt)
	{
		// c - (x0, y0) is a whole number of cells by construction; rounded, not floored, so
		// that a float error cannot move it to the cell below (or off the view).
		const int u = static_cast<int>(std::lround((c.x() - x0) / cell));
		const int v = static_cast<int>(std::lround((c.y() - y0) / cell));
		if (u < 1 || v < 1 || u + 1 >= wt || v + 1 >= ht)
			continue;
		for (int dv = -1; dv <= 1; dv++)
			for (int du = -1; du <= 1; du++)
			{
				const float w = (du == 0 ? 1.f : 0.5f) * (dv == 0 ? 1.f : 0.5f);
				float& t = T.at<float>(v + dv, u + du);
				t = std::max(t, w);
			}
	}
	cv::Mat FT;
	cv::dft(T, FT, 0, ht + 1);

	std::vector<Peak> peaks;
	cv::Mat S(rows, cols, CV_32F), FS, C;
	const int steps = std::max(1, static_cast<int>(std::lround(360.0 / p.yawStep_deg)));
	for (int k = 0; k < steps; k++)
	{
		const double yaw = 2 * M_PI * k / steps;
		const float c = static_cast<float>(std::cos(yaw)), s = static_cast<float>(std::sin(yaw));
		S.setTo(0);
		int n = 0;
		for (const auto& q : src)
		{
			const float x = c * q.x() - s * q.y(), y = s * q.x() + c * q.y();
			const int u = static_cast<int>(std::floor(x / cell)) + half;
			const int v = static_cast<int>(std::floor(y / cell)) + half;
			if (u < 0 || v < 0 || u >= ws || v >= ws)
				continue;
			float& e = S.at<float>(v, u);
			n += e == 0;
			e = 1;
		}
		if (n == 0)
			continue;
		cv::dft(S, FS, 0, ws);
		// C(d) = sum over p of T(p + d) S(p): source cell p lands on target cell p + d.
		cv::mulSpectrums(FT, FS, C, 0, true);
		cv::dft(C, C, cv::DFT_INVERSE | cv::DFT_SCALE | cv::DFT_REAL_OUTPUT);
		const double norm = std::min<double>(n, static_cast<double>(tgt.size()));
		// The best three peaks of this yaw, each with its 5 x 5 neighbourhood then cleared.
		for (int j = 0; j < 3; j++)
		{
			double best = 0;
			cv::Point at;
			cv::minMaxLoc(C, nullptr, &best, nullptr, &at);
			if (best <= 0)
				break;
			// Shifts wrap around: d in [-(ws - 1), wt - 1] (columns) and [-(ws - 1), ht - 1]
			// (rows) is stored modulo the size.
			const int du = at.x >= wt ? at.x - cols : at.x;
			const int dv = at.y >= ht ? at.y - rows : at.y;
			Peak pk;
			pk.yaw = yaw;
			// Target cell u is the structure at x0 + u cell; source cell u' holds the turned
			// points in [(u' - half) cell, (u' - half + 1) cell), centred half a cell on.
			pk.x = x0 + (du + half - 0.5) * cell;
			pk.y = y0 + (dv + half - 0.5) * cell;
			pk.score = std::min(1.0, best / norm);
			peaks.push_back(pk);
			for (int dy = -2; dy <= 2; dy++)
				for (int dx = -2; dx <= 2; dx++)
					C.at<float>((at.y + dy + rows) % rows, (at.x + dx + cols) % cols) = 0;
		}
	}
	std::sort(peaks.begin(), peaks.end(),
	          [](const Peak& a, const Peak& b) { return a.score > b.score; });
	std::vector<Peak> kept;
	for (const auto& pk : peaks)
	{
		bool distinct = true;
		for (const auto& k : kept)
			if (std::hypot(pk.x - k.x, pk.y - k.y) < p.distinct_m &&
			    yawGap_deg(pk.yaw, k.yaw) < p.distinct_deg)
				distinct = false;
		if (!distinct)
			continue;
		kept.push_back(pk);
		PlanarHypothesis h;
		h.T.linear() = Eigen::AngleAxisd(pk.yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
		h.T.translation() = Eigen::Vector3d(pk.x, pk.y, 0);
		h.score = pk.score;
		out.push_back(h);
		if (static_cast<int>(out.size()) >= p.hypotheses)
			break;
	}
	return out;
}

FreeSpaceCheck freeSpaceConflicts(const std::vector<Eigen::Vector3f>& source,
                                  const std::vector<Eigen::Vector3f>& target,
                                  const Eigen::Isometry3d& T, const FreeSpaceParams& params)
{
	// Each side's points by 1 m cell: the heights, for the lowest and highest and for the
	// band above the other side's ground.
	if (!(params.cell_m > 0) || !std::isfinite(params.cell_m))
		throw std::invalid_argument("freeSpaceConflicts: the cell must be positive and finite");
	const double cell = params.cell_m, flatSpan = params.flatSpan_m, bandLow = params.bandLow_m,
	             bandHigh = params.bandHigh_m;
	using Cells = std::unordered_map<int64_t, std::vector<float>>;
	// Cells packed as cx * 2^24 + cy: a point more than 2^22 cells from the origin (4,194 km
	// at 1 m) is left out, so that a cell and its neighbours stay distinct and the indices fit.
	constexpr double kReach = double(int64_t(1) << 22);
	const auto key = [](int64_t cx, int64_t cy) { return cx * (int64_t(1) << 24) + cy; };
	const auto fill = [&](Cells& cells, const Eigen::Vector3f& p)
	{
		const double cx = std::floor(p.x() / cell), cy = std::floor(p.y() / cell);
		if (!std::isfinite(p.z()) || !(std::abs(cx) < kReach) || !(std::abs(cy) < kReach))
			return;  // also NaN and inf
		cells[key(static_cast<int64_t>(cx), static_cast<int64_t>(cy))].push_back(p.z());
	};
	Cells targetCells, sourceCells;
	for (const auto& p : target)
		fill(targetCells, p);
	const Eigen::Isometry3f Tf = T.cast<float>();
	for (const auto& p : source)
		fill(sourceCells, Tf * p);
	// A cell is bare ground when it and its eight neighbours are observed and flat.
	const auto bareGround = [&](const Cells& cells, int64_t k)
	{
		for (int64_t dx = -1; dx <= 1; dx++)
			for (int64_t dy = -1; dy <= 1; dy++)
			{
				const auto it = cells.find(k + dx * (int64_t(1) << 24) + dy);
				if (it == cells.end())
					return false;
				const auto [lo, hi] = std::minmax_element(it->second.begin(), it->second.end());
				if (*hi - *lo > flatSpan)
					return false;
			}
		return true;
	};
	FreeSpaceCheck out;
	const auto oneWay = [&](const Cells& structure, const Cells& ground)
	{
		for (const auto& [k, zs] : structure)
		{
			const auto g = ground.find(k);
			if (g == ground.end())
				continue;  // the other side did not look there
			const float gLow = *std::min_element(g->second.begin(), g->second.end());
			// Low structure of this side, above the other side's lowest point there.
			const bool low =
			    std::any_of(zs.begin(), zs.end(),
			                [&](float z) { return z >= gLow + bandLow && z <= gLow + bandHigh; }) &&
			    (params.minTop_m <= 0 ||
			     *std::max_element(zs.begin(), zs.end()) > gLow + params.minTop_m);
			if (!low)
				continue;
			out.compared++;
			if (bareGround(ground, k))
				out.conflicts++;
		}
	};
	oneWay(sourceCells, targetCells);
	oneWay(targetCells, sourceCells);
	return out;
}

}  // namespace rasterslam::features
