// Warps from the unit square to the distributions the renderer samples.
#pragma once

#include <array>
#include <cmath>

#include "core/math.h"

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
