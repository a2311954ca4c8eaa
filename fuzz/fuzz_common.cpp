#include "fuzz_common.h"

#include <dlfcn.h>
#include <elf.h>
#include <link.h>
#include <malloc.h>
#include <mrpt/rtti/CObject.h>

#include <atomic>
#include <fstream>
#include <iterator>
#include <new>
#include <set>
#include <vector>

namespace rasterslam::fuzz
{
namespace
{
/** Names of the dynamic symbols of an ELF file that end with `suffix`. */
std::vector<std::string> dynamicSymbols(const std::string& path, const std::string& suffix)
{
	std::ifstream f(path, std::ios::binary);
	const std::vector<char> b((std::istreambuf_iterator<char>(f)),
	                          std::istreambuf_iterator<char>());
	std::vector<std::string> names;
	if (b.size() < sizeof(Elf64_Ehdr))
		return names;
	Elf64_Ehdr eh;
	std::memcpy(&eh, b.data(), sizeof eh);
	if (std::memcmp(eh.e_ident, ELFMAG, SELFMAG) != 0 || eh.e_ident[EI_CLASS] != ELFCLASS64 ||
	    eh.e_shoff == 0 || eh.e_shoff + uint64_t(eh.e_shnum) * sizeof(Elf64_Shdr) > b.size())
		return names;
	std::vector<Elf64_Shdr> sh(eh.e_shnum);
	std::memcpy(sh.data(), b.data() + eh.e_shoff, sh.size() * sizeof(Elf64_Shdr));
	for (const auto& s : sh)
	{
		if (s.sh_type != SHT_DYNSYM || s.sh_link >= sh.size())
			continue;
		const auto& str = sh[s.sh_link];
		if (s.sh_offset + s.sh_size > b.size() || str.sh_offset + str.sh_size > b.size())
			continue;
		for (uint64_t i = 0; i < s.sh_size / sizeof(Elf64_Sym); i++)
		{
			Elf64_Sym sym;
			std::memcpy(&sym, b.data() + s.sh_offset + i * sizeof(Elf64_Sym), sizeof sym);
			if (sym.st_shndx == SHN_UNDEF || sym.st_name >= str.sh_size)
				continue;
			const char* name = b.data() + str.sh_offset + sym.st_name;
			const std::string n(name, strnlen(name, str.sh_size - sym.st_name));
			if (n.size() >= suffix.size() &&
			    n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0)
				names.push_back(n);
		}
	}
	return names;
}
}  // namespace

void registerProjectClasses()
{
	std::vector<std::string> objects;
	::dl_iterate_phdr(
	    [](dl_phdr_info* info, std::size_t, void* out)
	    {
		    const std::string name = info->dlpi_name ? info->dlpi_name : "";
		    if (name.find("/librasterslam") != std::string::npos)
			    static_cast<std::vector<std::string>*>(out)->push_back(name);
		    return 0;
	    },
	    &objects);
	for (const auto& path : objects)
	{
		void* h = ::dlopen(path.c_str(), RTLD_NOW | RTLD_NOLOAD);
		if (!h)
			continue;
		// Mangled `...::runtimeClassId` (a static member named so: 14runtimeClassIdE).
		for (const auto& sym : dynamicSymbols(path, "14runtimeClassIdE"))
		{
			const auto* id =
			    static_cast<const mrpt::rtti::TRuntimeClassId*>(::dlsym(h, sym.c_str()));
			if (id && id->className && !mrpt::rtti::findRegisteredClass(id->className))
				mrpt::rtti::registerClass(id);
		}
		::dlclose(h);
	}
}

}  // namespace rasterslam::fuzz

// operator new as under the programs' memory cap (apps/common/app.h, capMemory): an allocation
// larger than the cap throws std::bad_alloc, which the readers report as an error. Under ASan
// operator new never throws (an allocation that fails is reported as out of memory and ends
// the process), so a length field that MRPT trusts (a string or a vector of a damaged object)
// would end every run although the programs handle it. The cap here is 256 MB (a single
// allocation; RASTERSLAM_FUZZ_MAX_ALLOC_MB changes it; ASAN_OPTIONS=max_allocation_size_mb
// does the same for malloc, see scripts/fuzz.sh). The programs' cap is on the total as well
// (RLIMIT_DATA): here the memory held through operator new is capped at 768 MB in all
// (RASTERSLAM_FUZZ_MAX_TOTAL_MB), below libFuzzer's -rss_limit_mb. A count that MRPT trusts and
// fills in many small allocations (CSensoryFrame's observation count sizes a std::deque: a
// 193-byte file asked for 2.7 GB) then fails with std::bad_alloc as in the programs, instead
// of ending the run.
// These replace ASan's new/delete (memory comes from its malloc, so overflows, use after free
// and leaks are still found; a mismatch of new and free is not).
namespace
{
/** Megabytes from the environment variable `name` (unset or empty: `def`), in bytes. */
std::size_t megabytesFromEnv(const char* name, unsigned long long def)
{
	const char* env = std::getenv(name);
	const unsigned long long mb = env && *env ? std::strtoull(env, nullptr, 10) : def;
	return static_cast<std::size_t>(mb) << 20;
}

std::size_t maxAllocation()
{
	static const std::size_t cap = megabytesFromEnv("RASTERSLAM_FUZZ_MAX_ALLOC_MB", 256);
	return cap;
}

std::size_t maxTotal()
{
	static const std::size_t cap = megabytesFromEnv("RASTERSLAM_FUZZ_MAX_TOTAL_MB", 768);
	return cap;
}

/** Bytes held through operator new (as malloc_usable_size counts them; signed, so that a
 *  block allocated with malloc and freed with delete cannot wrap it). */
std::atomic<long long> g_held{0};

void* allocateNoThrow(std::size_t n) noexcept
{
	if (n > maxAllocation() || g_held.load(std::memory_order_relaxed) + static_cast<long long>(n) >
	                               static_cast<long long>(maxTotal()))
		return nullptr;
	void* p = std::malloc(n ? n : 1);
	if (p)
		g_held.fetch_add(static_cast<long long>(::malloc_usable_size(p)),
		                 std::memory_order_relaxed);
	return p;
}

void* allocate(std::size_t n)
{
	void* p = allocateNoThrow(n);
	if (!p)
		throw std::bad_alloc();
	return p;
}

void release(void* p) noexcept
{
	if (!p)
		return;
	g_held.fetch_sub(static_cast<long long>(::malloc_usable_size(p)), std::memory_order_relaxed);
	std::free(p);
}
}  // namespace

void* operator new(std::size_t n)
{
	return allocate(n);
}
void* operator new[](std::size_t n)
{
	return allocate(n);
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept
{
	return allocateNoThrow(n);
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept
{
	return allocateNoThrow(n);
}
void operator delete(void* p) noexcept
{
	release(p);
}
void operator delete[](void* p) noexcept
{
	release(p);
}
void operator delete(void* p, std::size_t) noexcept
{
	release(p);
}
void operator delete[](void* p, std::size_t) noexcept
{
	release(p);
}
void operator delete(void* p, const std::nothrow_t&) noexcept
{
	release(p);
}
void operator delete[](void* p, const std::nothrow_t&) noexcept
{
	release(p);
}
