#include "core/large_vector.h"

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <list>
#include <mutex>

namespace obscura::detail {
namespace {

struct KeptBlocks {
  std::mutex mutex;
  std::list<std::pair<size_t, void*>> blocks;  // (bytes, block), oldest first
  size_t total = 0;
  size_t cap = 0;
};

// The most the kept blocks may hold: OBSCURA_KEEP_MEMORY MiB (0: keep
// none) if set to a number, else a quarter of the machine's memory, at
// most 4 GiB (a 1080p adaptive, denoised render with every AOV keeps
// ~0.7 GB; a 4K one ~2.8 GB).
size_t keptCap() {
#if defined(__SANITIZE_ADDRESS__)
  return 0;  // AddressSanitizer must see every block freed, to catch a use after it
#endif
  if (const char* v = std::getenv("OBSCURA_KEEP_MEMORY"); v && *v) {
    char* end = nullptr;
    const unsigned long long mib = std::strtoull(v, &end, 10);
    if (*end == '\0' && v[0] != '-') return size_t(std::min<unsigned long long>(mib, 1ULL << 40)) << 20;
  }
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  const size_t physical = pages > 0 && page > 0 ? size_t(pages) * size_t(page) : 0;
  return std::min(physical / 4, size_t(4) << 30);
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

}  // namespace

void* takeKeptBlock(size_t bytes) {
  KeptBlocks& k = kept();
  const std::lock_guard<std::mutex> lock(k.mutex);
  // The newest of that size: a render's blocks are a few dozen.
  for (auto it = k.blocks.rbegin(); it != k.blocks.rend(); ++it)
    if (it->first == bytes) {
      void* p = it->second;
      k.blocks.erase(std::next(it).base());
      k.total -= bytes;
      return p;
    }
  return nullptr;
}

bool keepBlock(void* p, size_t bytes) {
  if (bytes > kept().cap) return false;
  KeptBlocks& k = kept();
  const std::lock_guard<std::mutex> lock(k.mutex);
  // Over the cap the oldest go back to the system: renders at another
  // size (or another integrator's planes) replace the kept ones.
  while (k.total + bytes > k.cap && !k.blocks.empty()) {
    std::free(k.blocks.front().second);
    k.total -= k.blocks.front().first;
    k.blocks.pop_front();
  }
  k.blocks.emplace_back(bytes, p);
  k.total += bytes;
  return true;
}

size_t releaseKeptBlocks() {
  KeptBlocks& k = kept();
  const std::lock_guard<std::mutex> lock(k.mutex);
  for (const auto& block : k.blocks) std::free(block.second);
  k.blocks.clear();
  const size_t released = k.total;
  k.total = 0;
  return released;
}

size_t keptBytes() {
  KeptBlocks& k = kept();
  const std::lock_guard<std::mutex> lock(k.mutex);
  return k.total;
}

}  // namespace obscura::detail
