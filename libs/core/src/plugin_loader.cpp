#include <dlfcn.h>
#include <mrpt/system/os.h>
#include <rasterslam/core/plugin_loader.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

namespace fs = std::filesystem;

namespace rasterslam
{
namespace
{
constexpr const char* kPrefix = "librasterslam_plugin_";

std::string exeDir()
{
	std::error_code ec;
	const auto p = fs::read_symlink("/proc/self/exe", ec);
	return ec ? std::string() : p.parent_path().string();
}

/** Every registered class by name (a module may register a name again, replacing it). */
std::map<std::string, const mrpt::rtti::TRuntimeClassId*> registeredIds()
{
	std::map<std::string, const mrpt::rtti::TRuntimeClassId*> s;
	for (const auto* c : mrpt::rtti::getAllRegisteredClasses())
		s[c->className] = c;
	return s;
}

/** Why the module loaded as `handle` from `path` cannot be used, or "" when it can: it must
 *  carry its own ABI mark (rasterslam_plugin_abi(), defined by plugin.h in every module that
 *  includes it) of this build's RASTERSLAM_PLUGIN_ABI. A plugin built against other headers
 *  would call the wrong functions of the role classes, and crash or worse. */
std::string abiProblem(void* handle, const std::string& path)
{
	void* sym = handle ? ::dlsym(handle, "rasterslam_plugin_abi") : nullptr;
	Dl_info info{};
	std::error_code ec1, ec2;
	// dlsym searches the module's dependencies too: rasterslam's own libraries carry the mark.
	if (!sym || !::dladdr(sym, &info) || !info.dli_fname ||
	    fs::weakly_canonical(info.dli_fname, ec1) != fs::weakly_canonical(path, ec2))
		return "plugin module '" + path +
		       "' carries no plugin ABI mark: it was built against the headers of a rasterslam "
		       "older than ABI marks, or is not a rasterslam plugin; rebuild it against this "
		       "version's headers (plugin ABI " +
		       std::to_string(RASTERSLAM_PLUGIN_ABI) + ")";
	const int abi = reinterpret_cast<int (*)()>(sym)();
	if (abi != RASTERSLAM_PLUGIN_ABI)
		return "plugin module '" + path + "' was built for plugin ABI " + std::to_string(abi) +
		       " and this rasterslam has plugin ABI " + std::to_string(RASTERSLAM_PLUGIN_ABI) +
		       " (the role classes differ): rebuild it against this version's headers";
	return "";
}

const std::vector<std::pair<const mrpt::rtti::TRuntimeClassId*, std::string>>& roles()
{
	static const std::vector<std::pair<const mrpt::rtti::TRuntimeClassId*, std::string>> r = {
	    {CLASS_ID(Rasterizer), "rasterizer"},
	    {CLASS_ID(Odometry), "odometry"},
	    {CLASS_ID(MapManager), "map_manager"},
	    {CLASS_ID(LoopDetector), "loop_detector"},
	    {CLASS_ID(Optimizer), "optimizer"}};
	return r;
}
}  // namespace

std::string roleOfClass(const mrpt::rtti::TRuntimeClassId* id)
{
	for (const auto& [rid, name] : roles())
		if (id != rid && id->derivedFrom(rid))
			return name;
	return {};
}

PluginLoader& PluginLoader::instance()
{
	static PluginLoader loader;
	return loader;
}

std::vector<std::string> PluginLoader::searchPath() const
{
	std::vector<std::string> dirs;
	if (const char* env = std::getenv("RASTERSLAM_PLUGIN_PATH"))
	{
		std::stringstream ss(env);
		std::string d;
		while (std::getline(ss, d, ':'))
			if (!d.empty())
				dirs.push_back(d);
	}
	const auto exe = exeDir();
	if (!exe.empty())
		dirs.push_back(exe + "/../" RASTERSLAM_PLUGIN_SUBDIR);
	dirs.push_back(RASTERSLAM_BUILD_PLUGIN_DIR);
	dirs.push_back(RASTERSLAM_INSTALL_PLUGIN_DIR);
	// Remove duplicates (same folder reached by two routes), keeping the first.
	std::vector<std::string> out;
	std::set<std::string> seen;
	for (const auto& d : dirs)
	{
		std::error_code ec;
		const auto canon = fs::weakly_canonical(d, ec).string();
		if (seen.insert(ec ? d : canon).second)
			out.push_back(ec ? d : canon);
	}
	return out;
}

void PluginLoader::loadModule(const std::string& path)
{
	const std::string abs = fs::absolute(path).lexically_normal().string();
	for (const auto& l : loaded_)
		if (fs::path(l).filename() == fs::path(abs).filename())
			return;  // already loaded
	const auto before = registeredIds();
	std::string err;
	if (!mrpt::system::loadPluginModule(abs, err))
		throw std::runtime_error("cannot load plugin module '" + abs + "': " + err);
	// Modules stay loaded for the life of the process (MRPT unloads them at exit, and the
	// libraries they brought, such as glog under Ceres, with them: objects of theirs still
	// alive then would point into unmapped code). A second reference with RTLD_NODELETE pins
	// the module; it is already loaded, so this only marks it.
	void* handle = ::dlopen(abs.c_str(), RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
	mrpt::rtti::registerAllPendingClasses();
	// The classes it registered (new names, or names it registered again over another's).
	std::vector<std::string> added;
	for (const auto& [name, id] : registeredIds())
		if (const auto it = before.find(name); it == before.end() || it->second != id)
			added.push_back(name);
	if (const auto problem = abiProblem(handle, abs); !problem.empty())
	{
		// Loaded, it cannot be unloaded: its classes are refused by name, and one it
		// registered over an earlier module's class goes back to that one.
		for (const auto& name : added)
			if (const auto it = before.find(name); it != before.end())
				mrpt::rtti::registerClass(it->second);  // the earlier module's, usable
			else
				refused_[name] = problem;
		throw std::runtime_error(problem);
	}
	loaded_.push_back(abs);
	for (const auto& name : added)
	{
		classModule_[name] = abs;
		refused_.erase(name);
	}
}

void PluginLoader::load(const std::vector<std::string>& only)
{
	const auto dirs = searchPath();
	if (only.empty())
	{
		std::set<std::string> seenNames;
		for (const auto& d : dirs)
		{
			std::error_code ec;
			if (!fs::is_directory(d, ec))
				continue;
			std::vector<fs::path> files;
			for (const auto& e : fs::directory_iterator(d, ec))
			{
				const auto name = e.path().filename().string();
				if (name.rfind(kPrefix, 0) == 0 && e.path().extension() == ".so")
					files.push_back(e.path());
			}
			std::sort(files.begin(), files.end());  // deterministic load order
			for (const auto& f : files)
			{
				// The first of a name that loads: a stale copy refused earlier in the path
				// (built for another plugin ABI, say) does not hide a good one after it.
				if (seenNames.count(f.filename().string()))
					continue;
				// One broken module found on the path must not stop every run: it is
				// reported, and a config naming one of its classes fails with that report.
				try
				{
					loadModule(f.string());
					seenNames.insert(f.filename().string());
				}
				catch (const std::exception& e)
				{
					if (failedSet_.insert(f.string()).second)
					{
						failed_.push_back(e.what());
						std::cerr << "rasterslam: warning: " << e.what() << "\n";
					}
				}
			}
		}
		return;
	}
	for (const auto& name : only)
	{
		if (fs::path(name).is_absolute())
		{
			if (!fs::exists(name))
				throw std::runtime_error("plugin module '" + name + "' does not exist");
			loadModule(name);
			continue;
		}
		bool found = false;
		for (const auto& d : dirs)
		{
			const auto p = fs::path(d) / name;
			if (fs::exists(p))
			{
				loadModule(p.string());
				found = true;
				break;
			}
		}
		if (!found)
		{
			std::string where;
			for (const auto& d : dirs)
				where += "\n  " + d;
			throw std::runtime_error("plugin module '" + name +
			                         "' not found in the plugin search path:" + where +
			                         "\n(set RASTERSLAM_PLUGIN_PATH to add folders)");
		}
	}
}

std::vector<PluginClassInfo> PluginLoader::registeredClasses() const
{
	std::vector<PluginClassInfo> out;
	for (const auto* c : mrpt::rtti::getAllRegisteredClasses())
	{
		if (!c->ptrCreateObject || refused_.count(c->className))
			continue;  // abstract, or of a module refused
		const auto role = roleOfClass(c);
		if (role.empty())
			continue;
		const auto it = classModule_.find(c->className);
		out.push_back({c->className, role, it == classModule_.end() ? "" : it->second});
	}
	std::sort(out.begin(), out.end(),
	          [](const auto& a, const auto& b)
	          { return a.role != b.role ? a.role < b.role : a.className < b.className; });
	return out;
}

Plugin::Ptr PluginLoader::create(const std::string& className,
                                 const mrpt::rtti::TRuntimeClassId* role) const
{
	std::string roleName = role->className;
	for (const auto& [rid, name] : roles())
		if (rid == role)
			roleName = name;
	std::string known;
	for (const auto& c : registeredClasses())
		if (c.role == roleName)
			known += "\n  " + c.className;
	if (known.empty())
		known = " (none: were the plugins built, and found in the search path?)";
	for (const auto& f : failed_)
		known += "\n(not loaded: " + f + ")";

	if (const auto it = refused_.find(className); it != refused_.end())
		throw std::runtime_error(roleName + " plugin class '" + className +
		                         "' cannot be used: " + it->second);
	const auto* id = mrpt::rtti::findRegisteredClass(className, false);
	if (!id || !id->ptrCreateObject)
		throw std::runtime_error("unknown " + roleName + " plugin class '" + className +
		                         "'; registered " + roleName + " classes:" + known);
	if (!id->derivedFrom(role))
		throw std::runtime_error("class '" + className + "' is not a " + roleName +
		                         " plugin; registered " + roleName + " classes:" + known);
	auto obj = std::dynamic_pointer_cast<Plugin>(id->createObject());
	if (!obj)
		throw std::runtime_error("class '" + className + "' could not be created");
	return obj;
}

}  // namespace rasterslam
