// LargeVector: std::vector for whole-image arrays (the screen-space
// G-buffer, its estimates and sums), whose storage of 2 MiB or more is 2 MiB
// aligned, advised for transparent huge pages and kept for the next render
// of the same size; elements of trivially copyable types are left
// uninitialized. Why, and what was measured: core/util/large_vector.h. The
// allocation itself is out of line (core/util/large_vector.cpp).
#pragma once

#include <cstddef>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

namespace obscura {

namespace detail {
// `bytes` of storage (2 MiB aligned from 2 MiB up); throws std::bad_alloc.
void* largeAllocate(size_t bytes);
// Frees what largeAllocate(bytes) returned (or keeps it for the next render).
void largeDeallocate(void* p, size_t bytes) noexcept;
}  // namespace detail

template <class T>
struct LargeAllocator {
  using value_type = T;
  static constexpr size_t kHuge = size_t(2) << 20;
  LargeAllocator() = default;
  template <class U>
  LargeAllocator(const LargeAllocator<U>&) {}
  T* allocate(size_t n) { return static_cast<T*>(detail::largeAllocate(n * sizeof(T))); }
  void deallocate(T* p, size_t n) noexcept { detail::largeDeallocate(p, n * sizeof(T)); }
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

}  // namespace obscura
