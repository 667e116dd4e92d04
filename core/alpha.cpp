#include "core/alpha.h"

#include <bit>

#include "core/sampler.h"

namespace obscura {

float AlphaSurface::alphaAt(uint32_t prim, float u, float v) const {
  if (!texture || !uvs) return alpha;
  const uint32_t* tri = indices + size_t(prim) * 3;
  const float w = 1.0f - u - v;
  const float* t0 = uvs + size_t(tri[0]) * 2;
  const float* t1 = uvs + size_t(tri[1]) * 2;
  const float* t2 = uvs + size_t(tri[2]) * 2;
  // The same uv a baseColorTexture lookup uses (core/surface.cpp).
  return alpha * texture->sampleAlpha(t0[0] * w + t1[0] * u + t2[0] * v, t0[1] * w + t1[1] * u + t2[1] * v, wrapS, wrapT);
}

float blendSample(const float org[3], const float dir[3], uint32_t geomID, uint32_t primID, uint32_t instID) {
  uint32_t h = 0x2c1b3c6dU;
  for (int k = 0; k < 3; ++k) h = hashCombine(h, std::bit_cast<uint32_t>(org[k]));
  for (int k = 0; k < 3; ++k) h = hashCombine(h, std::bit_cast<uint32_t>(dir[k]));
  h = hashCombine(hashCombine(hashCombine(h, geomID), primID), instID);
  return float(h >> 8) * 0x1p-24f;  // 24 bits: exactly representable, < 1
}

namespace {
// Embree's filter for hits on a cut-out geometry (any ray type): rejects
// the hits alpha makes transparent.
void alphaFilter(const RTCFilterFunctionNArguments* a) {
  const auto& s = *static_cast<const AlphaSurface*>(a->geometryUserPtr);
  const unsigned N = a->N;
  for (unsigned i = 0; i < N; ++i) {
    if (a->valid[i] != -1) continue;
    const uint32_t prim = RTCHitN_primID(a->hit, N, i);
    const float alpha = s.alphaAt(prim, RTCHitN_u(a->hit, N, i), RTCHitN_v(a->hit, N, i));
    bool opaque;
    if (s.mode == AlphaMode::Mask) {
      opaque = alpha >= s.cutoff;
    } else {
      const float org[3] = {RTCRayN_org_x(a->ray, N, i), RTCRayN_org_y(a->ray, N, i), RTCRayN_org_z(a->ray, N, i)};
      const float dir[3] = {RTCRayN_dir_x(a->ray, N, i), RTCRayN_dir_y(a->ray, N, i), RTCRayN_dir_z(a->ray, N, i)};
      opaque = blendSample(org, dir, RTCHitN_geomID(a->hit, N, i), prim, RTCHitN_instID(a->hit, N, i, 0)) < alpha;
    }
    if (!opaque) a->valid[i] = 0;
  }
}
}  // namespace

void attachAlphaFilter(const Primitive& prim, AlphaSurface& surface) {
  rtcSetGeometryUserData(prim.geometry, &surface);
  rtcSetGeometryIntersectFilterFunction(prim.geometry, alphaFilter);
  rtcSetGeometryOccludedFilterFunction(prim.geometry, alphaFilter);
}

}  // namespace obscura
