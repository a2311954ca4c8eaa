#include <rasterslam/places/fusion.h>

#include <algorithm>
#include <map>
#include <tuple>

namespace rasterslam::places
{
std::vector<FusedPlace> fuseRankings(const std::vector<uint64_t>& first,
                                     const std::vector<uint64_t>& second, double k)
{
	std::vector<FusedPlace> fused;
	std::map<uint64_t, std::size_t> at;  // place -> its entry in fused
	const auto add = [&](uint64_t id, std::size_t r, bool inFirst)
	{
		auto [it, isNew] = at.emplace(id, fused.size());
		if (isNew)
			fused.push_back(FusedPlace{id});
		auto& f = fused[it->second];
		f.sum += 1.0 / (k + static_cast<double>(r) + 1);
		f.bestRank = std::min(f.bestRank, r);
		(inFirst ? f.firstRank : f.secondRank) = r;
	};
	for (std::size_t r = 0; r < first.size(); r++)
		add(first[r], r, true);
	for (std::size_t r = 0; r < second.size(); r++)
		add(second[r], r, false);
	std::sort(fused.begin(), fused.end(),
	          [](const FusedPlace& x, const FusedPlace& y)
	          {
		          return std::tie(y.sum, x.bestRank, x.firstRank, x.id) <
		                 std::tie(x.sum, y.bestRank, y.firstRank, y.id);
	          });
	return fused;
}

std::vector<RankedPlace> rankPlaces(const PolarIndex& index,
                                    const std::vector<PolarContext>& queries,
                                    const std::function<uint64_t(std::size_t)>& placeOf,
                                    std::size_t maxPlaces)
{
	std::map<uint64_t, PolarMatch> best;
	const auto compared = static_cast<std::size_t>(std::max(index.params().ringCandidates, 1));
	for (const auto& q : queries)
	{
		for (const auto& r : index.query(q, compared))
		{
			auto [it, isNew] = best.emplace(placeOf(r.id), r.match);
			if (!isNew && r.match.distance < it->second.distance)
				it->second = r.match;
		}
	}
	std::vector<RankedPlace> out;
	out.reserve(best.size());
	for (const auto& [id, m] : best)
		out.push_back({id, m});
	std::stable_sort(out.begin(), out.end(),
	                 [](const RankedPlace& a, const RankedPlace& b)
	                 { return a.match.distance < b.match.distance; });
	if (out.size() > maxPlaces)
		out.resize(maxPlaces);
	return out;
}

}  // namespace rasterslam::places
