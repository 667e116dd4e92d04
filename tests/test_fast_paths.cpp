// The hot-loop arithmetic made cheaper for speed (bench/bench_bare.cpp,
// README "Speed") against straightforward references computed here: the bit
// reversals of the sampler against a bit-by-bit loop, and the concentric
// map's octant sin/cos against the C library's std::sin/std::cos of the
// same angle; the lane (SIMD) forms against the scalar ones.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/math.h"
#include "core/sampler.h"
#include "core/warp.h"

namespace obscura::test {
namespace {

uint32_t reverseReference(uint32_t x) {
  uint32_t r = 0;
  for (int b = 0; b < 32; ++b) r |= ((x >> b) & 1U) << (31 - b);
  return r;
}

TEST(FastPaths, BitReversalsMatchABitLoop) {
  uint32_t x = 0x12345678U;
  for (int i = 0; i < (1 << 16); ++i) {
    x = mixBits32(x + uint32_t(i));
    const uint32_t y = mixBits32(x ^ 0xdeadbeefU);
    ASSERT_EQ(reverseBits32(x), reverseReference(x)) << x;
    const uint64_t both = reverseBits32x2(uint64_t(x) | uint64_t(y) << 32);
    ASSERT_EQ(uint32_t(both), reverseReference(x)) << x;
    ASSERT_EQ(uint32_t(both >> 32), reverseReference(y)) << y;
  }
  for (uint32_t e : {0U, 1U, 0x80000000U, 0xffffffffU}) EXPECT_EQ(reverseBits32(e), reverseReference(e));
}

// The concentric map of Shirley and Chiu written with the library's trig
// (the form the renderer used before): the polynomial octant sin/cos may
// differ from it by float rounding only. A point of the unit disk has
// coordinates of magnitude <= 1, so an absolute bound of a few float ulps
// of 1 (2^-23 = 1.2e-7) is the whole allowance.
void concentricReference(double u, double v, double& x, double& y) {
  const double a = 2 * u - 1, b = 2 * v - 1;
  if (a == 0 && b == 0) {
    x = y = 0;
    return;
  }
  const double r = std::abs(a) > std::abs(b) ? a : b;
  const double phi = std::abs(a) > std::abs(b) ? M_PI / 4 * (b / a) : M_PI / 2 - M_PI / 4 * (a / b);
  x = r * std::cos(phi);
  y = r * std::sin(phi);
}

TEST(FastPaths, ConcentricMapMatchesTheTrigForm) {
  const uint32_t key = Sampler(7).pixelKey(3, 4);
  double worst = 0;
  const auto check = [&](float u, float v) {
    float x, y;
    squareToConcentricDisk(u, v, x, y);
    double rx, ry;
    concentricReference(u, v, rx, ry);
    worst = std::max(worst, std::max(std::abs(x - rx), std::abs(y - ry)));
    ASSERT_LE(double(x) * x + double(y) * y, 1.0 + 4e-7) << u << " " << v;
  };
  for (uint32_t i = 0; i < (1U << 18); ++i) {
    const Sample2 s = Sampler::get2D(key, i, kFirstIntegratorDim);
    check(s.u, s.v);
  }
  // The centre, the diagonals (|a| = |b|: the second branch) and the edges.
  for (float u : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f - 0x1p-24f})
    for (float v : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f - 0x1p-24f}) check(u, v);
  float cx, cy;
  squareToConcentricDisk(0.5f, 0.5f, cx, cy);
  EXPECT_EQ(cx, 0.0f);
  EXPECT_EQ(cy, 0.0f);
  EXPECT_LE(worst, 3.0 * 0x1p-23) << "largest deviation from the trig form";
}

// The lane form of the cosine cone warp (SSE, four lanes at a time) equals
// the scalar warp bit for bit: on sampler points, on the centre, the
// diagonals and the edges of the square, for the hemisphere and a cone, and
// for lane counts that leave a scalar remainder.
TEST(FastPaths, CosineConeLanesEqualTheScalarWarp) {
  const uint32_t key = Sampler(11).pixelKey(5, 9);
  std::vector<float> u, v;
  for (uint32_t i = 0; i < 4096; ++i) {
    const Sample2 s = Sampler::get2D(key, i, kFirstIntegratorDim);
    u.push_back(s.u), v.push_back(s.v);
  }
  for (float a : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f - 0x1p-24f})
    for (float b : {0.0f, 0.25f, 0.5f, 0.75f, 1.0f - 0x1p-24f}) u.push_back(a), v.push_back(b);
  u.push_back(0.5f), v.push_back(0.5f);  // a remainder of 2 lanes
  for (float sinThetaMax : {1.0f, std::sin(0.3f * 1.5707964f)})
    for (size_t n : {u.size(), size_t(3), size_t(0)}) {
      std::vector<float> x(n), y(n), z(n);
      squareToCosineConeLanes(u.data(), v.data(), sinThetaMax, n, x.data(), y.data(), z.data());
      for (size_t l = 0; l < n; ++l) {
        const Vec3 w = squareToCosineCone(u[l], v[l], sinThetaMax);
        ASSERT_EQ(x[l], w.x) << u[l] << " " << v[l];
        ASSERT_EQ(y[l], w.y) << u[l] << " " << v[l];
        ASSERT_EQ(z[l], w.z) << u[l] << " " << v[l];
      }
    }
}

}  // namespace
}  // namespace obscura::test
