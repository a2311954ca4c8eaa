// rasterslam: the command line of the SLAM pipeline.
#include <mrpt/system/os.h>
#include <rasterslam/core/heap.h>
#include <rasterslam/core/plugin_loader.h>

#include <cstdio>
#include <iostream>

#include "cli.h"

using namespace rasterslam;

namespace
{
const char* kDescription =
    "rasterslam: lifelong 3D-LiDAR SLAM on rasterized elevation images. MRPT rawlogs in; "
    "trajectories, loops, timings and lifelong maps out. Each command's --help lists its "
    "options, e.g. rasterslam run --help.";

const char* kFooter =
    "Plugins are searched in $RASTERSLAM_PLUGIN_PATH (colon-separated), <bin>/../lib/rasterslam/\n"
    "plugins, the build tree and the install prefix; docs/plugins.md explains how to write one.\n";

int listPlugins()
{
	auto& loader = PluginLoader::instance();
	try
	{
		loader.load();
	}
	catch (const std::exception& e)
	{
		std::cerr << "rasterslam: " << e.what() << "\n";
		return cli::kExitError;
	}
	std::printf("plugin search path:\n");
	for (const auto& d : loader.searchPath())
		std::printf("  %s\n", d.c_str());
	const auto classes = loader.registeredClasses();
	std::printf("%zu plugin classes from %zu modules:\n", classes.size(),
	            loader.loadedModules().size());
	std::printf("  %-14s %-32s %s\n", "ROLE", "CLASS", "MODULE");
	for (const auto& c : classes)
		std::printf("  %-14s %-32s %s\n", c.role.c_str(), c.className.c_str(), c.module.c_str());
	for (const auto& f : loader.failedModules())
		std::printf("not loaded: %s\n", f.c_str());
	return loader.failedModules().empty() ? 0 : cli::kExitError;
}
}  // namespace

int main(int argc, char** argv)
{
	// Before anything is allocated: scans' blocks stay in the heap (see heap.h).
	rasterslam::keepScanBlocksInHeap();
	CLI::App app(kDescription, "rasterslam");
	cli::configure(app, mrpt::system::MRPT_getVersion());
	app.footer(std::string(kFooter) + cli::exitCodesFooter());
	app.require_subcommand(1);

	std::vector<cli::Command> commands{cli::addRunCommand(app), cli::addRelocalizeCommand(app),
	                                   cli::addExportCommand(app)};
	for (auto& c : cli::addMapCommands(app))
		commands.push_back(std::move(c));
	auto* list = cli::subcommand(app, "list-plugins", "list the plugin classes found and where");
	commands.push_back({list, listPlugins});

	if (const int rc = cli::parse(app, argc, argv); rc >= 0)
		return rc;
	for (const auto& c : commands)
		if (c.app->parsed())
			return c.run();
	cli::usageError("rasterslam", "no command given");
}
