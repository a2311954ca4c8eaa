// Two rankings of the same places fused by reciprocal rank (Cormack, Clarke and Buettcher,
// SIGIR 2009): each place scores 1 / (K + rank + 1) in each ranking that holds it, summed. The
// loop detector and rasterslam-bench-places fuse the words' ranking with the polar contexts'
// ranking this way.
#pragma once

#include <rasterslam/places/polar_context.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace rasterslam::places
{
/** A place of a fused ranking; a rank is SIZE_MAX where that ranking does not hold it. */
struct FusedPlace
{
	uint64_t id = 0;
	double sum = 0;  //!< the fused score
	std::size_t bestRank = SIZE_MAX, firstRank = SIZE_MAX, secondRank = SIZE_MAX;
};

/** `first` and `second` (place ids, best first, each id at most once in each) fused, best
 *  first. Equal sums (a place r-th in one ranking only against another r-th in the other
 *  only) go to the better single rank, then to the better rank in `first`, then to the
 *  lower id, so the order never depends on how the inputs were stored. */
std::vector<FusedPlace> fuseRankings(const std::vector<uint64_t>& first,
                                     const std::vector<uint64_t>& second, double k);

/** A place of a polar ranking: its best context's distance to any of the queries. */
struct RankedPlace
{
	uint64_t id = 0;
	PolarMatch match;
};

/** The places of `index` ranked by their best context against any of `queries` (each
 *  query compares the index's ringCandidates contexts in full); `placeOf` names the place a
 *  context belongs to. At most `maxPlaces`, by distance then id. Queries of other
 *  dimensions than the index's are an error (PolarIndex::query throws). */
std::vector<RankedPlace> rankPlaces(const PolarIndex& index,
                                    const std::vector<PolarContext>& queries,
                                    const std::function<uint64_t(std::size_t)>& placeOf,
                                    std::size_t maxPlaces);

}  // namespace rasterslam::places
