#include "core/texture.h"

#include <stb_image.h>

#include <cmath>

#include "core/error.h"

namespace obscura {

float srgbToLinear(float c) {
  // IEC 61966-2-1 transfer function.
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

float linearToSrgb(float c) {
  c = std::clamp(c, 0.0f, 1.0f);
  return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

Texture::Texture(std::vector<unsigned char> encoded, std::string source, bool srgb)
    : encoded_(std::move(encoded)), source_(std::move(source)), srgb_(srgb) {}

void Texture::decode() const {
  std::call_once(once_, [this] {
    struct Mark {
      std::atomic<bool>& flag;
      ~Mark() { flag.store(true, std::memory_order_release); }
    } mark{decodeAttempted_};
    int w = 0, h = 0, comp = 0;
    if (encoded_.size() > size_t(INT32_MAX)) {
      decodeError_ = "image too large";
      return;
    }
    // 16-bit images keep their precision; 8-bit ones go through a 256-entry
    // transfer table.
    const bool is16 = stbi_is_16_bit_from_memory(encoded_.data(), int(encoded_.size()));
    std::vector<float> lut;
    if (is16) {
      stbi_us* data = stbi_load_16_from_memory(encoded_.data(), int(encoded_.size()), &w, &h, &comp, 3);
      if (!data) {
        decodeError_ = stbi_failure_reason() ? stbi_failure_reason() : "decode failed";
        return;
      }
      texels_.resize(size_t(w) * size_t(h));
      for (size_t i = 0; i < texels_.size(); ++i) {
        Vec3 c(data[3 * i] / 65535.0f, data[3 * i + 1] / 65535.0f, data[3 * i + 2] / 65535.0f);
        if (srgb_) c = Vec3(srgbToLinear(c.x), srgbToLinear(c.y), srgbToLinear(c.z));
        texels_[i] = c;
      }
      stbi_image_free(data);
    } else {
      stbi_uc* data = stbi_load_from_memory(encoded_.data(), int(encoded_.size()), &w, &h, &comp, 3);
      if (!data) {
        decodeError_ = stbi_failure_reason() ? stbi_failure_reason() : "decode failed";
        return;
      }
      float table[256];
      for (int i = 0; i < 256; ++i) table[i] = srgb_ ? srgbToLinear(i / 255.0f) : i / 255.0f;
      texels_.resize(size_t(w) * size_t(h));
      for (size_t i = 0; i < texels_.size(); ++i)
        texels_[i] = Vec3(table[data[3 * i]], table[data[3 * i + 1]], table[data[3 * i + 2]]);
      stbi_image_free(data);
    }
    width_ = w;
    height_ = h;
    encoded_.clear();
    encoded_.shrink_to_fit();
  });
  if (!decodeError_.empty())
    throw Error(source_ + ": cannot decode texture image: " + decodeError_);
}

namespace {
// Integer texel index after applying a wrap mode (glTF 2.0 sampler semantics).
inline int wrapIndex(int i, int n, WrapMode mode) {
  switch (mode) {
    case WrapMode::ClampToEdge:
      return std::clamp(i, 0, n - 1);
    case WrapMode::MirroredRepeat: {
      const int period = 2 * n;
      int m = i % period;
      if (m < 0) m += period;
      return m < n ? m : period - 1 - m;
    }
    case WrapMode::Repeat:
    default: {
      int m = i % n;
      return m < 0 ? m + n : m;
    }
  }
}
}  // namespace

Vec3 Texture::sample(float u, float v, WrapMode wrapS, WrapMode wrapT) const {
  if (width_ == 0 || !std::isfinite(u) || !std::isfinite(v)) return Vec3(0, 0, 0);
  // Texel centres at half-integers; floor in double so huge uvs stay exact
  // enough and never overflow int.
  const double x = double(u) * width_ - 0.5, y = double(v) * height_ - 0.5;
  const double fx = std::floor(x), fy = std::floor(y);
  const float tx = float(x - fx), ty = float(y - fy);
  // Bring the integer coordinate into int range without changing what the
  // wrap mode makes of it: clamp for ClampToEdge, residue modulo 2n (a period
  // of both repeat modes) otherwise.
  const auto reduce = [](double f, int n, WrapMode mode) {
    if (mode == WrapMode::ClampToEdge) return int(std::clamp(f, -1.0, double(n)));
    return int(std::fmod(f, 2.0 * n));
  };
  const int ix = reduce(fx, width_, wrapS), iy = reduce(fy, height_, wrapT);
  const int x0 = wrapIndex(ix, width_, wrapS), x1 = wrapIndex(ix + 1, width_, wrapS);
  const int y0 = wrapIndex(iy, height_, wrapT), y1 = wrapIndex(iy + 1, height_, wrapT);
  const Vec3 a = texel(x0, y0) * (1 - tx) + texel(x1, y0) * tx;
  const Vec3 b = texel(x0, y1) * (1 - tx) + texel(x1, y1) * tx;
  return a * (1 - ty) + b * ty;
}

}  // namespace obscura
