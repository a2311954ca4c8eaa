// Configuration: strict, typed access to YAML parameters.
#pragma once

#include <mrpt/containers/yaml.h>

#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace rasterslam
{
/** A problem with a configuration file or key: the message names the file/key and what was
 *  expected. */
class ConfigError : public std::runtime_error
{
   public:
	using std::runtime_error::runtime_error;
};

/** Reads a YAML file whose root must be a map; throws ConfigError naming the file. The text
 *  is checked strictly first (see checkYamlText): syntax errors, duplicate keys, anchors,
 *  aliases and merge keys are errors naming `file:line:column` and the key path. */
mrpt::containers::yaml loadYamlFile(const std::string& path);

/** Checks YAML text strictly (yaml-cpp), without building anything: it must be valid YAML,
 *  one document, with unique keys in every map at any depth, plain scalar keys and no
 *  anchors, aliases or merge keys (`<<`). Throws ConfigError
 *  "source:line:column: what" (line and column 1-based). */
void checkYamlText(const std::string& text, const std::string& source);

/** Where key `keyPath` (dot-separated, e.g. "odometry.params.voxel_m") is written in the
 *  config file `file`: "file:line:column"; just `file` when the file cannot be read or does
 *  not hold that key. For error messages. */
std::string configLocation(const std::string& file, const std::string& keyPath);

/** Typed, strict reader of one parameter block (e.g. `odometry.params`).
 *  Every key read is recorded with the value in force; finish() throws on keys that were
 *  never read (typos do not pass silently). Conversions are strict: "2.5" is not an int,
 *  "abc" is not a double, and the message names `context.key`, the value and the type. */
class ParamReader
{
   public:
	/** `node` may be null/empty (all defaults) or a map. `source` names the file. */
	ParamReader(const mrpt::containers::yaml& node, std::string context, std::string source = "");

	double getDouble(const std::string& key, double def);
	int getInt(const std::string& key, int def);
	bool getBool(const std::string& key, bool def);
	std::string getString(const std::string& key, const std::string& def);
	/** A string that must be one of `allowed`. */
	std::string getChoice(const std::string& key, const std::string& def,
	                      const std::vector<std::string>& allowed);
	std::vector<double> getDoubles(const std::string& key, const std::vector<double>& def);
	/** A file path; a relative one is taken relative to the config file's folder. */
	std::string getPath(const std::string& key, const std::string& def);

	/** Range checks of values already read: each throws ConfigError
	 *  "file:line:column: context.key: must be ..., got v" (the position when the file holds
	 *  the key) unless v > 0, v >= min, or lo <= v <= hi. */
	void requirePositive(double v, const std::string& key) const;
	void requireAtLeast(double v, double min, const std::string& key) const;
	void requireRange(double v, double lo, double hi, const std::string& key) const;
	/** Throws ConfigError "file:line:column: context.key: <expected>, got v" unless `ok`. */
	void require(bool ok, double v, const std::string& key, const std::string& expected) const;
	/** Throws ConfigError "file:line:column: context.key: what" (other checks of a key). */
	[[noreturn]] void reject(const std::string& key, const std::string& what) const;

	/** Throws ConfigError listing keys present in the node that were never read. */
	void finish() const;
	/** Every parameter with the value in force (defaults included). */
	const mrpt::containers::yaml& inForce() const { return inForce_; }
	const std::string& context() const { return context_; }

   private:
	std::optional<std::string> scalar(const std::string& key) const;
	[[noreturn]] void fail(const std::string& key, const std::string& what) const;
	/** "file:line:column" of `context.key` (or "file", or "" without a source). */
	std::string location(const std::string& key) const;

	mrpt::containers::yaml node_;
	std::string context_, source_;
	std::set<std::string> used_;
	mrpt::containers::yaml inForce_ = mrpt::containers::yaml::Map();
};

/** The YAML text of a document, strings quoted where YAML needs it (MRPT's printAsYAML does
 *  not quote them: a value holding ": ", such as an error message, came out unreadable). */
std::string emitYaml(const mrpt::containers::yaml& doc);

}  // namespace rasterslam
