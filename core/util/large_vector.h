// std::vector for whole-image arrays (the screen-space G-buffer, its
// estimates and sums): storage of 2 MiB or more is 2 MiB aligned and
// advised for transparent huge pages, so first touching a 1920x1080 layer
// costs a few hundred page faults instead of ~10^5 (on virtual machines a
// fault costs microseconds: measured, faults were most of a G-buffer pass).
//
// LargeVector<T>(n) and resize(n) leave elements of trivially copyable
// types *uninitialized*: the whole-image passes write every element from
// all threads, so the pages are first touched (faulted in and cleared by
// the kernel) in parallel, instead of by one thread value-initializing
// them up front (a serial ~10 ms per 100 MB at 1080p, measured in the
// screen-space bench). Give a value (LargeVector(n, v), assign, or
// parallelFill below) where zeros are needed.
//
// Freed blocks of 2 MiB or more are kept for the next allocation of the
// same rounded size (up to a quarter of the memory the process may use -
// the machine's, or its cgroup's limit - at most 4 GiB, in all, or
// OBSCURA_KEEP_MEMORY MiB; past that the oldest go back
// to the system; a request of a size none has hands back the oldest, as
// many bytes as it takes): a process that renders again - `compare`'s
// cells, the Python module's renders - finds the pages of the last render's
// film, sums and filter planes already faulted in (blocks above glibc's
// largest mmap threshold, 32 MiB, would otherwise be unmapped and faulted
// in anew every render). Measured on the viking room at 1080p, adaptive +
// denoise, three renders in one Python process, three processes each way:
// the second and third took 1.96-2.06 and 1.82-1.94 s wall, 0.26-0.29 and
// 0.00-0.01 s system, against 2.00-2.36 and 1.88-2.05 s, 0.31-0.49 and
// 0.08-0.11 s keeping nothing (OBSCURA_KEEP_MEMORY=0). A kept block holds
// the bytes its last owner left, which is why nothing may read an element
// before writing it. Builds without NDEBUG, and the sanitized builds
// (OBSCURA_SANITIZE, OBSCURA_FUZZ: OBSCURA_SANITIZED_BUILD), fill every
// large block with 0xff bytes (NaN floats, all-ones integers) when it is
// handed out, fresh or kept, so that a read before a write shows in their
// tests; the sanitized builds keep nothing, so AddressSanitizer sees every
// use after free. (Note: LargeAllocator skips the value-initialization of
// trivially copyable types, default member initializers included: such
// arrays are filled, parallelFill, before use.)
#pragma once

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstddef>

#include <obscura/large_vector.h>

namespace obscura {

namespace detail {
// The kept blocks (core/util/large_vector.cpp). takeKeptBlock: a kept block of
// exactly `bytes` (a multiple of 2 MiB), or null. keepBlock: keeps the
// block (handing the oldest back to the system while the total would pass
// the cap), or returns false for a block larger than the cap (the caller
// frees it). A miss in takeKeptBlock hands back the oldest blocks of as
// many bytes as the caller is about to allocate.
void* takeKeptBlock(size_t bytes);
bool keepBlock(void* p, size_t bytes) noexcept;
// Hands every kept block back to the system; returns the bytes released.
size_t releaseKeptBlocks();
// The bytes the kept blocks hold: memory the next render has at hand.
size_t keptBytes();
// The cap on the kept bytes, and (for tests) another one; returns the
// previous cap, handing back the oldest blocks past the new one.
size_t keptCapacity();
size_t setKeptCapacity(size_t bytes);
}  // namespace detail

// v resized to n elements, every one set to `value`, by all threads: the
// pages are first touched in parallel (see above) instead of by the thread
// that resizes.
template <class T>
void parallelFill(LargeVector<T>& v, size_t n, const T& value) {
  v.resize(n);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, size_t(1) << 16), [&](const tbb::blocked_range<size_t>& r) {
    std::fill(v.begin() + std::ptrdiff_t(r.begin()), v.begin() + std::ptrdiff_t(r.end()), value);
  });
}

}  // namespace obscura
