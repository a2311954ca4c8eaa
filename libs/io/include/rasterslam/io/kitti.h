// KITTI odometry data: velodyne .bin scans.
#pragma once

#include <rasterslam/core/types.h>

#include <string>
#include <vector>

namespace rasterslam::io
{
/** Reads a KITTI velodyne .bin (little-endian float32 x y z intensity records). Throws
 *  naming the file if it cannot be read or its size is not a multiple of 16 bytes. */
std::vector<PointXYZI> loadKittiBin(const std::string& path);

/** The *.bin files of a folder, sorted by name. Throws if the folder has none. */
std::vector<std::string> listKittiBins(const std::string& dir);

}  // namespace rasterslam::io
