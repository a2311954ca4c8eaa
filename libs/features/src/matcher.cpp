#include <rasterslam/features/matcher.h>

#include <cmath>
#include <limits>
#include <map>

namespace rasterslam::features
{
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
	if (!gated)
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
