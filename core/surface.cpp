#include "core/surface.h"

#include <cmath>
#include <limits>

namespace obscura {

namespace {
Vec3 primitiveAlbedo(const Scene& scene, const Primitive& prim, const uint32_t* tri, float u, float v) {
  const Material* m = scene.materialOf(prim);
  if (!m) return Vec3(1, 1, 1);
  Vec3 a = m->baseColorFactor;
  if (m->texture >= 0 && !prim.uvs.empty()) {
    const float w = 1.0f - u - v;
    const float* t0 = &prim.uvs[size_t(tri[0]) * 2];
    const float* t1 = &prim.uvs[size_t(tri[1]) * 2];
    const float* t2 = &prim.uvs[size_t(tri[2]) * 2];
    const float tu = t0[0] * w + t1[0] * u + t2[0] * v;
    const float tv = t0[1] * w + t1[1] * u + t2[1] * v;
    const Texture& tex = *scene.textures[size_t(m->texture)];
    a = a * tex.sample(tu, tv, m->wrapS, m->wrapT);
  }
  return a;
}
}  // namespace

Vec3 surfaceAlbedo(const Scene& scene, unsigned geomID, unsigned primID, unsigned instID, float u, float v) {
  const Affine* toWorld = nullptr;
  const Primitive& prim = scene.primitiveOf(geomID, instID, &toWorld);
  return primitiveAlbedo(scene, prim, prim.indices + size_t(primID) * 3, u, v);
}

void computeSurfaceHit(const Scene& scene, unsigned geomID, unsigned primID, unsigned instID, float u,
                       float v, float t, Vec3 dir, bool albedo, SurfaceHit& out) {
  const Affine* toWorld = nullptr;
  const Primitive& prim = scene.primitiveOf(geomID, instID, &toWorld);
  const uint32_t* tri = prim.indices + size_t(primID) * 3;
  const uint32_t i0 = tri[0], i1 = tri[1], i2 = tri[2];
  const auto vertex = [&](uint32_t i) {
    const float* q = prim.positions + size_t(i) * 3;
    return Vec3(q[0], q[1], q[2]);
  };
  Vec3 v0 = vertex(i0), v1 = vertex(i1), v2 = vertex(i2);
  if (toWorld) {
    v0 = toWorld->point(v0);
    v1 = toWorld->point(v1);
    v2 = toWorld->point(v2);
  }
  const float w = 1.0f - u - v;
  out.p = v0 * w + v1 * u + v2 * v;
  out.t = t;

  // Offset scale from the magnitudes that bound the hit point's error.
  const auto absMax = [](Vec3 a) { return std::max(std::abs(a.x), std::max(std::abs(a.y), std::abs(a.z))); };
  const float mag = std::max(absMax(out.p), std::max(absMax(v0), std::max(absMax(v1), absMax(v2))));
  out.eps = std::max(mag * kRayOffsetRelative, std::numeric_limits<float>::min());

  // Geometric normal, facing the incoming ray. A (numerically) degenerate
  // triangle falls back to facing the ray head-on.
  Vec3 ng = cross(v1 - v0, v2 - v0);
  const float ngLen = length(ng);
  ng = (ngLen > 0.0f && std::isfinite(ngLen)) ? ng * (1.0f / ngLen) : normalize(-dir);
  const bool flipped = dot(ng, dir) > 0.0f;
  if (flipped) ng = -ng;
  out.ng = ng;

  Vec3 ns = ng;
  if (!prim.normals.empty()) {
    Vec3 n = prim.normals[i0] * w + prim.normals[i1] * u + prim.normals[i2] * v;
    if (toWorld) n = toWorld->normal(n);
    const float len = length(n);
    if (len > 0.0f && std::isfinite(len)) {
      n = n * (1.0f / len);
      ns = dot(n, ng) < 0.0f ? -n : n;  // two-sided: the side the ray came from
    }
  }
  out.ns = ns;

  if (albedo) out.albedo = primitiveAlbedo(scene, prim, tri, u, v);
}

}  // namespace obscura
