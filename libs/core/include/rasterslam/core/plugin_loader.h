// Finding, loading and instantiating plugin modules.
#pragma once

#include <rasterslam/core/plugin.h>

#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

namespace rasterslam
{
/** A registered plugin class. */
struct PluginClassInfo
{
	std::string className;  //!< e.g. "rasterslam::GicpOdometry"
	std::string role;       //!< e.g. "odometry"
	std::string module;     //!< path of the .so that registered it ("" if built in)
};

/** Loads plugin modules (librasterslam_plugin_*.so) once per process. Search path, in order:
 *  1. the directories of $RASTERSLAM_PLUGIN_PATH (colon-separated),
 *  2. <dir of the running program>/../lib/rasterslam/plugins (a relocated install),
 *  3. the build tree's plugin folder, 4. the install prefix's plugin folder.
 *  A file name found in several directories is loaded from the first where it loads. Loading every
 *  module found, one that fails is reported (failedModules(), stderr) and skipped. Modules are
 *  never unloaded (MRPT's class registry would keep dangling pointers). */
class PluginLoader
{
   public:
	static PluginLoader& instance();

	std::vector<std::string> searchPath() const;

	/** Loads every plugin module found, or, when `only` is non-empty, just those file names
	 *  (e.g. "librasterslam_plugin_gicp.so") or absolute paths. Throws std::runtime_error
	 *  for a named module that is not found or fails to load. Idempotent. */
	void load(const std::vector<std::string>& only = {});

	/** Loads one module by absolute path. Throws with the loader's message on failure, and
	 *  when the module does not carry this build's plugin ABI mark (RASTERSLAM_PLUGIN_ABI):
	 *  its classes are then refused by create(), naming the reason. */
	void loadModule(const std::string& path);

	/** Every registered class deriving from a plugin role. */
	std::vector<PluginClassInfo> registeredClasses() const;

	/** Creates `className`, checks it has the role's base class; throws std::runtime_error
	 *  naming the class, the role and listing the registered classes of that role. */
	Plugin::Ptr create(const std::string& className, const mrpt::rtti::TRuntimeClassId* role) const;

	template <class ROLE>
	std::shared_ptr<ROLE> create(const std::string& className) const
	{
		return std::dynamic_pointer_cast<ROLE>(create(className, CLASS_ID(ROLE)));
	}

	const std::vector<std::string>& loadedModules() const { return loaded_; }
	/** Modules found by load() without a list that failed to load, with the reason. */
	const std::vector<std::string>& failedModules() const { return failed_; }

   private:
	PluginLoader() = default;
	std::vector<std::string> loaded_;  //!< absolute paths, in load order
	std::vector<std::string> failed_;
	std::set<std::string> failedSet_;
	std::map<std::string, std::string> classModule_;  //!< class name -> module
	/** Classes of modules refused (no or another plugin ABI mark) -> why. */
	std::map<std::string, std::string> refused_;
};

/** Role name of a class id ("odometry", ...), or "" if it derives from no role. */
std::string roleOfClass(const mrpt::rtti::TRuntimeClassId* id);

}  // namespace rasterslam
