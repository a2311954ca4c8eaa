// Shared bits of the rasterslam command line.
#pragma once

#include <cstdlib>
#include <iostream>
#include <string>

namespace rasterslam::cli
{
/** Exit codes: 0 success; 1 bad input or a failure while running (outputs written for what
 *  was processed, when possible); 2 wrong command-line usage. */
constexpr int kExitError = 1, kExitUsage = 2;

[[noreturn]] inline void usageError(const std::string& msg)
{
	std::cerr << "rasterslam: " << msg << "\n(see rasterslam --help)\n";
	std::exit(kExitUsage);
}

int runCommand(int argc, char** argv);         // `rasterslam run ...`
int relocalizeCommand(int argc, char** argv);  // `rasterslam relocalize ...`
int mapCommand(int argc, char** argv);         // `rasterslam map ...`
std::size_t parseIndexArg(const std::string& opt, const std::string& v);
/** share/rasterslam/config/<name> from the environment, the install or the source tree. */
std::string findConfig(const std::string& name = "default.yaml");
inline std::string findDefaultConfig()
{
	return findConfig("default.yaml");
}

}  // namespace rasterslam::cli
