// ORB features spread over the image (paper, "Visual Odometry": 8 scale levels, grid cells,
// an adaptive FAST threshold so that every image yields enough features).
#pragma once

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <vector>

namespace rasterslam::features
{
/** The most features a config may ask of one image (an elevation image has about 250,000
 *  pixels): a bound for the plugins' parameter checks. */
constexpr int kMaxFeatures = 100000;

struct OrbParams
{
	int numFeatures = 2000;          //!< features kept per image
	int gridCols = 8, gridRows = 8;  //!< each cell keeps its share of the strongest
	int fastThreshold = 20;          //!< first FAST threshold tried...
	int minFastThreshold = 5;        //!< ...halved down to this while too few corners are found
	int levels = 3;                  // BEV images are metric: scale barely changes between scans
	float scaleFactor = 1.2f;
	int edgeThreshold = 31;
	int patchSize = 31;
};

class OrbExtractor
{
   public:
	explicit OrbExtractor(const OrbParams& p = {});
	/** Detects and describes; `descriptors` is N x 32 CV_8U, one row a keypoint. */
	void extract(const cv::Mat& image, std::vector<cv::KeyPoint>& keypoints, cv::Mat& descriptors);
	const OrbParams& params() const { return p_; }
	/** FAST threshold used by the last call. */
	int lastThreshold() const { return lastThreshold_; }
	/** FAST detections run so far (one per threshold tried). */
	std::size_t detections() const { return detections_; }
	/** The thresholds an image may be tried at, highest first. */
	const std::vector<int>& thresholds() const { return thresholds_; }

   private:
	OrbParams p_;
	cv::Ptr<cv::ORB> orb_;
	std::vector<int> thresholds_;
	std::size_t hint_ = 0;  //!< the last image's threshold, as an index of thresholds_
	std::size_t detections_ = 0;
	int lastThreshold_ = 0;
};

/** Keeps at most `n` keypoints, each grid cell first taking its share of the strongest, the
 *  remaining places going to the strongest left over. */
std::vector<cv::KeyPoint> distributeOverGrid(const std::vector<cv::KeyPoint>& kps, int width,
                                             int height, int cols, int rows, int n);

}  // namespace rasterslam::features
