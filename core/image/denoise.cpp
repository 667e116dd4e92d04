// The edge-aware a-trous denoiser (core/image/denoise.h; the weights and the
// measurements behind them: docs/denoise.md).
#include "core/image/denoise.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <obscura/error.h>
#include "core/image/film.h"
#include "core/util/large_vector.h"

namespace obscura {

namespace {

// The B3-spline's taps (1, 4, 6, 4, 1) / 16: the a-trous scaling function of
// docs/denoise.md "The filter"; the 3-tap kernel and the variance
// prefilter's taps are the binomial (1, 2, 1) / 4.
constexpr float kB3[5] = {1.0f / 16, 4.0f / 16, 6.0f / 16, 4.0f / 16, 1.0f / 16};
constexpr float kBinomial3[3] = {0.25f, 0.5f, 0.25f};

// Two pixels whose normals are closer than this (cos 25 degrees) and that
// belong to one object may share an inverse-depth difference for the
// gradient (docs/denoise.md "Depth").
constexpr float kGradientNormalDot = 0.9f;

// Beyond this exponent a tap weighs < 1e-13 of the centre: clamped there
// (and so, in effect, 0) rather than branched on, to keep the loop
// branch-free.
constexpr float kMaxExponent = 30.0f;

// The per-pixel guides as planes (structure of arrays): the tap loop runs
// along a row for one tap offset at a time, so the pixels and their taps
// are consecutive floats and the loop vectorizes (docs/denoise.md "Cost").
struct Guides {
  int width = 0, height = 0;
  LargeVector<float> n[3];
  LargeVector<float> d;        // 1 / Z; -1 where the pixel holds no W (never read)
  LargeVector<float> gx, gy;   // gradient of d in pixels
  LargeVector<uint32_t> object;
  LargeVector<float> live;      // 1 where the pixel holds W, else 0
  LargeVector<float> count;     // its samples over the largest count (1 without counts), 0 without W
  LargeVector<float> albedo[3];  // un-premultiplied; empty without albedo
};

// W (un-premultiplied) and its variance: what an iteration reads and writes.
struct State {
  LargeVector<float> w[3], var;
  void resize(size_t n) {
    for (auto& c : w) c.resize(n);
    var.resize(n);
  }
};

}  // namespace

// Every plane a call writes before it reads (uninitialized on first use, a
// previous call's values after): reuse keeps the pages, nothing else.
struct DenoiseWorkspace::Planes {
  Guides g;
  State a, b;
  LargeVector<float> start;
};
DenoiseWorkspace::DenoiseWorkspace() = default;
DenoiseWorkspace::~DenoiseWorkspace() = default;

namespace {

// Parameters of one pass of taps (an a-trous iteration, or the variance
// prefilter: 3 taps at step 1, no luminance term).
struct TapPass {
  const float* kernel;
  int radius;  // taps -radius..radius
  int step;    // pixels between taps
  bool luminance;
  bool varOnly;  // the prefilter: var = weighted mean of the taps' var, W copied
};

// exp(-x) for x in [0, kMaxExponent], to ~2e-7 relative: 2^(-x log2 e)
// split into an integer power (the exponent bits) and a degree-5
// polynomial of 2^f on [-0.5, 0.5] (Taylor of e^(f ln 2)). The weights are
// ratios of sums of these, so the error is far below the noise; unlike
// std::exp it vectorizes, and it gives the same bits on every machine.
[[gnu::always_inline]] inline float expNeg(float x) {
  const float t = -x * 1.44269504f;
  // Round to nearest by adding and subtracting 1.5 * 2^23 (|t| < 44).
  const float k = (t + 12582912.0f) - 12582912.0f;
  const float f = (t - k) * 0.69314718f;
  const float p = 1.0f + f * (1.0f + f * (0.5f + f * (1.0f / 6 + f * (1.0f / 24 + f * (1.0f / 120)))));
  const int32_t bits = (int32_t(k) + 127) << 23;
  float scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

// 8-wide float and int vectors (GCC/Clang vector extensions): one AVX
// register in tapRow's AVX2 clone, two SSE2 registers in its baseline
// x86-64 clone. Every operation is per lane, so the width changes no bit.
constexpr int kLanes = 8;
// The baseline clone passes no VF across a call (everything below is
// inlined into tapRow), so GCC's -Wpsabi warning that such a call's ABI
// would differ from AVX code's does not apply (GCC may still print its
// one-time note on the parameter alignment of 32-byte vectors).
#pragma GCC diagnostic ignored "-Wpsabi"
using VF = float __attribute__((vector_size(4 * kLanes)));
using VI = int32_t __attribute__((vector_size(4 * kLanes)));
[[gnu::always_inline]] inline VF loadV(const float* p) {
  VF v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
[[gnu::always_inline]] inline void storeV(float* p, VF v) { std::memcpy(p, &v, sizeof v); }
[[gnu::always_inline]] inline VF vabs(VF a) { return a < 0.0f ? -a : a; }
[[gnu::always_inline]] inline VF vmax(VF a, VF b) { return a > b ? a : b; }
[[gnu::always_inline]] inline VF vmin(VF a, VF b) { return a < b ? a : b; }
// expNeg of kLanes values, operation for operation.
[[gnu::always_inline]] inline VF expNegV(VF x) {
  const VF t = -x * 1.44269504f;
  const VF k = (t + 12582912.0f) - 12582912.0f;
  const VF f = (t - k) * 0.69314718f;
  const VF p = 1.0f + f * (1.0f + f * (0.5f + f * (1.0f / 6 + f * (1.0f / 24 + f * (1.0f / 120)))));
  const VI bits = (__builtin_convertvector(k, VI) + 127) << 23;
  VF scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

// Per-thread sums of one row: weight, W (3), variance.
struct RowSums {
  std::vector<float> w, c[3], v;
  void reset(int width) {
    w.assign(size_t(width), 0.0f);
    for (auto& x : c) x.assign(size_t(width), 0.0f);
    v.assign(size_t(width), 0.0f);
  }
};

// The planes of one row (p's) and the row sums, for tapSpan.
struct TapRowArgs {
  const float *n0, *n1, *n2, *d, *gx, *gy, *live;
  const uint32_t* object;
  const float *w0, *w1, *w2, *var;
  const float *a0, *a1, *a2;  // albedo, or nullptr
  float *sw, *sc0, *sc1, *sc2, *sv;
};
// One tap offset: q = p + off (in pixels of the planes), its kernel weight
// and its offset in x and y (signed and absolute).
struct TapOffset {
  ptrdiff_t off;
  float k, dx, dy, adx, ady;
};

// The taps at one offset for the pixels x0..x1-1 of a row. Branch-free in x
// (the options are template parameters; a tap outside the pixel's object or
// on a pixel without W gets weight 0 by a select), so it vectorizes.
template <bool Albedo, bool Luminance, bool VarOnly>
[[gnu::always_inline]] inline void tapSpan(const TapRowArgs& r, const TapOffset& o, const DenoiseSettings& s, float invAlbedo, int x0, int x1) {
  const float* __restrict n0 = r.n0;
  const float* __restrict n1 = r.n1;
  const float* __restrict n2 = r.n2;
  const float* __restrict d = r.d;
  const float* __restrict live = r.live;
  const float* __restrict gx = r.gx;
  const float* __restrict gy = r.gy;
  const uint32_t* __restrict obj = r.object;
  const float* __restrict w0 = r.w0;
  const float* __restrict w1 = r.w1;
  const float* __restrict w2 = r.w2;
  const float* __restrict var = r.var;
  float* __restrict sw = r.sw;
  float* __restrict sc0 = r.sc0;
  float* __restrict sc1 = r.sc1;
  float* __restrict sc2 = r.sc2;
  float* __restrict sv = r.sv;
  const ptrdiff_t off = o.off;
  const float sn = s.sigmaNormal, sz = s.sigmaDepth, ez = s.depthTolerance;
  const float sl2 = s.sigmaLuminance * s.sigmaLuminance, el2 = s.luminanceTolerance * s.luminanceTolerance;
  // kLanes pixels at a time with GCC's vector extensions (the same operations in
  // the same order as the scalar loop below, which finishes the row: the
  // bits do not depend on where a row is split). GCC 12 does not
  // vectorize the scalar loop by itself ("control flow in loop").
  int x = x0;
  for (; x + kLanes <= x1; x += kLanes) {
    const ptrdiff_t q = x + off;
    const VF dot = loadV(n0 + x) * loadV(n0 + q) + loadV(n1 + x) * loadV(n1 + q) + loadV(n2 + x) * loadV(n2 + q);
    VF e = sn * vmax(VF{} , 1.0f - dot);
    const VF dx4 = loadV(d + x), gx4 = loadV(gx + x), gy4 = loadV(gy + x), dq4 = loadV(d + q);
    const VF miss = dq4 - (dx4 + gx4 * o.dx + gy4 * o.dy);
    const VF tol = sz * (vabs(gx4) * o.adx + vabs(gy4) * o.ady) + ez * dx4;
    e += miss * miss / (tol * tol);
    if constexpr (Albedo) {
      const VF da = vmax(vabs(loadV(r.a0 + x) - loadV(r.a0 + q)),
                         vmax(vabs(loadV(r.a1 + x) - loadV(r.a1 + q)), vabs(loadV(r.a2 + x) - loadV(r.a2 + q))));
      e += da * invAlbedo;
    }
    const VF wq0 = loadV(w0 + q), wq1 = loadV(w1 + q), wq2 = loadV(w2 + q), vq = loadV(var + q);
    if constexpr (Luminance) {
      const VF dl = vmax(vabs(wq0 - loadV(w0 + x)), vmax(vabs(wq1 - loadV(w1 + x)), vabs(wq2 - loadV(w2 + x))));
      e += dl * dl / (sl2 * (loadV(var + x) + vq) + el2);
    }
    const VF wk = o.k * expNegV(vmin(e, VF{} + kMaxExponent));
    const VF lw = wk * loadV(live + q);
    VI oq, ox;
    std::memcpy(&oq, obj + q, sizeof oq);
    std::memcpy(&ox, obj + x, sizeof ox);
    const VF wt = oq == ox ? lw : VF{};
    storeV(sw + x, loadV(sw + x) + wt);
    storeV(sc0 + x, loadV(sc0 + x) + wt * wq0);
    storeV(sc1 + x, loadV(sc1 + x) + wt * wq1);
    storeV(sc2 + x, loadV(sc2 + x) + wt * wq2);
    storeV(sv + x, loadV(sv + x) + (VarOnly ? wt : wt * wt) * vq);
  }
  for (; x < x1; ++x) {
    const ptrdiff_t q = x + off;
    const float dot = n0[x] * n0[q] + n1[x] * n1[q] + n2[x] * n2[q];
    float e = sn * std::max(0.0f, 1.0f - dot);
    // Inverse depth is affine in the image on a plane: predict q's from
    // p's gradient; the miss is measured against what the gradient may be
    // off by over the offset, plus a share of the depth itself.
    const float miss = d[q] - (d[x] + gx[x] * o.dx + gy[x] * o.dy);
    const float tol = sz * (std::abs(gx[x]) * o.adx + std::abs(gy[x]) * o.ady) + ez * d[x];
    e += miss * miss / (tol * tol);
    if constexpr (Albedo) {
      const float da = std::max(std::abs(r.a0[x] - r.a0[q]), std::max(std::abs(r.a1[x] - r.a1[q]), std::abs(r.a2[x] - r.a2[q])));
      e += da * invAlbedo;
    }
    if constexpr (Luminance) {
      const float dl = std::max(std::abs(w0[q] - w0[x]), std::max(std::abs(w1[q] - w1[x]), std::abs(w2[q] - w2[x])));
      // Gaussian in the difference over its standard error (no square
      // root per tap: std::sqrt's errno path keeps the loop scalar).
      e += dl * dl / (sl2 * (var[x] + var[q]) + el2);
    }
    const float wk = o.k * expNeg(std::min(e, kMaxExponent));
    // d > 0 marks a pixel with W; folded in as a factor (a second compare
    // would mix mask widths and keep the loop scalar).
    const float wt = obj[q] == obj[x] ? wk * live[q] : 0.0f;
    sw[x] += wt;
    sc0[x] += wt * w0[q];
    sc1[x] += wt * w1[q];
    sc2[x] += wt * w2[q];
    sv[x] += (VarOnly ? wt : wt * wt) * var[q];
  }
}

// A mirrored pair of taps q = p + off and q' = p - off for the pixels
// x0..x1-1 of a row (docs/denoise.md "Symmetric taps"): both get the
// smaller of their two weights, so the taps p averages are placed
// symmetrically about p and a linear change of W across them (ao's gradient
// towards a crease) cancels in the mean: without this, a pixel next to an
// edge whose taps across it are cut off averages only the side away from
// the edge, and a gradient there biases it to first order. Same operations
// per tap as tapSpan, so the same vectorization.
template <bool Albedo, bool Luminance>
[[gnu::always_inline]] inline void tapSpanPair(const TapRowArgs& r, const TapOffset& o, const DenoiseSettings& s, float invAlbedo, int x0, int x1) {
  const float* __restrict n0 = r.n0;
  const float* __restrict n1 = r.n1;
  const float* __restrict n2 = r.n2;
  const float* __restrict d = r.d;
  const float* __restrict live = r.live;
  const float* __restrict gx = r.gx;
  const float* __restrict gy = r.gy;
  const uint32_t* __restrict obj = r.object;
  const float* __restrict w0 = r.w0;
  const float* __restrict w1 = r.w1;
  const float* __restrict w2 = r.w2;
  const float* __restrict var = r.var;
  float* __restrict sw = r.sw;
  float* __restrict sc0 = r.sc0;
  float* __restrict sc1 = r.sc1;
  float* __restrict sc2 = r.sc2;
  float* __restrict sv = r.sv;
  const ptrdiff_t off = o.off;
  const float sn = s.sigmaNormal, sz = s.sigmaDepth, ez = s.depthTolerance;
  const float sl2 = s.sigmaLuminance * s.sigmaLuminance, el2 = s.luminanceTolerance * s.luminanceTolerance;
  // The exponent of the tap at q = x + qo predicted along +/- the offset
  // (sign): the terms of tapSpan.
  auto exponentV = [&](int x, ptrdiff_t qo, float sign, VI& same) __attribute__((always_inline)) {
    const ptrdiff_t q = x + qo;
    const VF dot = loadV(n0 + x) * loadV(n0 + q) + loadV(n1 + x) * loadV(n1 + q) + loadV(n2 + x) * loadV(n2 + q);
    VF e = sn * vmax(VF{}, 1.0f - dot);
    const VF dx4 = loadV(d + x), gx4 = loadV(gx + x), gy4 = loadV(gy + x), dq4 = loadV(d + q);
    const VF miss = dq4 - (dx4 + sign * (gx4 * o.dx + gy4 * o.dy));
    const VF tol = sz * (vabs(gx4) * o.adx + vabs(gy4) * o.ady) + ez * dx4;
    e += miss * miss / (tol * tol);
    if constexpr (Albedo) {
      const VF da = vmax(vabs(loadV(r.a0 + x) - loadV(r.a0 + q)),
                         vmax(vabs(loadV(r.a1 + x) - loadV(r.a1 + q)), vabs(loadV(r.a2 + x) - loadV(r.a2 + q))));
      e += da * invAlbedo;
    }
    if constexpr (Luminance) {
      const VF dl = vmax(vabs(loadV(w0 + q) - loadV(w0 + x)),
                         vmax(vabs(loadV(w1 + q) - loadV(w1 + x)), vabs(loadV(w2 + q) - loadV(w2 + x))));
      e += dl * dl / (sl2 * (loadV(var + x) + loadV(var + q)) + el2);
    }
    VI oq, ox;
    std::memcpy(&oq, obj + q, sizeof oq);
    std::memcpy(&ox, obj + x, sizeof ox);
    // Another object or no W: weight exactly 0 (a select, see below).
    same = (oq == ox) & (loadV(live + q) > 0.0f);
    return e;
  };
  auto exponent1 = [&](int x, ptrdiff_t qo, float sign, bool& same) __attribute__((always_inline)) {
    const ptrdiff_t q = x + qo;
    const float dot = n0[x] * n0[q] + n1[x] * n1[q] + n2[x] * n2[q];
    float e = sn * std::max(0.0f, 1.0f - dot);
    const float miss = d[q] - (d[x] + sign * (gx[x] * o.dx + gy[x] * o.dy));
    const float tol = sz * (std::abs(gx[x]) * o.adx + std::abs(gy[x]) * o.ady) + ez * d[x];
    e += miss * miss / (tol * tol);
    if constexpr (Albedo) {
      const float da = std::max(std::abs(r.a0[x] - r.a0[q]), std::max(std::abs(r.a1[x] - r.a1[q]), std::abs(r.a2[x] - r.a2[q])));
      e += da * invAlbedo;
    }
    if constexpr (Luminance) {
      const float dl = std::max(std::abs(w0[q] - w0[x]), std::max(std::abs(w1[q] - w1[x]), std::abs(w2[q] - w2[x])));
      e += dl * dl / (sl2 * (var[x] + var[q]) + el2);
    }
    same = obj[q] == obj[x] && live[q] > 0.0f;
    return e;
  };
  int x = x0;
  for (; x + kLanes <= x1; x += kLanes) {
    VI sq, sm;
    const VF e = vmax(exponentV(x, off, 1.0f, sq), exponentV(x, -off, -1.0f, sm));
    const VF wk = o.k * expNegV(vmin(e, VF{} + kMaxExponent));
    const ptrdiff_t q = x + off, m = x - off;
    // Both taps weigh the smaller count of the two: still a symmetric pair.
    const VF wt = (sq & sm) != 0 ? wk * vmin(loadV(live + q), loadV(live + m)) : VF{};
    storeV(sw + x, loadV(sw + x) + (wt + wt));
    storeV(sc0 + x, loadV(sc0 + x) + wt * (loadV(w0 + q) + loadV(w0 + m)));
    storeV(sc1 + x, loadV(sc1 + x) + wt * (loadV(w1 + q) + loadV(w1 + m)));
    storeV(sc2 + x, loadV(sc2 + x) + wt * (loadV(w2 + q) + loadV(w2 + m)));
    storeV(sv + x, loadV(sv + x) + wt * wt * (loadV(var + q) + loadV(var + m)));
  }
  for (; x < x1; ++x) {
    bool sq, sm;
    const float e = std::max(exponent1(x, off, 1.0f, sq), exponent1(x, -off, -1.0f, sm));
    const ptrdiff_t q = x + off, m = x - off;
    const float wt = sq && sm ? o.k * expNeg(std::min(e, kMaxExponent)) * std::min(live[q], live[m]) : 0.0f;
    sw[x] += wt + wt;
    sc0[x] += wt * (w0[q] + w0[m]);
    sc1[x] += wt * (w1[q] + w1[m]);
    sc2[x] += wt * (w2[q] + w2[m]);
    sv[x] += wt * wt * (var[q] + var[m]);
  }
}

// One pass of taps over row y: dst = the normalized weighted mean of src's
// taps, dst.var = sum w^2 var / (sum w)^2 (the variance of that mean for
// independent pixels; docs/denoise.md "Variance"). Every weight is
// kernel(i) kernel(j) exp(-E), E the sum of the terms of core/image/denoise.h.
// Hot: no allocation (the row sums are the thread's, sized once), no
// branch in the inner loop over x (a tap outside the pixel's object or on
// a pixel without W gets weight 0 by a select).
// Cloned for AVX2 (picked at load time on CPUs that have it; no FMA, so
// no contraction changes a bit): tapSpan and tapSpanPair are inlined into
// each clone, and there a VF is one register instead of two.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx2", "default")))
#endif
void tapRow(const Guides& g, const DenoiseSettings& s, const TapPass& t, const State& src, State& dst, int y,
            RowSums& sums) {
  const int w = g.width, h = g.height;
  const bool albedo = !g.albedo[0].empty();
  const float invAlbedo = 1.0f / s.sigmaAlbedo;
  const size_t row = size_t(y) * size_t(w);
  sums.reset(w);
  float* __restrict sw = sums.w.data();
  float* __restrict sc0 = sums.c[0].data();
  float* __restrict sc1 = sums.c[1].data();
  float* __restrict sc2 = sums.c[2].data();
  float* __restrict sv = sums.v.data();
  const float* n0 = g.n[0].data() + row;
  const float* n1 = g.n[1].data() + row;
  const float* n2 = g.n[2].data() + row;
  const float* dp = g.d.data() + row;
  const float* gxp = g.gx.data() + row;
  const float* gyp = g.gy.data() + row;
  const uint32_t* op = g.object.data() + row;
  // The filter's passes weigh each tap by its count (1 without counts);
  // the variance prefilter by presence only (it averages V itself).
  const float* livep = (t.varOnly ? g.live.data() : g.count.data()) + row;
  const float* w0 = src.w[0].data() + row;
  const float* w1 = src.w[1].data() + row;
  const float* w2 = src.w[2].data() + row;
  const float* vp = src.var.data() + row;
  const bool symmetric = s.symmetric && !t.varOnly;
  // The row's pixels with W lie in [lo, hi): only theirs are summed (the
  // rest are copied through below, and a pixel's sums do not depend on
  // where its span starts), so a frame that is mostly background - the
  // viking room's is 77 % - filters the rows and spans its surfaces fill.
  int lo = 0, hi = w;
  while (lo < w && !(dp[lo] > 0.0f)) ++lo;
  while (hi > lo && !(dp[hi - 1] > 0.0f)) --hi;
  for (int j = -t.radius; j <= t.radius && lo < hi; ++j) {
    const int qy = y + j * t.step;
    if (qy < 0 || qy >= h) continue;
    // Symmetric taps: the pairs (j, i) and (-j, -i) together, from the
    // half with j > 0 or j = 0 < i, both rows inside the image.
    if (symmetric && j < 0) continue;
    if (symmetric && j > 0 && (y - j * t.step < 0)) continue;
    const ptrdiff_t dyRows = ptrdiff_t(j) * t.step * w;
    const float dyPx = float(j * t.step), ady = std::abs(dyPx);
    for (int i = -t.radius; i <= t.radius; ++i) {
      const int dx = i * t.step;
      const int x0 = std::max(lo, -dx), x1 = std::min(hi, w - dx);
      const ptrdiff_t off = dyRows + dx;
      const float k = t.kernel[i + t.radius] * t.kernel[j + t.radius];
      const float dxPx = float(dx), adx = std::abs(dxPx);
      const float* pa0 = albedo ? g.albedo[0].data() + row : nullptr;
      const float* pa1 = albedo ? g.albedo[1].data() + row : nullptr;
      const float* pa2 = albedo ? g.albedo[2].data() + row : nullptr;
      const TapRowArgs r{n0, n1, n2, dp, gxp, gyp, livep, op, w0, w1, w2, vp, pa0, pa1, pa2, sw, sc0, sc1, sc2, sv};
      const TapOffset o{off, k, dxPx, dyPx, adx, ady};
      if (symmetric && (j > 0 || i > 0)) {
        const int px0 = std::max(lo, std::abs(dx)), px1 = std::min(hi, w - std::abs(dx));
        if (albedo) {
          if (t.luminance) tapSpanPair<true, true>(r, o, s, invAlbedo, px0, px1);
          else tapSpanPair<true, false>(r, o, s, invAlbedo, px0, px1);
        } else if (t.luminance) {
          tapSpanPair<false, true>(r, o, s, invAlbedo, px0, px1);
        } else {
          tapSpanPair<false, false>(r, o, s, invAlbedo, px0, px1);
        }
        continue;
      }
      if (symmetric && j == 0 && i < 0) continue;
      if (albedo) {
        if (t.luminance) tapSpan<true, true, false>(r, o, s, invAlbedo, x0, x1);
        else tapSpan<true, false, false>(r, o, s, invAlbedo, x0, x1);
      } else if (t.luminance) {
        tapSpan<false, true, false>(r, o, s, invAlbedo, x0, x1);
      } else if (t.varOnly) {
        tapSpan<false, false, true>(r, o, s, invAlbedo, x0, x1);
      } else {
        tapSpan<false, false, false>(r, o, s, invAlbedo, x0, x1);
      }
    }
  }
  // A pixel with W has its centre tap (weight > 0), so sw > 0 there; the
  // others are copied through.
  for (int x = 0; x < w; ++x) {
    const size_t p = row + size_t(x);
    const bool ok = dp[x] > 0.0f;
    dst.w[0][p] = ok && !t.varOnly ? sc0[x] / sw[x] : w0[x];
    dst.w[1][p] = ok && !t.varOnly ? sc1[x] / sw[x] : w1[x];
    dst.w[2][p] = ok && !t.varOnly ? sc2[x] / sw[x] : w2[x];
    dst.var[p] = !ok ? vp[x] : t.varOnly ? sv[x] / sw[x] : sv[x] / (sw[x] * sw[x]);
  }
}

// The variance factor of the linear a-trous filter (every weight the
// kernel's): the taps at steps 1, 2, 4, ... convolved into one kernel, the
// sum of its squares in 2D (separable: the square of the 1D sum).
double linearVarianceFactor(int iterations, int taps) {
  std::vector<double> k{1.0};
  for (int i = 0; i < iterations; ++i) {
    const int step = 1 << i, r = taps / 2;
    std::vector<double> next(k.size() + size_t(2 * r * step), 0.0);
    for (size_t j = 0; j < k.size(); ++j)
      for (int t = -r; t <= r; ++t)
        next[j + size_t((t + r) * step)] += k[j] * double(taps == 5 ? kB3[t + r] : kBinomial3[t + r]);
    k = std::move(next);
  }
  double sq = 0;
  for (double v : k) sq += v * v;
  return sq * sq;
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
  if (s.kernel != 3 && s.kernel != 5) throw Error("denoise: kernel: must be 3 or 5, got " + std::to_string(s.kernel));
  if (s.threads < 0) throw Error("denoise: threads: must be >= 0, got " + std::to_string(s.threads));
}

void denoise(const DenoiseInput& in, const DenoiseSettings& s, float* out[3]) { denoise(in, s, out, nullptr); }

void denoise(const DenoiseInput& in, const DenoiseSettings& s, float* out[3], float* gain,
             DenoiseWorkspace* workspace) {
  checkDenoise(in, s);
  if (!out && !gain) throw Error("denoise: out: no output planes and no gain asked: nothing to write");
  const int w = in.width, h = in.height;
  const size_t n = size_t(w) * size_t(h);

  // Uninitialized, on huge pages (core/util/large_vector.h): every element is
  // written by the passes below before it is read, from all threads.
  DenoiseWorkspace own;
  if (!workspace) workspace = &own;
  if (!workspace->planes) workspace->planes = std::make_unique<DenoiseWorkspace::Planes>();
  Guides& g = workspace->planes->g;
  g.width = w, g.height = h;
  for (auto& c : g.n) c.resize(n);
  g.d.resize(n), g.gx.resize(n), g.gy.resize(n), g.object.resize(n), g.live.resize(n), g.count.resize(n);
  const bool hasAlbedo = in.albedo[0] != nullptr;
  if (hasAlbedo)
    for (auto& c : g.albedo) c.resize(n);
  else
    for (auto& c : g.albedo) c.clear();  // empty: the taps read no albedo (a reused workspace may hold some)
  State& a = workspace->planes->a;
  State& b = workspace->planes->b;
  a.resize(n), b.resize(n);

  const int threads = s.threads > 0 ? s.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  tbb::enumerable_thread_specific<RowSums> rowSums;
  auto rows = [&](auto&& body) {
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& r) { body(r.begin(), r.end()); });
    });
  };
  // The largest sample count (a maximum: the same whatever the split).
  float maxCount = 0.0f;
  if (in.samples)
    arena.execute([&] {
      maxCount = tbb::parallel_reduce(
          tbb::blocked_range<size_t>(0, n, size_t(1) << 16), 0.0f,
          [&](const tbb::blocked_range<size_t>& r, float m) {
            for (size_t p = r.begin(); p != r.end(); ++p) m = std::max(m, in.samples[p]);
            return m;
          },
          [](float a, float b) { return std::max(a, b); });
    });

  // Un-premultiply W and albedo; invalid pixels (no coverage, background
  // depth, non-finite data) keep their colour and are never read.
  // A span of pixels at a time, one plane per loop (the validity first):
  // the same operations per pixel as one loop over all ~25 planes, which
  // GCC kept scalar and spent reloading the planes' pointers.
  rows([&](int y0, int y1) {
    constexpr size_t kSpan = 512;
    bool okSpan[kSpan];
    // s0: the span's first pixel, len its pixels (n and b name the frame's
    // pixel count and the second state).
    for (size_t s0 = size_t(y0) * size_t(w), end = size_t(y1) * size_t(w); s0 < end; s0 += kSpan) {
      const size_t len = std::min(kSpan, end - s0);
      const float* __restrict al = in.alpha + s0;
      const float* __restrict z = in.depth + s0;
      const float* __restrict v = in.variance + s0;
      bool* __restrict ok = okSpan;
      for (size_t i = 0; i < len; ++i) {
        bool k = al[i] > 0.0f && z[i] > 0.0f && z[i] < kBackgroundDepth && std::isfinite(z[i]) && std::isfinite(v[i]);
        for (int c = 0; c < 3; ++c) k = k && std::isfinite(in.color[c][s0 + i]) && std::isfinite(in.normal[c][s0 + i]);
        ok[i] = k;
      }
      for (int c = 0; c < 3; ++c) {
        const float* __restrict nc = in.normal[c] + s0;
        const float* __restrict wc = in.color[c] + s0;
        float* __restrict gn = g.n[c].data() + s0;
        float* __restrict aw = a.w[c].data() + s0;
        for (size_t i = 0; i < len; ++i) gn[i] = ok[i] ? nc[i] : 0.0f;
        for (size_t i = 0; i < len; ++i) aw[i] = ok[i] ? wc[i] / al[i] : wc[i];
        if (hasAlbedo) {
          const float* __restrict ac = in.albedo[c] + s0;
          float* __restrict ga = g.albedo[c].data() + s0;
          for (size_t i = 0; i < len; ++i) ga[i] = ok[i] ? ac[i] / al[i] : 0.0f;
        }
      }
      float* __restrict d = g.d.data() + s0;
      float* __restrict live = g.live.data() + s0;
      float* __restrict count = g.count.data() + s0;
      float* __restrict var = a.var.data() + s0;
      for (size_t i = 0; i < len; ++i) d[i] = ok[i] ? 1.0f / z[i] : -1.0f;
      for (size_t i = 0; i < len; ++i) live[i] = ok[i] ? 1.0f : 0.0f;
      // samples / max: equal counts give exactly 1.
      for (size_t i = 0; i < len; ++i)
        count[i] = !ok[i] ? 0.0f : maxCount > 0.0f ? std::max(in.samples[s0 + i], 1.0f) / maxCount : 1.0f;
      for (size_t i = 0; i < len; ++i) var[i] = ok[i] ? std::max(0.0f, v[i]) : 0.0f;
      std::fill_n(g.gx.data() + s0, len, 0.0f);
      std::fill_n(g.gy.data() + s0, len, 0.0f);
      if (in.object)
        std::copy_n(in.object + s0, len, g.object.data() + s0);
      else
        std::fill_n(g.object.data() + s0, len, 0u);
    }
  });

  // The inverse-depth gradient from the neighbours on p's surface (same
  // object, normals within 25 degrees): the central difference where both
  // sides agree within a factor 2, else the smaller one-sided difference
  // (the other side crosses a depth step), one side where only one joins,
  // 0 where none does.
  auto joins = [&](size_t p, size_t q) {
    return g.d[q] > 0.0f && g.object[q] == g.object[p] &&
           g.n[0][p] * g.n[0][q] + g.n[1][p] * g.n[1][q] + g.n[2][p] * g.n[2][q] > kGradientNormalDot;
  };
  auto gradient = [&](size_t p, bool hasLo, size_t lo, bool hasHi, size_t hi) {
    const bool l = hasLo && joins(p, lo), u = hasHi && joins(p, hi);
    const float dl = l ? g.d[p] - g.d[lo] : 0.0f, du = u ? g.d[hi] - g.d[p] : 0.0f;
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
        if (!(g.d[p] > 0.0f)) continue;
        g.gx[p] = gradient(p, x > 0, p - 1, x + 1 < w, p + 1);
        g.gy[p] = gradient(p, y > 0, p - size_t(w), y + 1 < h, p + size_t(w));
      }
  });

  State* src = &a;
  State* dst = &b;
  auto pass = [&](const TapPass& t) {
    rows([&](int y0, int y1) {
      RowSums& sums = rowSums.local();
      for (int y = y0; y < y1; ++y) tapRow(g, s, t, *src, *dst, y, sums);
    });
    std::swap(src, dst);
  };
  // The variance estimate from two halves of the samples is itself noisy
  // (one degree of freedom): a 3 x 3 guided mean steadies it before the
  // luminance term reads it (docs/denoise.md "Variance").
  const bool luminance = s.sigmaLuminance > 0.0f;
  if (s.iterations > 0 && luminance) pass(TapPass{kBinomial3, 1, 1, false, true});
  // The variance the iterations start from, for the gain.
  LargeVector<float>& start = workspace->planes->start;
  if (gain) start = src->var;
  for (int it = 0; it < s.iterations; ++it)
    pass(s.kernel == 3 ? TapPass{kBinomial3, 1, 1 << it, luminance, false} : TapPass{kB3, 2, 1 << it, luminance, false});

  if (out)
    rows([&](int y0, int y1) {
      for (size_t p = size_t(y0) * size_t(w); p < size_t(y1) * size_t(w); ++p)
        for (int c = 0; c < 3; ++c) out[c][p] = g.d[p] > 0.0f ? src->w[c][p] * in.alpha[p] : in.color[c][p];
    });
  if (gain) {
    // The propagated variance takes the pixels as independent, which they
    // are not after the first iteration: in a flat region it falls as the
    // product of the iterations' factors, far below what the filter
    // achieves. No weights average more than the plain kernel over the
    // whole footprint, whose variance factor (the sum of squares of its
    // equivalent kernel, correlations included) is the floor.
    const float floor = float(linearVarianceFactor(s.iterations, s.kernel));
    rows([&](int y0, int y1) {
      for (size_t p = size_t(y0) * size_t(w); p < size_t(y1) * size_t(w); ++p)
        gain[p] = g.d[p] > 0.0f && start[p] > 0.0f ? std::clamp(src->var[p] / start[p], floor, 1.0f) : 1.0f;
    });
  }
}

}  // namespace obscura
