// MRPT's aligned allocator (mrpt::aligned_malloc, used by the point maps' coordinate vectors)
// returns null when memory runs out and its callers write through the pointer: a damaged
// point count in a rawlog then ends the process with a segmentation fault instead of the
// error the readers report for a failed allocation. Each program links this definition,
// which interposes MRPT's own (the dynamic linker finds a program's symbols first) and turns
// the failure into std::bad_alloc. Together with cli::capMemory() (a cap on the process's
// data memory), a damaged count fails one allocation cleanly.
#include <cstddef>
#include <cstdlib>
#include <new>

namespace mrpt
{
void* aligned_malloc(std::size_t size, std::size_t alignment)
{
	if (size == 0)
		return nullptr;
	// aligned_alloc wants a size that is a multiple of the alignment.
	const std::size_t rounded = (size + alignment - 1) / alignment * alignment;
	if (rounded < size)
		throw std::bad_alloc();
	void* p = std::aligned_alloc(alignment, rounded);
	if (!p)
		throw std::bad_alloc();
	return p;
}
}  // namespace mrpt
