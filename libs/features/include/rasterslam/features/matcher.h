// Brute-force matching of binary descriptors by Hamming distance, both directions in one pass.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <cstring>
#include <opencv2/core.hpp>
#include <vector>

namespace rasterslam::features
{
struct Match
{
	int a = -1, b = -1;  //!< rows of the two descriptor sets
	int distance = 0;    //!< Hamming distance, bits
};

/** Hamming distance of two 32-byte ORB descriptors. */
inline int hamming32(const uint8_t* a, const uint8_t* b)
{
	int d = 0;
	for (int k = 0; k < 4; k++)
	{
		uint64_t x, y;
		std::memcpy(&x, a + 8 * k, 8);
		std::memcpy(&y, b + 8 * k, 8);
		d += __builtin_popcountll(x ^ y);
	}
	return d;
}

struct MatchParams
{
	int maxDistance = 64;  //!< bits
	/** Lowe's ratio between the best and second best distance (1 disables it). */
	float ratio = 1.0f;
	/** When positions are given: only pairs whose positions are closer than this (m). */
	float gateRadius_m = 0;
};

/** Mutual nearest neighbours: a's best is b and b's best is a. When `posA` and `posB` are
 *  given (posA already predicted into B's frame) and gateRadius_m > 0, only pairs closer
 *  than the gate are compared. Deterministic: ties go to the lower index. */
std::vector<Match> matchMutual(const cv::Mat& descA, const cv::Mat& descB, const MatchParams& p,
                               const std::vector<Eigen::Vector3f>* posA = nullptr,
                               const std::vector<Eigen::Vector3f>* posB = nullptr);

/** The brute-force kernel matchMutual compares every pair with when it has no positions:
 *  "avx512" where the processor counts bits in AVX-512 registers (VPOPCNTDQ), else
 *  "portable". Both give the same matches. */
const char* matcherKernel();
/** Tests and benchmarks: true keeps matchMutual on the portable kernel. */
void forcePortableMatcher(bool portable);

/** Mutual nearest neighbours among the pairs in the same group only (groupA[i] == groupB[j]):
 *  a bag-of-words direct index, whose groups are vocabulary nodes, so that descriptors under
 *  different nodes are never compared (DBoW2's way). The ratio test compares the best and
 *  second best within the group. */
std::vector<Match> matchMutualGrouped(const cv::Mat& descA, const cv::Mat& descB,
                                      const MatchParams& p, const std::vector<uint32_t>& groupA,
                                      const std::vector<uint32_t>& groupB);

}  // namespace rasterslam::features
