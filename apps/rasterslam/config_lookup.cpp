// Where `rasterslam` finds its configs: a path, or the name of one shipped in share/.
#include <algorithm>
#include <filesystem>
#include <stdexcept>

#include "cli.h"

namespace fs = std::filesystem;

namespace rasterslam::cli
{
namespace
{
std::vector<fs::path> shareDirs()
{
	std::vector<fs::path> dirs;
	if (const char* env = std::getenv("RASTERSLAM_SHARE_DIR"))
		dirs.emplace_back(env);
	std::error_code ec;
	const auto exe = fs::read_symlink("/proc/self/exe", ec);
	if (!ec)
		dirs.push_back(exe.parent_path() / ".." / "share" / "rasterslam");
	dirs.emplace_back(RASTERSLAM_SOURCE_SHARE_DIR);
	dirs.emplace_back(RASTERSLAM_INSTALL_SHARE_DIR);
	return dirs;
}
}  // namespace

std::string findConfig(const std::string& file)
{
	std::error_code ec;
	for (const auto& d : shareDirs())
		if (fs::is_regular_file(d / "config" / file, ec))
			return (d / "config" / file).lexically_normal().string();
	throw std::runtime_error("no shipped config " + file +
	                         " (share/rasterslam/config/); give --config FILE");
}

std::vector<std::string> shippedConfigs()
{
	std::error_code ec;
	for (const auto& d : shareDirs())
	{
		std::vector<std::string> names;
		for (const auto& e : fs::directory_iterator(d / "config", ec))
			if (e.path().extension() == ".yaml")
				names.push_back(e.path().stem().string());
		if (!names.empty())
		{
			std::sort(names.begin(), names.end());
			return names;
		}
	}
	return {};
}

std::string resolveConfig(const std::string& arg, const std::string& fallback)
{
	if (arg.empty())
		return findConfig(fallback + ".yaml");
	std::error_code ec;
	if (fs::is_regular_file(arg, ec))
		return arg;
	if (arg.find('/') == std::string::npos)
	{
		const std::string file =
		    arg.size() > 5 && arg.substr(arg.size() - 5) == ".yaml" ? arg : arg + ".yaml";
		const auto names = shippedConfigs();
		const std::string stem = file.substr(0, file.size() - 5);
		if (std::find(names.begin(), names.end(), stem) != names.end())
			return findConfig(file);
	}
	std::string names;
	for (const auto& n : shippedConfigs())
		names += (names.empty() ? "" : ", ") + n;
	if (fs::exists(arg, ec))
		throw std::runtime_error("--config " + arg + ": not a regular file");
	throw std::runtime_error("--config " + arg + ": no such file, nor a shipped config (" + names +
	                         ")");
}

std::string configHelp(const std::string& fallback)
{
	std::string names;
	for (const auto& n : shippedConfigs())
		names += (names.empty() ? "" : ", ") + n;
	return "YAML pipeline config: a file, or a shipped config's name (" + names +
	       "); default: " + fallback;
}

}  // namespace rasterslam::cli
