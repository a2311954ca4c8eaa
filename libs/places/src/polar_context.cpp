#include <rasterslam/places/polar_context.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace rasterslam::places
{
namespace
{
/** The keys and unit columns of a context whose cells are set. */
void finishContext(PolarContext& c)
{
	const int R = c.rings, S = c.sectors;
	c.ringKey.assign(static_cast<std::size_t>(R), 0.0f);
	c.sectorKey.assign(static_cast<std::size_t>(S), 0);
	for (int r = 0; r < R; r++)
		for (int s = 0; s < S; s++)
			if (c.at(r, s) > 0)
			{
				c.ringKey[static_cast<std::size_t>(r)] += 1.0f / static_cast<float>(S);
				c.sectorKey[static_cast<std::size_t>(s)]++;
			}
	c.columns.assign(c.cells.size(), 0.0f);
	for (int s = 0; s < S; s++)
	{
		double n2 = 0;
		for (int r = 0; r < R; r++)
			n2 += static_cast<double>(c.at(r, s)) * c.at(r, s);
		if (n2 > 0)
			for (int r = 0; r < R; r++)
				c.columns[static_cast<std::size_t>(s * R + r)] =
				    static_cast<float>(c.at(r, s) / std::sqrt(n2));
	}
}
}  // namespace

PolarContext polarContext(const std::vector<PointXYZI>& pts, const PolarParams& p)
{
	if (p.rings < 1 || p.sectors < 1 || !(p.maxRange_m > 0))
		throw std::invalid_argument("polarContext: rings, sectors and max range must be positive");
	PolarContext c;
	c.rings = p.rings;
	c.sectors = p.sectors;
	c.cells.assign(static_cast<std::size_t>(p.rings) * static_cast<std::size_t>(p.sectors), 0.0f);
	const double ringWidth = p.maxRange_m / p.rings, sectorWidth = 2 * M_PI / p.sectors;
	for (const auto& pt : pts)
	{
		const double r = std::hypot(pt.x, pt.y);
		if (!(r < p.maxRange_m))
			continue;  // beyond the last ring (or not a number)
		const double h = pt.z + p.heightOffset_m;
		if (!(h > 0) || !std::isfinite(h))
			continue;  // on or below the ground, or not a number
		const int ring = std::min(p.rings - 1, static_cast<int>(r / ringWidth));
		double a = std::atan2(pt.y, pt.x);
		if (a < 0)
			a += 2 * M_PI;
		const int sector = std::min(p.sectors - 1, static_cast<int>(a / sectorWidth));
		float& cell = c.at(ring, sector);
		cell = std::max(cell, static_cast<float>(h));
	}
	finishContext(c);
	return c;
}

namespace
{
/** Dimensions and every array of the size they say (as polarContext() makes them). */
bool wellFormed(const PolarContext& c)
{
	const auto R = static_cast<std::size_t>(std::max(0, c.rings)),
	           S = static_cast<std::size_t>(std::max(0, c.sectors));
	return R > 0 && S > 0 && c.cells.size() == R * S && c.columns.size() == R * S &&
	       c.ringKey.size() == R && c.sectorKey.size() == S;
}

/** Distance of `a` and `b` with b's sectors shifted by `shift`: the sum of the cosines of
 *  the columns occupied in both is the dot product of the unit columns (an empty column is
 *  all zeros), taken in two contiguous pieces (before and after b's sectors wrap). */
double distanceAt(const PolarContext& a, const PolarContext& b, int shift)
{
	using Vec = Eigen::Map<const Eigen::VectorXf>;
	const Eigen::Index S = a.sectors, R = a.rings, sh = shift, head = S - sh;
	const float dot =
	    Vec(a.columns.data(), head * R).dot(Vec(b.columns.data() + sh * R, head * R)) +
	    Vec(a.columns.data() + head * R, sh * R).dot(Vec(b.columns.data(), sh * R));
	// Sectors occupied in both: the occupancy flags' dot product.
	const auto both = [](const int* x, const int* y, Eigen::Index n)
	{
		int c = 0;
		for (Eigen::Index i = 0; i < n; i++)
			c += (x[i] > 0) & (y[i] > 0);
		return c;
	};
	const int n = both(a.sectorKey.data(), b.sectorKey.data() + sh, head) +
	              both(a.sectorKey.data() + head, b.sectorKey.data(), sh);
	return n ? std::max(0.0, 1.0 - static_cast<double>(dot) / n) : 1.0;
}
}  // namespace

PolarMatch comparePolar(const PolarContext& a, const PolarContext& b, int shiftCandidates)
{
	if (!wellFormed(a) || !wellFormed(b) || a.rings != b.rings || a.sectors != b.sectors)
		throw std::invalid_argument(
		    "comparePolar: contexts of different or no dimensions (not made by polarContext?)");
	const int S = a.sectors;
	// The shifts whose sector occupancy agrees best (L1 of the occupied rings' counts; integer,
	// so that the sums vectorize), then each with its neighbours.
	std::vector<int> bKey2(b.sectorKey);  // twice over: a shifted window needs no modulo
	bKey2.insert(bKey2.end(), b.sectorKey.begin(), b.sectorKey.end());
	std::vector<std::pair<int, int>> byKey(static_cast<std::size_t>(S));
	for (int sh = 0; sh < S; sh++)
	{
		int d = 0;
		const int* x = a.sectorKey.data();
		const int* y = bKey2.data() + sh;
		for (int s = 0; s < S; s++)
			d += std::abs(x[s] - y[s]);
		byKey[static_cast<std::size_t>(sh)] = {d, sh};
	}
	const auto k = static_cast<std::size_t>(std::clamp(shiftCandidates, 1, S));
	std::partial_sort(byKey.begin(), byKey.begin() + static_cast<std::ptrdiff_t>(k), byKey.end());
	std::vector<char> tried(static_cast<std::size_t>(S), 0);
	PolarMatch best;
	best.distance = 2;
	for (std::size_t i = 0; i < k; i++)
		for (int dsh = -1; dsh <= 1; dsh++)
		{
			const int sh = ((byKey[i].second + dsh) % S + S) % S;
			if (tried[static_cast<std::size_t>(sh)])
				continue;
			tried[static_cast<std::size_t>(sh)] = 1;
			const double d = distanceAt(a, b, sh);
			if (d < best.distance || (d == best.distance && sh < best.shift))
				best = {d, sh};
		}
	return best;
}

std::vector<uint8_t> quantizedCells(const PolarContext& c, float step_m)
{
	if (!(step_m > 0))
		throw std::invalid_argument("quantizedCells: the step must be positive");
	std::vector<uint8_t> out(c.cells.size(), 0);
	for (std::size_t i = 0; i < c.cells.size(); i++)
		if (c.cells[i] > 0)  // occupied stays occupied, however low
			out[i] = static_cast<uint8_t>(
			    std::clamp(std::lround(c.cells[i] / step_m), long{1}, long{255}));
	return out;
}

PolarContext polarContextOfCells(int rings, int sectors, const uint8_t* cells, float step_m)
{
	if (rings < 1 || sectors < 1 || !(step_m > 0))
		throw std::invalid_argument(
		    "polarContextOfCells: rings, sectors and step must be positive");
	PolarContext c;
	c.rings = rings;
	c.sectors = sectors;
	c.cells.resize(static_cast<std::size_t>(rings) * static_cast<std::size_t>(sectors));
	for (std::size_t i = 0; i < c.cells.size(); i++)
		c.cells[i] = static_cast<float>(cells[i]) * step_m;
	finishContext(c);
	return c;
}

std::size_t PolarIndex::add(PolarContext ctx)
{
	if (!wellFormed(ctx) || ctx.rings != p_.rings || ctx.sectors != p_.sectors)
		throw std::invalid_argument(
		    "PolarIndex::add: a context of other dimensions than the index's");
	places_.push_back(std::move(ctx));
	live_.push_back(1);
	++live_count_;
	return places_.size() - 1;
}

bool PolarIndex::remove(std::size_t id)
{
	if (id >= places_.size() || !live_[id])
		return false;
	live_[id] = 0;
	--live_count_;
	places_[id] = PolarContext();  // its memory goes now
	return true;
}

std::vector<PolarIndex::Result> PolarIndex::query(const PolarContext& q,
                                                  std::size_t maxResults) const
{
	if (!wellFormed(q) || q.rings != p_.rings || q.sectors != p_.sectors)
		throw std::invalid_argument(
		    "PolarIndex::query: a context of other dimensions than the index's");
	std::vector<std::pair<double, std::size_t>> byRing;
	byRing.reserve(places_.size());
	for (std::size_t i = 0; i < places_.size(); i++)
	{
		if (!live_[i])
			continue;
		double d = 0;
		for (std::size_t r = 0; r < q.ringKey.size(); r++)
		{
			const double e = q.ringKey[r] - places_[i].ringKey[r];
			d += e * e;
		}
		byRing.emplace_back(d, i);
	}
	const auto k =
	    std::min(byRing.size(), static_cast<std::size_t>(std::max(1, p_.ringCandidates)));
	std::partial_sort(byRing.begin(), byRing.begin() + static_cast<std::ptrdiff_t>(k),
	                  byRing.end());
	std::vector<Result> out;
	out.reserve(k);
	for (std::size_t i = 0; i < k; i++)
		out.push_back(
		    {byRing[i].second, comparePolar(q, places_[byRing[i].second], p_.shiftCandidates)});
	std::sort(out.begin(), out.end(),
	          [](const Result& a, const Result& b)
	          {
		          return a.match.distance < b.match.distance ||
		                 (a.match.distance == b.match.distance && a.id < b.id);
	          });
	if (out.size() > maxResults)
		out.resize(maxResults);
	return out;
}

}  // namespace rasterslam::places
