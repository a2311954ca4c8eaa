#include <rasterslam/io/kitti.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

namespace fs = std::filesystem;

namespace rasterslam::io
{
std::vector<PointXYZI> loadKittiBin(const std::string& path)
{
	std::ifstream f(path, std::ios::binary | std::ios::ate);
	if (!f)
		throw std::runtime_error("cannot read KITTI scan '" + path + "'");
	const auto size = static_cast<std::size_t>(f.tellg());
	if (size % (4 * sizeof(float)) != 0)
		throw std::runtime_error(
		    "KITTI scan '" + path + "': size " + std::to_string(size) +
		    " bytes is not a multiple of 16 (x y z intensity float32 records)");
	std::vector<PointXYZI> pts(size / (4 * sizeof(float)));
	static_assert(sizeof(PointXYZI) == 4 * sizeof(float), "PointXYZI must be 4 packed floats");
	f.seekg(0);
	if (!f.read(reinterpret_cast<char*>(pts.data()), static_cast<std::streamsize>(size)))
		throw std::runtime_error("KITTI scan '" + path + "': read error");
	return pts;
}

std::vector<std::string> listKittiBins(const std::string& dir)
{
	std::error_code ec;
	if (!fs::is_directory(dir, ec))
		throw std::runtime_error("KITTI velodyne folder '" + dir + "' does not exist");
	std::vector<std::string> files;
	for (const auto& e : fs::directory_iterator(dir, ec))
		if (e.path().extension() == ".bin")
			files.push_back(e.path().string());
	if (files.empty())
		throw std::runtime_error("KITTI velodyne folder '" + dir + "' has no .bin files");
	std::sort(files.begin(), files.end());
	return files;
}

}  // namespace rasterslam::io
