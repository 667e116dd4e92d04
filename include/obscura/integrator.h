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

#include <obscura/environment.h>
#include <obscura/lobe.h>
#include <obscura/math.h>
#include <obscura/params.h>
#include <obscura/ray_batch.h>
#include <obscura/sampler.h>
#include <obscura/surface_hit.h>

namespace obscura {

// What lights shaded.* = albedo x W x lighting (docs/math.md §14.6):
// - Irradiance: W is a visibility-like factor of the unoccluded light, and
//   lighting = E0(n)/pi, the environment's irradiance at the normal (or at
//   the pass's bent normal, e0=bent) over pi: the ambient-transfer paper's
//   eq. 9 with the environment in place of La. The core declares the
//   pass's `e0` parameter. Every AO-family pass.
// - MeanRadiance: W is already the environment-weighted irradiance over
//   pi, relative to the mean radiance Lbar of the environment, and
//   lighting = Lbar (gi: shaded.* is then the reflected radiance).
enum class Shading { Irradiance, MeanRadiance };

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
  // Set by the core from the pass's `e0` parameter (passNeeds, never by an
  // integrator's needs()): shaded.* looks E0 up at the pass's bent normal,
  // the sum of SampleEstimate::bent over the pixel (docs/math.md §14.6).
  bool bentE0 = false;
};



// One camera sample's estimate of W as a ratio (see above). The render loop
// sets num = 0 and den = 1 before calling Integrator::estimate.
struct SampleEstimate {
  Vec3 num;
  Vec3 den;
  // The sample's contribution to the pass's bent normal: the sum of its
  // open directions, each weighted as it counts towards num (unnormalized;
  // zero when nothing is open), world space. Read only for e0=bent, from
  // integrators whose descriptor sets bentNormal; the render loop zeroes
  // it. A screen-space integrator rotates its view-space sum with
  // GBufferLayer::view.vectorToWorld.
  Vec3 bent;
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

class Scene;   // core/scene/scene.h: not part of the SDK
class Tracer;  // core/scene/tracer.h

// Per-thread services for an integrator: batches that keep their memory
// between calls, tracing that counts rays, and what a plugin may ask of the
// scene at a hit. The scene and the tracer stay opaque: every call that
// reaches them is out of line (one call per batch or per hit, never per
// ray of a batch), so the core's types can change without a plugin's
// noticing.
class IntegratorContext {
 public:
  IntegratorContext(const Scene& scene, const Tracer& tracer, const EnvironmentView& environment)
      : scene_(scene), tracer_(tracer), environment_(environment) {}
  // The light of the render (obscura/environment.h): read once per batch,
  // then looked up inline per ray.
  const EnvironmentView& environment() const { return environment_; }
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
  // Traces the batch (one Embree stream call) and counts its rays.
  void trace(OcclusionBatch& b);
  void trace(IntersectBatch& b);
  // The surface an intersect ray i of `batch` found (batch.hit(i) must be
  // true), keyed for sampling by (pixelKey, sampleIndex); `albedo` also
  // evaluates the material, which needs IntegratorNeeds::albedo.
  void surfaceAt(const IntersectBatch& b, size_t i, bool albedo, uint32_t pixelKey, uint32_t sampleIndex,
                 SurfaceHit& out) const;
  // Only the albedo of that surface (cheaper than surfaceAt).
  Vec3 albedoAt(const IntersectBatch& b, size_t i) const;
  // The material roughness at h, in [0, 1] (glTF roughnessFactor x the G
  // channel of its metallicRoughnessTexture; needs IntegratorNeeds::roughness).
  float roughnessAt(const SurfaceHit& h) const;
  // The texture parametrization at a hit (UvFrame); false where the
  // primitive has no texture coordinates or they are degenerate there.
  bool uvFrameAt(const SurfaceHit& h, UvFrame& out) const;
  // What h's surface is called in messages.
  std::string surfaceName(const SurfaceHit& h) const;
  // The albedo of h's surface at texture coordinates (u, v) (needs
  // IntegratorNeeds::albedo).
  Vec3 albedoAtUv(const SurfaceHit& h, float u, float v) const;
  RayCounters counters;

 private:
  const Scene& scene_;
  const Tracer& tracer_;
  const EnvironmentView& environment_;
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
//
// The rays go in blocks of 256: their samples are drawn a block at a time
// (Sampler::get2DLanes) and warped across the block's lanes (SIMD), then
// pushed in each hit's frame. Out of line (core/render/cosine_rays.cpp), so
// tuning it changes no plugin's binary.
void pushCosineRays(std::span<const SurfaceHit> hits, uint32_t rays, float R, const LobeControls& controls,
                    OcclusionBatch& batch);

// out[i].num = the fraction of hits[i]'s rays (rays i * rays + k of an
// any-hit batch) whose direction is open (on the lobe's side of the
// surface, and unoccluded), as a grey estimate.
// out[i].bent is the sum of the open directions.
inline void writeMeanVisibility(std::span<const SurfaceHit> hits, const OcclusionBatch& batch, uint32_t rays,
                                const LobeControls& controls, SampleEstimate* out) {
  size_t r = 0;
  for (size_t i = 0; i < hits.size(); ++i) {
    uint32_t open = 0;
    Vec3 bent(0, 0, 0);
    for (uint32_t k = 0; k < rays; ++k, ++r)
      if (controls.open(hits[i], batch, r)) {
        open += 1;
        bent += batch.dir(r);
      }
    const float v = sampleMean(double(open), rays);
    out[i].num = Vec3(v, v, v);
    out[i].bent = bent;
  }
}

class ScreenSpaceIntegrator;  // obscura/screen_space.h

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
  // tracing from camera hits (obscura/screen_space.h): render() then runs the layer
  // loop and never calls estimate().
  virtual const ScreenSpaceIntegrator* screenSpace() const { return nullptr; }
  // How shaded.* is lit (Shading above): the descriptor's `shading`, which
  // a test checks each built-in integrator agrees with.
  virtual Shading shading() const { return Shading::Irradiance; }
};

// How an integrator works, for listings and checks: from camera hits with
// rays (Integrator::estimate), or from G-buffer layers
// (ScreenSpaceIntegrator, obscura/screen_space.h).
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
  // How shaded.* is lit (above). Irradiance: the registry appends the
  // parameter `e0` (normal|bent) to params.
  Shading shading = Shading::Irradiance;
  // estimate() writes SampleEstimate::bent, so e0=bent can be given.
  bool bentNormal = false;
};

// Whether the pass's `e0` parameter (appended by the registry to
// Irradiance-lit integrators) asks for E0 at the bent normal: an integrator
// whose bent normal costs extra work computes it only then.
inline bool bentE0Requested(const ParamSet& params) {
  for (const ParamSpec& spec : params.specs())
    if (spec.name == "e0") return params.getEnum("e0") == "bent";
  return false;
}

// The pass's needs as the core uses them: desc.needs(params) with bentE0
// from the `e0` parameter. Throws obscura::Error naming the integrator for
// e0=bent on an integrator without a bent normal.
IntegratorNeeds passNeeds(const IntegratorDescriptor& desc, const ParamSet& params);

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
