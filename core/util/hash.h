// FNV-1a, 64 bit: stable keys for files, settings and content (checkpoint
// fingerprints, compare's cache names, the environment's content hash).
// Not for security.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

namespace obscura {

struct Fnv1a64 {
  uint64_t h = 1469598103934665603ull;
  Fnv1a64& add(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
    return *this;
  }
  // Sixteen lowercase hex digits.
  std::string hex() const {
    char text[17];
    std::snprintf(text, sizeof text, "%016llx", (unsigned long long)h);
    return text;
  }
};

}  // namespace obscura
