// Deterministic sample generation.
//
// Every random number is a pure function of (pixel, sample index, dimension,
// seed): no generator state exists, so the image is bit-identical for any
// thread count and tile size (docs/architecture.md, "Deterministic sampling").
//
// Each 2D dimension pair uses the first two Sobol' dimensions, Owen-scrambled
// with a hash-based nested uniform scramble and with the sample index itself
// shuffled by an independent scramble (Burley 2020, "Practical Hash-based Owen
// Scrambling", JCGT 9(4)). Padding dimension pairs this way keeps every pair
// a (0,2)-sequence in base 2 - stratified in 2D for any power-of-two prefix -
// while pairs stay mutually decorrelated through their seeds.
#pragma once

#include <cstddef>
#include <cstdint>

namespace obscura {

// 32-bit integer hash with good avalanche (a "lowbias32" style mix).
inline uint32_t mixBits32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

inline uint32_t hashCombine(uint32_t seed, uint32_t v) {
  return mixBits32(seed ^ (v + 0x9e3779b9U + (seed << 6) + (seed >> 2)));
}

// The bits within each byte are reversed by three swap steps, the bytes by
// one byte swap (an instruction, where the two further swap steps cost ten).
constexpr uint32_t reverseBits32(uint32_t x) {
  x = ((x >> 1) & 0x55555555U) | ((x & 0x55555555U) << 1);
  x = ((x >> 2) & 0x33333333U) | ((x & 0x33333333U) << 2);
  x = ((x >> 4) & 0x0f0f0f0fU) | ((x & 0x0f0f0f0fU) << 4);
  return __builtin_bswap32(x);
}

// Laine-Karras style permutation: each bit is flipped depending only on the
// bits below it, i.e. an Owen scramble when applied to bit-reversed values.
inline uint32_t laineKarrasPermutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cU;
  x ^= x * 0xb82f1e52U;
  x ^= x * 0xc7afe638U;
  x ^= x * 0x8d22f6e6U;
  return x;
}

inline uint32_t nestedUniformScramble(uint32_t x, uint32_t seed) {
  return reverseBits32(laineKarrasPermutation(reverseBits32(x), seed));
}

// Sobol' dimension 0 is the van der Corput sequence: bit reversal.
inline uint32_t sobol0(uint32_t i) { return reverseBits32(i); }

// Sobol' dimension 1: its generator matrix is the upper-triangular Pascal
// matrix mod 2, whose column j is v_j with v_0 = 2^31, v_(j+1) = v_j ^ (v_j >> 1).
// The index is scrambled to a full 32-bit value, so instead of a loop over
// its bits the product is taken a byte at a time from four 256-entry tables
// of XORed columns (built at compile time).
namespace detail {
struct Sobol1Tables {
  uint32_t t[4][256];
  constexpr Sobol1Tables() : t{} {
    uint32_t col[32] = {};
    uint32_t v = 1U << 31;
    for (int j = 0; j < 32; ++j, v ^= v >> 1) col[j] = v;
    for (int b = 0; b < 4; ++b)
      for (int x = 0; x < 256; ++x) {
        uint32_t r = 0;
        for (int k = 0; k < 8; ++k)
          if (x & (1 << k)) r ^= col[8 * b + k];
        t[b][x] = r;
      }
  }
};
inline constexpr Sobol1Tables kSobol1{};
}  // namespace detail

inline uint32_t sobol1(uint32_t i) {
  return detail::kSobol1.t[0][i & 0xff] ^ detail::kSobol1.t[1][(i >> 8) & 0xff] ^
         detail::kSobol1.t[2][(i >> 16) & 0xff] ^ detail::kSobol1.t[3][i >> 24];
}

// reverseBits32(sobol1(i)): bit reversal is linear over XOR, so it is the
// same table product with reversed columns.
namespace detail {
struct Sobol1ReversedTables {
  uint32_t t[4][256];
  constexpr Sobol1ReversedTables() : t{} {
    for (int b = 0; b < 4; ++b)
      for (int x = 0; x < 256; ++x) t[b][x] = reverseBits32(kSobol1.t[b][x]);
  }
};
inline constexpr Sobol1ReversedTables kSobol1Reversed{};
}  // namespace detail

inline uint32_t sobol1Reversed(uint32_t i) {
  return detail::kSobol1Reversed.t[0][i & 0xff] ^ detail::kSobol1Reversed.t[1][(i >> 8) & 0xff] ^
         detail::kSobol1Reversed.t[2][(i >> 16) & 0xff] ^ detail::kSobol1Reversed.t[3][i >> 24];
}

// The same product without tables, as five shift-and-XOR steps: by Lucas'
// theorem the Pascal matrix mod 2 has a 1 in row k, column j exactly when
// the bits of k are a subset of those of j, so bit k of reverse(sobol1(i))
// is the XOR of the bits j of i with j a superset of k (k, j in 0..31): the
// superset-sum transform over GF(2), one step per bit of k. Branch-free and
// table-free, so it runs across SIMD lanes (Sampler::get2DLanes); the tests
// check it against the tables.
constexpr uint32_t sobol1ReversedShifts(uint32_t x) {
  x ^= (x >> 1) & 0x55555555U;
  x ^= (x >> 2) & 0x33333333U;
  x ^= (x >> 4) & 0x0f0f0f0fU;
  x ^= (x >> 8) & 0x00ff00ffU;
  x ^= (x >> 16) & 0x0000ffffU;
  return x;
}

// reverseBits32 of both halves of a 64-bit word at once.
// (Bits within bytes, then a 64-bit byte swap, which also swaps the halves:
// a rotation by 32 puts them back.)
inline uint64_t reverseBits32x2(uint64_t x) {
  x = ((x >> 1) & 0x5555555555555555ULL) | ((x & 0x5555555555555555ULL) << 1);
  x = ((x >> 2) & 0x3333333333333333ULL) | ((x & 0x3333333333333333ULL) << 2);
  x = ((x >> 4) & 0x0f0f0f0f0f0f0f0fULL) | ((x & 0x0f0f0f0f0f0f0f0fULL) << 4);
  x = __builtin_bswap64(x);
  return (x >> 32) | (x << 32);
}

// Map 32 random bits to [0,1): 24 high bits, exact in float, never 1.
inline float bitsToUnitFloat(uint32_t x) { return float(x >> 8) * 0x1p-24f; }

struct Sample2 {
  float u, v;
};

// The sampler used by the renderer and every integrator. Cheap to copy.
class Sampler {
 public:
  explicit Sampler(uint32_t seed = 0) : seed_(mixBits32(seed ^ 0x5bd1e995U)) {}

  // Seed of one pixel: all of that pixel's samples share it.
  uint32_t pixelKey(uint32_t px, uint32_t py) const {
    return hashCombine(hashCombine(seed_, px), py);
  }

  // The 2D sample `index` of dimension pair `dim` of the pixel with `key`.
  //   x = nestedUniformScramble(sobol0(i), sx), y = nestedUniformScramble(sobol1(i), sy)
  // computed with fewer bit reversals (the same bits): sobol0 is a reversal,
  // so the scramble of it is reverse(LK(i, sx)); reverse(sobol1(i)) comes
  // from reversed tables; the last two reversals are done as one 64-bit one.
  static Sample2 get2D(uint32_t key, uint32_t index, uint32_t dim) { return get2D(seeds2D(key, dim), index); }

  // The scramble seeds of dimension pair `dim` of the pixel with `key`: what
  // all of that pixel's samples of the pair share (hashed once per pixel by
  // a caller that draws many of them).
  struct Seeds2 {
    uint32_t index, x, y;
  };
  static Seeds2 seeds2D(uint32_t key, uint32_t dim) {
    const uint32_t s = hashCombine(key, dim);
    return {s, hashCombine(s, 0xa511e9b3U), hashCombine(s, 0x63d83595U)};
  }
  static Sample2 get2D(const Seeds2& s, uint32_t index) {
    const uint32_t i = nestedUniformScramble(index, s.index);
    const uint32_t px = laineKarrasPermutation(i, s.x);
    const uint32_t py = laineKarrasPermutation(sobol1Reversed(i), s.y);
    const uint64_t xy = reverseBits32x2(uint64_t(px) | uint64_t(py) << 32);
    return {bitsToUnitFloat(uint32_t(xy)), bitsToUnitFloat(uint32_t(xy >> 32))};
  }

  // get2D for n lanes at once, bit for bit: lane l's sample index[l] with
  // the seeds {seedIndex[l], seedX[l], seedY[l]} into (u[l], v[l]). The
  // scalar form's integer steps, across SIMD lanes (core/util/sampler.cpp; the
  // hash and reversal steps are a quarter of the render loop's own time
  // when taken one lane at a time).
  static void get2DLanes(const uint32_t* seedIndex, const uint32_t* seedX, const uint32_t* seedY,
                         const uint32_t* index, size_t n, float* u, float* v);

  // nestedUniformScramble(sobol0(i), seed) = reverse(LK(i, seed)), as above.
  static float get1D(uint32_t key, uint32_t index, uint32_t dim) {
    const uint32_t s = hashCombine(key, dim ^ 0x80000000U);
    const uint32_t i = nestedUniformScramble(index, s);
    return bitsToUnitFloat(reverseBits32(laineKarrasPermutation(i, hashCombine(s, 0x2c1b3c6dU))));
  }

 private:
  uint32_t seed_;
};

// Camera sample `si` of a pixel draws from one of two independently
// scrambled replicates of the pixel's sequence: the even samples from the
// pixel's key at index si / 2, the odd ones from a key hashed from it, at
// the same index. Each replicate's first n points are a stratified net; the
// two are independent, so their difference measures the error of the
// pixel's mean honestly (docs/math.md §13). Splitting one scrambled
// sequence into its even and odd indices would not: the lowest index bit
// picks a half of the first dimension, so the two halves would integrate
// over different halves of the domain.
struct SampleStream {
  uint32_t key, index;
};
inline SampleStream sampleStream(uint32_t pixelKey, uint32_t si) {
  return {(si & 1U) ? hashCombine(pixelKey, 0x6f4f2a1dU) : pixelKey, si >> 1};
}

// Fixed dimension assignments of the core. Integrators use dimensions from
// kFirstIntegratorDim upward, so core and integrator streams never collide.
enum : uint32_t {
  kDimPixelFilter = 0,
  kDimShutterTime = 1,  // 1D: a camera sample's moment in the shutter (motion blur)
  kFirstIntegratorDim = 8,
};

}  // namespace obscura
