// Trajectories seen from above: the ground truth and estimates aligned on it, as a PNG.
#pragma once

#include <rasterslam/eval/trajectory_metrics.h>

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace rasterslam::eval
{
/** One estimate to draw: its poses already in the ground truth's frame (T_gt_est applied). */
struct PlottedTrajectory
{
	std::string label;
	std::vector<Eigen::Vector2d> xy;
};

/** The ground truth (black) and the estimates (in colours, legend with their labels) from
 *  above, x to the right and y up at one scale, with a metre grid; the start marked. */
cv::Mat renderTrajectoryPlot(const std::vector<Eigen::Vector2d>& groundTruth,
                             const std::vector<PlottedTrajectory>& estimates,
                             const std::string& title, int width = 900, int height = 800);

/** An estimate's associated poses moved into the ground truth's frame by `T_gt_est`. */
PlottedTrajectory alignedForPlot(const Trajectory& est, const Association& a,
                                 const Eigen::Isometry3d& T_gt_est, const std::string& label);

/** A plot's grid step: 1, 2 or 5 times a power of ten, about `lines` steps over `span`. */
double niceStep(double span, double lines);

/** Writes a PNG under a temporary name and renames it; throws naming the file on failure. */
void writePng(const std::string& path, const cv::Mat& img);

}  // namespace rasterslam::eval
