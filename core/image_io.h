// Image output through OpenImageIO: the film as a multi-channel EXR, and an
// sRGB PNG preview. Both are written atomically: to a temporary file in the
// destination's directory, then renamed over the destination, so a failed or
// interrupted write never leaves a truncated file where a good one was.
#pragma once

#include <string>
#include <variant>
#include <vector>

#include "core/film.h"

namespace obscura {

struct HeaderAttribute {
  std::string name;
  std::variant<std::string, int, float, std::vector<float>> value;  // vector: 16 floats = 4x4 matrix
};

struct ExrOptions {
  bool half = false;  // 16-bit half floats instead of 32-bit floats
  std::vector<HeaderAttribute> attributes;
};

// Throws obscura::Error naming the path on failure (nothing is left behind).
void writeExr(const std::string& path, const Film& film, const ExrOptions& options);
// sRGB preview of the pass (R,G,B over black); 8-bit PNG.
void writePreviewPng(const std::string& path, const Film& film);

}  // namespace obscura
