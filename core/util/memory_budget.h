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
// when `bytes`, with what the process already holds (MemoryHold), exceeds
// memoryBudget(). `what` names the file or option and what needs the memory.
void requireMemory(uint64_t bytes, const std::string& what);
void requireMemory(const MemoryEstimate& e, const std::string& what);

// What the process holds for the whole of a piece of work (a render's film
// while its scene is built and rendered, compare's films): checked by
// requireMemory when made, then counted by every later check until it is
// destroyed, so the budget bounds their sum - the whole process, also when
// Python threads render at once - and not each part alone.
class MemoryHold {
 public:
  MemoryHold() = default;
  MemoryHold(uint64_t bytes, const std::string& what);
  MemoryHold(MemoryHold&& o) noexcept : bytes_(o.bytes_) { o.bytes_ = 0; }
  MemoryHold& operator=(MemoryHold&& o) noexcept;
  MemoryHold(const MemoryHold&) = delete;
  MemoryHold& operator=(const MemoryHold&) = delete;
  ~MemoryHold();

 private:
  uint64_t bytes_ = 0;
};

// The bytes every MemoryHold alive holds.
uint64_t memoryHeld();

}  // namespace obscura
