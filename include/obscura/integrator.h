// The integrator seam: the one interface every integrator implements, and
// the registry the CLI lists and instantiates from. The core knows no
// integrator by name.
//
// An integrator estimates, for a batch of camera hits, the normalized ambient
// irradiance W of docs/math.md §1 (an RGB factor). It is called once per
// batch (a few hundred hits), never per ray: it fills ray batches through
// its IntegratorContext and the core traces each batch with one Embree
// stream call.
//
// Each camera sample's estimate is a ratio (num, den); a pixel's W is the
// ratio of sums over its samples, Sum num / Sum den (per RGB channel). Plain
// Monte Carlo estimators leave den = 1, so W is the sample mean; the ratio
// estimators of docs/math.md §4 set both, because a ratio taken per sample
// (one ray) degenerates to plain AO. A pixel whose denominators sum to 0
// resolves to W = 1: a ratio estimator has num <= den, so this is 0/0, which
// for the closed-form transfer means "no open direction, every occluder
// white" - the white-furnace limit lim_{a->1} f/(1 - a(1-f)) = 1.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "obscura/lobe.h"
#include "obscura/params.h"
#include "core/scene/scene.h"
#include "obscura/sampler.h"
#include "core/scene/surface.h"
#include "core/scene/tracer.h"
#include "obscura/warp.h"

namespace obscura {

// What an integrator needs from the scene; the core builds and fetches only
// that (docs/architecture.md).
struct IntegratorNeeds {
  bool albedo = false;  // SurfaceHit::albedo is read, here or at secondary hits (decodes textures)
  // IntegratorContext::roughnessAt is called (reads the materials'
  // metallicRoughness textures, Scene::dataTextures). Nothing else computes
  // roughness: a render whose integrator does not set this never decodes them.
  bool roughness = false;
  // resolvePixel maps W with the pixel's own albedo (multi-bounce AO), so W
  // changes wherever the albedo does and --denoise takes the albedo planes as
  // a guide (docs/denoise.md "Albedo"). Passes that read only the occluders'
  // albedo (transfer, gi) leave it false: the shaded point's texture edges are
  // no edges of their W, and stopping the filter there only keeps noise.
  bool pixelAlbedo = false;
};

// One camera sample's estimate of W as a ratio (see above). The render loop
// sets num = 0 and den = 1 before calling Integrator::estimate.
struct SampleEstimate {
  Vec3 num;
  Vec3 den;
};

// The mean of n values whose sum is `sum`, as a float: one correctly rounded
// division, so sum == n gives exactly 1 and integrators that share this
// arithmetic (ao, obscurance, transfer with black occluders) agree bit for bit.
inline float sampleMean(double sum, uint32_t n) { return float(sum / double(n)); }

// Ray counts, summed over threads at the end of a render.
struct RayCounters {
  uint64_t camera = 0;     // primary closest-hit rays
  uint64_t occlusion = 0;  // any-hit rays traced by integrators
  uint64_t closest = 0;    // secondary closest-hit rays traced by integrators
};

// Per-thread services for an integrator: batches that keep their memory
// between calls, and tracing that counts rays.
class IntegratorContext {
 public:
  IntegratorContext(const Scene& scene, const Tracer& tracer) : scene_(scene), tracer_(tracer) {}
  // A cleared batch able to hold `rays` rays.
  OcclusionBatch& occlusionBatch(size_t rays) {
    occlusion_.reserve(rays);
    occlusion_.clear();
    return occlusion_;
  }
  IntersectBatch& intersectBatch(size_t rays) {
    intersect_.reserve(rays);
    intersect_.clear();
    return intersect_;
  }
  void trace(OcclusionBatch& b) {
    tracer_.occluded(b);
    counters.occlusion += b.size();
  }
  void trace(IntersectBatch& b) {
    tracer_.intersect(b);
    counters.closest += b.size();
  }
  // The surface an intersect ray i of `batch` found (batch.hit(i) must be
  // true), keyed for sampling by (pixelKey, sampleIndex); `albedo` also
  // evaluates the material, which needs IntegratorNeeds::albedo.
  void surfaceAt(const IntersectBatch& b, size_t i, bool albedo, uint32_t pixelKey, uint32_t sampleIndex,
                 SurfaceHit& out) const {
    computeSurfaceHit(scene_, b.data()[i], albedo, out);
    out.pixelKey = pixelKey;
    out.sampleIndex = sampleIndex;
  }
  // Only the albedo of that surface (cheaper than surfaceAt).
  Vec3 albedoAt(const IntersectBatch& b, size_t i) const {
    return surfaceAlbedo(scene_, b.geomID(i), b.primID(i), b.instID(i), b.u(i), b.v(i));
  }
  // The material roughness at h, in [0, 1] (surfaceRoughness; needs
  // IntegratorNeeds::roughness).
  float roughnessAt(const SurfaceHit& h) const { return surfaceRoughness(scene_, h); }
  // The texture parametrization at a hit (see surfaceUvFrame).
  bool uvFrameAt(const SurfaceHit& h, UvFrame& out) const { return surfaceUvFrame(scene_, h, out); }
  // What h's surface is called in messages (Scene::surfaceName).
  std::string surfaceName(const SurfaceHit& h) const { return scene_.surfaceName(h.geomID, h.instID); }
  // The albedo of h's surface at texture coordinates (u, v) (needs
  // IntegratorNeeds::albedo).
  Vec3 albedoAtUv(const SurfaceHit& h, float u, float v) const { return surfaceAlbedoAtUv(scene_, h, u, v); }
  RayCounters counters;

 private:
  const Scene& scene_;
  const Tracer& tracer_;
  OcclusionBatch occlusion_;
  IntersectBatch intersect_;
};

// Direction k of `rays` drawn for hit h with density cos(theta)/pi about its
// shading normal (docs/math.md §1), or about the lobe's normal and within
// its cone (docs/math.md §11); `lobe` = LobeControls::at(h). The pixel's
// (sample, ray) pairs index one sequence, so all of a pixel's rays are
// jointly stratified.
inline Vec3 cosineDirection(const SurfaceHit& h, const Lobe& lobe, uint32_t rays, uint32_t k) {
  return lobe.direction(Sampler::get2D(h.pixelKey, h.sampleIndex * rays + k, kFirstIntegratorDim));
}

// For each hit, `rays` any-hit rays along cosineDirection k = 0..rays-1,
// over (controls.tnear, R]: the visibility rays of AO-style estimators, ray
// i * rays + k belonging to hits[i].
inline void pushCosineRays(std::span<const SurfaceHit> hits, uint32_t rays, float R, const LobeControls& controls,
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

// out[i].num = the fraction of hits[i]'s rays (rays i * rays + k of an
// any-hit batch) whose direction is open (on the lobe's side of the
// surface, and unoccluded), as a grey estimate.
inline void writeMeanVisibility(std::span<const SurfaceHit> hits, const OcclusionBatch& batch, uint32_t rays,
                                const LobeControls& controls, SampleEstimate* out) {
  size_t r = 0;
  for (size_t i = 0; i < hits.size(); ++i) {
    uint32_t open = 0;
    for (uint32_t k = 0; k < rays; ++k, ++r) open += controls.open(hits[i], batch, r) ? 1U : 0U;
    const float v = sampleMean(double(open), rays);
    out[i].num = Vec3(v, v, v);
  }
}

class ScreenSpaceIntegrator;  // core/render/gbuffer.h

class Integrator {
 public:
  virtual ~Integrator() = default;
  // Writes out[i], the estimate of docs/math.md §1 at hits[i] (out[i].num
  // alone for a plain mean). Samples must come from Sampler::get2D/get1D
  // keyed by hits[i].pixelKey and an index derived from hits[i].sampleIndex,
  // with dimensions from kFirstIntegratorDim upward, so results do not
  // depend on batching.
  virtual void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const = 0;
  // Maps a pixel's resolved W (Sum num / Sum den) to its final value, given
  // the pixel's mean albedo over its hits ((1,1,1) unless the integrator
  // needs albedo). Called once per covered pixel; for estimators that are
  // a nonlinear function of a converged pixel value (multi-bounce AO).
  virtual Vec3 resolvePixel(Vec3 W, Vec3 albedo) const {
    (void)albedo;
    return W;
  }
  // Non-null for an integrator that reads the camera's G-buffer instead of
  // tracing from camera hits (core/render/gbuffer.h): render() then runs the layer
  // loop and never calls estimate().
  virtual const ScreenSpaceIntegrator* screenSpace() const { return nullptr; }
};

// How an integrator works, for listings and checks: from camera hits with
// rays (Integrator::estimate), or from G-buffer layers
// (ScreenSpaceIntegrator, core/render/gbuffer.h).
enum class IntegratorKind { RayTraced, ScreenSpace };

struct IntegratorDescriptor {
  std::string name;  // [a-z0-9_-]+
  std::string doc;  // one line
  std::vector<ParamSpec> params;
  IntegratorNeeds (*needs)(const ParamSet&) = nullptr;
  std::unique_ptr<Integrator> (*create)(const ParamSet&) = nullptr;
  // ScreenSpace: create() returns a ScreenSpaceIntegrator. `obscura
  // integrators` lists the kind.
  IntegratorKind kind = IntegratorKind::RayTraced;
};

class IntegratorRegistry {
 public:
  static IntegratorRegistry& instance();
  // Adds an integrator; throws obscura::Error if the name is taken or the
  // descriptor is incomplete. `origin` names the plugin in messages.
  void add(IntegratorDescriptor d, const std::string& origin = "built-in");
  // Throws obscura::Error listing the known names if `name` is unknown.
  const IntegratorDescriptor& find(const std::string& name) const;
  const std::vector<IntegratorDescriptor>& all() const { return all_; }

 private:
  std::vector<IntegratorDescriptor> all_;
  std::vector<std::string> origins_;
};

// Integrators register through a plugin entry point (include/obscura/plugin.h): each
// integrator file adds its descriptor function to its module's list with
// OBSCURA_REGISTER_INTEGRATOR(fn); the module's OBSCURA_PLUGIN_ENTRY hands
// the list to the registry when the loader has checked the ABI version.
}  // namespace obscura
