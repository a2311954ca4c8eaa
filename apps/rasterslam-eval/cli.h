// Shared by the subcommands of rasterslam-eval: the command line (CLI11 with the project's
// conventions, rasterslam/cli/app.h), option checks and JSON values.
#pragma once

#include <rasterslam/cli/app.h>
#include <rasterslam/eval/loop_metrics.h>
#include <rasterslam/eval/trajectory_metrics.h>
#include <rasterslam/io/trajectory_io.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace rasterslam_eval_cli
{
namespace io = rasterslam::io;
namespace eval = rasterslam::eval;
namespace cli = rasterslam::cli;

/** The JSON the subcommands print: keys in the order they are set. */
using Json = nlohmann::ordered_json;

/** A number in text: up to 9 significant digits, no trailing zeros ("850", "0.02"). */
inline std::string numberText(double v)
{
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.9g", v);
	return buf;
}

/** A JSON number rounded to 9 significant digits (0.005 rather than
 *  0.005000000000000022), or null when the figure is not valid or not finite (NaN, inf). */
inline Json jsonNumber(double v, bool valid = true)
{
	if (!valid || !std::isfinite(v))
		return nullptr;
	return std::strtod(numberText(v).c_str(), nullptr);
}

/** One JSON object on one line. File names that are no valid UTF-8 get U+FFFD rather than
 *  failing the output. */
inline std::string jsonLine(const Json& j)
{
	return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

/** A subcommand: its CLI11 app and what runs it once the command line is parsed. */
struct Command
{
	CLI::App* app = nullptr;
	std::function<int()> run;
};

Command addTraj(CLI::App& app);
Command addLoops(CLI::App& app);
Command addLocalMaps(CLI::App& app);
Command addTimings(CLI::App& app);
Command addReloc(CLI::App& app);
Command addScene(CLI::App& app);

// ---- option checks (CLI11 validators: failures are usage errors, exit 2) ----

/** A finite number >= 0. */
inline CLI::Validator nonNegativeNumber()
{
	return rasterslam::cli::numberIn(0, std::numeric_limits<double>::infinity(), "a number");
}

/** A whole number in [min, max] (digits only: no sign, no exponent). */
inline CLI::Validator wholeNumber(std::uint64_t min, std::uint64_t max)
{
	return CLI::Validator(
	    [min, max](std::string& s) -> std::string
	    {
		    const bool digits = !s.empty() && s.size() < 19 &&
		                        s.find_first_not_of("0123456789") == std::string::npos;
		    const std::uint64_t v = digits ? std::strtoull(s.c_str(), nullptr, 10) : 0;
		    if (!digits || v < min || v > max)
			    return "expected a whole number from " + std::to_string(min) + " to " +
			           std::to_string(max) + ", got '" + s + "'";
		    return {};
	    },
	    "");
}

/** A file name to write: not empty. */
inline CLI::Validator outputFile()
{
	return CLI::Validator(
	    [](std::string& s) -> std::string { return s.empty() ? "empty file name" : ""; }, "");
}

}  // namespace rasterslam_eval_cli
