// FNV-1a, 64 bit: stable keys for settings and content (compare's cache
// names and resumption, the environment's content hash). Not for security.
// (The checkpoint's checksum keeps its own loop: it starts from another
// basis, and files on disk hold its values. The fingerprint's file hashes,
// app/render_setup.cpp fileHash, take 8-byte words for speed.)
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

namespace obscura {

struct Fnv1a64 {
  uint64_t h = 0xcbf29ce484222325ull;
  Fnv1a64& add(const void* data, size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
    return *this;
  }
  // A string and a separator: ("ab", "c") and ("a", "bc") differ.
  Fnv1a64& add(const std::string& s) {
    add(s.data(), s.size());
    return add("\x1f", 1);
  }
  // Sixteen lowercase hex digits.
  std::string hex() const {
    char text[17];
    std::snprintf(text, sizeof text, "%016llx", (unsigned long long)h);
    return text;
  }
};

}  // namespace obscura
