// Batched ray queries on the scene's Embree BVH: a batch
// (obscura/ray_batch.h) is an array of rays that integrators and the render
// loop fill in place; tracing hands the whole array to Embree's stream API
// (rtcOccluded1M / rtcIntersect1M) in one call.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>

#include "core/scene/objects.h"
#include <obscura/math.h>
#include <obscura/ray_batch.h>

namespace obscura {

// What rays from objects whose occlusion is self or others need (core/scene/objects.h):
// the object of each top-level geometry and each object's scope. The
// object a ray leaves from is its id (RayBatch::push).
struct OcclusionScopes {
  const uint32_t* objectOfTop = nullptr;  // by top-level geomID
  const uint8_t* scope = nullptr;         // OcclusionScope, by object
  uint32_t objectCount = 0;
};

enum class RayCoherence { Coherent, Incoherent };

// A benchmark hook, not a rendering feature: bench/bench_transfer.cpp
// captures every batch a render traces, to replay the very same rays through
// raw Embree. When a Tracer has a recorder, it hands each batch to it instead
// of calling Embree; the recorder must trace it with the same call
// (rtcIntersect1M / rtcOccluded1M over n rays with `ctx`) and may keep a copy
// of the rays before and of the hits after. It is called from every render
// thread at once, so it must be thread-safe. Ordinary renders have none
// (RenderSettings::recorder = nullptr): the cost is one well-predicted null
// check per batch (of up to a few hundred rays). Measured as nil: a render
// with a pass-through recorder (check taken + a virtual call per batch,
// `obscura_bench_transfer --hook-check`) is within run-to-run noise of one
// without, and so is `obscura render -i gi` built with and without the check.
class RayRecorder {
 public:
  virtual ~RayRecorder() = default;
  virtual void intersect(RTCScene scene, RTCIntersectContext& ctx, RTCRayHit* rays, unsigned n) = 0;
  virtual void occluded(RTCScene scene, RTCIntersectContext& ctx, RTCRay* rays, unsigned n) = 0;
};

// Traces batches against one Embree scene. Stateless and thread-safe.
class Tracer {
 public:
  // `scopes`: Scene::occlusionScopes(), null when no object limits its
  // occluders (then no filter runs).
  explicit Tracer(RTCScene scene, RayRecorder* recorder = nullptr, const OcclusionScopes* scopes = nullptr)
      : scene_(scene), recorder_(recorder), scopes_(scopes) {}
  void occluded(OcclusionBatch& batch, RayCoherence c = RayCoherence::Incoherent) const;
  void intersect(IntersectBatch& batch, RayCoherence c = RayCoherence::Incoherent) const;
  RTCScene scene() const { return scene_; }
  // The Embree view of a batch's rays (the same memory: obscura::Ray and
  // RayHit have Embree's layout, checked in tracer.cpp).
  static RTCRay* embree(Ray* r) { return reinterpret_cast<RTCRay*>(r); }
  static RTCRayHit* embree(RayHit* r) { return reinterpret_cast<RTCRayHit*>(r); }

 private:
  RTCScene scene_;
  RayRecorder* recorder_;  // null but in a benchmark's capture (see RayRecorder)
  const OcclusionScopes* scopes_;
};

}  // namespace obscura
