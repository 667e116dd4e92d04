#include "core/texture.h"

#include <emmintrin.h>
#include <xmmintrin.h>
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
// The fast path of Texture::sample: repeat wrapping on both axes and (u, v)
// in the unit square, the albedo AOV's common lookup (a textured primitive's
// uvs inside [0, 1)), in SSE. Along each axis x = c n - 0.5 lies in
// [-0.5, n - 0.5), so footprint()'s floor is -1 or x's truncation, and
// wrapPair's remainder is that, or n - 1 for -1. Both axes at once in two
// double lanes: the same doubles (c n is exact in a double, and so is
// - 0.5), the same ints and the same float weights as the general form.
inline Texture::UnitFootprint repeatUnitFootprint(float u, float v, int width, int height) {
  const __m128d size = _mm_setr_pd(double(width), double(height));
  const __m128d x = _mm_sub_pd(_mm_mul_pd(_mm_cvtps_pd(_mm_setr_ps(u, v, 0.0f, 0.0f)), size), _mm_set1_pd(0.5));
  // floor(x): the truncation, minus 1 where x < 0 (x > -1 there). The
  // comparison's 64-bit masks, packed into the low two 32-bit lanes.
  const __m128i negative = _mm_shuffle_epi32(_mm_castpd_si128(_mm_cmplt_pd(x, _mm_setzero_pd())), _MM_SHUFFLE(3, 3, 2, 0));
  const __m128i i = _mm_add_epi32(_mm_cvttpd_epi32(x), negative);
  const __m128 t = _mm_cvtpd_ps(_mm_sub_pd(x, _mm_cvtepi32_pd(i)));
  // i0 = i < 0 ? n - 1 : i; i1 = i0 + 1, or 0 where that is n.
  const __m128i n = _mm_setr_epi32(width, height, 0, 0);
  const __m128i i0 = _mm_add_epi32(i, _mm_and_si128(negative, n));
  const __m128i next = _mm_add_epi32(i0, _mm_set1_epi32(1));
  const __m128i i1 = _mm_andnot_si128(_mm_cmpeq_epi32(next, n), next);
  alignas(16) int a0[4], a1[4];
  alignas(16) float w[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(a0), i0);
  _mm_store_si128(reinterpret_cast<__m128i*>(a1), i1);
  _mm_store_ps(w, t);
  return {a0[0], a1[0], a0[1], a1[1], w[0], w[1]};
}

// A bilinear blend of four texels held as (r, g, b, 0) in SSE registers:
// per channel a = t00 (1 - tx) + t10 tx, b = t01 (1 - tx) + t11 tx,
// a (1 - ty) + b ty, the Vec3 expression of Texture::sample channel by
// channel (no fused multiply-add in either: the same roundings).
inline Vec3 blend(__m128 t00, __m128 t10, __m128 t01, __m128 t11, float tx, float ty) {
  const __m128 sx = _mm_set1_ps(1 - tx), wx = _mm_set1_ps(tx);
  const __m128 a = _mm_add_ps(_mm_mul_ps(t00, sx), _mm_mul_ps(t10, wx));
  const __m128 b = _mm_add_ps(_mm_mul_ps(t01, sx), _mm_mul_ps(t11, wx));
  const __m128 r = _mm_add_ps(_mm_mul_ps(a, _mm_set1_ps(1 - ty)), _mm_mul_ps(b, _mm_set1_ps(ty)));
  alignas(16) float out[4];
  _mm_store_ps(out, r);
  return Vec3(out[0], out[1], out[2]);
}
}  // namespace

void Texture::sampleBatch(const float* u, const float* v, size_t n, WrapMode wrapS, WrapMode wrapT,
                          Vec3* out) const {
  if (!(wrapS == WrapMode::Repeat && wrapT == WrapMode::Repeat && width_ > 0)) {
    for (size_t i = 0; i < n; ++i) out[i] = sample(u[i], v[i], wrapS, wrapT);
    return;
  }
  // The fast path's footprints (sample() below), row starts as texel
  // indices; a lookup off the unit square is marked and takes sample().
  UnitFootprint f[kBatch];
  bool fast[kBatch];
  const char* base = texels_.empty() ? reinterpret_cast<const char*>(bytes_.data())
                                     : reinterpret_cast<const char*>(texels_.data());
  const size_t stride = texels_.empty() ? sizeof(uint32_t) : sizeof(Vec3), w = size_t(width_);
  for (size_t i = 0; i < n; ++i) {
    fast[i] = u[i] >= 0.0f && u[i] < 1.0f && v[i] >= 0.0f && v[i] < 1.0f;
    if (!fast[i]) continue;
    f[i] = repeatUnitFootprint(u[i], v[i], width_, height_);
    _mm_prefetch(base + (size_t(f[i].y0) * w + size_t(f[i].x0)) * stride, _MM_HINT_T0);
    _mm_prefetch(base + (size_t(f[i].y1) * w + size_t(f[i].x0)) * stride, _MM_HINT_T0);
  }
  for (size_t i = 0; i < n; ++i) out[i] = fast[i] ? blendFootprint(f[i]) : sample(u[i], v[i], wrapS, wrapT);
}

Vec3 Texture::blendFootprint(const UnitFootprint& f) const {
  const size_t w = size_t(width_), r0 = size_t(f.y0) * w, r1 = size_t(f.y1) * w;
  if (texels_.empty()) {
    // 8-bit texels through the transfer table, channel by channel.
    const auto at = [&](size_t i) {
      const uint32_t c = bytes_[i];
      return _mm_setr_ps(lut_[c & 0xff], lut_[(c >> 8) & 0xff], lut_[(c >> 16) & 0xff], 0.0f);
    };
    return blend(at(r0 + size_t(f.x0)), at(r0 + size_t(f.x1)), at(r1 + size_t(f.x0)), at(r1 + size_t(f.x1)), f.tx,
                 f.ty);
  }
  const auto at = [&](size_t i) {
    const Vec3& c = texels_[i];
    return _mm_setr_ps(c.x, c.y, c.z, 0.0f);
  };
  return blend(at(r0 + size_t(f.x0)), at(r0 + size_t(f.x1)), at(r1 + size_t(f.x0)), at(r1 + size_t(f.x1)), f.tx,
               f.ty);
}

Vec3 Texture::sample(float u, float v, WrapMode wrapS, WrapMode wrapT) const {
  int x0, x1, y0, y1;
  float tx, ty;
  if (wrapS == WrapMode::Repeat && wrapT == WrapMode::Repeat && u >= 0.0f && u < 1.0f && v >= 0.0f && v < 1.0f &&
      width_ > 0) {
    // Bit for bit footprint()'s result and the blend below
    // (FastPaths.TextureUnitSquareLookups, FastPaths.Texture8BitUnitSquareLookups).
    return blendFootprint(repeatUnitFootprint(u, v, width_, height_));
  }
  if (!footprint(u, v, wrapS, wrapT, x0, x1, y0, y1, tx, ty)) return Vec3(0, 0, 0);
  const Vec3 a = texel(x0, y0) * (1 - tx) + texel(x1, y0) * tx;
  const Vec3 b = texel(x0, y1) * (1 - tx) + texel(x1, y1) * tx;
  return a * (1 - ty) + b * ty;
}

}  // namespace obscura
