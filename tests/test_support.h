// Helpers shared by the tests.
#pragma once

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace rasterslam::test
{
/** The folder ../shared/data beside the checkout. In CI (CI set in the environment) a
 *  missing folder fails the test loudly; elsewhere the test is skipped with a message. */
inline std::string sharedData(const std::string& sub = "")
{
	const std::filesystem::path p = std::filesystem::path(RASTERSLAM_SHARED_DATA_DIR) / sub;
	return p.string();
}
inline bool sharedDataAvailable() { return std::filesystem::is_directory(RASTERSLAM_SHARED_DATA_DIR); }

#define RASTERSLAM_REQUIRE_SHARED_DATA()                                                   \
	do                                                                                     \
	{                                                                                      \
		if (!rasterslam::test::sharedDataAvailable())                                      \
		{                                                                                  \
			if (std::getenv("CI"))                                                         \
				FAIL() << "CI: the reference data folder " << RASTERSLAM_SHARED_DATA_DIR   \
					   << " is missing (../shared/data beside the checkout)";              \
			else                                                                           \
				GTEST_SKIP() << "reference data " << RASTERSLAM_SHARED_DATA_DIR            \
							 << " not found (../shared/data beside the checkout); skipped"; \
		}                                                                                  \
	} while (0)

/** A fresh empty folder under the system temp dir, unique to the running test. */
inline std::filesystem::path tempDir(const std::string& tag)
{
	const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
	auto p = std::filesystem::temp_directory_path() /
		("rasterslam-test-" + tag + "-" + std::string(info ? info->name() : "x") + "-" +
		 std::to_string(::getpid()));
	std::filesystem::remove_all(p);
	std::filesystem::create_directories(p);
	return p;
}

}  // namespace rasterslam::test
