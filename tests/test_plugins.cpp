// Plugin loading, creation by class name, and strict configuration.
#include <dlfcn.h>
#include <mrpt/core/initializer.h>
#include <rasterslam/core/config.h>
#include <rasterslam/core/engine.h>
#include <rasterslam/core/plugin_loader.h>

#include "test_support.h"

using namespace rasterslam;
using mrpt::containers::yaml;

namespace rasterslam_test
{
/** A class of the test program whose name the module of another plugin ABI registers too. */
class ShadowedRasterizer : public Rasterizer
{
	DEFINE_MRPT_OBJECT(ShadowedRasterizer, rasterslam_test)

   public:
	void rasterize(const Scan&, RasterFrame&) override {}

   protected:
	void initializeImpl(ParamReader&) override {}
};
}  // namespace rasterslam_test

IMPLEMENTS_MRPT_OBJECT(ShadowedRasterizer, rasterslam::Rasterizer, rasterslam_test)
MRPT_INITIALIZER(register_test_plugins_shadowed)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam_test::ShadowedRasterizer));
}

namespace
{
std::string errorOf(const std::function<void()>& f)
{
	try
	{
		f();
	}
	catch (const std::exception& e)
	{
		return e.what();
	}
	return "";
}
}  // namespace

TEST(PluginLoader, FindsAndRegistersTheBuiltPlugins)
{
	auto& loader = PluginLoader::instance();
	loader.load();
	const auto classes = loader.registeredClasses();
	bool gicp = false, levmarq = false;
	for (const auto& c : classes)
	{
		if (c.className == "rasterslam::GicpOdometry")
		{
			gicp = true;
			EXPECT_EQ(c.role, "odometry");
			EXPECT_NE(c.module.find("librasterslam_plugin_gicp.so"), std::string::npos);
		}
		if (c.className == "rasterslam::LevMarqOptimizer")
		{
			levmarq = true;
			EXPECT_EQ(c.role, "optimizer");
		}
	}
	EXPECT_TRUE(gicp);
	EXPECT_TRUE(levmarq);
	// Loading again is a no-op, not a second registration.
	const auto n = loader.loadedModules().size();
	loader.load();
	EXPECT_EQ(loader.loadedModules().size(), n);
}

TEST(PluginLoader, CreatesByNameAndChecksTheRole)
{
	auto& loader = PluginLoader::instance();
	loader.load();
	auto odo = loader.create<Odometry>("rasterslam::GicpOdometry");
	ASSERT_TRUE(odo);
	EXPECT_EQ(odo->role(), "odometry");

	const auto unknown = errorOf([&] { loader.create<Odometry>("rasterslam::NoSuchThing"); });
	EXPECT_NE(unknown.find("unknown odometry plugin class 'rasterslam::NoSuchThing'"),
	          std::string::npos)
	    << unknown;
	EXPECT_NE(unknown.find("rasterslam::GicpOdometry"), std::string::npos) << unknown;  // listed

	const auto wrongRole =
	    errorOf([&] { loader.create<Odometry>("rasterslam::LevMarqOptimizer"); });
	EXPECT_NE(wrongRole.find("is not a odometry plugin"), std::string::npos) << wrongRole;
}

TEST(PluginLoader, NamedModuleMissingFromThePathIsAnError)
{
	const auto e = errorOf([] { PluginLoader::instance().load({"librasterslam_plugin_nope.so"}); });
	EXPECT_NE(e.find("librasterslam_plugin_nope.so' not found"), std::string::npos) << e;
	EXPECT_NE(e.find(RASTERSLAM_BUILD_PLUGIN_DIR), std::string::npos) << e;  // lists the path
}

TEST(PluginLoader, ModulesOfAnotherPluginAbiAreRefusedNamingWhy)
{
	auto& loader = PluginLoader::instance();
	loader.load();
	// Every built plugin carries its own mark of this build's ABI.
	ASSERT_FALSE(loader.loadedModules().empty());
	for (const auto& m : loader.loadedModules())
	{
		void* h = ::dlopen(m.c_str(), RTLD_NOW | RTLD_NOLOAD);
		ASSERT_TRUE(h) << m;
		const auto mark = reinterpret_cast<int (*)()>(::dlsym(h, "rasterslam_plugin_abi"));
		ASSERT_TRUE(mark) << m;
		Dl_info info{};
		ASSERT_TRUE(::dladdr(reinterpret_cast<void*>(mark), &info)) << m;
		EXPECT_EQ(std::string(info.dli_fname), m);  // its own, not its libraries'
		EXPECT_EQ(mark(), RASTERSLAM_PLUGIN_ABI) << m;
		::dlclose(h);
	}
	// A module built for ABI 0: refused, and so is its class, by name, with the reason;
	// the built rasterizer is still there.
	const std::string dir = RASTERSLAM_TEST_MODULE_DIR;
	const auto old =
	    errorOf([&] { loader.loadModule(dir + "/librasterslam_test_module_old_abi.so"); });
	EXPECT_NE(old.find("librasterslam_test_module_old_abi.so' was built for plugin ABI 0 and "
	                   "this rasterslam has plugin ABI " +
	                   std::to_string(RASTERSLAM_PLUGIN_ABI)),
	          std::string::npos)
	    << old;
	EXPECT_NE(old.find("rebuild it"), std::string::npos) << old;
	const auto create =
	    errorOf([&] { loader.create<Rasterizer>("rasterslam_test::OldAbiRasterizer"); });
	EXPECT_NE(create.find("rasterizer plugin class 'rasterslam_test::OldAbiRasterizer' cannot "
	                      "be used: plugin module"),
	          std::string::npos)
	    << create;
	for (const auto& c : loader.registeredClasses())
		EXPECT_NE(c.className, "rasterslam_test::OldAbiRasterizer");
	for (const auto& m : loader.loadedModules())
		EXPECT_EQ(m.find("old_abi"), std::string::npos) << m;
	EXPECT_TRUE(loader.create<Rasterizer>("rasterslam::ElevationRasterizer"));
	// It also registered a class under the name of one of this program's: the name is
	// given back to this program's class, which stays usable.
	EXPECT_EQ(mrpt::rtti::findRegisteredClass("rasterslam_test::ShadowedRasterizer"),
	          CLASS_ID(rasterslam_test::ShadowedRasterizer));
	const auto shadowed = loader.create<Rasterizer>("rasterslam_test::ShadowedRasterizer");
	ASSERT_TRUE(shadowed);
	EXPECT_TRUE(std::dynamic_pointer_cast<rasterslam_test::ShadowedRasterizer>(shadowed));
	// A module with no mark of its own: the mark dlsym finds through it is the core
	// library's, which the loader must not take for the module's.
	const auto unmarkedPath = dir + "/librasterslam_test_module_unmarked.so";
	{
		void* h = ::dlopen(unmarkedPath.c_str(), RTLD_NOW | RTLD_LOCAL);
		ASSERT_TRUE(h) << ::dlerror();
		void* mark = ::dlsym(h, "rasterslam_plugin_abi");
		ASSERT_TRUE(mark);
		Dl_info info{};
		ASSERT_TRUE(::dladdr(mark, &info));
		EXPECT_NE(std::string(info.dli_fname).find("librasterslam_core.so"), std::string::npos)
		    << info.dli_fname;
		::dlclose(h);
	}
	const auto unmarked = errorOf([&] { loader.loadModule(unmarkedPath); });
	EXPECT_NE(unmarked.find("librasterslam_test_module_unmarked.so' carries no plugin ABI mark"),
	          std::string::npos)
	    << unmarked;
}

TEST(Config, ParamReaderIsStrict)
{
	const yaml y = yaml::FromText("a: 2.5\nb: 3\nc: hello\nd: yes\ne: [1, 2.5]\n");
	{
		ParamReader p(y, "odometry.params", "cfg.yaml");
		EXPECT_DOUBLE_EQ(p.getDouble("a", 0), 2.5);
		EXPECT_EQ(p.getInt("b", 0), 3);
		EXPECT_EQ(p.getString("c", ""), "hello");
		EXPECT_TRUE(p.getBool("d", false));
		EXPECT_EQ(p.getDoubles("e", {}), (std::vector<double>{1, 2.5}));
		EXPECT_DOUBLE_EQ(p.getDouble("missing", 7.0), 7.0);
		EXPECT_NO_THROW(p.finish());
		EXPECT_DOUBLE_EQ(p.inForce()["missing"].as<double>(), 7.0);
	}
	{
		ParamReader p(y, "odometry.params", "cfg.yaml");
		const auto e = errorOf([&] { p.getInt("a", 0); });  // 2.5 is not an int
		EXPECT_NE(e.find("cfg.yaml: key 'odometry.params.a': expected an integer, got '2.5'"),
		          std::string::npos)
		    << e;
		EXPECT_NE(errorOf([&] { p.getDouble("c", 0); }).find("expected a number"),
		          std::string::npos);
		EXPECT_NE(errorOf([&] { p.getBool("b", 0); }).find("expected true or false"),
		          std::string::npos);
		EXPECT_NE(errorOf(
		              [&] {
			              p.getChoice("c", "x", {"x", "y"});
		              })
		              .find("expected one of {x, y}"),
		          std::string::npos);
	}
	{
		ParamReader p(y, "odometry.params", "cfg.yaml");
		p.getDouble("a", 0);
		const auto e = errorOf([&] { p.finish(); });
		EXPECT_NE(e.find("unknown key(s) in 'odometry.params': b, c, d, e"), std::string::npos)
		    << e;
	}
}

TEST(Config, EngineRejectsBadConfigs)
{
	auto engineError = [](const std::string& text)
	{ return errorOf([&] { Engine e(yaml::FromText(text), "test.yaml"); }); };
	EXPECT_EQ(engineError("odometry: {class: rasterslam::GicpOdometry}\n"), "");
	EXPECT_NE(
	    engineError("odometry: {class: rasterslam::Nope}\n").find("unknown odometry plugin class"),
	    std::string::npos);
	EXPECT_NE(engineError("optimizer: {class: rasterslam::LevMarqOptimizer}\n")
	              .find("section 'odometry' is required"),
	          std::string::npos);
	EXPECT_NE(engineError("odometry: {class: rasterslam::GicpOdometry}\nodometri: {}\n")
	              .find("unknown section 'odometri'"),
	          std::string::npos);
	EXPECT_NE(engineError("odometry: {class: rasterslam::GicpOdometry, params: {voxel: 0.5}}\n")
	              .find("unknown key(s) in 'odometry.params': voxel"),
	          std::string::npos);
	EXPECT_NE(engineError("odometry: {class: rasterslam::GicpOdometry, params: {voxel_m: big}}\n")
	              .find("'odometry.params.voxel_m': expected a number, got 'big'"),
	          std::string::npos);
	EXPECT_NE(engineError("odometry: {class: rasterslam::GicpOdometry, params: {voxel_m: -1}}\n")
	              .find("voxel_m: must be > 0"),
	          std::string::npos);
	EXPECT_NE(
	    engineError("odometry: {class: rasterslam::GicpOdometry}\nengine: {on_bad_scan: maybe}\n")
	        .find("expected one of {error, skip}"),
	    std::string::npos);
}

TEST(Config, ShippedConfigsLoad)
{
	for (const auto* name : {"tracking.yaml", "gicp-baseline.yaml"})
	{
		const auto path = test::sourcePath(std::string("share/rasterslam/config/") + name);
		EXPECT_EQ(errorOf([&] { Engine e(loadYamlFile(path), path); }), "") << path;
	}
	const auto e = errorOf([] { loadYamlFile("/nonexistent/x.yaml"); });
	EXPECT_NE(e.find("cannot read config file '/nonexistent/x.yaml'"), std::string::npos) << e;
}
