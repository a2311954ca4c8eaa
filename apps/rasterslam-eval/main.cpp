// rasterslam-eval: accuracy and cost metrics of SLAM outputs. Subcommands: traj, loops,
// localmaps, timings.
#include "cli.h"

using namespace rasterslam_eval_cli;

namespace
{
struct Command
{
	const char* name;
	const char* summary;
	std::function<int(int, char**)> run;
};

// Add subcommands here.
const std::vector<Command>& commands()
{
	static const std::vector<Command> cmds = {
	    {"traj", "trajectory errors: ATE, per-frame RPE, KITTI devkit relative errors", runTraj},
	    {"loops", "loop closure: precision/recall against ground truth, PR sweep and plot",
	     runLoops},
	    {"localmaps", "relative errors between the keyframes of each local map of a saved map",
	     runLocalMaps},
	    {"timings", "cost per scan and memory of runs from their timings.csv, and a plot",
	     runTimings},
	};
	return cmds;
}

void printUsage(std::ostream& os)
{
	os << "Usage: rasterslam-eval <command> [options]\n\nCommands:\n";
	std::size_t width = 0;
	for (const auto& c : commands())
		width = std::max(width, std::strlen(c.name));
	for (const auto& c : commands())
		os << "  " << std::left << std::setw(static_cast<int>(width + 4)) << c.name << c.summary
		   << "\n";
	os << "\nrasterslam-eval <command> --help shows the options of a command.\n";
}
}  // namespace

int main(int argc, char** argv)
{
	if (argc < 2)
	{
		printUsage(std::cerr);
		return 2;
	}
	const std::string cmd = argv[1];
	if (cmd == "--help" || cmd == "-h" || cmd == "help")
	{
		printUsage(std::cout);
		return 0;
	}
	for (const auto& c : commands())
	{
		if (cmd != c.name)
			continue;
		try
		{
			return c.run(argc - 2, argv + 2);
		}
		catch (const UsageError& e)
		{
			std::cerr << "rasterslam-eval " << cmd << ": " << e.what() << "\n"
			          << "(rasterslam-eval " << cmd << " --help for the options)\n";
			return 2;
		}
		catch (const std::exception& e)
		{
			std::cerr << "rasterslam-eval " << cmd << ": error: " << e.what() << "\n";
			return 1;
		}
	}
	std::cerr << "rasterslam-eval: unknown command '" << cmd << "'\n";
	printUsage(std::cerr);
	return 2;
}
