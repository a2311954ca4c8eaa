// Shared by the subcommands of rasterslam-eval: option parsing and JSON text.
#pragma once

#include <rasterslam/eval/loop_metrics.h>
#include <rasterslam/eval/trajectory_metrics.h>
#include <rasterslam/io/trajectory_io.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace rasterslam_eval_cli
{
namespace io = rasterslam::io;
namespace eval = rasterslam::eval;

/** Bad command line: exit code 2 (bad input files give 1). */
struct UsageError : std::runtime_error
{
	using std::runtime_error::runtime_error;
};

/** "--key value" and "--key=value" options; flags take no value. */
class Options
{
   public:
	Options(int argc, char** argv, const std::vector<std::string>& valued,
	        const std::vector<std::string>& flags)
	{
		for (int i = 0; i < argc; ++i)
		{
			std::string a = argv[i];
			std::string value;
			bool hasValue = false;
			if (const auto eq = a.find('='); a.rfind("--", 0) == 0 && eq != std::string::npos)
			{
				value = a.substr(eq + 1);
				a = a.substr(0, eq);
				hasValue = true;
			}
			if (contains(flags, a) && !hasValue)
				flags_.push_back(a);
			else if (contains(valued, a))
			{
				if (!hasValue)
				{
					if (i + 1 >= argc)
						throw UsageError("option " + a + " needs a value");
					value = argv[++i];
				}
				values_[a] = value;
			}
			else
				throw UsageError("unknown option '" + std::string(argv[i]) + "'");
		}
	}
	bool flag(const std::string& k) const { return contains(flags_, k); }
	bool has(const std::string& k) const { return values_.count(k) > 0; }
	std::string get(const std::string& k, const std::string& def = "") const
	{
		const auto it = values_.find(k);
		return it == values_.end() ? def : it->second;
	}
	std::string require(const std::string& k) const
	{
		if (!has(k))
			throw UsageError("missing required option " + k);
		return get(k);
	}
	double number(const std::string& k, double def) const
	{
		if (!has(k))
			return def;
		const std::string s = get(k);
		char* end = nullptr;
		const double v = std::strtod(s.c_str(), &end);
		if (s.empty() || *end != '\0' || !std::isfinite(v) || v < 0)
			throw UsageError("option " + k + ": expected a non-negative number, got '" + s + "'");
		return v;
	}

   private:
	static bool contains(const std::vector<std::string>& v, const std::string& s)
	{
		for (const auto& x : v)
		{
			if (x == s)
				return true;
		}
		return false;
	}
	std::map<std::string, std::string> values_;
	std::vector<std::string> flags_;
};

inline std::string jsonNumber(double v, bool valid = true)
{
	if (!valid || !std::isfinite(v))
		return "null";
	char buf[64];
	std::snprintf(buf, sizeof(buf), "%.9g", v);
	return buf;
}

inline std::string jsonString(const std::string& s)
{
	std::string out = "\"";
	for (const char c : s)
	{
		if (c == '"' || c == '\\')
			out += std::string("\\") + c;
		else if (static_cast<unsigned char>(c) < 0x20)
		{
			char buf[8];
			std::snprintf(buf, sizeof(buf), "\\u%04x", c);
			out += buf;
		}
		else
			out += c;
	}
	return out + "\"";
}

int runTraj(int argc, char** argv);
int runLoops(int argc, char** argv);
int runLocalMaps(int argc, char** argv);
int runTimings(int argc, char** argv);

}  // namespace rasterslam_eval_cli
