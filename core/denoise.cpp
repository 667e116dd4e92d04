// The edge-aware a-trous denoiser (core/denoise.h; the weights and the
// measurements behind them: docs/denoise.md).
#include "core/denoise.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/film.h"

namespace obscura {

namespace {

// The B3-spline's taps (1, 4, 6, 4, 1) / 16: the a-trous scaling function of
// docs/denoise.md "The filter"; the variance prefilter's 3 x 3 taps are
// (1, 2, 1) / 4.
constexpr float kB3[5] = {1.0f / 16, 4.0f / 16, 6.0f / 16, 4.0f / 16, 1.0f / 16};
constexpr float kBinomial3[3] = {0.25f, 0.5f, 0.25f};

// Two pixels whose normals are closer than this (cos 25 degrees) and that
// belong to one object may share an inverse-depth difference for the
// gradient (docs/denoise.md "Depth").
constexpr float kGradientNormalDot = 0.9f;

// The per-pixel guides, un-premultiplied and laid out for the tap loop.
struct Guides {
  int width = 0, height = 0;
  std::vector<uint8_t> valid;              // alpha > 0 and a finite depth below the background's
  std::vector<float> invDepth, gx, gy;     // d = 1 / Z and its gradient in pixels
  const float* normal[3] = {nullptr, nullptr, nullptr};
  std::vector<float> albedo[3];            // un-premultiplied; empty without albedo
  const uint32_t* object = nullptr;
  bool hasAlbedo = false;
};

// The planes one iteration reads and writes: W (3 channels, un-premultiplied)
// and its variance.
struct Planes {
  std::vector<float> w[3];
  std::vector<float> var;
  void resize(size_t n) {
    for (auto& c : w) c.assign(n, 0.0f);
    var.assign(n, 0.0f);
  }
};

// Parameters of one pass of taps (an a-trous iteration, or the variance
// prefilter: 3 taps at step 1, no luminance term).
struct TapPass {
  const float* kernel;
  int radius;  // taps -radius..radius
  int step;    // pixels between taps
  bool luminance;
};

// exp(-E) of the guide terms (normal, depth, albedo) between p and its tap q
// at offset (dx, dy), or 0 if q holds no W or another object. Hot: no
// allocation, one exp per tap (the terms are summed in the exponent).
inline float guideExponent(const Guides& g, const DenoiseSettings& s, size_t p, size_t q, int dx, int dy, bool& ok) {
  ok = g.valid[q] && (!g.object || g.object[q] == g.object[p]);
  if (!ok) return 0.0f;
  const float dot = g.normal[0][p] * g.normal[0][q] + g.normal[1][p] * g.normal[1][q] + g.normal[2][p] * g.normal[2][q];
  float e = s.sigmaNormal * std::max(0.0f, 1.0f - dot);
  // Inverse depth is affine in the image on a plane (docs/denoise.md
  // "Depth"): predict q's from p's gradient, and measure the miss against
  // what the gradient itself may be off by over that offset.
  const float lx = g.gx[p] * float(dx), ly = g.gy[p] * float(dy);
  const float miss = g.invDepth[q] - (g.invDepth[p] + lx + ly);
  const float tol = s.sigmaDepth * (std::abs(lx) + std::abs(ly)) + s.depthTolerance * g.invDepth[p];
  const float r = miss / tol;
  e += r * r;
  if (g.hasAlbedo) {
    float da = 0.0f;
    for (int c = 0; c < 3; ++c) da = std::max(da, std::abs(g.albedo[c][p] - g.albedo[c][q]));
    e += da / s.sigmaAlbedo;
  }
  return e;
}

// One pass of taps over rows [y0, y1): dst = the normalized weighted mean of
// src's taps, dst.var = sum w^2 var / (sum w)^2 (the variance of that mean
// for independent pixels; docs/denoise.md "Variance through the
// iterations"). With varOnly the W planes are copied and only var is
// filtered (the prefilter of the variance estimate).
void tapRows(const Guides& g, const DenoiseSettings& s, const TapPass& t, const Planes& src, Planes& dst, int y0, int y1,
             bool varOnly) {
  const int w = g.width, h = g.height;
  for (int y = y0; y < y1; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t p = size_t(y) * size_t(w) + size_t(x);
      if (!g.valid[p]) {
        for (int c = 0; c < 3; ++c) dst.w[c][p] = src.w[c][p];
        dst.var[p] = src.var[p];
        continue;
      }
      const float wp[3] = {src.w[0][p], src.w[1][p], src.w[2][p]};
      const float vp = src.var[p];
      float sumW = 0.0f, sumC[3] = {0.0f, 0.0f, 0.0f}, sumV = 0.0f;
      for (int j = -t.radius; j <= t.radius; ++j) {
        const int qy = y + j * t.step;
        if (qy < 0 || qy >= h) continue;
        for (int i = -t.radius; i <= t.radius; ++i) {
          const int qx = x + i * t.step;
          if (qx < 0 || qx >= w) continue;
          const size_t q = size_t(qy) * size_t(w) + size_t(qx);
          bool ok;
          float e = guideExponent(g, s, p, q, i * t.step, j * t.step, ok);
          if (!ok) continue;
          if (t.luminance) {
            float dl = 0.0f;
            for (int c = 0; c < 3; ++c) dl = std::max(dl, std::abs(src.w[c][q] - wp[c]));
            e += dl / (s.sigmaLuminance * std::sqrt(vp + src.var[q]) + s.luminanceTolerance);
          }
          const float wt = t.kernel[i + t.radius] * t.kernel[j + t.radius] * std::exp(-e);
          sumW += wt;
          for (int c = 0; c < 3; ++c) sumC[c] += wt * src.w[c][q];
          sumV += varOnly ? wt * src.var[q] : wt * wt * src.var[q];
        }
      }
      // The centre tap always counts (e = 0), so sumW > 0.
      for (int c = 0; c < 3; ++c) dst.w[c][p] = varOnly ? wp[c] : sumC[c] / sumW;
      dst.var[p] = varOnly ? sumV / sumW : sumV / (sumW * sumW);
    }
}

void checkPlane(const void* p, const char* field) {
  if (!p) throw Error(std::string("denoise: ") + field + ": plane missing");
}

}  // namespace

void checkDenoise(const DenoiseInput& in, const DenoiseSettings& s) {
  if (in.width <= 0 || in.height <= 0)
    throw Error("denoise: size: " + std::to_string(in.width) + "x" + std::to_string(in.height) + " is empty");
  for (int c = 0; c < 3; ++c) checkPlane(in.color[c], "color");
  checkPlane(in.alpha, "alpha");
  checkPlane(in.variance, "variance");
  for (int c = 0; c < 3; ++c) checkPlane(in.normal[c], "normal");
  checkPlane(in.depth, "depth");
  const int albedoPlanes = (in.albedo[0] != nullptr) + (in.albedo[1] != nullptr) + (in.albedo[2] != nullptr);
  if (albedoPlanes != 0 && albedoPlanes != 3) throw Error("denoise: albedo: give all three planes or none");
  auto positive = [](float v, const char* field) {
    if (!(v > 0.0f) || !std::isfinite(v))
      throw Error(std::string("denoise: ") + field + ": must be a positive finite number, got " + std::to_string(v));
  };
  if (s.iterations < 0 || s.iterations > 10)
    throw Error("denoise: iterations: must be in 0..10, got " + std::to_string(s.iterations));
  if (!(s.sigmaNormal >= 0.0f) || !std::isfinite(s.sigmaNormal))
    throw Error("denoise: sigmaNormal: must be a finite number >= 0, got " + std::to_string(s.sigmaNormal));
  positive(s.sigmaDepth, "sigmaDepth");
  positive(s.depthTolerance, "depthTolerance");
  if (!(s.sigmaLuminance >= 0.0f) || !std::isfinite(s.sigmaLuminance))
    throw Error("denoise: sigmaLuminance: must be a finite number >= 0, got " + std::to_string(s.sigmaLuminance));
  positive(s.luminanceTolerance, "luminanceTolerance");
  positive(s.sigmaAlbedo, "sigmaAlbedo");
  if (s.threads < 0) throw Error("denoise: threads: must be >= 0, got " + std::to_string(s.threads));
}

void denoise(const DenoiseInput& in, const DenoiseSettings& s, float* out[3]) {
  checkDenoise(in, s);
  const int w = in.width, h = in.height;
  const size_t n = size_t(w) * size_t(h);

  Guides g;
  g.width = w, g.height = h;
  g.valid.assign(n, 0);
  g.invDepth.assign(n, 0.0f);
  g.gx.assign(n, 0.0f);
  g.gy.assign(n, 0.0f);
  for (int c = 0; c < 3; ++c) g.normal[c] = in.normal[c];
  g.object = in.object;
  g.hasAlbedo = in.albedo[0] != nullptr;
  if (g.hasAlbedo)
    for (auto& a : g.albedo) a.assign(n, 0.0f);
  Planes a, b;
  a.resize(n);
  b.resize(n);

  const int threads = s.threads > 0 ? s.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  auto rows = [&](auto&& body) {
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& r) { body(r.begin(), r.end()); });
    });
  };

  // Un-premultiply W and albedo; invalid pixels (no coverage, background
  // depth, non-finite data) keep their colour and are never read.
  rows([&](int y0, int y1) {
    for (size_t p = size_t(y0) * size_t(w); p < size_t(y1) * size_t(w); ++p) {
      const float al = in.alpha[p], z = in.depth[p];
      bool ok = al > 0.0f && z > 0.0f && z < kBackgroundDepth && std::isfinite(z) && std::isfinite(in.variance[p]);
      for (int c = 0; c < 3; ++c) ok = ok && std::isfinite(in.color[c][p]) && std::isfinite(in.normal[c][p]);
      g.valid[p] = ok;
      for (int c = 0; c < 3; ++c) a.w[c][p] = ok ? in.color[c][p] / al : in.color[c][p];
      a.var[p] = ok ? std::max(0.0f, in.variance[p]) : 0.0f;
      g.invDepth[p] = ok ? 1.0f / z : 0.0f;
      if (g.hasAlbedo)
        for (int c = 0; c < 3; ++c) g.albedo[c][p] = ok ? in.albedo[c][p] / al : 0.0f;
    }
  });

  // The inverse-depth gradient from the neighbours on p's surface (same
  // object, normals within 25 degrees): the central difference where both
  // sides agree within a factor 2, else the smaller one-sided difference
  // (the other side crosses a depth step), one side where only one joins,
  // 0 where none does.
  auto joins = [&](size_t p, size_t q) {
    if (!g.valid[q] || (g.object && g.object[q] != g.object[p])) return false;
    const float dot = in.normal[0][p] * in.normal[0][q] + in.normal[1][p] * in.normal[1][q] + in.normal[2][p] * in.normal[2][q];
    return dot > kGradientNormalDot;
  };
  auto gradient = [&](size_t p, bool hasLo, size_t lo, bool hasHi, size_t hi) {
    const bool l = hasLo && joins(p, lo), u = hasHi && joins(p, hi);
    const float dl = l ? g.invDepth[p] - g.invDepth[lo] : 0.0f, du = u ? g.invDepth[hi] - g.invDepth[p] : 0.0f;
    if (l && u) {
      if (std::abs(dl - du) <= 0.5f * std::max(std::abs(dl), std::abs(du))) return 0.5f * (dl + du);
      return std::abs(dl) < std::abs(du) ? dl : du;
    }
    return l ? dl : du;
  };
  rows([&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < w; ++x) {
        const size_t p = size_t(y) * size_t(w) + size_t(x);
        if (!g.valid[p]) continue;
        g.gx[p] = gradient(p, x > 0, p - 1, x + 1 < w, p + 1);
        g.gy[p] = gradient(p, y > 0, p - size_t(w), y + 1 < h, p + size_t(w));
      }
  });

  // The variance estimate from two halves of the samples is itself noisy
  // (one degree of freedom): a 3 x 3 guided mean steadies it before the
  // luminance term reads it (docs/denoise.md "Variance").
  Planes* src = &a;
  Planes* dst = &b;
  if (s.iterations > 0 && s.sigmaLuminance > 0.0f) {
    const TapPass pre{kBinomial3, 1, 1, false};
    rows([&](int y0, int y1) { tapRows(g, s, pre, *src, *dst, y0, y1, true); });
    std::swap(src, dst);
  }
  for (int it = 0; it < s.iterations; ++it) {
    const TapPass t{kB3, 2, 1 << it, s.sigmaLuminance > 0.0f};
    rows([&](int y0, int y1) { tapRows(g, s, t, *src, *dst, y0, y1, false); });
    std::swap(src, dst);
  }

  rows([&](int y0, int y1) {
    for (size_t p = size_t(y0) * size_t(w); p < size_t(y1) * size_t(w); ++p)
      for (int c = 0; c < 3; ++c) out[c][p] = g.valid[p] ? src->w[c][p] * in.alpha[p] : in.color[c][p];
  });
}

}  // namespace obscura
