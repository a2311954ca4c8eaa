// libFuzzer target: an input is a config file (YAML) read by rasterslam::loadYamlFile, then
// given to rasterslam::Engine, whose constructor validates every section and has each plugin
// read and check its parameters (ParamReader). Plugin modules are loaded once per process,
// from $RASTERSLAM_PLUGIN_PATH (set here to the fuzz build's plugin folder when unset).
// With RASTERSLAM_FUZZ_CONFIG_YAML_ONLY=1 only the YAML reading and a ParamReader pass over
// each section are fuzzed (no plugins).
// Errors (exceptions) are expected; crashes, leaks, undefined behaviour, hangs and unbounded
// allocations are findings.
#include <rasterslam/core/config.h>
#include <rasterslam/core/engine.h>
#include <rasterslam/core/plugin_loader.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>

#include "fuzz_common.h"

namespace
{
bool yamlOnly = false;

/** What a section reader does, without plugins: every key as each type, then finish(). */
void readSection(const mrpt::containers::yaml& node, const std::string& name,
                 const std::string& source)
{
	rasterslam::ParamReader p(node, name, source);
	if (!node.isMap())
		return;
	for (const auto& kv : node.asMap())
	{
		const auto key = kv.first.as<std::string>();
		auto attempt = [&](auto&& f)
		{
			try
			{
				f();
			}
			catch (const rasterslam::ConfigError&)
			{
			}
		};
		attempt([&] { (void)p.getDouble(key, 0); });
		attempt([&] { (void)p.getInt(key, 0); });
		attempt([&] { (void)p.getBool(key, false); });
		attempt([&] { (void)p.getString(key, ""); });
		attempt([&] { (void)p.getChoice(key, "a", {"a", "b"}); });
		attempt([&] { (void)p.getDoubles(key, {}); });
		attempt([&] { (void)p.getPath(key, ""); });
		if (node[key].isMap())
			attempt([&] { readSection(node[key], name + "." + key, source); });
	}
	p.finish();
}
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***)
{
	::setenv("RASTERSLAM_PLUGIN_PATH", RASTERSLAM_FUZZ_PLUGIN_DIR, 0);
	const char* only = std::getenv("RASTERSLAM_FUZZ_CONFIG_YAML_ONLY");
	yamlOnly = only && std::string(only) == "1";
	std::filesystem::create_directories(rasterslam::fuzz::scratchDir() + "/config");
	if (!yamlOnly)
	{
		// Every module once, then the classes their registration missed (fuzz_common.h).
		rasterslam::PluginLoader::instance().load();
		rasterslam::fuzz::registerProjectClasses();
	}
	return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size)
{
	const auto path = rasterslam::fuzz::inputFile("config/input.yaml", data, size);
	try
	{
		const auto cfg = rasterslam::loadYamlFile(path);
		if (yamlOnly)
		{
			for (const auto& kv : cfg.asMap())
				readSection(kv.second, kv.first.as<std::string>(), path);
			return 0;
		}
		rasterslam::Engine engine(cfg, path);
		(void)engine.configInForce();
	}
	catch (const std::exception&)
	{
	}
	return 0;
}
