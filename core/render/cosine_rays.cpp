// pushCosineRays (obscura/integrator.h): the visibility rays of the AO-style
// estimators, cosine-distributed about each hit's lobe (docs/math.md §1,
// §11). Out of line so that its SIMD can be tuned without changing the
// plugin ABI; the bits are those of the inline version it replaces (the
// determinism tests compare whole passes).
#include <cstddef>
#include <cstdint>
#include <span>

#include <obscura/integrator.h>
#include <obscura/lobe.h>
#include <obscura/sampler.h>
#include <obscura/surface_hit.h>
#include <obscura/warp.h>

namespace obscura {

void pushCosineRays(std::span<const SurfaceHit> hits, uint32_t rays, float R, const LobeControls& controls,
                    OcclusionBatch& batch) {
  // The rays go in blocks: each ray's scramble seeds and sample index, then
  // the whole block's samples at once (Sampler::get2DLanes, SIMD), then the
  // warp and the pushes. A pixel's hits come one after another (the render
  // loop is pixel-major), keyed by one key or by two that alternate (a
  // pixel's sample streams), so the seeds of the last two keys are kept and
  // hashed once per key's run instead of once per ray.
  if (rays == 0) return;
  constexpr size_t kBlock = 256;
  uint32_t seedIndex[kBlock], seedX[kBlock], seedY[kBlock], index[kBlock];
  float u[kBlock], v[kBlock], x[kBlock], y[kBlock], z[kBlock];
  uint32_t keys[2] = {0, 0};
  Sampler::Seeds2 seeds[2] = {};
  int held = 0, last = 0;  // keys held; the slot used last
  size_t hit = 0;          // the hit of the block's first ray
  uint32_t ray = 0;        // and that ray's k
  while (hit < hits.size()) {
    // Fill the block from (hit, ray) on.
    size_t n = 0, i = hit;
    uint32_t k = ray;
    for (; i < hits.size() && n < kBlock; ++i, k = 0) {
      const SurfaceHit& h = hits[i];
      int slot = held > 0 && keys[0] == h.pixelKey ? 0 : held > 1 && keys[1] == h.pixelKey ? 1 : -1;
      if (slot < 0) {
        slot = held < 2 ? held++ : 1 - last;  // the slot not used last
        keys[slot] = h.pixelKey;
        seeds[slot] = Sampler::seeds2D(h.pixelKey, kFirstIntegratorDim);
      }
      last = slot;
      for (; k < rays && n < kBlock; ++k, ++n) {
        seedIndex[n] = seeds[slot].index, seedX[n] = seeds[slot].x, seedY[n] = seeds[slot].y;
        index[n] = h.sampleIndex * rays + k;
      }
      if (k < rays) break;  // the block is full within this hit
    }
    Sampler::get2DLanes(seedIndex, seedX, seedY, index, n, u, v);
    // Lobe::direction in two steps: the cone's local directions across the
    // block's lanes (SIMD, the same bits), then each hit's frame.
    squareToCosineConeLanes(u, v, controls.sinThetaMax, n, x, y, z);
    // Push the block's rays, walking (hit, ray) again.
    for (size_t j = 0; j < n; ++hit, ray = 0) {
      const SurfaceHit& h = hits[hit];
      const Lobe lobe = controls.at(h);
      for (; ray < rays && j < n; ++ray, ++j) {
        const Vec3 w = lobe.frame.toWorld(Vec3(x[j], y[j], z[j]));
        batch.push(spawnOrigin(h, w), w, controls.tnear, R, h);
      }
      if (ray < rays) break;  // the hit goes on in the next block
    }
  }
}

}  // namespace obscura
