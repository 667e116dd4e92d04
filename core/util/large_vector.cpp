#include "core/util/large_vector.h"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <list>
#include <mutex>
#include <string>

#include <obscura/error.h>

namespace obscura::detail {
namespace {

struct KeptBlocks {
  std::mutex mutex;
  std::list<std::pair<size_t, void*>> blocks;  // (bytes, block), oldest first
  size_t total = 0;
  size_t cap = 0;
};

// The memory this process may use: the machine's, or its cgroup's limit (a
// Slurm job, a container) when that is lower.
size_t memoryLimit() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  size_t limit = pages > 0 && page > 0 ? size_t(pages) * size_t(page) : 0;
  for (const char* path : {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {
    if (std::FILE* f = std::fopen(path, "r")) {
      unsigned long long bytes = 0;
      if (std::fscanf(f, "%llu", &bytes) == 1 && bytes > 0) limit = std::min<size_t>(limit, size_t(bytes));
      std::fclose(f);
    }
  }
  return limit;
}

// The most the kept blocks may hold: OBSCURA_KEEP_MEMORY MiB (0: keep
// none) if set, else a quarter of the memory this process may use, at most
// 4 GiB (a 1080p adaptive, denoised render with every AOV keeps ~0.7 GB;
// a 4K one ~2.8 GB). Sanitized builds keep nothing: AddressSanitizer must
// see every block freed to catch a use after it.
size_t keptCap() {
#if defined(OBSCURA_SANITIZED_BUILD) || defined(__SANITIZE_ADDRESS__)
  return 0;
#endif
  const size_t limit = memoryLimit();
  if (const char* v = std::getenv("OBSCURA_KEEP_MEMORY"); v && *v) {
    errno = 0;
    char* end = nullptr;
    const unsigned long long mib = std::strtoull(v, &end, 10);
    if (std::isdigit(static_cast<unsigned char>(v[0])) && *end == '\0' && errno == 0)
      return std::min<size_t>(limit, size_t(std::min<unsigned long long>(mib, 1ULL << 40)) << 20);
    Log::warnOnce(std::string("OBSCURA_KEEP_MEMORY: expected a number of MiB, got '") + v +
                  "': the default (a quarter of memory, at most 4 GiB) is kept");
  }
  return std::min(limit / 4, size_t(4) << 30);
}

// Never destroyed: vectors in static objects may free blocks during the
// process's exit, after any function-local static would be gone.
KeptBlocks& kept() {
  static KeptBlocks* k = [] {
    auto* b = new KeptBlocks;
    b->cap = keptCap();
    return b;
  }();
  return *k;
}

// Moves the oldest kept blocks into `out` until at least `bytes` have gone
// or none is left (the caller frees them outside the lock).
void evictOldest(KeptBlocks& k, size_t bytes, std::list<std::pair<size_t, void*>>& out) {
  size_t freed = 0;
  while (freed < bytes && !k.blocks.empty()) {
    freed += k.blocks.front().first;
    k.total -= k.blocks.front().first;
    out.splice(out.end(), k.blocks, k.blocks.begin());
  }
}

void freeAll(const std::list<std::pair<size_t, void*>>& blocks) {
  for (const auto& block : blocks) std::free(block.second);
}

}  // namespace

void* takeKeptBlock(size_t bytes) {
  KeptBlocks& k = kept();
  std::list<std::pair<size_t, void*>> evicted;
  {
    const std::lock_guard<std::mutex> lock(k.mutex);
    // The newest of that size: a render's blocks are a few dozen.
    for (auto it = k.blocks.rbegin(); it != k.blocks.rend(); ++it)
      if (it->first == bytes) {
        void* p = it->second;
        k.blocks.erase(std::next(it).base());
        k.total -= bytes;
        return p;
      }
    // None: as much of the oldest goes back to the system as the caller is
    // about to allocate, so the kept and the used together never pass the
    // process's high-water mark (and availableMemoryBytes may count the kept
    // bytes as available).
    evictOldest(k, bytes, evicted);
  }
  freeAll(evicted);
  return nullptr;
}

bool keepBlock(void* p, size_t bytes) noexcept {
  KeptBlocks& k = kept();
  if (bytes > k.cap) return false;
  std::list<std::pair<size_t, void*>> evicted;
  try {
    const std::lock_guard<std::mutex> lock(k.mutex);
    // Over the cap the oldest go back to the system: renders at another
    // size (or another integrator's planes) replace the kept ones.
    if (k.total + bytes > k.cap) evictOldest(k, k.total + bytes - k.cap, evicted);
    k.blocks.emplace_back(bytes, p);
    k.total += bytes;
  } catch (...) {  // no memory for the list's node: the caller frees the block
    freeAll(evicted);
    return false;
  }
  freeAll(evicted);
  return true;
}

size_t releaseKeptBlocks() {
  KeptBlocks& k = kept();
  std::list<std::pair<size_t, void*>> all;
  size_t released = 0;
  {
    const std::lock_guard<std::mutex> lock(k.mutex);
    all.splice(all.end(), k.blocks);
    released = k.total;
    k.total = 0;
  }
  freeAll(all);
  return released;
}

size_t keptBytes() {
  KeptBlocks& k = kept();
  const std::lock_guard<std::mutex> lock(k.mutex);
  return k.total;
}

size_t keptCapacity() { return kept().cap; }

size_t setKeptCapacity(size_t bytes) {
  KeptBlocks& k = kept();
  std::list<std::pair<size_t, void*>> evicted;
  size_t before = 0;
  {
    const std::lock_guard<std::mutex> lock(k.mutex);
    before = k.cap;
    k.cap = bytes;
    if (k.total > k.cap) evictOldest(k, k.total - k.cap, evicted);
  }
  freeAll(evicted);
  return before;
}

}  // namespace obscura::detail

namespace obscura::detail {

namespace {
constexpr size_t kHuge = size_t(2) << 20;
size_t roundedBytes(size_t bytes) { return (bytes + kHuge - 1) / kHuge * kHuge; }
}  // namespace

void* largeAllocate(size_t bytes) {
  void* p = nullptr;
  if (bytes >= kHuge) {
    const size_t rounded = roundedBytes(bytes);
    p = takeKeptBlock(rounded);
    if (!p) {
      p = std::aligned_alloc(kHuge, rounded);
      if (p) madvise(p, rounded, MADV_HUGEPAGE);  // advice only: failure is harmless
    }
#if !defined(NDEBUG) || defined(OBSCURA_SANITIZED_BUILD)
    if (p) std::memset(p, 0xff, rounded);
#endif
  } else {
    p = std::malloc(bytes ? bytes : 1);
  }
  if (!p) throw std::bad_alloc();
  return p;
}

void largeDeallocate(void* p, size_t bytes) noexcept {
  if (bytes >= kHuge && keepBlock(p, roundedBytes(bytes))) return;
  std::free(p);
}

}  // namespace obscura::detail
