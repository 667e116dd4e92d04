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
// A header attribute of an image file as text ("" if absent); throws
// obscura::Error naming the path if the file cannot be opened.
std::string readExrAttribute(const std::string& path, const std::string& name);
// sRGB preview of the pass (R,G,B over black); 8-bit PNG.
void writePreviewPng(const std::string& path, const Film& film);
// An 8-bit sRGB PNG from interleaved RGB bytes, row-major, top row first.
void writePngRgb8(const std::string& path, int width, int height, const unsigned char* rgb);
// sRGB encoding of a linear value in [0, 1] (clamped), as a byte.
unsigned char linearToSrgb8(float v);

}  // namespace obscura
