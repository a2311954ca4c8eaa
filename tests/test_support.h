// Helpers shared by the tests.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <regex>
#include <string>
#include <vector>

namespace rasterslam::test
{
/** The folder ../shared/data beside the checkout. In CI (CI set in the environment) a
 *  missing folder fails the test loudly; elsewhere the test is skipped with a message. */
inline std::string sharedData(const std::string& sub = "")
{
	const std::filesystem::path p = std::filesystem::path(RASTERSLAM_SHARED_DATA_DIR) / sub;
	return p.string();
}
inline bool sharedDataAvailable()
{
	return std::filesystem::is_directory(RASTERSLAM_SHARED_DATA_DIR);
}

#define RASTERSLAM_REQUIRE_SHARED_DATA()                                                    \
	do                                                                                      \
	{                                                                                       \
		if (!rasterslam::test::sharedDataAvailable())                                       \
		{                                                                                   \
			if (std::getenv("CI"))                                                          \
				FAIL() << "CI: the reference data folder " << RASTERSLAM_SHARED_DATA_DIR    \
				       << " is missing (../shared/data beside the checkout)";               \
			else                                                                            \
				GTEST_SKIP() << "reference data " << RASTERSLAM_SHARED_DATA_DIR             \
				             << " not found (../shared/data beside the checkout); skipped"; \
		}                                                                                   \
	} while (0)

/** Removes a file or folder when the test program ends (also after failed tests). */
inline void removeAtExit(const std::filesystem::path& p)
{
	struct Registry
	{
		std::mutex mutex;
		std::vector<std::filesystem::path> paths;
		~Registry()
		{
			std::error_code ec;
			for (const auto& q : paths)
				std::filesystem::remove_all(q, ec);
		}
	};
	static Registry registry;
	std::lock_guard<std::mutex> lk(registry.mutex);
	registry.paths.push_back(p);
}

/** A fresh empty folder under the system temp dir, unique to the running test; removed when
 *  the test program ends. */
inline std::filesystem::path tempDir(const std::string& tag)
{
	const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
	auto p = std::filesystem::temp_directory_path() /
	         ("rasterslam-test-" + tag + "-" + std::string(info ? info->name() : "x") + "-" +
	          std::to_string(::getpid()));
	std::filesystem::remove_all(p);
	std::filesystem::create_directories(p);
	removeAtExit(p);
	return p;
}

/** An input several test programs share: made once a ctest run into the build tree by the
 *  fixture TestData.Make (tests/fixtures/make-test-data.cmake). When it is not there (a test
 *  program run by hand), `make(path)` makes it into a temporary folder of this program,
 *  removed when it ends. */
template <typename Make>
std::string sharedTestInput(const std::string& name, Make&& make)
{
	const auto made = std::filesystem::path(RASTERSLAM_TEST_DATA_DIR) / name;
	std::error_code ec;
	if (std::filesystem::is_regular_file(made, ec))
		return made.string();
	const auto p = std::filesystem::temp_directory_path() /
	               ("rasterslam-test-input-" + std::to_string(::getpid()) + "-" + name);
	removeAtExit(p);
	make(p.string());
	return p.string();
}

/** A fresh folder (see tempDir) removed with everything in it when the object goes out of
 *  scope, also when the test fails. */
class ScopedTempDir
{
   public:
	explicit ScopedTempDir(const std::string& tag) : path_(tempDir(tag)) {}
	~ScopedTempDir()
	{
		std::error_code ec;
		std::filesystem::remove_all(path_, ec);
	}
	ScopedTempDir(const ScopedTempDir&) = delete;
	ScopedTempDir& operator=(const ScopedTempDir&) = delete;
	const std::filesystem::path& path() const { return path_; }
	std::filesystem::path operator/(const std::string& sub) const { return path_ / sub; }

   private:
	std::filesystem::path path_;
};

}  // namespace rasterslam::test

#include <sys/wait.h>

#include <array>

namespace rasterslam::test
{
struct CommandResult
{
	int exitCode = -1;
	std::string output;  //!< stdout and stderr together
};

/** Runs a shell command, capturing stdout and stderr. */
inline CommandResult runCommand(const std::string& cmd)
{
	CommandResult r;
	FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
	if (!p)
		return r;
	std::array<char, 4096> buf{};
	size_t n = 0;
	while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0)
		r.output.append(buf.data(), n);
	const int st = ::pclose(p);
	r.exitCode = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
	return r;
}

/** A program of the build tree (build/bin). */
inline std::string bin(const std::string& name)
{
	return std::string(RASTERSLAM_BIN_DIR) + "/" + name;
}

/** A file of the source tree. */
inline std::string sourcePath(const std::string& rel)
{
	return std::string(RASTERSLAM_SOURCE_DIR) + "/" + rel;
}

/** The text of a shipped config (share/rasterslam/config/`name`) with its vocabulary path
 *  made absolute, to be written elsewhere. */
inline std::string shippedConfig(const std::string& name)
{
	std::ifstream in(sourcePath("share/rasterslam/config/" + name));
	const std::string y((std::istreambuf_iterator<char>(in)), {});
	EXPECT_FALSE(y.empty()) << "no config " << name;
	return std::regex_replace(y, std::regex("vocabulary_file: \\.\\./vocab/"),
	                          "vocabulary_file: " + sourcePath("share/rasterslam/vocab/"));
}

}  // namespace rasterslam::test

namespace rasterslam::test
{
/** The simulated VLP-16 drive (rawlogs/town-vlp16.yaml), made once a ctest run
 *  (sharedTestInput). */
inline const std::string& townVlp16Rawlog()
{
	static const std::string path = sharedTestInput(
	    "town-vlp16.rawlog",
	    [](const std::string& p)
	    {
		    const auto r = runCommand(bin("rasterslam-sim") + " --scenario " +
		                              sourcePath("rawlogs/town-vlp16.yaml") + " -o " + p);
		    EXPECT_EQ(r.exitCode, 0) << r.output;
	    });
	return path;
}
}  // namespace rasterslam::test
