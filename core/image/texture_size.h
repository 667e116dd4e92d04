// What decoding a texture (core/image/texture.h) will take, read from the
// image's header without decoding it, for the memory budget
// (core/util/memory_budget.h): a small file may declare a huge image (a
// 262 KB PNG of 16384 x 16384 decodes to 2 GiB).
#pragma once

#include <cstdint>
#include <vector>

namespace obscura {

// kept: the bytes Texture::decode() keeps; transient: what it holds besides
// while it runs (the decoder's RGBA buffer). Zero when the header is
// unreadable (decode() reports that).
struct DecodedImageSize {
  uint64_t kept = 0, transient = 0;
  int width = 0, height = 0;
};
DecodedImageSize decodedImageSize(const std::vector<unsigned char>& encoded);

}  // namespace obscura
