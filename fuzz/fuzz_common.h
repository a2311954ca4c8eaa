// Shared by the libFuzzer targets: one scratch folder per process (made with mkdtemp, removed
// at exit), into which each input is written under a fixed name before the reader opens it.
#pragma once

#include <stdlib.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

namespace rasterslam::fuzz
{
/** The process's scratch folder, made on first use and removed (with all it holds) at exit. */
inline const std::string& scratchDir()
{
	static const std::string dir = []
	{
		const char* base = std::getenv("TMPDIR");
		std::string tmpl = std::string(base && *base ? base : "/tmp") + "/rasterslam-fuzz-XXXXXX";
		if (!::mkdtemp(tmpl.data()))
		{
			std::perror("mkdtemp");
			std::abort();
		}
		return tmpl;
	}();
	static const bool registered = []
	{
		std::atexit(
		    []
		    {
			    std::error_code ec;
			    std::filesystem::remove_all(scratchDir(), ec);
		    });
		return true;
	}();
	(void)registered;
	return dir;
}

/** Writes `size` bytes to `path` (replacing it); aborts if that fails (not the input's fault). */
inline void writeFile(const std::string& path, const uint8_t* data, std::size_t size)
{
	FILE* f = std::fopen(path.c_str(), "wb");
	if (!f || (size && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0)
	{
		std::perror(path.c_str());
		std::abort();
	}
}

/** A file of the scratch folder: `name` under it, written with the input. */
inline std::string inputFile(const std::string& name, const uint8_t* data, std::size_t size)
{
	const auto path = scratchDir() + "/" + name;
	writeFile(path, data, size);
	return path;
}

/** Registers with MRPT the classes of the project's libraries and loaded plugin modules that
 *  their own registration missed. Needed with clang: each library registers its classes in an
 *  MRPT_INITIALIZER (a constructor function) that clang runs before the dynamic initializer
 *  of the class's TRuntimeClassId (it holds a std::function), so that registration sees a null
 *  class name and is dropped ("registerClass: Invoked with a nullptr classname"); GCC
 *  initializes the name statically and the same code works. Call after loading plugins. */
void registerProjectClasses();

}  // namespace rasterslam::fuzz
