// std::vector for whole-image arrays (the screen-space G-buffer, its
// estimates and sums): storage of 2 MiB or more is 2 MiB aligned and
// advised for transparent huge pages, so first touching a 1920x1080 layer
// costs a few hundred page faults instead of ~10^5 (on virtual machines a
// fault costs microseconds: measured, faults were most of a G-buffer pass).
#pragma once

#include <sys/mman.h>

#include <cstdlib>
#include <new>
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
  template <class U>
  bool operator==(const LargeAllocator<U>&) const { return true; }
};

template <class T>
using LargeVector = std::vector<T, LargeAllocator<T>>;

}  // namespace obscura
