// Shared bits of the rasterslam command line (conventions in rasterslam/cli/app.h).
#pragma once

#include <rasterslam/cli/app.h>

#include <functional>
#include <string>
#include <vector>

namespace rasterslam::cli
{
/** A subcommand and what runs it once the command line is parsed. */
struct Command
{
	CLI::App* app = nullptr;
	std::function<int()> run;
};

Command addRunCommand(CLI::App& app);                // `rasterslam run ...`
Command addRelocalizeCommand(CLI::App& app);         // `rasterslam relocalize ...`
std::vector<Command> addMapCommands(CLI::App& app);  // `rasterslam map info|export|merge|prune`
Command addExportCommand(CLI::App& app);             // `rasterslam export ...`

/** share/rasterslam/config/<file> from $RASTERSLAM_SHARE_DIR, the install or the source tree. */
std::string findConfig(const std::string& file);
/** The names of the shipped configs (file names without .yaml), sorted. */
std::vector<std::string> shippedConfigs();
/** What --config names: an existing file, or a shipped config's name (`slam`, `tracking`,
 *  `gicp-baseline`, with or without .yaml). Empty: the shipped `fallback`. Throws naming the
 *  argument and the shipped names when it is neither. */
std::string resolveConfig(const std::string& arg, const std::string& fallback = "slam");
/** Help text of --config. */
std::string configHelp(const std::string& fallback = "slam");

}  // namespace rasterslam::cli
