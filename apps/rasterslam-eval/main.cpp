// rasterslam-eval: accuracy and cost metrics of SLAM outputs. Subcommands: traj, loops,
// localmaps, timings, reloc, scene.
#include "cli.h"

using namespace rasterslam_eval_cli;

int main(int argc, char** argv)
{
	CLI::App app("Accuracy and cost metrics of SLAM outputs.", "rasterslam-eval");
	cli::configure(app);
	app.require_subcommand(1);
	// Add subcommands here.
	const std::vector<Command> commands = {addTraj(app),    addLoops(app), addLocalMaps(app),
	                                       addTimings(app), addReloc(app), addScene(app)};
	app.footer(std::string("rasterslam-eval COMMAND --help shows the options of a command.\n\n") +
	           cli::exitCodesFooter());

	if (argc >= 2)
	{
		const std::string first = argv[1];
		if (first == "help")
		{
			std::cout << app.help();
			return cli::kExitOk;
		}
		// CLI11 would only say that a subcommand is required.
		bool known = false;
		for (const auto& c : commands)
			known = known || c.app->get_name() == first;
		if (!known && first.rfind('-', 0) != 0)
			cli::usageError("rasterslam-eval", "unknown command '" + first + "'");
	}
	if (const int code = cli::parse(app, argc, argv); code >= 0)
		return code;

	for (const auto& c : commands)
	{
		if (!c.app->parsed())
			continue;
		try
		{
			return c.run();
		}
		catch (const std::exception& e)
		{
			std::cerr << "rasterslam-eval " << c.app->get_name() << ": error: " << e.what() << "\n";
			return cli::kExitError;
		}
	}
	return cli::kExitUsage;  // not reached: require_subcommand(1)
}
