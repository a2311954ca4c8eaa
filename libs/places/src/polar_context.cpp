#include <rasterslam/places/polar_context.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

namespace rasterslam::places
{
namespace
{
/** Sectors rounded up to whole blocks of 16 (the windows of comparePolar's sector keys). */
int paddedSectors(int S)
{
	return (S + 15) / 16 * 16;
}

/** `n` elements on the stack when they are few (comparePolar runs for each of a query's
 *  candidates: allocating would cost as much as comparing), on the heap otherwise. */
template <typename T, std::size_t N>
class Scratch
{
   public:
	explicit Scratch(std::size_t n) : p_(n <= N ? stack_.data() : (heap_.resize(n), heap_.data()))
	{
	}
	Scratch(const Scratch&) = delete;  // p_ may point into the object's own array
	Scratch& operator=(const Scratch&) = delete;
	T* data() { return p_; }
	T& operator[](std::size_t i) { return p_[i]; }

   private:
	std::array<T, N> stack_;
	std::vector<T> heap_;
	T* p_;
};

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
	c.sectorBytes.clear();
	if (R <= 255)
	{
		const int n = paddedSectors(S);
		c.sectorBytes.resize(static_cast<std::size_t>(S + n));
		for (int i = 0; i < S + n; i++)
			c.sectorBytes[static_cast<std::size_t>(i)] =
			    static_cast<uint8_t>(c.sectorKey[static_cast<std::size_t>(i % S)]);
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
	       c.ringKey.size() == R && c.sectorKey.size() == S &&
	       c.sectorBytes.size() ==
	           (R <= 255 ? S + static_cast<std::size_t>(paddedSectors(c.sectors)) : 0);
}

/** The sectors a context occupies as bits (sector s: bit s), for up to 64 sectors. */
uint64_t occupancyBits(const PolarContext& c)
{
	uint64_t bits = 0;
	for (int s = 0; s < c.sectors; s++)
		bits |= static_cast<uint64_t>(c.sectorKey[static_cast<std::size_t>(s)] > 0) << s;
	return bits;
}

/** Distance of `a` and `b` with b's sectors shifted by `shift`: the sum of the cosines of
 *  the columns occupied in both is the dot product of the unit columns (an empty column is
 *  all zeros), taken in two contiguous pieces (before and after b's sectors wrap). With up
 *  to 64 sectors the sectors occupied in both are counted on the occupancy bits (`bitsA`,
 *  `bitsB`), otherwise on the sector keys. */
double distanceAt(const PolarContext& a, const PolarContext& b, int shift, uint64_t bitsA,
                  uint64_t bitsB)
{
	using Vec = Eigen::Map<const Eigen::VectorXf>;
	const Eigen::Index S = a.sectors, R = a.rings, sh = shift, head = S - sh;
	const float dot =
	    Vec(a.columns.data(), head * R).dot(Vec(b.columns.data() + sh * R, head * R)) +
	    Vec(a.columns.data() + head * R, sh * R).dot(Vec(b.columns.data(), sh * R));
	int n = 0;
	if (S <= 64)
	{
		// Sector s of a meets sector (s + sh) mod S of b: b's bits turned right by sh.
		const uint64_t turned =
		    sh == 0 ? bitsB : (bitsB >> sh) | (bitsB << static_cast<unsigned>(S - sh));
		const uint64_t mask = S == 64 ? ~uint64_t{0} : (uint64_t{1} << S) - 1;
		n = __builtin_popcountll(bitsA & turned & mask);
	}
	else
	{
		const auto both = [](const int* x, const int* y, Eigen::Index count)
		{
			int c = 0;
			for (Eigen::Index i = 0; i < count; i++)
				c += (x[i] > 0) & (y[i] > 0);
			return c;
		};
		n = both(a.sectorKey.data(), b.sectorKey.data() + sh, head) +
		    both(a.sectorKey.data() + head, b.sectorKey.data(), sh);
	}
	return n ? std::max(0.0, 1.0 - static_cast<double>(dot) / n) : 1.0;
}
}  // namespace

namespace
{
/** For each shift of b's sectors, the L1 distance of the sector keys of `a` and `b` (the
 *  occupied rings' counts). In bytes (PolarContext::sectorBytes), over windows of whole
 *  blocks of 16 so that each block is one sum-of-absolute-differences instruction: a's key
 *  is padded with zeros, which adds the padded part of b's window (|0 - b| = b), taken off
 *  again by prefix sums of b's bytes. */
void keyDistances(const PolarContext& a, const PolarContext& b, int* out)
{
	const int S = a.sectors, n = paddedSectors(S);
	const auto un = static_cast<std::size_t>(n);
	Scratch<uint8_t, 256> a0(un);
	std::fill(a0.data(), a0.data() + n, uint8_t{0});
	std::copy(a.sectorBytes.begin(), a.sectorBytes.begin() + S, a0.data());
	const uint8_t* b2 = b.sectorBytes.data();
	Scratch<int, 513> prefix(b.sectorBytes.size() + 1);
	prefix[0] = 0;
	for (std::size_t i = 0; i < b.sectorBytes.size(); i++)
		prefix[i + 1] = prefix[i] + b2[i];
	for (int sh = 0; sh < S; sh++)
	{
		int d = 0;
		const uint8_t* y = b2 + sh;
		for (std::size_t s = 0; s < un; s++)
			d += std::abs(static_cast<int>(a0[s]) - static_cast<int>(y[s]));
		out[sh] = d - (prefix[static_cast<std::size_t>(sh + n)] -
		               prefix[static_cast<std::size_t>(sh + S)]);
	}
}

/** The same in ints, for keys that do not fit a byte (more than 255 rings). */
void keyDistancesWide(const PolarContext& a, const PolarContext& b, int* out)
{
	const int S = a.sectors;
	for (int sh = 0; sh < S; sh++)
	{
		int d = 0;
		for (int s = 0; s < S; s++)
			d += std::abs(a.sectorKey[static_cast<std::size_t>(s)] -
			              b.sectorKey[static_cast<std::size_t>((s + sh) % S)]);
		out[sh] = d;
	}
}

/** The sector keys' distance at each shift (out: a.sectors values), in bytes where the
 *  contexts have them. */
void keyDistancesOf(const PolarContext& a, const PolarContext& b, int* out)
{
	if (a.sectorBytes.empty())
		keyDistancesWide(a, b, out);
	else
		keyDistances(a, b, out);
}

/** Throws naming `caller` unless both contexts are well formed and of the same dimensions. */
void requireComparable(const PolarContext& a, const PolarContext& b, const char* caller)
{
	if (!wellFormed(a) || !wellFormed(b) || a.rings != b.rings || a.sectors != b.sectors)
		throw std::invalid_argument(
		    std::string(caller) +
		    ": contexts of different or no dimensions (not made by polarContext?)");
}

/** comparePolar() of two well-formed contexts of the same dimensions; `bitsA` is
 *  occupancyBits(a) when a has up to 64 sectors (a query compared with many contexts
 *  computes it once). */
PolarMatch compareChecked(const PolarContext& a, uint64_t bitsA, const PolarContext& b,
                          int shiftCandidates)
{
	const int S = a.sectors;
	// The shifts whose sector occupancy agrees best, then each with its neighbours.
	Scratch<int, 256> keyDist(static_cast<std::size_t>(S));
	keyDistancesOf(a, b, keyDist.data());
	// The best k by (distance, shift), kept sorted.
	const int k = std::clamp(shiftCandidates, 1, S);
	Scratch<std::pair<int, int>, 16> best(static_cast<std::size_t>(k));
	int kept = 0;
	for (int sh = 0; sh < S; sh++)
	{
		const std::pair<int, int> e{keyDist[static_cast<std::size_t>(sh)], sh};
		if (kept == k && !(e < best[static_cast<std::size_t>(k - 1)]))
			continue;
		if (kept < k)
			kept++;
		int i = kept - 1;  // insertion: moves the worse ones one down
		for (; i > 0 && e < best[static_cast<std::size_t>(i - 1)]; i--)
			best[static_cast<std::size_t>(i)] = best[static_cast<std::size_t>(i - 1)];
		best[static_cast<std::size_t>(i)] = e;
	}
	const uint64_t bitsB = S <= 64 ? occupancyBits(b) : 0;
	Scratch<int, 48> tried(static_cast<std::size_t>(3 * k));
	int triedCount = 0;
	PolarMatch match;
	match.distance = 2;
	for (int i = 0; i < kept; i++)
		for (int dsh = -1; dsh <= 1; dsh++)
		{
			const int sh = ((best[static_cast<std::size_t>(i)].second + dsh) % S + S) % S;
			if (std::find(tried.data(), tried.data() + triedCount, sh) != tried.data() + triedCount)
				continue;
			tried[static_cast<std::size_t>(triedCount++)] = sh;
			const double dist = distanceAt(a, b, sh, bitsA, bitsB);
			if (dist < match.distance || (dist == match.distance && sh < match.shift))
				match = {dist, sh};
		}
	return match;
}
}  // namespace

std::vector<int> sectorKeyDistances(const PolarContext& a, const PolarContext& b)
{
	requireComparable(a, b, "sectorKeyDistances");
	std::vector<int> out(static_cast<std::size_t>(a.sectors));
	keyDistancesOf(a, b, out.data());
	return out;
}

PolarMatch comparePolar(const PolarContext& a, const PolarContext& b, int shiftCandidates)
{
	requireComparable(a, b, "comparePolar");
	return compareChecked(a, a.sectors <= 64 ? occupancyBits(a) : 0, b, shiftCandidates);
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
	ringKeys_.insert(ringKeys_.end(), ctx.ringKey.begin(), ctx.ringKey.end());
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
	// The ring keys side by side (ringKeys_), not behind each context's own allocation: the
	// scan over every place is the part of a query that grows with the map.
	const std::size_t R = q.ringKey.size();
	std::vector<std::pair<double, std::size_t>> byRing;
	byRing.reserve(live_count_);
	const float* key = ringKeys_.data();
	for (std::size_t i = 0; i < places_.size(); i++, key += R)
	{
		if (!live_[i])
			continue;
		double d = 0;
		for (std::size_t r = 0; r < R; r++)
		{
			const double e = q.ringKey[r] - key[r];
			d += e * e;
		}
		byRing.emplace_back(d, i);
	}
	// (distance, id) pairs are all different: the first k are the same set in the same order
	// whichever selection finds them.
	const auto k =
	    std::min(byRing.size(), static_cast<std::size_t>(std::max(1, p_.ringCandidates)));
	if (k < byRing.size())
		std::nth_element(byRing.begin(), byRing.begin() + static_cast<std::ptrdiff_t>(k),
		                 byRing.end());
	std::sort(byRing.begin(), byRing.begin() + static_cast<std::ptrdiff_t>(k));
	std::vector<Result> out;
	out.reserve(k);
	const uint64_t bitsQ = q.sectors <= 64 ? occupancyBits(q) : 0;
	// The candidates lie anywhere in memory, each behind pointers: each comparison waited for
	// its context, then for its keys. The context two ahead and the keys of the next one are
	// fetched while one is compared.
	const auto prefetch = [](const void* p, std::size_t bytes)
	{
#if defined(__GNUC__)
		for (std::size_t o = 0; o < bytes; o += 64)
			__builtin_prefetch(static_cast<const char*>(p) + o);
#else
		(void)p, (void)bytes;
#endif
	};
	for (std::size_t i = 0; i < k; i++)
	{
		if (i + 2 < k)
			prefetch(&places_[byRing[i + 2].second], sizeof(PolarContext));
		if (i + 1 < k)
		{
			const auto& next = places_[byRing[i + 1].second];
			prefetch(next.sectorBytes.data(), next.sectorBytes.size());
			prefetch(next.sectorKey.data(),
			         std::min<std::size_t>(4 * 64, 4 * next.sectorKey.size()));
			prefetch(next.columns.data(), std::min<std::size_t>(4 * 64, 4 * next.columns.size()));
		}
		out.push_back({byRing[i].second,
		               compareChecked(q, bitsQ, places_[byRing[i].second], p_.shiftCandidates)});
	}
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
