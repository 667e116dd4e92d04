#include "core/image/png_check.h"

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include <obscura/error.h>

namespace obscura {

void checkPngFitsItsFile(const std::string& path) {
  std::error_code ec;
  const uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return;
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return;
  unsigned char h[29] = {};
  const size_t n = std::fread(h, 1, sizeof h, f);
  std::fclose(f);
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (n < sizeof h || std::memcmp(h, kSignature, 8) != 0 || std::memcmp(h + 12, "IHDR", 4) != 0) return;
  const auto be32 = [&](int at) {
    return uint32_t(h[at]) << 24 | uint32_t(h[at + 1]) << 16 | uint32_t(h[at + 2]) << 8 | uint32_t(h[at + 3]);
  };
  const uint64_t w = be32(16), rows = be32(20), depth = h[24];
  // Samples per pixel by colour type (PNG 1.2, 11.2.2): grey, -, RGB, palette, grey+alpha, -, RGBA.
  static const int kChannels[7] = {1, 0, 3, 1, 2, 0, 4};
  const int channels = h[25] < 7 ? kChannels[h[25]] : 0;
  if (channels == 0 || depth == 0) return;  // invalid: the reader says so
  // The filtered data, a filter byte per row (non-interlaced; Adam7 adds more).
  const uint64_t bytes = rows * (1 + (w * uint64_t(channels) * depth + 7) / 8);
  if (bytes / 1032 > size)
    throw Error(path + ": the PNG header declares " + std::to_string(w) + "x" + std::to_string(rows) + " pixels (" +
                std::to_string(bytes) + " bytes of image data), more than its " + std::to_string(size) +
                " bytes can hold (deflate packs at most 1032 bytes into one): a truncated or forged file");
}

}  // namespace obscura
