// The integrator seam: the one interface every integrator implements, and
// the registry the CLI lists and instantiates from. The core knows no
// integrator by name.
//
// An integrator estimates, for a batch of camera hits, the normalized ambient
// irradiance W of MATH.md section 1 (an RGB factor). It is called once per
// batch (a few hundred hits), never per ray: it fills ray batches through
// its IntegratorContext and the core traces each batch with one Embree
// stream call.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/params.h"
#include "core/sampler.h"
#include "core/surface.h"
#include "core/tracer.h"
#include "core/warp.h"

namespace obscura {

// What an integrator needs from the scene; the core builds and fetches only
// that (MATH.md: "compute only what a scene and integrator need").
struct IntegratorNeeds {
  bool albedo = false;  // SurfaceHit::albedo is read (decodes textures)
};

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
  explicit IntegratorContext(const Tracer& tracer) : tracer_(tracer) {}
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
  RayCounters counters;

 private:
  const Tracer& tracer_;
  OcclusionBatch occlusion_;
  IntersectBatch intersect_;
};

// Direction k of `rays` drawn for hit h with density cos(theta)/pi about its
// shading normal (MATH.md section 1); `frame` = Frame::fromNormal(h.ns). The
// pixel's (sample, ray) pairs index one sequence, so all of a pixel's rays
// are jointly stratified.
inline Vec3 cosineDirection(const SurfaceHit& h, const Frame& frame, uint32_t rays, uint32_t k) {
  const Sample2 s = Sampler::get2D(h.pixelKey, h.sampleIndex * rays + k, kFirstIntegratorDim);
  return frame.toWorld(squareToCosineHemisphere(s.u, s.v));
}

class Integrator {
 public:
  virtual ~Integrator() = default;
  // Writes W for every hit: W[i] estimates MATH.md section 1 at hits[i].
  // Samples must come from Sampler::get2D/get1D keyed by hits[i].pixelKey
  // and an index derived from hits[i].sampleIndex, with dimensions from
  // kFirstIntegratorDim upward, so results do not depend on batching.
  virtual void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, Vec3* W) const = 0;
};

struct IntegratorDescriptor {
  std::string name;  // [a-z0-9_-]+
  std::string doc;  // one line
  std::vector<ParamSpec> params;
  IntegratorNeeds (*needs)(const ParamSet&) = nullptr;
  std::unique_ptr<Integrator> (*create)(const ParamSet&) = nullptr;
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

// Integrators register through a plugin entry point (core/plugin.h): each
// integrator file adds its descriptor function to its module's list with
// OBSCURA_REGISTER_INTEGRATOR(fn); the module's OBSCURA_PLUGIN_ENTRY hands
// the list to the registry when the loader has checked the ABI version.
}  // namespace obscura
