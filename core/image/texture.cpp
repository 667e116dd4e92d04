#include "core/image/texture.h"
#include "core/image/texture_size.h"

#include <stb_image.h>

#include <cmath>

#include <obscura/error.h>

namespace obscura {

UvTransform UvTransform::fromKhr(double offsetU, double offsetV, double rotation, double scaleU, double scaleV) {
  // KHR_texture_transform's matrix: translation x rotation x scale, with the
  // rotation [cos sin; -sin cos] as the extension writes it (v down).
  const double c = std::cos(rotation), s = std::sin(rotation);
  UvTransform t;
  t.a = float(c * scaleU), t.b = float(s * scaleV), t.e = float(offsetU);
  t.c = float(-s * scaleU), t.d = float(c * scaleV), t.f = float(offsetV);
  t.cosR = float(c), t.sinR = float(s);
  t.identity = offsetU == 0 && offsetV == 0 && rotation == 0 && scaleU == 1 && scaleV == 1;
  return t;
}

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
      stbi_us* data = stbi_load_16_from_memory(encoded_.data(), int(encoded_.size()), &w, &h, &comp, 4);
      if (!data) {
        decodeError_ = stbi_failure_reason() ? stbi_failure_reason() : "decode failed";
        return;
      }
      hasAlpha_ = comp == 2 || comp == 4;
      texels_.resize(size_t(w) * size_t(h));
      if (hasAlpha_) alphas_.resize(texels_.size());
      for (size_t i = 0; i < texels_.size(); ++i) {
        Vec3 c(data[4 * i] / 65535.0f, data[4 * i + 1] / 65535.0f, data[4 * i + 2] / 65535.0f);
        if (srgb_) c = Vec3(srgbToLinear(c.x), srgbToLinear(c.y), srgbToLinear(c.z));
        texels_[i] = c;
        if (hasAlpha_) alphas_[i] = data[4 * i + 3] / 65535.0f;  // alpha is linear (glTF 2.0 3.9.2)
      }
      stbi_image_free(data);
    } else {
      stbi_uc* data = stbi_load_from_memory(encoded_.data(), int(encoded_.size()), &w, &h, &comp, 4);
      if (!data) {
        decodeError_ = stbi_failure_reason() ? stbi_failure_reason() : "decode failed";
        return;
      }
      hasAlpha_ = comp == 2 || comp == 4;
      for (int i = 0; i < 256; ++i) lut_[i] = srgb_ ? srgbToLinear(i / 255.0f) : i / 255.0f;
      bytes_.resize(size_t(w) * size_t(h));
      // stb fills alpha with 255 when the image has none.
      for (size_t i = 0; i < bytes_.size(); ++i)
        bytes_[i] = uint32_t(data[4 * i]) | uint32_t(data[4 * i + 1]) << 8 | uint32_t(data[4 * i + 2]) << 16 |
                    uint32_t(data[4 * i + 3]) << 24;
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

DecodedImageSize decodedImageSize(const std::vector<unsigned char>& encoded_) {
  DecodedImageSize d;
  if (encoded_.empty() || encoded_.size() > size_t(INT32_MAX)) return d;
  int comp = 0;
  if (!stbi_info_from_memory(encoded_.data(), int(encoded_.size()), &d.width, &d.height, &comp) || d.width < 1 ||
      d.height < 1)
    return DecodedImageSize{};
  const uint64_t n = uint64_t(d.width) * uint64_t(d.height);
  // As decode() stores them: 8-bit images one word a texel, 16-bit ones a
  // Vec3 (and a float alpha); stb's buffer is RGBA at 1 or 2 bytes a channel.
  if (stbi_is_16_bit_from_memory(encoded_.data(), int(encoded_.size()))) {
    d.kept = n * (sizeof(Vec3) + (comp == 2 || comp == 4 ? sizeof(float) : 0));
    d.transient = n * 8;
  } else {
    d.kept = n * sizeof(uint32_t);
    d.transient = n * 4;
  }
  return d;
}

namespace {
// The two texel indices a bilinear lookup reads along one axis: floor f and
// f + 1 after the wrap mode (glTF 2.0 sampler semantics). f is an integer
// held in a double (any magnitude); the repeat modes reduce it exactly, by
// an integer remainder when it fits an int, else by fmod.
inline void wrapPair(double f, int n, WrapMode mode, int& i0, int& i1) {
  if (mode == WrapMode::ClampToEdge) {
    const int i = int(std::clamp(f, -1.0, double(n)));
    i0 = std::clamp(i, 0, n - 1);
    i1 = std::clamp(i + 1, 0, n - 1);
    return;
  }
  const int period = mode == WrapMode::MirroredRepeat ? 2 * n : n;
  // Inside the first period (uvs in [0, 1) for repeat) the remainder is f
  // itself: no integer division, the common case of every lookup.
  int m = f >= 0.0 && f < double(period) ? int(f)
          : std::abs(f) < 0x1p31       ? int(f) % period
                                       : int(std::fmod(f, double(period)));
  if (m < 0) m += period;
  const int m1 = m + 1 == period ? 0 : m + 1;
  if (mode == WrapMode::MirroredRepeat) {
    i0 = m < n ? m : period - 1 - m;
    i1 = m1 < n ? m1 : period - 1 - m1;
  } else {
    i0 = m;
    i1 = m1;
  }
}
}  // namespace

bool Texture::footprint(float u, float v, WrapMode wrapS, WrapMode wrapT, int& x0, int& x1, int& y0, int& y1, float& tx,
                        float& ty) const {
  if (width_ == 0 || !std::isfinite(u) || !std::isfinite(v)) return false;
  // Texel centres at half-integers; floor in double so huge uvs stay exact
  // enough and never overflow int.
  const double x = double(u) * width_ - 0.5, y = double(v) * height_ - 0.5;
  const double fx = std::floor(x), fy = std::floor(y);
  tx = float(x - fx), ty = float(y - fy);
  wrapPair(fx, width_, wrapS, x0, x1);
  wrapPair(fy, height_, wrapT, y0, y1);
  return true;
}

float Texture::sampleAlpha(float u, float v, WrapMode wrapS, WrapMode wrapT) const {
  if (!hasAlpha_) return 1.0f;
  int x0, x1, y0, y1;
  float tx, ty;
  if (!footprint(u, v, wrapS, wrapT, x0, x1, y0, y1, tx, ty)) return 0.0f;
  const float a = alphaTexel(x0, y0) * (1 - tx) + alphaTexel(x1, y0) * tx;
  const float b = alphaTexel(x0, y1) * (1 - tx) + alphaTexel(x1, y1) * tx;
  return a * (1 - ty) + b * ty;
}

namespace {
// footprint() along one axis for repeat wrapping and a coordinate c in
// [0, 1), the common lookup of the render loop's albedo AOV: x = c n - 0.5
// lies in [-0.5, n - 0.5), so floor(x) is -1 or x's truncation, and
// wrapPair's remainder is that, or n - 1 for -1. The same doubles and ints
// as the general form, without its range cases.
inline void repeatUnitAxis(float c, int n, int& i0, int& i1, float& t) {
  const double x = double(c) * n - 0.5;
  const int i = x < 0.0 ? -1 : int(x);
  t = float(x - double(i));
  i0 = i < 0 ? n - 1 : i;
  i1 = i0 + 1 == n ? 0 : i0 + 1;
}
}  // namespace

Vec3 Texture::sample(float u, float v, WrapMode wrapS, WrapMode wrapT) const {
  int x0, x1, y0, y1;
  float tx, ty;
  if (wrapS == WrapMode::Repeat && wrapT == WrapMode::Repeat && u >= 0.0f && u < 1.0f && v >= 0.0f && v < 1.0f &&
      width_ > 0) {
    // Bit for bit footprint()'s result (FastPaths.TextureUnitSquareLookups).
    repeatUnitAxis(u, width_, x0, x1, tx);
    repeatUnitAxis(v, height_, y0, y1, ty);
  } else if (!footprint(u, v, wrapS, wrapT, x0, x1, y0, y1, tx, ty)) {
    return Vec3(0, 0, 0);
  }
  const Vec3 a = texel(x0, y0) * (1 - tx) + texel(x1, y0) * tx;
  const Vec3 b = texel(x0, y1) * (1 - tx) + texel(x1, y1) * tx;
  return a * (1 - ty) + b * ty;
}

}  // namespace obscura
