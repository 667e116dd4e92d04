// Ray batches: the arrays of rays integrators fill and the core traces, one
// Embree stream call (rtcOccluded1M / rtcIntersect1M) per batch.
//
// Ray, Hit and RayHit have the memory layout of Embree 3's RTCRay, RTCHit
// and RTCRayHit (one instance level), so the core hands a batch's array to
// Embree as it is, without a copy; core/scene/tracer.cpp checks every offset
// with static_assert. They are declared here so that a plugin compiles
// against this header alone, without Embree's.
//
// Why streams: the AO integrator's rays traced raw ran ~12 % faster as
// streams than as 16-wide packets and ~65 % faster than as single rays on a
// 1.1M-triangle scene (2 threads), and equal on small scenes
// (docs/architecture.md "Streams written in place").
#pragma once

#include <concepts>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <new>
#include <type_traits>

#include <obscura/math.h>

namespace obscura {

// A ray, as RTCRay: origin, tnear, direction, time, tfar, mask, id, flags.
struct alignas(16) Ray {
  float org_x, org_y, org_z, tnear;
  float dir_x, dir_y, dir_z, time;
  float tfar;
  uint32_t mask, id, flags;
};
// A closest hit, as RTCHit: geometric normal, barycentrics and ids.
struct alignas(16) Hit {
  float Ng_x, Ng_y, Ng_z, u, v;
  uint32_t primID, geomID, instID[1];
};
struct alignas(16) RayHit {
  Ray ray;
  Hit hit;
};

// No geometry (RTC_INVALID_GEOMETRY_ID): Hit::geomID of a ray that hit nothing.
inline constexpr uint32_t kInvalidGeometryId = 0xffffffffu;
// Ray masks: camera rays see the objects whose `camera` role is on, every
// other ray the objects whose `occluder` role is on (docs/production.md "Objects and roles").
inline constexpr uint32_t kRayMaskCamera = 1u;
inline constexpr uint32_t kRayMaskSecondary = 2u;
// The object of a ray that leaves from no surface (camera rays), or of a
// surface that belongs to no object (geometry added without one).
inline constexpr uint32_t kNoObject = 0xffffffffu;

// A distance as a ray's tfar: +inf when beyond float range (a distance R of
// 1e300 means "unbounded", not float's largest value).
inline float toRayDistance(double t) {
  return t > double(std::numeric_limits<float>::max()) ? kInfinity : float(t);
}

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

// A batch of rays for one stream call: an array of Ray (any-hit) or RayHit
// (closest hit).
template <class R>
class RayBatch {
 public:
  void clear() { size_ = 0; }
  void reserve(size_t rays) { rays_.reserve(rays); }
  size_t size() const { return size_; }

  // Appends a secondary ray from org along unit dir over (tnear, tfar),
  // leaving the surface hit `from` (a SurfaceHit, obscura/surface_hit.h):
  // the ray carries its object (what objects' occlusion scopes test) and its
  // time (the camera sample's moment in the shutter, so it meets the scene
  // as that sample saw it; 0 without motion blur). Returns its index.
  template <class SurfaceHitT>
    requires requires(const SurfaceHitT& h) {
      { h.object } -> std::convertible_to<uint32_t>;
      { h.time } -> std::convertible_to<float>;
    }
  size_t push(Vec3 org, Vec3 dir, float tnear, float tfar, const SurfaceHitT& from) {
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
    R& r = rays_.data()[i];
    Ray& p = ray(r);
    p.org_x = org.x; p.org_y = org.y; p.org_z = org.z; p.tnear = tnear;
    p.dir_x = dir.x; p.dir_y = dir.y; p.dir_z = dir.z; p.time = time;
    p.tfar = tfar; p.mask = mask; p.id = from; p.flags = 0;
    if constexpr (std::is_same_v<R, RayHit>) {
      r.hit.geomID = kInvalidGeometryId;
      r.hit.instID[0] = kInvalidGeometryId;
    }
    return i;
  }
  Vec3 org(size_t i) const {
    const Ray& p = ray(rays_.data()[i]);
    return {p.org_x, p.org_y, p.org_z};
  }
  Vec3 dir(size_t i) const {
    const Ray& p = ray(rays_.data()[i]);
    return {p.dir_x, p.dir_y, p.dir_z};
  }
  // tfar after tracing: the hit distance (closest hit), -inf if blocked (any-hit).
  float tfar(size_t i) const { return ray(rays_.data()[i]).tfar; }
  R* data() const { return rays_.data(); }

 protected:
  static Ray& ray(R& r) {
    if constexpr (std::is_same_v<R, RayHit>) return r.ray; else return r;
  }
  static const Ray& ray(const R& r) {
    if constexpr (std::is_same_v<R, RayHit>) return r.ray; else return r;
  }
  AlignedBuffer<R> rays_;
  size_t size_ = 0;
};

// Any-hit (occlusion) rays.
class OcclusionBatch : public RayBatch<Ray> {
 public:
  // After tracing: was ray i blocked? (Embree sets tfar to -inf on a hit.)
  bool occluded(size_t i) const { return tfar(i) < 0.0f; }
};

// Closest-hit rays.
class IntersectBatch : public RayBatch<RayHit> {
 public:
  bool hit(size_t i) const { return rays_.data()[i].hit.geomID != kInvalidGeometryId; }
  unsigned geomID(size_t i) const { return rays_.data()[i].hit.geomID; }
  unsigned primID(size_t i) const { return rays_.data()[i].hit.primID; }
  unsigned instID(size_t i) const { return rays_.data()[i].hit.instID[0]; }
  float u(size_t i) const { return rays_.data()[i].hit.u; }
  float v(size_t i) const { return rays_.data()[i].hit.v; }
  float t(size_t i) const { return tfar(i); }
};

}  // namespace obscura
