// The command-line conventions every rasterslam program follows, on CLI11:
//  - `-h`/`--help` prints the program's (or the subcommand's) options and exits 0;
//  - `--version` prints "PROGRAM VERSION" and exits 0;
//  - a usage error prints "PROGRAM: what is wrong" and "(see PROGRAM --help)" on stderr and
//    exits 2; bad input or a failure while running exits 1.
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#ifndef RASTERSLAM_VERSION
#define RASTERSLAM_VERSION "unknown"
#endif

namespace rasterslam::cli
{
/** 0 success; 1 bad input or a failure while running (outputs written for what was
 *  processed, when possible); 2 wrong command-line usage. */
constexpr int kExitOk = 0, kExitError = 1, kExitUsage = 2;

/** Greedy word wrap at `width` columns; existing line breaks are kept. */
inline std::string wrap(const std::string& text, std::size_t width)
{
	std::string out, line, word;
	auto flushWord = [&]
	{
		if (word.empty())
			return;
		if (!line.empty() && line.size() + 1 + word.size() > width)
		{
			out += line + "\n";
			line.clear();
		}
		line += (line.empty() ? "" : " ") + word;
		word.clear();
	};
	for (const char c : text)
	{
		if (c == ' ')
			flushWord();
		else if (c == '\n')
		{
			flushWord();
			out += line + "\n";
			line.clear();
		}
		else
			word += c;
	}
	flushWord();
	return out + line;
}

/** CLI11's formatter with descriptions, footers and the subcommand list wrapped at 100
 *  columns (CLI11 2.1 does not wrap). */
class Formatter : public CLI::Formatter
{
   public:
	static constexpr std::size_t kWidth = 100;
	std::string make_option_desc(const CLI::Option* opt) const override
	{
		return wrap(CLI::Formatter::make_option_desc(opt), kWidth - get_column_width());
	}
	std::string make_subcommand(const CLI::App* sub) const override
	{
		std::stringstream out;
		CLI::detail::format_help(out, sub->get_display_name(true),
		                         wrap(sub->get_description(), kWidth - get_column_width()),
		                         get_column_width());
		return out.str();
	}
	std::string make_description(const CLI::App* app) const override
	{
		return wrap(CLI::Formatter::make_description(app), kWidth);
	}
	std::string make_footer(const CLI::App* app) const override
	{
		const std::string f = app->get_footer();
		return f.empty() ? std::string() : wrap(f, kWidth) + "\n";
	}
};

inline const char* exitCodesFooter()
{
	return "Exit codes: 0 success; 1 bad input or run failure (outputs are still written for what "
	       "was processed); 2 usage error.";
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
	app.formatter(std::make_shared<Formatter>());
	app.get_formatter()->column_width(34);
	app.footer(exitCodesFooter());
}

/** A validator without the type note CLI11 prints after the option's name ("R:POSITIVE"). */
inline CLI::Validator unnamed(CLI::Validator v)
{
	v.description("");
	return v;
}

/** Which ends of numberIn()'s interval belong to it. */
enum class Ends
{
	Closed,  //!< [lo, hi]
	Open     //!< (lo, hi)
};

/** A number's text in a message: up to 6 significant digits ("10", "0.205", "inf"). */
inline std::string numberWord(double v)
{
	char buf[32];
	std::snprintf(buf, sizeof(buf), "%.6g", v);
	return buf;
}

/** A CLI11 check: the whole text is one finite number (strtod's syntax; not NaN, not inf)
 *  in the interval from lo to hi, whose ends `ends` says; hi may be infinite (no upper
 *  bound). The message names `what` and the interval: "expects a height in metres in (0, 10),
 *  got '0'", "expects a number >= 0, got '-1'". Failures are usage errors (exit 2). */
inline CLI::Validator numberIn(double lo, double hi, const std::string& what,
                               Ends ends = Ends::Closed)
{
	const bool open = ends == Ends::Open;
	const std::string interval = std::isinf(hi)
	                                 ? std::string(open ? " > " : " >= ") + numberWord(lo)
	                                 : std::string(open ? " in (" : " in [") + numberWord(lo) +
	                                       ", " + numberWord(hi) + (open ? ")" : "]");
	return CLI::Validator(
	    [=](std::string& v) -> std::string
	    {
		    char* end = nullptr;
		    const double x = std::strtod(v.c_str(), &end);
		    const bool number = !v.empty() && end == v.c_str() + v.size() && std::isfinite(x);
		    const bool inside = open ? x > lo && x < hi : x >= lo && x <= hi;
		    return number && inside ? std::string()
		                            : "expects " + what + interval + ", got '" + v + "'";
	    },
	    "");
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
	// CLI11 2.1 converts with base 0, which reads 010 as octal: leading zeros go first.
	const CLI::Validator decimal(
	    [](std::string& v) -> std::string
	    {
		    const auto nz = v.find_first_not_of('0');
		    v = nz == std::string::npos ? std::string("0") : v.substr(nz);
		    return std::string();
	    },
	    "");
	return app.add_option(name, value, description)
	    ->check(wholeNumber)
	    ->transform(decimal)
	    ->type_name("N");
}

/** A subcommand with the same look (its own --help and the exit codes; the parent's
 *  --version). `description` is one line (the parent's list of subcommands shows it);
 *  `details`, when given, is printed below the options. */
inline CLI::App* subcommand(CLI::App& app, const std::string& name, const std::string& description,
                            const std::string& details = "")
{
	CLI::App* sub = app.add_subcommand(name, description);
	sub->set_help_flag("-h,--help", "print this help and exit");
	sub->footer(details.empty() ? std::string(exitCodesFooter())
	                            : details + "\n\n" + exitCodesFooter());
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

/** Caps the process's data memory (heap and private writable mappings: RLIMIT_DATA), so that
 *  a damaged count or size in an input file makes its allocation fail (std::bad_alloc, which
 *  the readers report naming the file and the offset) instead of taking the machine's memory.
 *  The cap is a quarter of the physical memory (at least 2 GB), or $RASTERSLAM_MAX_MEMORY_MB
 *  (0: none); apps/common/mrpt_aligned_malloc.cpp makes MRPT's allocations honour it with a
 *  std::bad_alloc too. Returns it in
 *  MB (0: none set). A malformed variable is a usage error. */
inline double capMemory(const std::string& program)
{
#if defined(__SANITIZE_ADDRESS__)
	(void)program;
	return 0;  // AddressSanitizer reserves terabytes of address space: no cap under it
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
	(void)program;
	return 0;
#endif
#endif
	const double physicalMb = static_cast<double>(::sysconf(_SC_PHYS_PAGES)) *
	                          static_cast<double>(::sysconf(_SC_PAGE_SIZE)) / (1024.0 * 1024.0);
	double mb = std::max(2048.0, physicalMb / 4);
	if (const char* env = std::getenv("RASTERSLAM_MAX_MEMORY_MB"))
	{
		char* end = nullptr;
		mb = std::strtod(env, &end);
		if (end == env || *end != '\0' || !(mb >= 0) || mb > 1e9)
		{
			std::cerr << program << ": RASTERSLAM_MAX_MEMORY_MB='" << env
			          << "': expected megabytes >= 0 (0: no cap)\n";
			std::exit(kExitUsage);
		}
	}
	if (!(mb > 0))
		return 0;
	rlimit lim{};
	if (::getrlimit(RLIMIT_DATA, &lim) != 0)
		return 0;
	const auto bytes = static_cast<rlim_t>(mb * 1024.0 * 1024.0);
	if (lim.rlim_max != RLIM_INFINITY && bytes > lim.rlim_max)
		return static_cast<double>(lim.rlim_cur) / (1024.0 * 1024.0);  // a lower cap is set
	lim.rlim_cur = bytes;
	if (::setrlimit(RLIMIT_DATA, &lim) != 0)
		return 0;
	return mb;
}

/** Prints a usage error in the project's form and exits 2. */
[[noreturn]] inline void usageError(const std::string& command, const std::string& message)
{
	std::cerr << command << ": " << message << "\n(see " << command << " --help)\n";
	std::exit(kExitUsage);
}

/** Parses the command line. Returns -1 when the program should go on (its memory then capped,
 *  see capMemory()); otherwise the exit code to return at once: 0 after --help or --version, 2
 *  after a usage error (message printed). */
inline int parse(CLI::App& app, int argc, char** argv)
{
	// A word where a subcommand is expected must be one: CLI11 would only say that a
	// subcommand is required.
	CLI::App* cur = &app;
	std::string path = app.get_name();
	for (int i = 1; i < argc; i++)
	{
		const auto subs = cur->get_subcommands([](CLI::App*) { return true; });
		const std::string arg = argv[i];
		if (subs.empty() || arg.empty() || arg[0] == '-')
			break;
		CLI::App* next = nullptr;
		for (auto* s : subs)
			if (s->check_name(arg))
				next = s;
		if (!next)
		{
			std::string names;
			for (const auto* s : subs)
				names += (names.empty() ? "" : ", ") + s->get_name();
			std::cerr << path << ": unknown command '" << arg << "' (" << names << ")\n(see "
			          << path << " --help)\n";
			return kExitUsage;
		}
		cur = next;
		path += " " + arg;
	}
	try
	{
		app.parse(argc, argv);
		capMemory(app.get_name());
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
	catch (const CLI::ValidationError& e)
	{
		// A named input that is not there is bad input (exit 1), as when a program finds it
		// missing itself; other invalid values are usage errors.
		const std::string cmd = commandPath(app), what = e.what();
		const bool missing = what.find("File does not exist: ") != std::string::npos ||
		                     what.find("Directory does not exist: ") != std::string::npos ||
		                     what.find("Path does not exist: ") != std::string::npos;
		if (missing)
		{
			std::cerr << cmd << ": error: " << what << "\n";
			return kExitError;
		}
		std::cerr << cmd << ": " << what << "\n(see " << cmd << " --help)\n";
		return kExitUsage;
	}
	catch (const CLI::ParseError& e)
	{
		const std::string cmd = commandPath(app);
		std::cerr << cmd << ": " << e.what() << "\n(see " << cmd << " --help)\n";
		return kExitUsage;
	}
}

}  // namespace rasterslam::cli
