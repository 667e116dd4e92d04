#include "core/scene/alpha.h"

#include <bit>


namespace obscura {

float AlphaSurface::alphaAt(uint32_t prim, float u, float v) const {
  if (!texture || !uvs) return alpha;
  const uint32_t* tri = indices + size_t(prim) * 3;
  const float w = 1.0f - u - v;
  const float* t0 = uvs + size_t(tri[0]) * 2;
  const float* t1 = uvs + size_t(tri[1]) * 2;
  const float* t2 = uvs + size_t(tri[2]) * 2;
  // The same uv a baseColorTexture lookup uses (core/scene/surface.cpp).
  float s = t0[0] * w + t1[0] * u + t2[0] * v, t = t0[1] * w + t1[1] * u + t2[1] * v;
  transform.apply(s, t);
  return alpha * texture->sampleAlpha(s, t, wrapS, wrapT);
}

namespace {
// SplitMix64's finalizer (Steele, Lea and Flood 2014): a bijection of 64-bit
// words whose every output bit depends on every input bit.
inline uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}
inline uint64_t pack(float a, float b) { return uint64_t(std::bit_cast<uint32_t>(a)) | uint64_t(std::bit_cast<uint32_t>(b)) << 32; }
}  // namespace

float blendSample(const float org[3], const float dir[3], uint32_t geomID, uint32_t primID, uint32_t instID) {
  // The ray's six floats and the hit's three ids as four 64-bit words,
  // chained through the finalizer (a quarter of the multiplies of hashing
  // nine 32-bit words one by one: this runs for every candidate hit).
  uint64_t h = mix64(pack(org[0], org[1]) ^ 0x2c1b3c6d5f7a9e13ULL);
  h = mix64(h ^ pack(org[2], dir[0]));
  h = mix64(h ^ pack(dir[1], dir[2]));
  h = mix64(h ^ (uint64_t(geomID) | uint64_t(primID) << 32) ^ (uint64_t(instID) * 0x9e3779b97f4a7c15ULL));
  return float(h >> 40) * 0x1p-24f;  // 24 bits: exactly representable, < 1
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
