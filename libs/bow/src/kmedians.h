// Private to the library: Hamming distance and one k-medians clustering step of the
// vocabulary tree.
#pragma once

#include <rasterslam/bow/vocabulary.h>

#include <cstring>
#include <random>
#include <vector>

namespace rasterslam::bow::detail
{
/** Number of differing bits; memcpy because the array of bytes need not be 8-byte aligned. */
inline int hamming(const Descriptor& a, const Descriptor& b)
{
	uint64_t x[4], y[4];
	std::memcpy(x, a.data(), sizeof x);
	std::memcpy(y, b.data(), sizeof y);
	return __builtin_popcountll(x[0] ^ y[0]) + __builtin_popcountll(x[1] ^ y[1]) +
	       __builtin_popcountll(x[2] ^ y[2]) + __builtin_popcountll(x[3] ^ y[3]);
}

/** Index of the nearest centre (the first one on ties). */
int nearest(const Descriptor& d, const std::vector<Descriptor>& centres);

/** Bitwise majority of the descriptors `members` of `all`: a bit is set if more than half of
 *  them have it (ties give 0). */
Descriptor majority(const std::vector<Descriptor>& all, const std::vector<uint32_t>& members);

/** k-means++ seeding: the first centre uniformly at random, each next one drawn with
 *  probability proportional to the squared distance to the nearest centre already chosen.
 *  Returns fewer than k centres when the set has fewer than k distinct descriptors. */
std::vector<Descriptor> seedKMeansPP(const std::vector<Descriptor>& all,
                                     const std::vector<uint32_t>& members, int k,
                                     std::mt19937& rng);

/** Clusters `members` of `all` into at most k groups by k-medians from k-means++ seeds, until
 *  the assignments stop changing or after maxIterations centre updates. Every descriptor is
 *  in the group of its nearest centre on return; empty groups are dropped. */
void kMedians(const std::vector<Descriptor>& all, const std::vector<uint32_t>& members, int k,
              int maxIterations, std::mt19937& rng, std::vector<Descriptor>& centres,
              std::vector<std::vector<uint32_t>>& groups);

}  // namespace rasterslam::bow::detail
