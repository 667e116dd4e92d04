// pushUniformRays: the visibility rays of the uniform (solid-angle) AO
// alpha = Int V dw / (the cone's solid angle) [IAO 4] (`ao weighting=uniform`,
// `multibounce mapping=improved|fitted`; docs/math.md §6), the counterpart of
// pushCosineRays (obscura/integrator.h) with directions uniform in solid
// angle over the lobe's cone (squareToUniformCone about the lobe's frame),
// from the same sample stream, over (controls.tnear, R]: ray i * rays + k
// belongs to hits[i]. One definition for both integrators, so
// `mapping=improved` traces exactly the rays of `ao weighting=uniform`.
#pragma once

#include <span>

#include <obscura/integrator.h>

namespace obscura {

inline void pushUniformRays(std::span<const SurfaceHit> hits, uint32_t rays, float R, const LobeControls& controls,
                            OcclusionBatch& batch) {
  for (const SurfaceHit& h : hits) {
    const Frame frame = controls.at(h).frame;
    for (uint32_t k = 0; k < rays; ++k) {
      const Sample2 s = Sampler::get2D(h.pixelKey, h.sampleIndex * rays + k, kFirstIntegratorDim);
      const Vec3 w = frame.toWorld(squareToUniformCone(s.u, s.v, controls.cosThetaMax));
      batch.push(spawnOrigin(h, w), w, controls.tnear, R, h);
    }
  }
}

}  // namespace obscura
