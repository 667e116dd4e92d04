// CRC-32 as the PNG specification defines it, computed a bit at a time (the
// code under test uses a byte table), so the two agree only if both follow
// the spec: for the PNG chunks the tests write and check.
#pragma once

#include <cstddef>
#include <cstdint>

namespace obscura::test {

inline uint32_t bitwiseCrc32(const unsigned char* p, size_t n) {
  uint32_t c = 0xFFFFFFFFu;
  for (size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return ~c;
}

}  // namespace obscura::test
