// Warps from the unit square to the distributions the renderer samples.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <obscura/math.h>

namespace obscura {

// sin and cos of x = (pi/4) t for t in [-1, 1] (|x| <= pi/4): their Taylor
// series to degree 9 and 10, whose first omitted terms are below
// (pi/4)^11/11! < 2e-9 and (pi/4)^12/12! < 2e-10, far under float's
// resolution; what remains is the rounding of the Horner steps, an ulp or
// two. No call, no branch, no range reduction: the concentric map below
// only ever needs this octant (sincosf cost 3 % of an `ao` render).
inline void sinCosQuarterPi(float t, float& s, float& c) {
  const float x = (kPi / 4.0f) * t, x2 = x * x;
  s = x * (1.0f + x2 * (-1.0f / 6.0f + x2 * (1.0f / 120.0f + x2 * (-1.0f / 5040.0f + x2 * (1.0f / 362880.0f)))));
  c = 1.0f + x2 * (-0.5f + x2 * (1.0f / 24.0f + x2 * (-1.0f / 720.0f + x2 * (1.0f / 40320.0f +
                                                                               x2 * (-1.0f / 3628800.0f)))));
}

// Shirley-Chiu concentric map of [0,1)^2 to the unit disk: area preserving
// and low-distortion, so stratification of (u,v) survives the warp
// (docs/math.md §1). With a = 2u - 1, b = 2v - 1: where |a| > |b| the point
// is r = a at phi = (pi/4)(b/a), i.e. (a cos, a sin) of (pi/4) t, t = b/a;
// elsewhere r = b at phi = pi/2 - (pi/4)(a/b), i.e. (b sin, b cos) of
// (pi/4) t, t = a/b. Written without branches (the side is a coin flip per
// sample) and with the octant's sin/cos above; the centre a = b = 0 gives
// t = 0/(0 + 1) and r = 0, the point (0, 0).
inline void squareToConcentricDisk(float u, float v, float& dx, float& dy) {
  const float a = 2.0f * u - 1.0f, b = 2.0f * v - 1.0f;
  const bool wide = std::abs(a) > std::abs(b);
  const float r = wide ? a : b;
  const float t = (wide ? b : a) / (r + float(r == 0.0f));
  float s, c;
  sinCosQuarterPi(t, s, c);
  dx = r * (wide ? c : s);
  dy = r * (wide ? s : c);
}

// Direction with density cos(theta) / (pi sin^2(thetaMax)) over the cone
// theta < thetaMax about +z, from sinThetaMax = sin(thetaMax) in (0, 1]
// (the `spread` lobe, docs/math.md §11). Malley's method again: a point
// uniform on the disk of radius s = sinThetaMax (density 1/(pi s^2) per unit
// area) projected straight up to the unit hemisphere lands at
// z = sqrt(1 - r^2) = cos(theta), r = sin(theta) <= s, so inside the cone; the
// projection's area element is dA = cos(theta) dw, hence the density
// cos(theta)/(pi s^2) per solid angle, which integrates to 1 over the cone.
// The uniform disk of radius s is the unit concentric disk scaled by s (area
// preserving up to the constant s^2, so stratification survives).
// s = 1 is the cosine hemisphere, with the arithmetic of the hemisphere warp
// before the cone existed: x * 1.0f == x exactly in IEEE arithmetic.
inline Vec3 squareToCosineCone(float u, float v, float sinThetaMax) {
  float x, y;
  squareToConcentricDisk(u, v, x, y);
  x *= sinThetaMax;
  y *= sinThetaMax;
  const float z = std::sqrt(std::max(0.0f, 1.0f - x * x - y * y));
  return {x, y, z};
}

// squareToCosineCone for n lanes at once, bit for bit: (x, y, z)[l] of
// (u, v)[l], four lanes per SSE instruction. The same IEEE operations in the
// same order (products, sums, the correctly rounded division and square
// root; selects for the branch-free sides; max(val, 0) keeps std::max(0,
// val)'s result for NaN and -0 alike), no fused multiply-add, so every lane
// equals the scalar warp (tests/test_warp.cpp); the scalar warp takes the
// remainder. One ray at a time the warp's division and square root stall
// (pushCosineRays was a sixth of an `ao` render, perf).
inline void squareToCosineConeLanes(const float* u, const float* v, float sinThetaMax, size_t n, float* x, float* y,
                                    float* z) {
  size_t l = 0;
#if defined(__SSE2__)
  const __m128 one = _mm_set1_ps(1.0f), two = _mm_set1_ps(2.0f), zero = _mm_setzero_ps();
  const __m128 signBit = _mm_set1_ps(-0.0f), scale = _mm_set1_ps(sinThetaMax);
  const auto select = [](__m128 mask, __m128 a, __m128 b) {
    return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b));
  };
  const auto madd = [](__m128 a, __m128 b, float c) { return _mm_add_ps(_mm_set1_ps(c), _mm_mul_ps(a, b)); };
  for (; l + 4 <= n; l += 4) {
    const __m128 a = _mm_sub_ps(_mm_mul_ps(two, _mm_loadu_ps(u + l)), one);
    const __m128 b = _mm_sub_ps(_mm_mul_ps(two, _mm_loadu_ps(v + l)), one);
    const __m128 wide = _mm_cmpgt_ps(_mm_andnot_ps(signBit, a), _mm_andnot_ps(signBit, b));
    const __m128 r = select(wide, a, b);
    const __m128 t = _mm_div_ps(select(wide, b, a), _mm_add_ps(r, _mm_and_ps(_mm_cmpeq_ps(r, zero), one)));
    // sinCosQuarterPi, term for term.
    const __m128 q = _mm_mul_ps(_mm_set1_ps(kPi / 4.0f), t), q2 = _mm_mul_ps(q, q);
    const __m128 sn = _mm_mul_ps(
        q, madd(q2, madd(q2, madd(q2, madd(q2, _mm_set1_ps(1.0f / 362880.0f), -1.0f / 5040.0f), 1.0f / 120.0f),
                         -1.0f / 6.0f),
                1.0f));
    const __m128 cs = madd(
        q2,
        madd(q2, madd(q2, madd(q2, madd(q2, _mm_set1_ps(-1.0f / 3628800.0f), 1.0f / 40320.0f), -1.0f / 720.0f),
                      1.0f / 24.0f),
             -0.5f),
        1.0f);
    const __m128 dx = _mm_mul_ps(_mm_mul_ps(r, select(wide, cs, sn)), scale);
    const __m128 dy = _mm_mul_ps(_mm_mul_ps(r, select(wide, sn, cs)), scale);
    const __m128 dz =
        _mm_sqrt_ps(_mm_max_ps(_mm_sub_ps(_mm_sub_ps(one, _mm_mul_ps(dx, dx)), _mm_mul_ps(dy, dy)), zero));
    _mm_storeu_ps(x + l, dx);
    _mm_storeu_ps(y + l, dy);
    _mm_storeu_ps(z + l, dz);
  }
#endif
  for (; l < n; ++l) {
    const Vec3 w = squareToCosineCone(u[l], v[l], sinThetaMax);
    x[l] = w.x, y[l] = w.y, z[l] = w.z;
  }
}

// Direction with density cos(theta)/pi about +z (Malley's method: project the
// uniform disk up to the hemisphere). docs/math.md §1: with this density
// the estimator of W = (1/pi) int V cos dw is the plain mean of V. The cone
// of half-angle pi/2, exactly (see above).
inline Vec3 squareToCosineHemisphere(float u, float v) { return squareToCosineCone(u, v, 1.0f); }

// Direction with uniform density 1/(2 pi (1 - cos(thetaMax))) over the cone
// theta < thetaMax about +z: z = cos(theta) uniform on [cosThetaMax, 1]
// (Archimedes: equal z-slabs of the sphere have equal area). cosThetaMax = 0
// gives z = 0 + u * 1 == u exactly.
inline Vec3 squareToUniformCone(float u, float v, float cosThetaMax) {
  const float z = cosThetaMax + u * (1.0f - cosThetaMax);
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  const float phi = 2.0f * kPi * v;
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Direction with uniform density 1/(2 pi) over the hemisphere about +z
// (z = cos(theta) is uniform on [0, 1]): the cone of half-angle pi/2.
inline Vec3 squareToUniformHemisphere(float u, float v) { return squareToUniformCone(u, v, 0.0f); }

// Direction with density (m + 1)/(2 pi) cos^m(theta) over the hemisphere
// theta < pi/2 about +z (a normalised Phong lobe, docs/math.md §12), given
// e = 1/(m + 1) in [0, 1] rather than m, so that the mirror limit m -> inf
// is e = 0 and nothing is infinite. The cdf of c = cos(theta) is
// P(cos theta <= c) = c^(m+1), inverted as c = (1 - u)^e = exp(e log1p(-u));
// sin^2 = 1 - c^2 = -expm1(2 e log1p(-u)) keeps its digits as e -> 0 (where
// 1 - c^2 would cancel to 0 and then round). u < 1, so the log is finite:
// e = 0 gives exactly (0, 0, 1), e = 1 (m = 0) the uniform hemisphere.
inline Vec3 squareToPowerCosine(float u, float v, float e) {
  const float t = e * std::log1p(-u);  // log cos(theta), in [-17, 0]
  const float z = std::exp(t);
  const float s = std::sqrt(std::max(0.0f, -std::expm1(2.0f * t)));
  const float phi = 2.0f * kPi * v;
  return {s * std::cos(phi), s * std::sin(phi), z};
}

// Pixel reconstruction by filter importance sampling: each camera sample is
// offset from the pixel centre with a density equal to the normalised filter,
// and weighted 1. A sample therefore belongs to exactly one pixel, which
// keeps tiles independent and the result bit-identical for any tiling.
enum class PixelFilter { Box, Gaussian };

// Truncated Gaussian, standard deviation 0.5 px, radius 1.5 px (3 sigma),
// sampled by a tabulated inverse CDF computed once from std::erf.
class GaussianFilterSampler {
 public:
  static constexpr float kSigma = 0.5f;
  static constexpr float kRadius = 1.5f;
  static const GaussianFilterSampler& instance() {
    static const GaussianFilterSampler s;
    return s;
  }
  // u in [0,1) -> offset in [-kRadius, kRadius] pixels.
  float sample(float u) const {
    const float x = u * float(kTable - 1);
    const int i = std::min(int(x), kTable - 2);
    const float t = x - float(i);
    return inv_[i] + t * (inv_[i + 1] - inv_[i]);
  }

 private:
  static constexpr int kTable = 1025;
  GaussianFilterSampler() {
    // CDF of the truncated normal, inverted by bisection at each table node.
    const double s = kSigma * std::sqrt(2.0), lo = std::erf(-kRadius / s),
                 hi = std::erf(kRadius / s);
    for (int k = 0; k < kTable; ++k) {
      const double target = double(k) / double(kTable - 1);
      double a = -kRadius, b = kRadius;
      for (int it = 0; it < 60; ++it) {
        const double m = 0.5 * (a + b);
        const double cdf = (std::erf(m / s) - lo) / (hi - lo);
        (cdf < target ? a : b) = m;
      }
      inv_[k] = float(0.5 * (a + b));
    }
  }
  std::array<float, kTable> inv_{};
};

}  // namespace obscura
