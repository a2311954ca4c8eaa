#include <rasterslam/core/config.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace rasterslam
{
using mrpt::containers::yaml;

yaml loadYamlFile(const std::string& path)
{
	std::ifstream f(path);
	if (!f)
		throw ConfigError("cannot read config file '" + path + "'");
	std::stringstream ss;
	ss << f.rdbuf();
	yaml y;
	try
	{
		y = yaml::FromText(ss.str());
	}
	catch (const std::exception& e)
	{
		throw ConfigError("config file '" + path + "' is not valid YAML: " + e.what());
	}
	// MRPT's parser reports some syntax errors on stderr and returns a null node.
	if (!y.isMap())
		throw ConfigError("config file '" + path +
		                  "': expected a YAML map of sections at the top level");
	return y;
}

ParamReader::ParamReader(const yaml& node, std::string context, std::string source)
    : node_(node), context_(std::move(context)), source_(std::move(source))
{
	if (!node_.isNullNode() && !node_.empty() && !node_.isMap())
		throw ConfigError((source_.empty() ? "" : source_ + ": ") + "'" + context_ +
		                  "' must be a map of parameters");
}

void ParamReader::fail(const std::string& key, const std::string& what) const
{
	throw ConfigError((source_.empty() ? "" : source_ + ": ") + "key '" + context_ + "." + key +
	                  "': " + what);
}

std::optional<std::string> ParamReader::scalar(const std::string& key) const
{
	if (!node_.isMap() || !node_.has(key))
		return std::nullopt;
	const yaml v = node_[key];
	if (v.isNullNode())
		return std::nullopt;
	if (!v.isScalar())
		fail(key, "expected a single value, got a list or a map");
	return v.as<std::string>();
}

namespace
{
std::string trim(const std::string& s)
{
	const auto a = s.find_first_not_of(" \t");
	const auto b = s.find_last_not_of(" \t");
	return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
}
bool parseDouble(const std::string& s, double& out)
{
	const std::string t = trim(s);
	if (t.empty())
		return false;
	char* end = nullptr;
	errno = 0;
	out = std::strtod(t.c_str(), &end);
	return errno == 0 && end == t.c_str() + t.size() && std::isfinite(out);
}
}  // namespace

double ParamReader::getDouble(const std::string& key, double def)
{
	used_.insert(key);
	double v = def;
	if (const auto n = scalar(key))
	{
		const auto s = *n;
		if (!parseDouble(s, v))
			fail(key, "expected a number, got '" + s + "'");
	}
	inForce_[key] = v;
	return v;
}

int ParamReader::getInt(const std::string& key, int def)
{
	used_.insert(key);
	int v = def;
	if (const auto n = scalar(key))
	{
		const auto s = trim(*n);
		char* end = nullptr;
		errno = 0;
		const long l = std::strtol(s.c_str(), &end, 10);
		if (s.empty() || errno != 0 || end != s.c_str() + s.size() || l < INT32_MIN ||
		    l > INT32_MAX)
			fail(key, "expected an integer, got '" + s + "'");
		v = static_cast<int>(l);
	}
	inForce_[key] = v;
	return v;
}

bool ParamReader::getBool(const std::string& key, bool def)
{
	used_.insert(key);
	bool v = def;
	if (const auto n = scalar(key))
	{
		const auto s = trim(*n);
		if (s == "true" || s == "True" || s == "yes")
			v = true;
		else if (s == "false" || s == "False" || s == "no")
			v = false;
		else
			fail(key, "expected true or false, got '" + s + "'");
	}
	inForce_[key] = v;
	return v;
}

std::string ParamReader::getString(const std::string& key, const std::string& def)
{
	used_.insert(key);
	std::string v = def;
	if (const auto n = scalar(key))
		v = *n;
	inForce_[key] = v;
	return v;
}

std::string ParamReader::getChoice(const std::string& key, const std::string& def,
                                   const std::vector<std::string>& allowed)
{
	const std::string v = getString(key, def);
	for (const auto& a : allowed)
		if (a == v)
			return v;
	std::string list;
	for (const auto& a : allowed)
		list += (list.empty() ? "" : ", ") + a;
	fail(key, "expected one of {" + list + "}, got '" + v + "'");
}

std::vector<double> ParamReader::getDoubles(const std::string& key, const std::vector<double>& def)
{
	used_.insert(key);
	std::vector<double> v = def;
	if (node_.isMap() && node_.has(key) && !node_[key].isNullNode())
	{
		const yaml n = node_[key];
		if (!n.isSequence())
			fail(key, "expected a list of numbers");
		v.clear();
		for (const auto& e : n.asSequence())
		{
			double d = 0;
			const auto s = e.isScalar() ? e.as<std::string>() : std::string("<non-scalar>");
			if (!parseDouble(s, d))
				fail(key, "expected a list of numbers, got element '" + s + "'");
			v.push_back(d);
		}
	}
	yaml seq = yaml::Sequence();
	for (double d : v)
		seq.push_back(d);
	inForce_[key] = seq;
	return v;
}

std::string ParamReader::getPath(const std::string& key, const std::string& def)
{
	std::string v = getString(key, def);
	if (!v.empty() && !source_.empty() && std::filesystem::path(v).is_relative())
		v = (std::filesystem::path(source_).parent_path() / v).lexically_normal().string();
	inForce_[key] = v;
	return v;
}

void ParamReader::requirePositive(double v, const std::string& key) const
{
	if (!(v > 0))
		throw ConfigError((source_.empty() ? "" : source_ + ": ") + context_ + "." + key +
		                  ": must be > 0, got " + std::to_string(v));
}

void ParamReader::finish() const
{
	if (!node_.isMap())
		return;
	std::string unknown;
	for (const auto& kv : node_.asMap())
	{
		const auto k = kv.first.as<std::string>();
		if (!used_.count(k))
			unknown += (unknown.empty() ? "" : ", ") + k;
	}
	if (unknown.empty())
		return;
	std::string known;
	for (const auto& k : used_)
		known += (known.empty() ? "" : ", ") + k;
	throw ConfigError((source_.empty() ? "" : source_ + ": ") + "unknown key(s) in '" + context_ +
	                  "': " + unknown + " (known: " + known + ")");
}

}  // namespace rasterslam
