// The memory budget of the process (--max-memory, LoadOptions::maxMemoryBytes):
// what a command would allocate is estimated from headers and counts before
// the work - decoded texture and image sizes from their headers, node and
// motion tables, the BVH, the film - and refused when it exceeds the budget,
// with the estimate in the message, instead of exhausting the machine or
// failing as "out of memory" half-way (docs/cli.md "Memory").
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace obscura {

inline constexpr uint64_t kDefaultMemoryBudget = uint64_t(8) << 30;

// The budget every check below uses (set once at start-up by the front
// end, before any work; not thread-safe).
void setMemoryBudget(uint64_t bytes);
uint64_t memoryBudget();

// "12.7 MiB" / "3.4 GiB".
std::string formatBytes(uint64_t bytes);

// An estimate as named parts ("textures", "BVH", ...), for messages and `info`.
struct MemoryEstimate {
  std::vector<std::pair<std::string, uint64_t>> parts;
  void add(const std::string& what, uint64_t bytes);
  uint64_t total() const;
  // "3.4 GiB (textures 2.0 GiB, BVH 1.2 GiB, ...)", the parts above zero.
  std::string describe() const;
};

// Throws obscura::Error "`what`: needs N, over the --max-memory budget of B"
// when `bytes` exceeds memoryBudget(). `what` names the file or option
// and what needs the memory.
void requireMemory(uint64_t bytes, const std::string& what);
void requireMemory(const MemoryEstimate& e, const std::string& what);

}  // namespace obscura
