#include <rasterslam/features/orb_extractor.h>

#include <algorithm>
#include <climits>

namespace rasterslam::features
{
OrbExtractor::OrbExtractor(const OrbParams& p) : p_(p)
{
	// Three times the features kept are detected, for the grid to choose from (in 64 bits: a
	// config may ask for any count; OpenCV takes an int).
	const int detect =
	    static_cast<int>(std::min<long long>(3LL * std::max(p_.numFeatures, 1), INT_MAX));
	orb_ = cv::ORB::create(detect, p_.scaleFactor, p_.levels, p_.edgeThreshold, 0, 2,
	                       cv::ORB::HARRIS_SCORE, p_.patchSize, p_.fastThreshold);
}

std::vector<cv::KeyPoint> distributeOverGrid(const std::vector<cv::KeyPoint>& kps, int width,
                                             int height, int cols, int rows, int n)
{
	if (static_cast<int>(kps.size()) <= n)
		return kps;
	const int cells = cols * rows;
	std::vector<std::vector<int>> byCell(cells);
	for (int i = 0; i < static_cast<int>(kps.size()); i++)
	{
		const int c = std::clamp(static_cast<int>(kps[i].pt.x * cols / width), 0, cols - 1);
		const int r = std::clamp(static_cast<int>(kps[i].pt.y * rows / height), 0, rows - 1);
		byCell[r * cols + c].push_back(i);
	}
	auto stronger = [&](int a, int b)
	{ return kps[a].response != kps[b].response ? kps[a].response > kps[b].response : a < b; };
	const int share = std::max(1, n / cells);
	std::vector<char> taken(kps.size(), 0);
	std::vector<cv::KeyPoint> out;
	out.reserve(n);
	for (auto& cell : byCell)
	{
		std::sort(cell.begin(), cell.end(), stronger);
		for (int k = 0; k < std::min<int>(share, cell.size()); k++)
		{
			out.push_back(kps[cell[k]]);
			taken[cell[k]] = 1;
		}
	}
	if (static_cast<int>(out.size()) < n)
	{
		std::vector<int> rest;
		for (int i = 0; i < static_cast<int>(kps.size()); i++)
			if (!taken[i])
				rest.push_back(i);
		std::sort(rest.begin(), rest.end(), stronger);
		for (int i : rest)
		{
			if (static_cast<int>(out.size()) >= n)
				break;
			out.push_back(kps[i]);
		}
	}
	return out;
}

void OrbExtractor::extract(const cv::Mat& image, std::vector<cv::KeyPoint>& keypoints,
                           cv::Mat& descriptors)
{
	// No more corners than pixels (OpenCV sizes its buffers by the count asked for).
	const long long pixels = static_cast<long long>(image.rows) * image.cols;
	orb_->setMaxFeatures(static_cast<int>(
	    std::max(1LL, std::min({3LL * std::max(p_.numFeatures, 1), pixels, 1LL * INT_MAX}))));
	int thr = p_.fastThreshold;
	std::vector<cv::KeyPoint> kps;
	for (;;)
	{
		orb_->setFastThreshold(thr);
		kps.clear();
		orb_->detect(image, kps);
		if (static_cast<int>(kps.size()) >= p_.numFeatures || thr <= p_.minFastThreshold)
			break;
		thr = std::max(p_.minFastThreshold, thr / 2);
	}
	lastThreshold_ = thr;
	keypoints =
	    distributeOverGrid(kps, image.cols, image.rows, p_.gridCols, p_.gridRows, p_.numFeatures);
	orb_->compute(image, keypoints, descriptors);
}

}  // namespace rasterslam::features
