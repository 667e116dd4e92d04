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
#pragma once

#include <sys/mman.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdlib>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace obscura {

template <class T>
struct LargeAllocator {
  using value_type = T;
  static constexpr size_t kHuge = size_t(2) << 20;
  LargeAllocator() = default;
  template <class U>
  LargeAllocator(const LargeAllocator<U>&) {}
  T* allocate(size_t n) {
    const size_t bytes = n * sizeof(T);
    void* p = nullptr;
    if (bytes >= kHuge) {
      const size_t rounded = (bytes + kHuge - 1) / kHuge * kHuge;
      p = std::aligned_alloc(kHuge, rounded);
      if (p) madvise(p, rounded, MADV_HUGEPAGE);  // advice only: failure is harmless
    } else {
      p = std::malloc(bytes ? bytes : 1);
    }
    if (!p) throw std::bad_alloc();
    return static_cast<T*>(p);
  }
  void deallocate(T* p, size_t) { std::free(p); }
  // Value-initialization (no arguments) of trivially copyable types is
  // skipped; everything else is constructed as usual.
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    if constexpr (sizeof...(Args) == 0 && std::is_trivially_copyable_v<U> && std::is_trivially_destructible_v<U>) {
      // Nothing written: U (trivial copy and destruction) is an
      // implicit-lifetime type, whose objects the allocation created.
      (void)p;
    } else {
      ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
  }
  template <class U>
  bool operator==(const LargeAllocator<U>&) const { return true; }
};

template <class T>
using LargeVector = std::vector<T, LargeAllocator<T>>;

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
