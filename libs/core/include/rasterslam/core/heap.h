// The process's heap policy for scan processing (glibc): what a program that runs the engine
// calls once at its start.
#pragma once

#include <string>

namespace rasterslam
{
/** Keeps the blocks a scan needs (its points, images, clouds: 0.1-10 MB each) in the heap
 *  between scans instead of mapping them from the system and giving them back every time:
 *  blocks up to 32 MB (glibc's own largest threshold) come from the heap, and free() no longer
 * returns its top to the system (the engine's back end trims the heap every few keyframes,
 * `malloc_trim`, so a long run stays flat). glibc's default maps and unmaps such blocks, or trims
 * them, scan after scan, and each page is faulted in again: 310 page faults a KITTI scan, about a
 * quarter of the tracking's time on a virtual machine (README, Tracking).
 *
 *  Does nothing, and says why in the returned text, where the heap is not glibc's (jemalloc's,
 *  see heapAllocator) or where the
 *  user has set glibc's own heap settings (GLIBC_TUNABLES, MALLOC_MMAP_THRESHOLD_,
 *  MALLOC_TRIM_THRESHOLD_, MALLOC_TOP_PAD_, MALLOC_MMAP_MAX_): theirs stand. Returns an empty
 *  text when the policy was applied. */
std::string keepScanBlocksInHeap();

/** The process's allocator: "jemalloc" when its malloc is jemalloc's (the `rasterslam` program
 *  is linked with it where the build found it, or it was preloaded), else "glibc" or
 *  "system". jemalloc keeps its own blocks and returns memory by itself: the glibc policy above
 *  and the back end's trims are then left out. */
const char* heapAllocator();
}  // namespace rasterslam
