#include <dlfcn.h>
#include <rasterslam/core/heap.h>

#include <cstdlib>

#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace rasterslam
{
const char* heapAllocator()
{
	// jemalloc's own interface: present only where jemalloc is the process's malloc.
	static const char* const kind = ::dlsym(RTLD_DEFAULT, "mallctl") ? "jemalloc"
#ifdef __GLIBC__
	                                                                 : "glibc";
#else
	                                                                 : "system";
#endif
	return kind;
}

std::string keepScanBlocksInHeap()
{
	if (std::string(heapAllocator()) == "jemalloc")
		return "the heap is jemalloc's";
#ifdef __GLIBC__
	for (const char* name : {"GLIBC_TUNABLES", "MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_",
	                         "MALLOC_TOP_PAD_", "MALLOC_MMAP_MAX_"})
		if (std::getenv(name))
			return std::string("the heap policy is the environment's (") + name + ")";
	constexpr int kBlocks = 32 << 20;  // blocks up to this come from the heap
	constexpr int kTrim = 1 << 30;     // free() leaves the heap's top alone (below 1 GB)
	if (::mallopt(M_MMAP_THRESHOLD, kBlocks) != 1 || ::mallopt(M_TRIM_THRESHOLD, kTrim) != 1)
		return "mallopt refused the heap policy";
	return {};
#else
	return "the heap is not glibc's";
#endif
}
}  // namespace rasterslam
