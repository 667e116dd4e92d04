#include "core/util/memory_budget.h"

#include <cstdio>

#include <obscura/error.h>
#include "core/util/option_names.h"

namespace obscura {
namespace {
uint64_t gBudget = kDefaultMemoryBudget;
}  // namespace

void setMemoryBudget(uint64_t bytes) { gBudget = bytes; }
uint64_t memoryBudget() { return gBudget; }

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
  if (bytes > gBudget)
    throw Error(what + ": needs " + formatBytes(bytes) + ", over the " + settingName(Setting::MaxMemory) + " budget of " +
                formatBytes(gBudget));
}

void requireMemory(const MemoryEstimate& e, const std::string& what) {
  if (e.total() > gBudget)
    throw Error(what + ": needs an estimated " + e.describe() + ", over the " + settingName(Setting::MaxMemory) +
                " budget of " + formatBytes(gBudget));
}

}  // namespace obscura
