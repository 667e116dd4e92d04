// Albedo textures: encoded bytes kept from the scene file, decoded on first
// use (so a render that never reads albedo never pays for decoding), then
// sampled bilinearly in linear RGB with the glTF sampler's wrap modes.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <obscura/math.h>

namespace obscura {

enum class WrapMode { Repeat, ClampToEdge, MirroredRepeat };

// glTF's KHR_texture_transform: the texture is looked up at
// (s, t) = T R S (u, v), T the offset, R the rotation, S the scale, in the
// file's uv convention (v runs down the image); identity by default.
// docs/scenes.md "Texture transforms".
struct UvTransform {
  // s = a u + b v + e, t = c u + d v + f.
  float a = 1, b = 0, c = 0, d = 1, e = 0, f = 0;
  // The rotation alone (cos, sin): what a normal map's tangent frame turns by.
  float cosR = 1, sinR = 0;
  bool identity = true;
  // The extension's offset, rotation (radians) and scale, composed in
  // double and rounded once per coefficient.
  static UvTransform fromKhr(double offsetU, double offsetV, double rotation, double scaleU, double scaleV);
  void apply(float& u, float& v) const {
    if (identity) return;
    const float s = a * u + b * v + e;
    v = c * u + d * v + f;
    u = s;
  }
};

class Texture {
 public:
  // `encoded` holds a PNG/JPEG/... file's bytes; `source` names it in errors.
  Texture(std::vector<unsigned char> encoded, std::string source, bool srgb);

  // Decodes if not done yet. Thread-safe; throws obscura::Error on bad data.
  void decode() const;
  // Bilinear lookup at (u,v) in linear RGB. decode() must have succeeded.
  Vec3 sample(float u, float v, WrapMode wrapS, WrapMode wrapT) const;
  // The alpha channel (linear, as glTF defines it), bilinear at (u, v); 1
  // for an image without one. decode() must have succeeded.
  float sampleAlpha(float u, float v, WrapMode wrapS, WrapMode wrapT) const;
  // After decode(): does the image have an alpha channel?
  bool hasAlpha() const { return hasAlpha_; }

  // True once decode() has run (whether or not it succeeded).
  bool decoded() const { return decodeAttempted_.load(std::memory_order_acquire); }
  int width() const { return width_; }
  int height() const { return height_; }
  const std::string& source() const { return source_; }

 private:
  // 8-bit images keep their bytes (RGB in the low 24 bits of a word, alpha
  // in the high 8) and the 256-entry table they decode through: the same
  // floats as a float texel array, at a third of the memory (fewer cache
  // misses for scattered lookups). 16-bit images keep float texels (and
  // float alphas when they have alpha).
  Vec3 texel(int x, int y) const {
    const size_t i = size_t(y) * size_t(width_) + size_t(x);
    if (texels_.empty()) {
      const uint32_t c = bytes_[i];
      return Vec3(lut_[c & 0xff], lut_[(c >> 8) & 0xff], lut_[(c >> 16) & 0xff]);
    }
    return texels_[i];
  }
  float alphaTexel(int x, int y) const {
    const size_t i = size_t(y) * size_t(width_) + size_t(x);
    if (texels_.empty()) return float(bytes_[i] >> 24) * (1.0f / 255.0f);
    return alphas_[i];
  }
  // The texels (x0|x1, y0|y1) and weights (tx, ty) of a bilinear lookup.
  bool footprint(float u, float v, WrapMode wrapS, WrapMode wrapT, int& x0, int& x1, int& y0, int& y1, float& tx,
                 float& ty) const;
  mutable std::vector<unsigned char> encoded_;  // released after decoding
  std::string source_;
  bool srgb_;
  mutable std::once_flag once_;
  mutable std::vector<Vec3> texels_;     // 16-bit images
  mutable std::vector<float> alphas_;    // 16-bit images with alpha
  mutable std::vector<uint32_t> bytes_;  // 8-bit images
  mutable bool hasAlpha_ = false;
  mutable float lut_[256] = {};
  mutable int width_ = 0, height_ = 0;
  mutable std::string decodeError_;
  mutable std::atomic<bool> decodeAttempted_{false};
};

float srgbToLinear(float c);
float linearToSrgb(float c);

}  // namespace obscura
