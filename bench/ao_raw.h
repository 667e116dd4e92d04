// The ao integrator's rays traced straight through Embree, with no shading:
// the "speed of light" obscura_bench_ao compares the renderer against.
//
// For every pixel and sample the camera ray is exactly the renderer's (same
// RasterCamera, Sampler key, dimension and box filter, same tiles, same
// pixel-major sample order inside a tile). For every camera hit one AO ray is
// traced (the ao integrator's default rays=1), built the way integrators/ao.cpp
// builds it - cosine direction from Sampler::get2D(pixelKey, sampleIndex,
// kFirstIntegratorDim), origin pushed off the surface by 2^-16 of the point's
// magnitude - except that nothing is read back from the scene:
//   * the frame is the geometric normal Embree returns (Ng, normalized and
//     flipped to face the camera ray) instead of the interpolated shading
//     normal, and
//   * the hit point is org + t*dir instead of the barycentric reconstruction,
//     and eps scales with |p| only instead of |p| and the triangle's vertices.
// The AO ray count is therefore identical to the renderer's (one per camera
// hit) and the directions statistically equivalent (same cosine density,
// slightly different frame where shading normals bend away from Ng).
#pragma once

#include <cstdint>
#include <memory>

#include "core/scene/camera.h"
#include "core/scene/scene.h"

namespace obscura::bench {

// Single, Packet16 and Stream1M are the raw variants. StreamSurface is a
// diagnostic, not a candidate for "best raw": Stream1M plus the renderer's
// hit reconstruction (obscura::computeSurfaceHit: barycentric point,
// interpolated shading normal, eps from the vertices) and its AO ray
// (shading-normal frame, spawnOrigin), so the renderer's loss splits into
// "surface reconstruction" and "render loop + integrator plumbing".
enum class RawApi { Single, Packet16, Stream1M, StreamSurface };
const char* rawApiName(RawApi api);

struct RayTally {
  uint64_t camera = 0;      // camera (closest-hit) rays
  uint64_t ao = 0;          // AO (occlusion) rays = camera hits
  uint64_t unoccluded = 0;  // AO rays that reached R (or escaped)
};

struct RawSettings {
  int width = 1920, height = 1080;
  int spp = 16;
  uint32_t seed = 0;
  int threads = 1;         // resolved (> 0)
  int tileSize = 16;       // as the renderer's default
  int chunk = 256;         // camera samples per batch (packets, streams); the renderer's kChunk
  float aoDistance = INFINITY;
};

// Owns the per-thread ray buffers, so repeated runs allocate nothing.
class RawAoTracer {
 public:
  RawAoTracer(const Scene& scene, const Camera& camera, const RawSettings& settings);
  ~RawAoTracer();
  RawAoTracer(const RawAoTracer&) = delete;
  RawAoTracer& operator=(const RawAoTracer&) = delete;

  // One full frame with the given API; returns wall seconds of the parallel
  // loop (arena creation included, as in obscura::render) and the ray counts.
  double run(RawApi api, RayTally& tally);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace obscura::bench
