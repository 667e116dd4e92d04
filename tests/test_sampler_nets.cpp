// The sampler (include/obscura/sampler.h) against properties computed independently of
// its code: the unscrambled Sobol' dimensions against the direction numbers
// of their definition, and the scrambled sequences against the net
// properties that make them worth using.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include <obscura/sampler.h>

namespace obscura::test {
namespace {

// Sobol' dimension 1 from its definition (Bratley and Fox 1988): primitive
// polynomial x + 1 (degree s = 1, no inner coefficients), initial direction
// integer m_1 = 1 and the recurrence m_j = 2 m_(j-1) XOR m_(j-1); direction
// numbers v_j = m_j / 2^j, and the i-th point XORs v_j over the set bits j of
// i (bit 0 <-> v_1). A different formulation from the sampler's (columns of
// the Pascal matrix mod 2).
uint32_t sobol1Reference(uint32_t i) {
  uint32_t m = 1, r = 0;
  for (int j = 1; j <= 32; ++j, m = (m << 1) ^ m) {
    if ((i >> (j - 1)) & 1U) r ^= m << (32 - j);  // m_j < 2^j: v_j as a 32-bit fraction
  }
  return r;
}

TEST(SobolSequence, UnscrambledDimensionsMatchTheirDefinition) {
  // The first points of dimension 1 as published (e.g. Joe and Kuo's
  // tables: 0, 1/2, 3/4, 1/4, 5/8, 1/8, 3/8, 7/8 in index order).
  const double first[] = {0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875};
  for (uint32_t i = 0; i < 8; ++i) {
    EXPECT_EQ(double(sobol1(i)) * 0x1p-32, first[i]) << i;
    EXPECT_EQ(sobol1Reference(i), sobol1(i)) << i;
  }
  for (uint32_t i = 0; i < (1U << 16); ++i) ASSERT_EQ(sobol1(i), sobol1Reference(i)) << i;
  for (uint64_t k = 0; k < (1ULL << 32); k += 65537ULL * 3 + 1)
    ASSERT_EQ(sobol1(uint32_t(k)), sobol1Reference(uint32_t(k)));
  EXPECT_EQ(sobol1(0xffffffffU), sobol1Reference(0xffffffffU));
  // The reversed tables are the bit reversal; dimension 0 is van der Corput.
  for (uint32_t i = 0; i < (1U << 16); ++i) {
    ASSERT_EQ(sobol1Reversed(i * 40503U), reverseBits32(sobol1(i * 40503U)));
    uint32_t r = 0;
    for (int b = 0; b < 32; ++b) r |= ((i >> b) & 1U) << (31 - b);
    ASSERT_EQ(sobol0(i), r);
  }
}

// The table-free form of the reversed dimension 1 (the superset-sum steps)
// against the definition above, and the lane form of get2D against the
// scalar one, bit for bit, on every lane count up to a few SIMD widths and
// on unaligned lanes (the loop's vector body and its scalar remainder).
TEST(SobolSequence, LaneFormsMatchTheScalarForm) {
  for (uint32_t i = 0; i < (1U << 16); ++i)
    ASSERT_EQ(sobol1ReversedShifts(i), reverseBits32(sobol1Reference(i))) << i;
  for (uint64_t k = 0; k < (1ULL << 32); k += 65537ULL * 3 + 1)
    ASSERT_EQ(sobol1ReversedShifts(uint32_t(k)), reverseBits32(sobol1Reference(uint32_t(k))));
  constexpr size_t kMax = 77;
  std::vector<uint32_t> si(kMax + 1), sx(kMax + 1), sy(kMax + 1), index(kMax + 1);
  std::vector<float> u(kMax + 1), v(kMax + 1);
  const Sampler sampler(7);
  for (size_t n = 0; n <= kMax; ++n)
    for (size_t offset : {size_t(0), size_t(1)}) {
      const size_t m = std::min(n, kMax + 1 - offset);
      for (size_t l = 0; l < m; ++l) {
        // Lanes of a few pixels and dimensions, indices small and large.
        const Sampler::Seeds2 s = Sampler::seeds2D(sampler.pixelKey(uint32_t(l / 5), 3), uint32_t(l % 3));
        si[offset + l] = s.index, sx[offset + l] = s.x, sy[offset + l] = s.y;
        index[offset + l] = l % 2 ? uint32_t(l) : mixBits32(uint32_t(l + n));
      }
      Sampler::get2DLanes(si.data() + offset, sx.data() + offset, sy.data() + offset, index.data() + offset, m,
                          u.data() + offset, v.data() + offset);
      for (size_t l = 0; l < m; ++l) {
        const Sample2 e = Sampler::get2D({si[offset + l], sx[offset + l], sy[offset + l]}, index[offset + l]);
        ASSERT_EQ(u[offset + l], e.u) << n << " " << l;
        ASSERT_EQ(v[offset + l], e.v) << n << " " << l;
      }
    }
}

// The scrambled sequence of every pixel and dimension pair: the first 2^m
// points form a (0, m, 2)-net in base 2 - exactly one point in each
// elementary interval [i/2^a, (i+1)/2^a) x [j/2^(m-a), (j+1)/2^(m-a)),
// a = 0..m (so each coordinate alone is stratified into 2^m intervals) - for
// m up to 12, several seeds, pixels and dimensions. The 1D dimensions are
// stratified the same way. This is what owen scrambling must preserve; a
// broken scramble or sequence (a dropped bit, a wrong column) breaks it.
TEST(SobolSequence, ScrambledPrefixesAreZeroMTwoNets) {
  size_t checked = 0;
  for (const uint32_t seed : {0U, 1U, 0xdeadbeefU})
    for (const auto& px : {std::pair{0U, 0U}, std::pair{3U, 5U}, std::pair{1919U, 1079U}}) {
      const uint32_t key = Sampler(seed).pixelKey(px.first, px.second);
      for (const uint32_t dim : {uint32_t(kDimPixelFilter), uint32_t(kFirstIntegratorDim), kFirstIntegratorDim + 5,
                                 kFirstIntegratorDim + 4 * 9}) {
        const int mMax = 12;
        std::vector<Sample2> pts(size_t(1) << mMax);
        std::vector<float> ones(pts.size());
        for (uint32_t i = 0; i < pts.size(); ++i) {
          pts[i] = Sampler::get2D(key, i, dim);
          ones[i] = Sampler::get1D(key, i, dim);
        }
        for (int m = 0; m <= mMax; ++m) {
          const size_t n = size_t(1) << m;
          for (int a = 0; a <= m; ++a) {
            std::vector<int> count(n, 0);
            for (size_t i = 0; i < n; ++i) {
              const size_t cx = size_t(double(pts[i].u) * double(1 << a));
              const size_t cy = size_t(double(pts[i].v) * double(1 << (m - a)));
              ASSERT_LT(cx, size_t(1) << a);
              ASSERT_LT(cy, size_t(1) << (m - a));
              ++count[(cx << (m - a)) | cy];
            }
            for (size_t c = 0; c < n; ++c)
              ASSERT_EQ(count[c], 1) << "seed " << seed << " pixel " << px.first << "," << px.second << " dim " << dim
                                     << ": 2^" << m << " points, intervals 2^-" << a << " x 2^-" << m - a;
            ++checked;
          }
          std::vector<int> count(n, 0);
          for (size_t i = 0; i < n; ++i) ++count[size_t(double(ones[i]) * double(n))];
          for (size_t c = 0; c < n; ++c) ASSERT_EQ(count[c], 1) << "1D dim " << dim << " 2^" << m << " points";
        }
      }
    }
  EXPECT_EQ(checked, size_t(3 * 3 * 4 * 91));
}

// Different pixels and dimension pairs get different scrambles (else pixels
// or bounces would repeat each other's noise).
TEST(SobolSequence, PixelsAndDimensionsAreScrambledApart) {
  const Sampler s(0);
  const Sample2 a = Sampler::get2D(s.pixelKey(0, 0), 1, kFirstIntegratorDim);
  const Sample2 b = Sampler::get2D(s.pixelKey(1, 0), 1, kFirstIntegratorDim);
  const Sample2 c = Sampler::get2D(s.pixelKey(0, 0), 1, kFirstIntegratorDim + 4);
  EXPECT_TRUE(a.u != b.u || a.v != b.v);
  EXPECT_TRUE(a.u != c.u || a.v != c.v);
}

}  // namespace
}  // namespace obscura::test
