// The command-line conventions every rasterslam program follows, on CLI11:
//  - `-h`/`--help` prints the program's (or the subcommand's) options and exits 0;
//  - `--version` prints "PROGRAM VERSION" and exits 0;
//  - a usage error prints "PROGRAM: what is wrong" and "(see PROGRAM --help)" on stderr and
//    exits 2; bad input or a failure while running exits 1.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <iostream>
#include <string>

#ifndef RASTERSLAM_VERSION
#define RASTERSLAM_VERSION "unknown"
#endif

namespace rasterslam::cli
{
/** 0 success; 1 bad input or a failure while running (outputs written for what was
 *  processed, when possible); 2 wrong command-line usage. */
constexpr int kExitOk = 0, kExitError = 1, kExitUsage = 2;

inline const char* exitCodesFooter()
{
	return "Exit codes: 0 success; 1 bad input or run failure (outputs are still written for\n"
	       "what was processed); 2 usage error.";
}

/** Gives `app` the project's look: --version, a footer with the exit codes, wide option
 *  column, options may come in any order. `extraVersion` is appended to the version line. */
inline void configure(CLI::App& app, const std::string& extraVersion = "")
{
	std::string version = app.get_name() + " " + RASTERSLAM_VERSION;
	if (!extraVersion.empty())
		version += " (" + extraVersion + ")";
	app.set_help_flag("-h,--help", "print this help and exit");
	app.set_version_flag("--version", version, "print the version and exit");
	app.footer(exitCodesFooter());
	app.get_formatter()->column_width(34);
	app.option_defaults()->always_capture_default();
}

/** An input index such as --first/--last: a whole number >= 0 (negative values are usage
 *  errors rather than wrapping around). */
template <typename T>
CLI::Option* addIndex(CLI::App& app, const std::string& name, T& value,
                      const std::string& description)
{
	const CLI::Validator wholeNumber(
	    [](std::string& v) -> std::string
	    {
		    const bool ok = !v.empty() && v.size() < 19 &&
		                    v.find_first_not_of("0123456789") == std::string::npos;
		    return ok ? std::string() : "expects a whole number >= 0, got '" + v + "'";
	    },
	    "");
	return app.add_option(name, value, description)->check(wholeNumber)->type_name("N");
}

/** A subcommand with the same look (its own --help; the parent's --version). */
inline CLI::App* subcommand(CLI::App& app, const std::string& name, const std::string& description)
{
	CLI::App* sub = app.add_subcommand(name, description);
	sub->set_help_flag("-h,--help", "print this help and exit");
	sub->get_formatter()->column_width(34);
	return sub;
}

/** The full command name of the deepest subcommand parsed: "rasterslam map merge". */
inline std::string commandPath(const CLI::App& app)
{
	std::string path = app.get_name();
	const CLI::App* cur = &app;
	for (;;)
	{
		const auto subs = cur->get_subcommands();
		if (subs.empty())
			break;
		cur = subs.front();
		path += " " + cur->get_name();
	}
	return path;
}

/** Prints a usage error in the project's form and exits 2. */
[[noreturn]] inline void usageError(const std::string& command, const std::string& message)
{
	std::cerr << command << ": " << message << "\n(see " << command << " --help)\n";
	std::exit(kExitUsage);
}

/** Parses the command line. Returns -1 when the program should go on; otherwise the exit code
 *  to return at once: 0 after --help or --version, 2 after a usage error (message printed). */
inline int parse(CLI::App& app, int argc, char** argv)
{
	try
	{
		app.parse(argc, argv);
		return -1;
	}
	catch (const CLI::CallForHelp& e)
	{
		return app.exit(e);
	}
	catch (const CLI::CallForAllHelp& e)
	{
		return app.exit(e);
	}
	catch (const CLI::CallForVersion& e)
	{
		return app.exit(e);
	}
	catch (const CLI::ParseError& e)
	{
		const std::string cmd = commandPath(app);
		std::cerr << cmd << ": " << e.what() << "\n(see " << cmd << " --help)\n";
		return kExitUsage;
	}
}

}  // namespace rasterslam::cli
