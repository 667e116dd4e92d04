// The surface point a camera ray (or any closest-hit ray) found, with what
// integrators need to continue from it, and the rules every ray leaving it
// follows (where it starts, which directions are open).
#pragma once

#include <cstddef>
#include <cstdint>

#include <obscura/math.h>

namespace obscura {

struct SurfaceHit {
  Vec3 p;        // world-space position, from barycentrics (not o + t*d)
  Vec3 ng;       // unit geometric normal, facing the side the ray came from
  Vec3 ns;       // unit shading normal, in the same hemisphere as ng
  Vec3 albedo;   // diffuse albedo; only filled when requested
  Vec3 dir;      // unit direction of the ray that found p, towards p (a camera hit's view direction)
  float eps;     // robust offset distance for rays leaving p (see spawnOrigin)
  float t;       // distance along the incoming ray
  uint32_t pixelKey;     // Sampler key of the pixel
  uint32_t sampleIndex;  // the camera sample's index within its pixel
  // Where on the scene: Embree's ids and the primitive-local coordinates
  // (triangle barycentrics, or a subdivision face's patch u, v), for the
  // lookups few integrators need (surfaceUvFrame).
  uint32_t geomID, primID, instID;
  float hitU, hitV;
  // The object (Scene::objects) the surface belongs to, kNoObject if none:
  // rays leaving the hit carry it (RayBatch::push's `from`).
  uint32_t object;
  // The moment of the camera sample in the shutter, in [0, 1) (0 without
  // motion blur): the time of the ray that found p, which every ray leaving
  // p carries on (RayBatch::push), so a sample sees one instant of the scene.
  float time = 0.0f;
};

// The surface's texture parametrization at a hit: uv, and the world-space
// derivatives dP/du, dP/dv of the (undisplaced) surface that carries it -
// in the height maps' convention, v = 0 at the bottom row of an image (OBJ;
// a glTF primitive's v, which runs down, is reported as 1 - v), so a height
// map reads the same at these uvs as `--displace` reads it.
struct UvFrame {
  float u, v;
  Vec3 dpdu, dpdv;
};

// Relative offset: 2^-16 of the largest coordinate magnitude involved in the
// hit, i.e. about 128 float ulps of it. Embree's triangle test and our
// barycentric reconstruction both err by a few ulps of the vertex and point
// magnitudes, so this clears self-intersection at every scene scale without
// an absolute epsilon (in the spirit of Waechter & Binder, "A Fast and Robust
// Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6, with the
// scale taken from the triangle itself instead of a fixed origin threshold).
constexpr float kRayOffsetRelative = 0x1p-16f;

// Origin for a ray leaving the hit in direction d: pushed off the surface to
// the side d points to. (Push the ray with `from` = h.object, so objects'
// occlusion scopes see where it leaves from.)
inline Vec3 spawnOrigin(const SurfaceHit& h, Vec3 d) {
  const float s = dot(d, h.ng) >= 0.0f ? h.eps : -h.eps;
  return h.p + h.ng * s;
}

// Surfaces are opaque: a direction below the geometric plane (which a cosine
// lobe about a tilted shading normal reaches) is blocked by the surface
// itself, at distance 0, whatever a ray would find. A direction exactly in
// the plane (w . ng == 0, measure zero) counts as blocked too, deliberately:
// only directions strictly above the surface are open, the same test for
// every integrator (all of them, and openDirection, come through here). A
// tangent ray could not be traced meaningfully anyway - it would run
// parallel to the surface at the offset height eps, so whether it met the
// neighbouring facets would depend on eps, not on the scene. A NaN direction
// fails the comparison and is blocked as well.
// The test itself, against a geometric normal ng (a lobe's, include/obscura/lobe.h,
// which may face away from the hit's).
inline bool intoSurface(Vec3 ng, Vec3 w) { return !(dot(w, ng) > 0.0f); }
inline bool intoSurface(const SurfaceHit& h, Vec3 w) { return intoSurface(h.ng, w); }

// An any-hit ray i of `batch` that was spawned from h: is its direction open?
template <class Batch>
inline bool openDirection(const SurfaceHit& h, const Batch& batch, size_t i) {
  return !intoSurface(h, batch.dir(i)) && !batch.occluded(i);
}

}  // namespace obscura
