// k-medians with k-means++ seeding over binary descriptors (Hamming distance): the step that
// splits one node of the vocabulary tree into up to k children.
#include "kmedians.h"

#include <algorithm>
#include <array>
#include <limits>

namespace rasterslam::bow::detail
{
int nearest(const Descriptor& d, const std::vector<Descriptor>& centres)
{
	int best = 0, bestDist = std::numeric_limits<int>::max();
	for (std::size_t c = 0; c < centres.size(); ++c)
	{
		const int dist = hamming(d, centres[c]);
		if (dist < bestDist)
		{
			bestDist = dist;
			best = static_cast<int>(c);
		}
	}
	return best;
}

Descriptor majority(const std::vector<Descriptor>& all, const std::vector<uint32_t>& members)
{
	std::array<uint32_t, 256> ones{};
	for (const uint32_t m : members)
	{
		const Descriptor& d = all[m];
		for (int byte = 0; byte < 32; ++byte)
		{
			const unsigned v = d[byte];
			for (int bit = 0; bit < 8; ++bit)
				ones[byte * 8 + bit] += (v >> bit) & 1u;
		}
	}
	Descriptor out{};
	const std::size_t n = members.size();
	for (int i = 0; i < 256; ++i)
		if (2 * static_cast<std::size_t>(ones[i]) > n)
			out[i / 8] = static_cast<uint8_t>(out[i / 8] | (1u << (i % 8)));
	return out;
}

std::vector<Descriptor> seedKMeansPP(const std::vector<Descriptor>& all,
                                     const std::vector<uint32_t>& members, int k, std::mt19937& rng)
{
	std::vector<Descriptor> centres;
	if (members.empty() || k <= 0)
		return centres;
	// Integer draws only: std::uniform_int_distribution over a uint64 keeps the result
	// identical for a seed whatever the floating-point settings.
	std::uniform_int_distribution<std::size_t> first(0, members.size() - 1);
	centres.push_back(all[members[first(rng)]]);
	std::vector<uint64_t> d2(members.size());
	uint64_t total = 0;
	for (std::size_t i = 0; i < members.size(); ++i)
	{
		const uint64_t d = static_cast<uint64_t>(hamming(all[members[i]], centres[0]));
		d2[i] = d * d;
		total += d2[i];
	}
	while (static_cast<int>(centres.size()) < k && total > 0)
	{
		std::uniform_int_distribution<uint64_t> pick(0, total - 1);
		uint64_t r = pick(rng);
		std::size_t chosen = 0;
		for (; chosen < members.size(); ++chosen)
		{
			if (r < d2[chosen])
				break;
			r -= d2[chosen];
		}
		// d2[chosen] > 0: the new centre differs from every one already taken.
		centres.push_back(all[members[chosen]]);
		total = 0;
		for (std::size_t i = 0; i < members.size(); ++i)
		{
			const uint64_t d = static_cast<uint64_t>(hamming(all[members[i]], centres.back()));
			d2[i] = std::min(d2[i], d * d);
			total += d2[i];
		}
	}
	return centres;
}

void kMedians(const std::vector<Descriptor>& all, const std::vector<uint32_t>& members, int k,
              int maxIterations, std::mt19937& rng, std::vector<Descriptor>& centres,
              std::vector<std::vector<uint32_t>>& groups)
{
	centres = seedKMeansPP(all, members, k, rng);
	std::vector<int> assign(members.size());
	for (std::size_t i = 0; i < members.size(); ++i)
		assign[i] = nearest(all[members[i]], centres);
	const auto makeGroups = [&]
	{
		groups.assign(centres.size(), {});
		for (std::size_t i = 0; i < members.size(); ++i)
			groups[assign[i]].push_back(members[i]);
	};
	makeGroups();
	const auto reassign = [&]
	{
		bool changed = false;
		for (std::size_t i = 0; i < members.size(); ++i)
		{
			const int a = nearest(all[members[i]], centres);
			changed = changed || a != assign[i];
			assign[i] = a;
		}
		return changed;
	};
	const auto reseedEmpty = [&]
	{
		std::vector<std::size_t> size(centres.size(), 0);
		for (const int a : assign)
			++size[a];
		bool any = false;
		for (std::size_t c = 0; c < centres.size(); ++c)
		{
			if (size[c] != 0)
				continue;
			std::size_t far = 0;
			int farDist = 0;
			for (std::size_t i = 0; i < members.size(); ++i)
			{
				if (size[assign[i]] < 2)
					continue;
				const int d = hamming(all[members[i]], centres[assign[i]]);
				if (d > farDist)
				{
					farDist = d;
					far = i;
				}
			}
			if (farDist == 0)
				break;  // every group is tight: nothing to split
			--size[assign[far]];
			centres[c] = all[members[far]];
			assign[far] = static_cast<int>(c);
			size[c] = 1;
			any = true;
		}
		return any;
	};
	for (int it = 0; it < maxIterations; ++it)
	{
		for (std::size_t c = 0; c < centres.size(); ++c)
			if (!groups[c].empty())  // an empty group keeps its centre (it may win back later)
				centres[c] = majority(all, groups[c]);
		bool changed = reassign();
		// A centre left without descriptors (two seeds in one true cluster converge to the
		// same median) restarts at the descriptor farthest from its centre: that one most
		// likely sits in a cluster that absorbed two true ones, which Lloyd steps alone
		// would never split.
		if (reseedEmpty())
			changed = reassign() || true;
		if (!changed)
			break;
		makeGroups();
	}
	// Drop empty groups; the rest keep their order.
	std::size_t out = 0;
	for (std::size_t c = 0; c < centres.size(); ++c)
	{
		if (groups[c].empty())
			continue;
		if (out != c)  // a vector moved onto itself ends up empty
		{
			centres[out] = centres[c];
			groups[out] = std::move(groups[c]);
		}
		++out;
	}
	centres.resize(out);
	groups.resize(out);
}

}  // namespace rasterslam::bow::detail
