// Polar contexts (places::polarContext, comparePolar, PolarIndex): a scene turned about its
// origin matches itself at the sector shift of the turn, other scenes do not, and the index
// ranks the turned scene's own place first among many.
#include <gtest/gtest.h>
#include <rasterslam/places/fusion.h>
#include <rasterslam/places/polar_context.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace
{
using namespace rasterslam;

/** A seeded scene: `n` boxes (walls, poles) of random size, height and place within 50 m,
 *  their outlines sampled every 0.25 m and every 0.5 m of height, as a LiDAR sees them. The
 *  sensor is 1.73 m above the ground (the default height offset). */
std::vector<PointXYZI> scene(uint32_t seed, int n = 40)
{
	std::mt19937 rng(seed);
	std::uniform_real_distribution<float> pos(-45.f, 45.f), size(0.3f, 8.f), height(0.8f, 12.f);
	std::vector<PointXYZI> pts;
	for (int b = 0; b < n; b++)
	{
		const float cx = pos(rng), cy = pos(rng), sx = size(rng), sy = size(rng), h = height(rng);
		for (float z = 0.25f; z <= h; z += 0.5f)
			for (float t = 0; t < 2 * (sx + sy); t += 0.25f)
			{
				float x = cx - sx / 2, y = cy - sy / 2;
				if (t < sx)
					x += t;
				else if (t < sx + sy)
					x += sx, y += t - sx;
				else if (t < 2 * sx + sy)
					x += sx - (t - sx - sy), y += sy;
				else
					y += sy - (t - 2 * sx - sy);
				pts.push_back({x, y, z - 1.73f, 0});
			}
	}
	return pts;
}

std::vector<PointXYZI> turned(const std::vector<PointXYZI>& pts, double yaw)
{
	const float c = static_cast<float>(std::cos(yaw)), s = static_cast<float>(std::sin(yaw));
	std::vector<PointXYZI> out = pts;
	for (auto& p : out)
	{
		const float x = c * p.x - s * p.y, y = s * p.x + c * p.y;
		p.x = x;
		p.y = y;
	}
	return out;
}

TEST(PolarContext, CellsHoldTheHighestPointAboveTheGround)
{
	places::PolarParams p;
	p.rings = 20;  // of 3 m; 60 sectors of 6 degrees
	// Two points in ring 3 (9-12 m) and sector 7 (42-48 degrees), one below the ground.
	const double a = 45 * M_PI / 180;
	const std::vector<PointXYZI> pts{
	    {static_cast<float>(10 * std::cos(a)), static_cast<float>(10 * std::sin(a)), 0.5f, 0},
	    {static_cast<float>(11 * std::cos(a)), static_cast<float>(11 * std::sin(a)), -0.27f, 0},
	    {static_cast<float>(5 * std::cos(a)), static_cast<float>(5 * std::sin(a)), -3.0f, 0},
	    {70.f, 0.f, 1.f, 0}};  // beyond the last ring
	const auto c = places::polarContext(pts, p);
	ASSERT_EQ(c.cells.size(), 20u * 60u);
	EXPECT_FLOAT_EQ(c.at(3, 7), 0.5f + 1.73f);
	EXPECT_FLOAT_EQ(c.at(1, 7), 0.0f);  // below the ground: left empty
	int occupied = 0;
	for (float v : c.cells)
		occupied += v > 0;
	EXPECT_EQ(occupied, 1);
	EXPECT_FLOAT_EQ(c.ringKey[3], 1.0f / 60);
	EXPECT_EQ(c.sectorKey[7], 1);
}

TEST(PolarContext, ATurnedSceneMatchesItselfAtTheTurnsShift)
{
	const auto pts = scene(7);
	const auto a = places::polarContext(pts);
	for (const double deg : {90.0, 30.0, 180.0, 246.0, 354.0})
	{
		const auto b = places::polarContext(turned(pts, deg * M_PI / 180));
		const auto m = places::comparePolar(a, b);
		// A point at azimuth t in a is at t + deg in b: a's sector s is b's s + deg / 6.
		const int expected = static_cast<int>(std::lround(deg / 6)) % 60;
		const int off = std::abs(m.shift - expected);
		EXPECT_LE(std::min(off, 60 - off), 1) << deg << " deg: shift " << m.shift;
		EXPECT_LT(m.distance, 0.1) << deg << " deg";
	}
	// Another scene of the same kind is far from it at any shift.
	const auto other = places::comparePolar(a, places::polarContext(scene(8)), 60);
	EXPECT_GT(other.distance, 0.3);
}

/** The comparison written the plain way at one shift: each column pair's cosine of the raw
 *  cells, the mean over the sectors occupied in both. */
double plainAt(const places::PolarContext& a, const places::PolarContext& b, int sh)
{
	double sum = 0;
	int n = 0;
	for (int s = 0; s < a.sectors; s++)
	{
		double dot = 0, na = 0, nb = 0;
		for (int r = 0; r < a.rings; r++)
		{
			const double x = a.at(r, s), y = b.at(r, (s + sh) % a.sectors);
			dot += x * y, na += x * x, nb += y * y;
		}
		if (na > 0 && nb > 0)
			sum += 1 - dot / std::sqrt(na * nb), n++;
	}
	return n ? sum / n : 1.0;
}

/** The same at every shift: the best. */
places::PolarMatch bruteForce(const places::PolarContext& a, const places::PolarContext& b)
{
	places::PolarMatch best;
	best.distance = 2;
	for (int sh = 0; sh < a.sectors; sh++)
	{
		const double d = plainAt(a, b, sh);
		if (d < best.distance)
			best = {d, sh};
	}
	return best;
}

TEST(PolarContext, TheShiftsComparedAreTheOnesThePlainSectorKeysRankAtAnyDimensions)
{
	// The sector keys' L1 distance at each shift is the plain sum (in bytes over padded
	// windows when the counts fit a byte, in ints when not: 300 rings; sectors fewer than a
	// block of 16, a whole block, more), and comparePolar (shiftCandidates 1) compares the
	// shift where it is least and its two neighbours.
	for (const auto& [rings, sectors] :
	     std::vector<std::pair<int, int>>{{10, 60}, {4, 7}, {3, 16}, {6, 33}, {2, 1}, {300, 20}})
		for (uint32_t seed = 31; seed < 37; seed++)
		{
			places::PolarParams p;
			p.rings = rings;
			p.sectors = sectors;
			// Scenes of 6 boxes: many sectors empty, keys that differ from shift to shift.
			const auto a = places::polarContext(scene(seed, 6), p),
			           b = places::polarContext(turned(scene(seed + 100, 6), 1.9), p);
			const std::size_t padded = (static_cast<std::size_t>(sectors) + 15) / 16 * 16;
			EXPECT_EQ(a.sectorBytes.size(), rings <= 255 ? sectors + padded : 0u) << rings;
			std::vector<int> plainKeys(static_cast<std::size_t>(sectors));
			for (int sh = 0; sh < sectors; sh++)
				for (int s = 0; s < sectors; s++)
					plainKeys[static_cast<std::size_t>(sh)] +=
					    std::abs(a.sectorKey[static_cast<std::size_t>(s)] -
					             b.sectorKey[static_cast<std::size_t>((s + sh) % sectors)]);
			EXPECT_EQ(places::sectorKeyDistances(a, b), plainKeys)
			    << rings << " x " << sectors << ", seed " << seed;
			std::pair<int, int> least{1 << 30, 0};  // (L1, shift)
			for (int sh = 0; sh < sectors; sh++)
				least =
				    std::min(least, std::make_pair(plainKeys[static_cast<std::size_t>(sh)], sh));
			places::PolarMatch expected;
			expected.distance = 2;
			for (const int dsh : {-1, 0, 1})
			{
				const int sh = ((least.second + dsh) % sectors + sectors) % sectors;
				const double d = plainAt(a, b, sh);
				if (d < expected.distance || (d == expected.distance && sh < expected.shift))
					expected = {d, sh};
			}
			const auto m = places::comparePolar(a, b, 1);
			EXPECT_EQ(m.shift, expected.shift) << rings << " x " << sectors << ", seed " << seed;
			EXPECT_NEAR(m.distance, expected.distance, 1e-5)
			    << rings << " x " << sectors << ", seed " << seed;
		}
	const auto small = places::polarContext(scene(1), places::PolarParams{5});
	EXPECT_THROW(places::sectorKeyDistances(small, places::polarContext(scene(1))),
	             std::invalid_argument);
}

TEST(PolarContext, TheComparisonAgreesWithThePlainOneAtEveryShift)
{
	// Trying every shift, the fast comparison (unit columns' dot products in two pieces
	// either side of the wrap, occupancy counts) finds what the plain one finds, for turned
	// copies (also across the wrap) and for other scenes, also partly empty ones.
	const auto a = places::polarContext(scene(11));
	for (const double deg : {0.0, 12.0, 100.0, 200.0, 348.0, 359.0})
	{
		const auto b = places::polarContext(turned(scene(11), deg * M_PI / 180));
		const auto fast = places::comparePolar(a, b, 60), plain = bruteForce(a, b);
		EXPECT_EQ(fast.shift, plain.shift) << deg << " deg";
		EXPECT_NEAR(fast.distance, plain.distance, 1e-5) << deg << " deg";
	}
	for (const uint32_t seed : {12u, 13u})
	{
		const auto b = places::polarContext(scene(seed, 6));  // 6 boxes: many empty sectors
		const auto fast = places::comparePolar(a, b, 60), plain = bruteForce(a, b);
		EXPECT_EQ(fast.shift, plain.shift) << "scene " << seed;
		EXPECT_NEAR(fast.distance, plain.distance, 1e-5) << "scene " << seed;
	}
	// Nothing in common: the distance is 1.
	EXPECT_EQ(places::comparePolar(a, places::polarContext({})).distance, 1.0);
	// Other sector counts: the sectors occupied in both are counted on 64-bit occupancy
	// masks up to 64 sectors (turned across the wrap: 1, 7, 63, 64), on the keys beyond.
	for (const int sectors : {1, 7, 63, 64, 65, 90})
	{
		places::PolarParams p;
		p.sectors = sectors;
		const auto c = places::polarContext(scene(11), p);
		for (const uint32_t seed : {11u, 12u, 13u})
			for (const double deg : {0.0, 100.0, 359.0})
			{
				const auto d = places::polarContext(
				    turned(scene(seed, seed == 11 ? 40 : 6), deg * M_PI / 180), p);
				const auto fast = places::comparePolar(c, d, sectors), plain = bruteForce(c, d);
				EXPECT_EQ(fast.shift, plain.shift)
				    << sectors << " sectors, scene " << seed << ", " << deg << " deg";
				EXPECT_NEAR(fast.distance, plain.distance, 1e-5)
				    << sectors << " sectors, scene " << seed << ", " << deg << " deg";
			}
	}
}

TEST(PolarContext, TheIndexRanksATurnedPlaceFirstAmongMany)
{
	places::PolarParams p;
	p.ringCandidates = 5;  // the ring-key prefilter decides which 5 are compared in full
	places::PolarIndex index(p);
	for (uint32_t s = 100; s < 160; s++)
		EXPECT_EQ(index.add(places::polarContext(scene(s))), s - 100);
	for (const uint32_t s : {103u, 131u, 159u})
	{
		const auto res = index.query(places::polarContext(turned(scene(s), M_PI / 3)), 5);
		ASSERT_EQ(res.size(), 5u);
		EXPECT_EQ(res[0].id, s - 100);
		// The query is the place turned by +60 deg: the place's sector s + shift is the
		// query's s at shift -10 sectors, 50.
		EXPECT_LE(std::abs(res[0].match.shift - 50), 1);
		for (std::size_t i = 1; i < res.size(); i++)
			EXPECT_LE(res[i - 1].match.distance, res[i].match.distance);
		EXPECT_LT(res[0].match.distance + 0.2, res[1].match.distance);
	}
}

TEST(PolarContext, KeptInStepsOf5CmAPlaceComparesAsBeforeAndLeavesTheIndex)
{
	const auto a = places::polarContext(scene(21));
	const auto cells = places::quantizedCells(a, 0.05f);
	ASSERT_EQ(cells.size(), a.cells.size());
	const auto back = places::polarContextOfCells(a.rings, a.sectors, cells.data(), 0.05f);
	for (std::size_t i = 0; i < a.cells.size(); i++)
	{
		EXPECT_EQ(back.cells[i] > 0, a.cells[i] > 0) << "cell " << i;  // occupancy kept
		if (a.cells[i] > 0)
		{
			EXPECT_NEAR(back.cells[i], std::clamp(a.cells[i], 0.05f, 12.75f), 0.026);
		}
	}
	EXPECT_EQ(back.ringKey, a.ringKey);
	EXPECT_EQ(back.sectorKey, a.sectorKey);
	// Kept, a turned place compares with the original as it did unquantized.
	const auto q = places::polarContext(turned(scene(21), 0.7));
	EXPECT_NEAR(places::comparePolar(q, back).distance, places::comparePolar(q, a).distance, 0.01);
	EXPECT_EQ(places::comparePolar(q, back).shift, places::comparePolar(q, a).shift);
	// The step's bounds: a low cell stays occupied, a high one saturates.
	places::PolarContext tiny = a;
	tiny.cells.assign(tiny.cells.size(), 0.0f);
	tiny.cells[3] = 0.001f;
	tiny.cells[4] = 40.0f;
	const auto t = places::quantizedCells(tiny, 0.05f);
	EXPECT_EQ(t[3], 1);
	EXPECT_EQ(t[4], 255);
	EXPECT_EQ(t[5], 0);
	EXPECT_THROW(places::quantizedCells(a, 0), std::invalid_argument);

	// A removed place is never an answer and frees its id's slot, not the others' ids.
	places::PolarIndex index;
	for (uint32_t s = 20; s < 25; s++)
		index.add(places::polarContext(scene(s)));
	ASSERT_EQ(index.query(q, 1).at(0).id, 1u);
	EXPECT_TRUE(index.remove(1));
	EXPECT_FALSE(index.remove(1));
	EXPECT_FALSE(index.remove(99));
	EXPECT_EQ(index.size(), 4u);
	EXPECT_FALSE(index.contains(1));
	EXPECT_EQ(index.context(1), nullptr);
	const auto res = index.query(q, 10);
	EXPECT_EQ(res.size(), 4u);
	for (const auto& r : res)
		EXPECT_NE(r.id, 1u);
	EXPECT_EQ(index.add(places::polarContext(scene(21))), 5u);  // ids are never reused
	EXPECT_EQ(index.query(q, 1).at(0).id, 5u);
}

TEST(PolarContext, ContextsOfOtherDimensionsAreRefused)
{
	places::PolarParams small;
	small.rings = 5;
	const auto a = places::polarContext(scene(1), small), b = places::polarContext(scene(1));
	EXPECT_THROW(places::comparePolar(a, b), std::invalid_argument);
	places::PolarIndex index;
	EXPECT_THROW(index.add(a), std::invalid_argument);
	EXPECT_THROW(index.query(a, 5), std::invalid_argument);
	small.sectors = 0;
	EXPECT_THROW(places::polarContext(scene(1), small), std::invalid_argument);
}

}  // namespace

TEST(PlaceFusion, ReciprocalRanksAreSummedAndTiesGoToTheBetterSingleRank)
{
	// K 10: rank r scores 1 / (11 + r).
	const auto f = places::fuseRankings({7, 3, 5, 9}, {5, 8, 3}, 10);
	ASSERT_EQ(f.size(), 5u);
	const auto sumOf = [&](uint64_t id)
	{
		for (const auto& p : f)
			if (p.id == id)
				return p.sum;
		return -1.0;
	};
	EXPECT_DOUBLE_EQ(sumOf(5), 1.0 / 13 + 1.0 / 11);  // third and first
	EXPECT_DOUBLE_EQ(sumOf(3), 1.0 / 12 + 1.0 / 13);
	EXPECT_DOUBLE_EQ(sumOf(9), 1.0 / 14);
	// Those in both rankings first: 5 (0.168), 3 (0.160); then 7 (first in the first only,
	// 0.091), 8 (second in the second only, 0.083), 9 (0.071).
	const std::vector<uint64_t> order{5, 3, 7, 8, 9};
	for (std::size_t i = 0; i < order.size(); i++)
		EXPECT_EQ(f[i].id, order[i]) << "at " << i;
	EXPECT_EQ(f[0].firstRank, 2u);
	EXPECT_EQ(f[0].secondRank, 0u);
	EXPECT_EQ(f[0].bestRank, 0u);
	EXPECT_EQ(f[2].secondRank, SIZE_MAX);  // 7: not in the second ranking
	EXPECT_EQ(f[3].firstRank, SIZE_MAX);   // 8: not in the first

	// Equal sums, K 0 (rank r scores 1 / (r + 1)): 30, second in both (1/2 + 1/2), against 40
	// and 10, first in one ranking only (1): the better single rank first, then the first
	// ranking's place, whatever the ids.
	const auto t = places::fuseRankings({40, 30}, {10, 30}, 0);
	ASSERT_EQ(t.size(), 3u);
	EXPECT_DOUBLE_EQ(t[0].sum, t[2].sum);
	EXPECT_EQ(t[0].id, 40u);
	EXPECT_EQ(t[1].id, 10u);
	EXPECT_EQ(t[2].id, 30u);
	EXPECT_TRUE(places::fuseRankings({}, {}, 10).empty());
}

TEST(PlaceFusion, PlacesRankByTheirBestContextAgainstAnyQuery)
{
	// 30 places of 2 contexts each (contexts 2p and 2p + 1 belong to place 100 + p).
	places::PolarIndex index;
	for (uint32_t c = 0; c < 60; c++)
		index.add(places::polarContext(scene(500 + c)));
	const auto placeOf = [](std::size_t c) -> uint64_t { return 100 + c / 2; };
	// A query turned from context 13 (place 106) ranks place 106 first, once.
	const auto one =
	    places::rankPlaces(index, {places::polarContext(turned(scene(513), 0.5))}, placeOf, 30);
	ASSERT_EQ(one.size(), 30u);
	EXPECT_EQ(one[0].id, 106u);
	for (std::size_t i = 1; i < one.size(); i++)
	{
		EXPECT_NE(one[i].id, 106u);
		EXPECT_LE(one[i - 1].match.distance, one[i].match.distance);
	}
	// Two queries: each place at its best against either; places 106 and 120 (context 40)
	// first; at most maxPlaces.
	const auto two = places::rankPlaces(
	    index, {places::polarContext(scene(513)), places::polarContext(scene(540))}, placeOf, 5);
	ASSERT_EQ(two.size(), 5u);
	EXPECT_EQ(std::min(two[0].id, two[1].id), 106u);
	EXPECT_EQ(std::max(two[0].id, two[1].id), 120u);
	EXPECT_LT(two[1].match.distance, 1e-6);
	// A query of other dimensions is an error.
	places::PolarParams other;
	other.sectors = 30;
	EXPECT_THROW(places::rankPlaces(index, {places::polarContext(scene(1), other)}, placeOf, 5),
	             std::invalid_argument);
}
