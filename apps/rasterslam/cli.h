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

int runCommand(int argc, char** argv);  // `rasterslam run ...`
std::string findDefaultConfig();

}  // namespace rasterslam::cli
