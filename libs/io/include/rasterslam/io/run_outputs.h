// The files a run leaves in its output folder.
#pragma once

#include <mrpt/containers/yaml.h>
#include <rasterslam/core/engine.h>
#include <rasterslam/core/pose_conversions.h>

#include <Eigen/Geometry>
#include <string>

namespace rasterslam::io
{
using rasterslam::toIsometry;  // Eigen isometry of an MRPT pose (core/pose_conversions.h)

/** Writes into `dir` (every file through a temporary name and a rename):
 *  - trajectory.tum, trajectory.kitti: one pose per processed scan;
 *  - groundtruth.tum, groundtruth.kitti: when every processed scan had ground truth;
 *  - timings.csv: per-scan stage times (ms), status, inliers, keyframe flag;
 *  - loops.txt: every loop candidate examined, when a loop detector ran;
 *  - pose_graph.graph: the keyframe pose graph in MRPT's text format (opens in MRPT tools);
 *  - run.yaml: `runInfo` as given (config, versions, input, counts, summary). */
void writeRunOutputs(const std::string& dir, const RunResult& res,
                     const mrpt::containers::yaml& runInfo);

/** Checks that `dir` exists or can be created and that a file can be written in it; throws
 *  naming the folder otherwise. */
void ensureWritableDir(const std::string& dir);

}  // namespace rasterslam::io
