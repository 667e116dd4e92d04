// Batched ray queries on the scene's Embree BVH.
//
// A batch is an array of Embree rays (RTCRay / RTCRayHit) that integrators
// and the render loop fill in place; tracing hands the whole array to
// Embree's stream API (rtcOccluded1M / rtcIntersect1M) in one call. The
// benchmark (bench/obscura_bench_ao) measured streams ~12 % faster than
// 16-wide packets and ~65 % faster than single rays for the AO integrator's
// rays on a 1.1M-triangle scene (2 threads), and equal on small scenes.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>
#include <concepts>
#include <cstdlib>
#include <new>
#include <type_traits>
#include <vector>

#include "obscura/math.h"
#include "core/scene/objects.h"

namespace obscura {

// What rays from objects whose occlusion is self or others need (core/scene/objects.h):
// the object of each top-level geometry and each object's scope. The
// object a ray leaves from is its id (RayBatch::push).
struct OcclusionScopes {
  const uint32_t* objectOfTop = nullptr;  // by top-level geomID
  const uint8_t* scope = nullptr;         // OcclusionScope, by object
  uint32_t objectCount = 0;
};

// Aligned storage that never shrinks, so steady-state batches don't allocate.
template <class T>
class AlignedBuffer {
 public:
  AlignedBuffer() = default;
  AlignedBuffer(const AlignedBuffer&) = delete;
  AlignedBuffer& operator=(const AlignedBuffer&) = delete;
  ~AlignedBuffer() { std::free(data_); }
  void reserve(size_t count) {
    if (count <= capacity_) return;
    std::free(data_);
    const size_t bytes = (count * sizeof(T) + 63) / 64 * 64;
    data_ = static_cast<T*>(std::aligned_alloc(64, bytes));
    if (!data_) throw std::bad_alloc();
    capacity_ = count;
  }
  T* data() const { return data_; }

 private:
  T* data_ = nullptr;
  size_t capacity_ = 0;
};

// A batch of rays for Embree's stream API: an array of RTCRay (any-hit) or
// RTCRayHit (closest hit), traced by one rtcOccluded1M / rtcIntersect1M call.
template <class Ray>
class RayBatch {
 public:
  void clear() { size_ = 0; }
  void reserve(size_t rays) { rays_.reserve(rays); }
  size_t size() const { return size_; }

  // Appends a secondary ray from org along unit dir over (tnear, tfar),
  // leaving the surface hit `from` (a SurfaceHit, core/scene/surface.h): the ray
  // carries its object (what objects' occlusion scopes test) and its time
  // (the camera sample's moment in the shutter, so it meets the scene as
  // that sample saw it; 0 without motion blur). Returns its index.
  template <class Hit>
    requires requires(const Hit& h) {
      { h.object } -> std::convertible_to<uint32_t>;
      { h.time } -> std::convertible_to<float>;
    }
  size_t push(Vec3 org, Vec3 dir, float tnear, float tfar, const Hit& from) {
    return push(org, dir, tnear, tfar, from.object, kRayMaskSecondary, from.time);
  }
  // A secondary ray that leaves no surface (a screen-space query from the
  // camera): no object, time 0.
  size_t push(Vec3 org, Vec3 dir, float tnear, float tfar) {
    return push(org, dir, tnear, tfar, kNoObject, kRayMaskSecondary, 0.0f);
  }
  // A camera ray at `time` in [0, 1) across the shutter (0 without one):
  // sees the objects whose `camera` role is on.
  size_t pushCamera(Vec3 org, Vec3 dir, float tnear, float tfar, float time = 0.0f) {
    return push(org, dir, tnear, tfar, kNoObject, kRayMaskCamera, time);
  }
  size_t push(Vec3 org, Vec3 dir, float tnear, float tfar, uint32_t from, uint32_t mask, float time) {
    const size_t i = size_++;
    Ray& r = rays_.data()[i];
    RTCRay& p = ray(r);
    p.org_x = org.x; p.org_y = org.y; p.org_z = org.z; p.tnear = tnear;
    p.dir_x = dir.x; p.dir_y = dir.y; p.dir_z = dir.z; p.time = time;
    p.tfar = tfar; p.mask = mask; p.id = from; p.flags = 0;
    if constexpr (std::is_same_v<Ray, RTCRayHit>) {
      r.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      r.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    }
    return i;
  }
  Vec3 org(size_t i) const {
    const RTCRay& p = ray(rays_.data()[i]);
    return {p.org_x, p.org_y, p.org_z};
  }
  Vec3 dir(size_t i) const {
    const RTCRay& p = ray(rays_.data()[i]);
    return {p.dir_x, p.dir_y, p.dir_z};
  }
  // tfar after tracing: the hit distance (closest hit), -inf if blocked (any-hit).
  float tfar(size_t i) const { return ray(rays_.data()[i]).tfar; }
  Ray* data() const { return rays_.data(); }

 protected:
  static RTCRay& ray(Ray& r) {
    if constexpr (std::is_same_v<Ray, RTCRayHit>) return r.ray; else return r;
  }
  static const RTCRay& ray(const Ray& r) {
    if constexpr (std::is_same_v<Ray, RTCRayHit>) return r.ray; else return r;
  }
  AlignedBuffer<Ray> rays_;
  size_t size_ = 0;
};

// Any-hit (occlusion) rays.
class OcclusionBatch : public RayBatch<RTCRay> {
 public:
  // After tracing: was ray i blocked? (Embree sets tfar to -inf on a hit.)
  bool occluded(size_t i) const { return tfar(i) < 0.0f; }
};

// Closest-hit rays.
class IntersectBatch : public RayBatch<RTCRayHit> {
 public:
  bool hit(size_t i) const { return rays_.data()[i].hit.geomID != RTC_INVALID_GEOMETRY_ID; }
  unsigned geomID(size_t i) const { return rays_.data()[i].hit.geomID; }
  unsigned primID(size_t i) const { return rays_.data()[i].hit.primID; }
  unsigned instID(size_t i) const { return rays_.data()[i].hit.instID[0]; }
  float u(size_t i) const { return rays_.data()[i].hit.u; }
  float v(size_t i) const { return rays_.data()[i].hit.v; }
  float t(size_t i) const { return tfar(i); }
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

 private:
  RTCScene scene_;
  RayRecorder* recorder_;  // null but in a benchmark's capture (see RayRecorder)
  const OcclusionScopes* scopes_;
};

}  // namespace obscura
