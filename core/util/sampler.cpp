#include <obscura/sampler.h>

namespace obscura {

// Sampler::get2D's steps on plain arrays, in a loop the compiler vectorizes:
// 32-bit multiplies, shifts, masks, byte swaps (a byte shuffle) and the
// table-free Sobol' product. Integer arithmetic is exact, so every clone
// gives the scalar form's bits; the AVX2 clone (picked at load time on CPUs
// that have it) takes eight lanes per instruction where the baseline x86-64
// clone has no 32-bit lane multiply.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("avx2", "default")))
#endif
void Sampler::get2DLanes(const uint32_t* seedIndex, const uint32_t* seedX, const uint32_t* seedY,
                         const uint32_t* index, size_t n, float* u, float* v) {
  for (size_t l = 0; l < n; ++l) {
    const uint32_t i = reverseBits32(laineKarrasPermutation(reverseBits32(index[l]), seedIndex[l]));
    const uint32_t px = laineKarrasPermutation(i, seedX[l]);
    const uint32_t py = laineKarrasPermutation(sobol1ReversedShifts(i), seedY[l]);
    u[l] = bitsToUnitFloat(reverseBits32(px));
    v[l] = bitsToUnitFloat(reverseBits32(py));
  }
}

}  // namespace obscura
