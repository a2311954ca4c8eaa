#include <rasterslam/features/matcher.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>

namespace rasterslam::features
{
namespace
{
std::atomic<bool> gPortableOnly{false};

constexpr int kLanes = 16;  // B padded to a multiple of 16 distances (one AVX-512 register)

#if defined(__x86_64__) && defined(__GNUC__)
/** Every pair of A and B, B's descriptors as four columns of 64-bit words (`w`, nb rows
 *  padded to `padded` with zeros; `penalty` is 0 for B's rows and 2^20 for the padding, so a
 *  padding row is never the least): the least and second least distance of each A row with
 *  the first B row that has it, and the least of each B row with the first A row that has it.
 *  The same choices as comparing pair after pair, ties to the lower index, in loops the
 *  compiler turns into vector code: the distances of one A row to all of B (into `d`), then
 *  reductions over them. */
inline __attribute__((always_inline)) void allPairs(const cv::Mat& descA,
                                                    const std::vector<uint64_t> (&w)[4],
                                                    const int* penalty, int padded, int* d,
                                                    int* bestA, int* distA, int* secondA,
                                                    int* bestB, int* distB)
{
	constexpr int kInf = std::numeric_limits<int>::max();
	constexpr int kPadding = 1 << 20;
	const uint64_t* __restrict w0 = w[0].data();
	const uint64_t* __restrict w1 = w[1].data();
	const uint64_t* __restrict w2 = w[2].data();
	const uint64_t* __restrict w3 = w[3].data();
	const int* __restrict pen = penalty;
	int* __restrict dist = d;
	int* __restrict bB = bestB;
	int* __restrict dB = distB;
	for (int i = 0; i < descA.rows; i++)
	{
		uint64_t a[4];
		std::memcpy(a, descA.ptr<uint8_t>(i), 32);
		const uint64_t a0 = a[0], a1 = a[1], a2 = a[2], a3 = a[3];
		// The least distance with the first row that has it: the least of (distance, row).
		uint64_t least = ~0ull;
		for (int j = 0; j < padded; j++)
		{
			const int x = static_cast<int>(
			                  __builtin_popcountll(w0[j] ^ a0) + __builtin_popcountll(w1[j] ^ a1) +
			                  __builtin_popcountll(w2[j] ^ a2) + __builtin_popcountll(w3[j] ^ a3)) +
			              pen[j];
			dist[j] = x;
			least = std::min(least, (static_cast<uint64_t>(x) << 32) | static_cast<uint32_t>(j));
			// B's side: rows of A come in order, so the first with the least is kept.
			bB[j] = x < dB[j] ? i : bB[j];
			dB[j] = std::min(dB[j], x);
		}
		// The second least: the least of the other rows (the least again if it is tied).
		const int first = static_cast<int>(least & 0xffffffffu);
		int second = kInf;
		for (int j = 0; j < padded; j++)
			second = std::min(second, j == first ? kInf : dist[j]);
		bestA[i] = first;
		distA[i] = static_cast<int>(least >> 32);
		secondA[i] = second >= kPadding ? kInf : second;
	}
}

__attribute__((target("avx512f,avx512vl,avx512bw,avx512dq,avx512vpopcntdq"))) void allPairsAvx512(
    const cv::Mat& descA, const std::vector<uint64_t> (&w)[4], const int* penalty, int padded,
    int* d, int* bestA, int* distA, int* secondA, int* bestB, int* distB)
{
	allPairs(descA, w, penalty, padded, d, bestA, distA, secondA, bestB, distB);
}

bool processorHasAvx512Popcount()
{
	static const bool has =
	    __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
	    __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq") &&
	    __builtin_cpu_supports("avx512vpopcntdq");
	return has;
}
#else
bool processorHasAvx512Popcount()
{
	return false;
}
#endif
}  // namespace

const char* matcherKernel()
{
	return !gPortableOnly.load() && processorHasAvx512Popcount() ? "avx512" : "portable";
}

void forcePortableMatcher(bool portable)
{
	gPortableOnly = portable;
}

std::vector<Match> matchMutual(const cv::Mat& descA, const cv::Mat& descB, const MatchParams& p,
                               const std::vector<Eigen::Vector3f>* posA,
                               const std::vector<Eigen::Vector3f>* posB)
{
	const int na = descA.rows, nb = descB.rows;
	std::vector<Match> out;
	if (na == 0 || nb == 0)
		return out;
	CV_Assert(descA.cols == 32 && descB.cols == 32 && descA.type() == CV_8U &&
	          descB.type() == CV_8U);
	const bool gated = posA && posB && p.gateRadius_m > 0;
	const float gate2 = p.gateRadius_m * p.gateRadius_m;
	constexpr int kInf = std::numeric_limits<int>::max();
	std::vector<int> bestA(na, -1), distA(na, kInf), secondA(na, kInf);
	std::vector<int> bestB(nb, -1), distB(nb, kInf);
	auto consider = [&](int i, int j)
	{
		const int d = hamming32(descA.ptr<uint8_t>(i), descB.ptr<uint8_t>(j));
		if (d < distA[i])
		{
			secondA[i] = distA[i];
			distA[i] = d;
			bestA[i] = j;
		}
		else if (d < secondA[i])
			secondA[i] = d;
		if (d < distB[j] || (d == distB[j] && i < bestB[j]))
		{
			distB[j] = d;
			bestB[j] = i;
		}
	};
	if (!gated && std::strcmp(matcherKernel(), "avx512") == 0)
	{
#if defined(__x86_64__) && defined(__GNUC__)
		const int padded = (nb + kLanes - 1) / kLanes * kLanes;
		std::vector<uint64_t> w[4];
		for (auto& c : w)
			c.resize(static_cast<std::size_t>(padded), 0);
		for (int j = 0; j < nb; j++)
			for (int k = 0; k < 4; k++)
				std::memcpy(&w[k][static_cast<std::size_t>(j)], descB.ptr<uint8_t>(j) + 8 * k, 8);
		std::vector<int> penalty(static_cast<std::size_t>(padded), 1 << 20), d(penalty.size());
		std::fill(penalty.begin(), penalty.begin() + nb, 0);
		bestB.resize(penalty.size(), -1);
		distB.resize(penalty.size(), kInf);
		allPairsAvx512(descA, w, penalty.data(), padded, d.data(), bestA.data(), distA.data(),
		               secondA.data(), bestB.data(), distB.data());
#endif
	}
	else if (!gated)
	{
		for (int i = 0; i < na; i++)
			for (int j = 0; j < nb; j++)
				consider(i, j);
	}
	else
	{
		// Bucket B by (x, y) into cells one gate wide: a gated pair lies in neighbouring cells.
		const float cell = p.gateRadius_m;
		auto key = [&](float x, float y)
		{
			return std::make_pair(static_cast<int>(std::floor(x / cell)),
			                      static_cast<int>(std::floor(y / cell)));
		};
		std::map<std::pair<int, int>, std::vector<int>> grid;
		for (int j = 0; j < nb; j++)
			grid[key((*posB)[j].x(), (*posB)[j].y())].push_back(j);
		for (int i = 0; i < na; i++)
		{
			const auto [cx, cy] = key((*posA)[i].x(), (*posA)[i].y());
			for (int dx = -1; dx <= 1; dx++)
				for (int dy = -1; dy <= 1; dy++)
				{
					const auto it = grid.find({cx + dx, cy + dy});
					if (it == grid.end())
						continue;
					for (int j : it->second)
						if (((*posA)[i] - (*posB)[j]).squaredNorm() <= gate2)
							consider(i, j);
				}
		}
	}
	for (int i = 0; i < na; i++)
	{
		const int j = bestA[i];
		if (j < 0 || bestB[j] != i || distA[i] > p.maxDistance)
			continue;
		if (p.ratio < 1.0f && secondA[i] != kInf && distA[i] >= p.ratio * secondA[i])
			continue;
		out.push_back({i, j, distA[i]});
	}
	return out;
}

std::vector<Match> matchMutualGrouped(const cv::Mat& descA, const cv::Mat& descB,
                                      const MatchParams& p, const std::vector<uint32_t>& groupA,
                                      const std::vector<uint32_t>& groupB)
{
	const int na = descA.rows, nb = descB.rows;
	std::vector<Match> out;
	if (na == 0 || nb == 0)
		return out;
	CV_Assert(descA.cols == 32 && descB.cols == 32 && descA.type() == CV_8U &&
	          descB.type() == CV_8U && groupA.size() == static_cast<std::size_t>(na) &&
	          groupB.size() == static_cast<std::size_t>(nb));
	constexpr int kInf = std::numeric_limits<int>::max();
	std::vector<int> bestA(na, -1), distA(na, kInf), secondA(na, kInf);
	std::vector<int> bestB(nb, -1), distB(nb, kInf);
	std::map<uint32_t, std::vector<int>> byGroup;
	for (int j = 0; j < nb; j++)
		byGroup[groupB[static_cast<std::size_t>(j)]].push_back(j);
	for (int i = 0; i < na; i++)
	{
		const auto it = byGroup.find(groupA[static_cast<std::size_t>(i)]);
		if (it == byGroup.end())
			continue;
		for (const int j : it->second)
		{
			const int d = hamming32(descA.ptr<uint8_t>(i), descB.ptr<uint8_t>(j));
			if (d < distA[i])
			{
				secondA[i] = distA[i];
				distA[i] = d;
				bestA[i] = j;
			}
			else if (d < secondA[i])
				secondA[i] = d;
			if (d < distB[j] || (d == distB[j] && i < bestB[j]))
			{
				distB[j] = d;
				bestB[j] = i;
			}
		}
	}
	for (int i = 0; i < na; i++)
	{
		const int j = bestA[i];
		if (j < 0 || bestB[j] != i || distA[i] > p.maxDistance)
			continue;
		if (p.ratio < 1.0f && secondA[i] != kInf && distA[i] >= p.ratio * secondA[i])
			continue;
		out.push_back({i, j, distA[i]});
	}
	return out;
}

}  // namespace rasterslam::features
