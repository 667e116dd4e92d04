#include "core/util/memory_budget.h"

#include <atomic>
#include <cstdio>

#include <obscura/error.h>
#include "core/util/option_names.h"

namespace obscura {
namespace {
// Atomic: the Python module sets the budget per call, from any thread.
std::atomic<uint64_t> gBudget{kDefaultMemoryBudget};
std::atomic<uint64_t> gHeld{0};

// " beside the 1.2 GiB this process already holds" when it holds any.
std::string heldText(uint64_t held) {
  return held == 0 ? std::string() : " beside the " + formatBytes(held) + " this process already holds";
}
}  // namespace

void setMemoryBudget(uint64_t bytes) { gBudget.store(bytes, std::memory_order_relaxed); }
uint64_t memoryBudget() { return gBudget.load(std::memory_order_relaxed); }
uint64_t memoryHeld() { return gHeld.load(std::memory_order_relaxed); }

std::string formatBytes(uint64_t bytes) {
  char text[48];
  if (bytes >= (uint64_t(1) << 30)) std::snprintf(text, sizeof text, "%.1f GiB", double(bytes) / double(uint64_t(1) << 30));
  else std::snprintf(text, sizeof text, "%.1f MiB", double(bytes) / double(1 << 20));
  return text;
}

void MemoryEstimate::add(const std::string& what, uint64_t bytes) {
  for (auto& p : parts)
    if (p.first == what) {
      p.second += bytes;
      return;
    }
  parts.emplace_back(what, bytes);
}

uint64_t MemoryEstimate::total() const {
  uint64_t t = 0;
  for (const auto& p : parts) t += p.second;
  return t;
}

std::string MemoryEstimate::describe() const {
  std::string list;
  for (const auto& [what, bytes] : parts)
    if (bytes >= (uint64_t(1) << 20)) list += (list.empty() ? "" : ", ") + what + " " + formatBytes(bytes);
  return formatBytes(total()) + (list.empty() ? "" : " (" + list + ")");
}

void requireMemory(uint64_t bytes, const std::string& what) {
  const uint64_t budget = memoryBudget(), held = memoryHeld();
  if (bytes > budget || held > budget - bytes)
    throw Error(what + ": needs " + formatBytes(bytes) + heldText(held) + ", over the " + settingName(Setting::MaxMemory) +
                " budget of " + formatBytes(budget));
}

void requireMemory(const MemoryEstimate& e, const std::string& what) {
  const uint64_t budget = memoryBudget(), held = memoryHeld(), bytes = e.total();
  if (bytes > budget || held > budget - bytes)
    throw Error(what + ": needs an estimated " + e.describe() + heldText(held) + ", over the " +
                settingName(Setting::MaxMemory) + " budget of " + formatBytes(budget));
}

MemoryHold::MemoryHold(uint64_t bytes, const std::string& what) {
  requireMemory(bytes, what);
  gHeld.fetch_add(bytes, std::memory_order_relaxed);
  bytes_ = bytes;
}

MemoryHold& MemoryHold::operator=(MemoryHold&& o) noexcept {
  if (this != &o) {
    gHeld.fetch_sub(bytes_, std::memory_order_relaxed);
    bytes_ = o.bytes_;
    o.bytes_ = 0;
  }
  return *this;
}

MemoryHold::~MemoryHold() { gHeld.fetch_sub(bytes_, std::memory_order_relaxed); }

}  // namespace obscura
