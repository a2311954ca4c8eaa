#include <rasterslam/core/config.h>
#include <yaml-cpp/emitter.h>
#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/exceptions.h>
#include <yaml-cpp/mark.h>
#include <yaml-cpp/node/convert.h>
#include <yaml-cpp/node/impl.h>
#include <yaml-cpp/node/iterator.h>
#include <yaml-cpp/node/node.h>
#include <yaml-cpp/node/parse.h>
#include <yaml-cpp/parser.h>

#include <any>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <sstream>

namespace rasterslam
{
using mrpt::containers::yaml;

namespace
{
/** "source:line:column" of a yaml-cpp mark (0-based there); "source" without one. */
std::string position(const std::string& source, const YAML::Mark& m)
{
	if (m.is_null() || m.line < 0)
		return source;
	return source + ":" + std::to_string(m.line + 1) + ":" + std::to_string(m.column + 1);
}
std::string at(const std::string& source, const YAML::Mark& m)
{
	return position(source, m) + ": ";
}

/** Walks yaml-cpp's parse events: the key path of every node, duplicate keys in a map (which
 *  yaml-cpp accepts, the last one winning in MRPT's yaml), anchors, aliases and merge keys
 *  (MRPT's parser does not support them). Records where each key path is written. */
class StrictHandler : public YAML::EventHandler
{
   public:
	explicit StrictHandler(std::string source) : source_(std::move(source)) {}

	/** First occurrence of each key path ("a.b", "a.list[2].c"). */
	std::map<std::string, YAML::Mark> keys;

	void OnDocumentStart(const YAML::Mark& m) override
	{
		if (++documents_ > 1)
			fail(m, "a second YAML document ('---'): a config file holds one");
	}
	void OnDocumentEnd() override {}
	void OnNull(const YAML::Mark& m, YAML::anchor_t) override { node(m, Kind::Null, ""); }
	void OnAlias(const YAML::Mark& m, YAML::anchor_t) override
	{
		fail(m,
		     "an alias (*name): anchors and aliases are not supported in config files, "
		     "write the values out");
	}
	void OnScalar(const YAML::Mark& m, const std::string&, YAML::anchor_t,
	              const std::string& value) override
	{
		node(m, Kind::Scalar, value);
	}
	void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t,
	                     YAML::EmitterStyle::value style) override
	{
		node(m, Kind::Sequence, "");
		push(false, m, style);
	}
	void OnSequenceEnd() override { stack_.pop_back(); }
	void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t,
	                YAML::EmitterStyle::value style) override
	{
		node(m, Kind::Map, "");
		push(true, m, style);
	}
	void OnMapEnd() override { stack_.pop_back(); }
	void OnAnchor(const YAML::Mark& m, const std::string& name) override
	{
		fail(m, "anchor '&" + name +
		            "': anchors and aliases are not supported in config files, write the "
		            "values out");
	}

	/** The innermost flow collection ({...} or [...]) still open, for syntax errors. */
	std::string openFlow() const
	{
		for (auto it = stack_.rbegin(); it != stack_.rend(); ++it)
			if (it->flow)
				return std::string(" (in the '") + (it->map ? "{" : "[") + "' opened at line " +
				       std::to_string(it->mark.line + 1) + ", column " +
				       std::to_string(it->mark.column + 1) + ")";
		return "";
	}

   private:
	enum class Kind
	{
		Null,
		Scalar,
		Sequence,
		Map
	};
	struct Frame
	{
		bool map = false;
		std::string path;
		YAML::Mark mark;
		bool flow = false;
		bool expectKey = true;
		std::string key;  //!< path of the key whose value comes next
		std::size_t index = 0;
	};

	void push(bool map, const YAML::Mark& m, YAML::EmitterStyle::value style)
	{
		Frame f;
		f.map = map;
		f.path = pendingPath_;
		f.mark = m;
		f.flow = style == YAML::EmitterStyle::Flow;
		stack_.push_back(std::move(f));
	}

	[[noreturn]] void fail(const YAML::Mark& m, const std::string& what) const
	{
		throw ConfigError(at(source_, m) + what);
	}

	/** A node starts: a key of the enclosing map, or a value (whose path is pendingPath_). */
	void node(const YAML::Mark& m, Kind kind, const std::string& value)
	{
		if (stack_.empty())
		{
			pendingPath_.clear();
			return;
		}
		Frame& f = stack_.back();
		if (f.map && f.expectKey)
		{
			const std::string where = f.path.empty() ? "" : " in '" + f.path + "'";
			if (kind == Kind::Null)
				fail(m, "an empty or null key" + where);
			if (kind != Kind::Scalar)
				fail(m, "a list or a map as a key" + where + ": keys must be plain names");
			if (value == "<<")
				fail(m, "merge key '<<'" + where +
				            ": merge keys are not supported in config "
				            "files, write the keys out");
			const std::string path = f.path.empty() ? value : f.path + "." + value;
			const auto [it, inserted] = keys.emplace(path, m);
			if (!inserted)
				fail(m, "duplicate key '" + path + "' (first at line " +
				            std::to_string(it->second.line + 1) + ")");
			f.key = path;
			f.expectKey = false;
			return;
		}
		if (f.map)
		{
			pendingPath_ = f.key;
			f.expectKey = true;
		}
		else
			pendingPath_ = f.path + "[" + std::to_string(f.index++) + "]";
	}

	std::string source_;
	int documents_ = 0;
	std::vector<Frame> stack_;
	std::string pendingPath_;
};

/** Runs the strict check; returns the key positions. */
std::map<std::string, YAML::Mark> checkYaml(const std::string& text, const std::string& source)
{
	StrictHandler h(source);
	std::istringstream in(text);
	try
	{
		YAML::Parser parser(in);
		while (parser.HandleNextDocument(h))
		{
		}
	}
	catch (const YAML::Exception& e)
	{
		// yaml-cpp's messages for a key indented wrongly in a block map name no cause.
		const bool blockMap = e.msg == "end of map not found" || e.msg == "illegal map value";
		throw ConfigError(at(source, e.mark) + "YAML syntax error: " + e.msg + h.openFlow() +
		                  (blockMap && h.openFlow().empty() ? " (check the indentation)" : ""));
	}
	return std::move(h.keys);
}

std::string readFile(const std::string& path)
{
	std::ifstream f(path);
	if (!f)
		throw ConfigError("cannot read config file '" + path + "'");
	std::stringstream ss;
	ss << f.rdbuf();
	return ss.str();
}

/** yaml-cpp's tree as MRPT's: scalars as strings, "~"/"null"/nothing as null nodes, marks
 *  kept. The same tree MRPT's own parser (libfyaml) gives for valid text, but for comments
 *  (not kept), without that parser's leaks on invalid text (it throws without freeing its
 *  parser and events), and with "key:" a null value where that parser throws. */
yaml::node_t toMrpt(const YAML::Node& n, const std::string& source)
{
	yaml::node_t out;
	const auto m = n.Mark();
	out.marks.input_pos = m.pos < 0 ? 0 : static_cast<std::size_t>(m.pos);
	out.marks.line = m.line;
	out.marks.column = m.column;
	switch (n.Type())
	{
		case YAML::NodeType::Undefined:
		case YAML::NodeType::Null:
			break;
		case YAML::NodeType::Scalar:
			out.d.emplace<yaml::scalar_t>().emplace<std::string>(n.Scalar());
			break;
		case YAML::NodeType::Sequence:
		{
			auto& seq = out.d.emplace<yaml::sequence_t>();
			seq.reserve(n.size());
			for (const auto& e : n)
				seq.push_back(toMrpt(e, source));
			break;
		}
		case YAML::NodeType::Map:
		{
			auto& map = out.d.emplace<yaml::map_t>();
			for (const auto& kv : n)
			{
				if (!kv.first.IsScalar())
					throw ConfigError(at(source, kv.first.Mark()) +
					                  "a map key must be a plain value, not a collection");
				yaml::node_t key(kv.first.Scalar());
				key.marks.line = kv.first.Mark().line;
				key.marks.column = kv.first.Mark().column;
				map[key] = toMrpt(kv.second, source);
			}
			break;
		}
	}
	return out;
}

/** A value for a message: 0.3, -5, 1e-09. */
std::string num(double v)
{
	std::ostringstream os;
	os << std::setprecision(10) << v;
	return os.str();
}
}  // namespace

void checkYamlText(const std::string& text, const std::string& source)
{
	checkYaml(text, source);
}

std::string configLocation(const std::string& file, const std::string& keyPath)
{
	try
	{
		const auto keys = checkYaml(readFile(file), file);
		const auto it = keys.find(keyPath);
		if (it != keys.end())
			return position(file, it->second);
	}
	catch (const std::exception&)
	{
	}
	return file;
}

yaml loadYamlFile(const std::string& path)
{
	const std::string text = readFile(path);
	// Strict first (duplicate keys, anchors and aliases, positions of errors), then the tree.
	checkYamlText(text, path);
	yaml y;
	try
	{
		y = yaml(toMrpt(YAML::Load(text), path));
	}
	catch (const YAML::Exception& e)
	{
		throw ConfigError(at(path, e.mark) + "YAML syntax error: " + e.msg);
	}
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

std::string ParamReader::location(const std::string& key) const
{
	return source_.empty() ? "" : configLocation(source_, context_ + "." + key);
}

void ParamReader::fail(const std::string& key, const std::string& what) const
{
	const auto loc = location(key);
	throw ConfigError((loc.empty() ? "" : loc + ": ") + "key '" + context_ + "." + key +
	                  "': " + what);
}

void ParamReader::reject(const std::string& key, const std::string& what) const
{
	const auto loc = location(key);
	throw ConfigError((loc.empty() ? "" : loc + ": ") + context_ + "." + key + ": " + what);
}

std::optional<std::string> ParamReader::scalar(const std::string& key) const
{
	if (!node_.isMap() || !node_.has(key))
		return std::nullopt;
	const yaml v = node_[key];
	if (v.isNullNode())
		fail(key, "has no value (write one, or leave the key out for the default)");
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

void ParamReader::require(bool ok, double v, const std::string& key,
                          const std::string& expected) const
{
	if (!ok)
		reject(key, expected + ", got " + num(v));
}

void ParamReader::requirePositive(double v, const std::string& key) const
{
	require(v > 0, v, key, "must be > 0");
}

void ParamReader::requireAtLeast(double v, double min, const std::string& key) const
{
	require(v >= min, v, key, "must be >= " + num(min));
}

void ParamReader::requireRange(double v, double lo, double hi, const std::string& key) const
{
	require(v >= lo && v <= hi, v, key, "must be in [" + num(lo) + ", " + num(hi) + "]");
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

namespace
{
void emitNode(YAML::Emitter& out, const mrpt::containers::yaml::node_t& n)
{
	if (n.isNullNode())
		out << YAML::Null;
	else if (n.isMap())
	{
		out << YAML::BeginMap;
		for (const auto& [k, v] : n.asMap())
		{
			out << YAML::Key;
			emitNode(out, k);
			out << YAML::Value;
			emitNode(out, v);
		}
		out << YAML::EndMap;
	}
	else if (n.isSequence())
	{
		out << YAML::BeginSeq;
		for (const auto& v : n.asSequence())
			emitNode(out, v);
		out << YAML::EndSeq;
	}
	else
	{
		const std::any& a = n.asScalar();
		if (const auto* b = std::any_cast<bool>(&a))
			out << *b;
		else if (const auto* d = std::any_cast<double>(&a))
			out << *d;
		else if (const auto* f = std::any_cast<float>(&a))
			out << *f;
		else if (const auto* i = std::any_cast<int>(&a))
			out << *i;
		else if (const auto* u = std::any_cast<unsigned>(&a))
			out << *u;
		else if (const auto* l = std::any_cast<long>(&a))
			out << *l;
		else if (const auto* ul = std::any_cast<unsigned long>(&a))
			out << *ul;
		else if (const auto* ll = std::any_cast<long long>(&a))
			out << *ll;
		else if (const auto* ull = std::any_cast<unsigned long long>(&a))
			out << *ull;
		else
			out << std::string(n.internalAsStr());  // strings (quoted where YAML needs it)
	}
}
}  // namespace

std::string emitYaml(const mrpt::containers::yaml& doc)
{
	YAML::Emitter out;
	out.SetDoublePrecision(17);
	out.SetFloatPrecision(9);
	emitNode(out, doc.node());
	if (!out.good())
		throw std::runtime_error("cannot write YAML: " + out.GetLastError());
	return std::string(out.c_str()) + "\n";
}

}  // namespace rasterslam
