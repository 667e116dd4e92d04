#include "core/surface.h"

#include "core/error.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace obscura {

namespace {
// A subdivision surface's albedo: its material's factor (textures need uvs,
// which subdivision surfaces do not carry to the hit).
Vec3 materialFactor(const Scene& scene, const Primitive& prim) {
  const Material* m = scene.materialOf(prim);
  return m ? m->baseColorFactor : Vec3(1, 1, 1);
}

float absMax(Vec3 a) { return std::max(std::abs(a.x), std::max(std::abs(a.y), std::abs(a.z))); }

// The limit surface of an Embree subdivision face at patch coordinates
// (u, v): its tangents dP/du, dP/dv.
void limitTangents(const Primitive& prim, unsigned face, float u, float v, Vec3& du, Vec3& dv) {
  float P[3], a[3], b[3];
  rtcInterpolate1(prim.geometry, face, u, v, RTC_BUFFER_TYPE_VERTEX, 0, P, a, b, 3);
  du = Vec3(a[0], a[1], a[2]);
  dv = Vec3(b[0], b[1], b[2]);
}

// x + dx in a subdivision face's patch coordinates, kept on the face: a
// quad's (u, v) span [0, 1]; other faces encode a sub-quad and the position
// in it (Embree's parametrization), whose local coordinate is clamped to
// [0, 1] and encoded back - beyond it CageUvs reads the cage edge, not an
// extrapolation.
float patchStep(bool quad, float x, float dx) {
  if (quad) return std::clamp(x + dx, 0.0f, 1.0f);
  const float base = 2.0f * std::floor(0.5f * x);                    // 2 l
  const float local = std::clamp(x - base - 0.5f + dx, 0.0f, 1.0f);  // sub-quad coordinate
  return base + 0.5f + local;
}

// The uv frame of a hit on an Embree subdivision surface with uvs: the
// limit tangents dP/d(patch u, v) times the inverse of the Jacobian of
// (patch u, v) -> uv (central differences of CageUvs, bilinear inside a
// sub-quad, so exact there up to rounding).
bool subdivisionUvFrame(const Primitive& prim, const SurfaceHit& h, UvFrame& out) {
  const SubdivisionSurface& s = *prim.subdivision;
  if (s.uvs.empty()) return false;
  const unsigned face = h.primID;
  const float u = h.hitU, v = h.hitV;
  float su, sv;
  s.uvs.at(face, u, v, su, sv);
  const bool quad = s.uvs.faceSize(face) == 4;
  constexpr float kStep = 1e-3f;
  const float u0 = patchStep(quad, u, -kStep), u1 = patchStep(quad, u, kStep);
  const float v0 = patchStep(quad, v, -kStep), v1 = patchStep(quad, v, kStep);
  if (!(u1 > u0) || !(v1 > v0)) return false;
  float a0, b0, a1, b1, c0, d0, c1, d1;
  s.uvs.at(face, u0, v, a0, b0), s.uvs.at(face, u1, v, a1, b1);
  s.uvs.at(face, u, v0, c0, d0), s.uvs.at(face, u, v1, c1, d1);
  // J = d(s, t)/d(u, v).
  const double j00 = (double(a1) - a0) / (u1 - u0), j10 = (double(b1) - b0) / (u1 - u0);
  const double j01 = (double(c1) - c0) / (v1 - v0), j11 = (double(d1) - d0) / (v1 - v0);
  const double det = j00 * j11 - j01 * j10;
  if (!(std::abs(det) > 1e-20) || !std::isfinite(det)) return false;
  Vec3 du, dv;
  limitTangents(prim, face, u, v, du, dv);
  // [dP/ds dP/dt] = [dP/du dP/dv] J^-1.
  const float i00 = float(j11 / det), i01 = float(-j01 / det), i10 = float(-j10 / det), i11 = float(j00 / det);
  out.u = su, out.v = sv;
  out.dpdu = du * i00 + dv * i10;
  out.dpdv = du * i01 + dv * i11;
  if (prim.uvsRunDown) out.v = 1.0f - out.v, out.dpdv = -out.dpdv;
  return isFinite(out.dpdu) && isFinite(out.dpdv);
}

// A hit on an Embree subdivision surface. The point is the ray's (o + t d):
// the tessellation Embree intersected is not the limit surface, so a point
// re-evaluated on the limit could lie on the far side of it. The geometric
// normal is the tessellation's; the shading normal the limit's or, when
// displaced, the displaced surface's: P' = P + d N has tangents
// dP/du + (dd/du) N + d dN/du, of which the last (displacement times
// curvature, small where displacement is small against the radius of
// curvature) is dropped, and dd/du is a central difference over one
// tessellation step of a quad (half a step on the sub-quads of other faces,
// which Embree tessellates at half the rate) - the scale the traced surface
// resolves. (Four patch
// evaluations for the full difference cost 60 % of a render; the height
// map lookups this takes instead are cheap.)
void subdivisionHit(const Scene& scene, const Primitive& prim, const RTCRayHit& rh, bool albedo, SurfaceHit& out) {
  const Vec3 org(rh.ray.org_x, rh.ray.org_y, rh.ray.org_z), dir(rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z);
  const unsigned face = rh.hit.primID;
  const float u = rh.hit.u, v = rh.hit.v;
  out.t = rh.ray.tfar;
  out.p = org + dir * out.t;
  out.dir = normalize(dir);
  out.geomID = rh.hit.geomID, out.primID = face, out.instID = rh.hit.instID[0];
  out.object = scene.objectOf(out.geomID, out.instID);
  out.hitU = u, out.hitV = v;
  out.time = rh.ray.time;
  // o + t d errs by ulps of |o| and of t|d|; the grid test by ulps of |p|.
  const float mag = std::max(absMax(out.p), absMax(org) + out.t * absMax(dir));
  out.eps = std::max(mag * kRayOffsetRelative, std::numeric_limits<float>::min());
  Vec3 ng(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
  const float ngLen = length(ng);
  ng = (ngLen > 0.0f && std::isfinite(ngLen)) ? ng * (1.0f / ngLen) : normalize(-dir);
  if (dot(ng, dir) > 0.0f) ng = -ng;
  out.ng = ng;

  const SubdivisionSurface& s = *prim.subdivision;
  Vec3 du, dv;
  limitTangents(prim, face, u, v, du, dv);
  Vec3 n = cross(du, dv);
  if (s.height) {
    // Differences divide by the span patchStep actually took.
    const float h = 0.5f / s.faceRate[face];
    const bool quad = s.uvs.faceSize(face) == 4;
    const float u0 = patchStep(quad, u, -h), u1 = patchStep(quad, u, h);
    const float v0 = patchStep(quad, v, -h), v1 = patchStep(quad, v, h);
    const float ddu = u1 > u0 ? (s.displacement(face, u1, v) - s.displacement(face, u0, v)) / (u1 - u0) : 0.0f;
    const float ddv = v1 > v0 ? (s.displacement(face, u, v1) - s.displacement(face, u, v0)) / (v1 - v0) : 0.0f;
    const float len = length(n);
    if (len > 0.0f && std::isfinite(len)) {
      const Vec3 N = n * (1.0f / len);
      n = cross(du + N * ddu, dv + N * ddv);
    }
  }
  const float len = length(n);
  Vec3 ns = ng;
  if (len > 0.0f && std::isfinite(len)) {
    n = n * (1.0f / len);
    ns = dot(n, ng) < 0.0f ? -n : n;
  }
  out.ns = ns;
  if (albedo) out.albedo = materialFactor(scene, prim);
}

// The material of a primitive with texture coordinates at (tu, tv).
Vec3 materialAlbedo(const Scene& scene, const Material& m, float tu, float tv) {
  const Texture& tex = *scene.textures[size_t(m.texture)];
  return m.baseColorFactor * tex.sample(tu, tv, m.wrapS, m.wrapT);
}

Vec3 primitiveAlbedo(const Scene& scene, const Primitive& prim, const uint32_t* tri, float u, float v) {
  const Material* m = scene.materialOf(prim);
  if (!m) return Vec3(1, 1, 1);
  if (m->texture < 0 || prim.uvs.empty()) return m->baseColorFactor;
  const float w = 1.0f - u - v;
  const float* t0 = &prim.uvs[size_t(tri[0]) * 2];
  const float* t1 = &prim.uvs[size_t(tri[1]) * 2];
  const float* t2 = &prim.uvs[size_t(tri[2]) * 2];
  return materialAlbedo(scene, *m, t0[0] * w + t1[0] * u + t2[0] * v, t0[1] * w + t1[1] * u + t2[1] * v);
}
}  // namespace

Vec3 surfaceAlbedo(const Scene& scene, unsigned geomID, unsigned primID, unsigned instID, float u, float v) {
  const Affine* toWorld = nullptr;
  const Primitive& prim = scene.primitiveOf(geomID, instID, &toWorld);
  if (prim.subdivision) return materialFactor(scene, prim);
  return primitiveAlbedo(scene, prim, prim.indices + size_t(primID) * 3, u, v);
}

void computeSurfaceHit(const Scene& scene, unsigned geomID, unsigned primID, unsigned instID, float u,
                       float v, float t, Vec3 dir, float time, bool albedo, SurfaceHit& out) {
  Affine moved;
  const Affine* toWorld = nullptr;
  const Primitive& prim = scene.primitiveAt(geomID, instID, time, moved, &toWorld);
  if (prim.subdivision)  // its hit point needs the ray's origin: the RTCRayHit form
    throw Error("internal: computeSurfaceHit from barycentrics on a subdivision surface");
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
  out.dir = normalize(dir);
  out.geomID = geomID, out.primID = primID, out.instID = instID;
  out.object = scene.objectOf(geomID, instID);
  out.hitU = u, out.hitV = v;
  out.time = time;

  // Offset scale from the magnitudes that bound the hit point's error.
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

void computeSurfaceHit(const Scene& scene, const RTCRayHit& rh, bool albedo, SurfaceHit& out) {
  const Affine* toWorld = nullptr;
  const Primitive& prim = scene.primitiveOf(rh.hit.geomID, rh.hit.instID[0], &toWorld);
  if (prim.subdivision) return subdivisionHit(scene, prim, rh, albedo, out);
  computeSurfaceHit(scene, rh.hit.geomID, rh.hit.primID, rh.hit.instID[0], rh.hit.u, rh.hit.v, rh.ray.tfar,
                    Vec3(rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z), rh.ray.time, albedo, out);
}

Vec3 surfaceAlbedoAtUv(const Scene& scene, const SurfaceHit& h, float u, float v) {
  const Affine* toWorld = nullptr;
  const Primitive& prim = scene.primitiveOf(h.geomID, h.instID, &toWorld);
  const Material* m = scene.materialOf(prim);
  if (!m) return Vec3(1, 1, 1);
  if (m->texture < 0 || prim.uvs.empty()) return m->baseColorFactor;
  return materialAlbedo(scene, *m, u, prim.uvsRunDown ? 1.0f - v : v);
}

float surfaceRoughness(const Scene& scene, const SurfaceHit& h) {
  const Affine* toWorld = nullptr;
  const Primitive& prim = scene.primitiveOf(h.geomID, h.instID, &toWorld);
  const Material* m = scene.materialOf(prim);
  if (!m) return 1.0f;
  if (m->roughnessTexture < 0 || prim.subdivision || prim.uvs.empty()) return m->roughnessFactor;
  const Texture& tex = *scene.dataTextures[size_t(m->roughnessTexture)];
  tex.decode();  // once (std::call_once); later calls only check that it succeeded
  // The same uv a baseColorTexture lookup uses (primitiveAlbedo), in the
  // file's convention (v down), as the texture is stored.
  const uint32_t* tri = prim.indices + size_t(h.primID) * 3;
  const float w = 1.0f - h.hitU - h.hitV;
  const float* t0 = &prim.uvs[size_t(tri[0]) * 2];
  const float* t1 = &prim.uvs[size_t(tri[1]) * 2];
  const float* t2 = &prim.uvs[size_t(tri[2]) * 2];
  const float tu = t0[0] * w + t1[0] * h.hitU + t2[0] * h.hitV, tv = t0[1] * w + t1[1] * h.hitU + t2[1] * h.hitV;
  // G is roughness (glTF 2.0 3.9.2); the product stays in [0, 1] (the factor
  // is checked at load, texels are in [0, 1]) up to rounding, clamped.
  const float r = m->roughnessFactor * tex.sample(tu, tv, m->roughnessWrapS, m->roughnessWrapT).y;
  return std::clamp(r, 0.0f, 1.0f);
}

bool surfaceUvFrame(const Scene& scene, const SurfaceHit& h, UvFrame& out) {
  Affine moved;
  const Affine* toWorld = nullptr;
  const Primitive& prim = scene.primitiveAt(h.geomID, h.instID, h.time, moved, &toWorld);
  if (prim.subdivision) return subdivisionUvFrame(prim, h, out);
  if (prim.uvs.empty() || !prim.indices) return false;
  const uint32_t* tri = prim.indices + size_t(h.primID) * 3;
  const auto vertex = [&](int k) {
    const float* q = prim.positions + size_t(tri[k]) * 3;
    const Vec3 p(q[0], q[1], q[2]);
    return toWorld ? toWorld->point(p) : p;
  };
  const float* t0 = &prim.uvs[size_t(tri[0]) * 2];
  const float* t1 = &prim.uvs[size_t(tri[1]) * 2];
  const float* t2 = &prim.uvs[size_t(tri[2]) * 2];
  const float w = 1.0f - h.hitU - h.hitV;
  out.u = t0[0] * w + t1[0] * h.hitU + t2[0] * h.hitV;
  out.v = t0[1] * w + t1[1] * h.hitU + t2[1] * h.hitV;
  const bool down = prim.uvsRunDown;  // glTF: report v = 1 - v_file (see UvFrame)
  // Solve [dp1 dp2] = [dpdu dpdv] [duv1 duv2] for the two derivatives.
  const Vec3 p0 = vertex(0), dp1 = vertex(1) - p0, dp2 = vertex(2) - p0;
  const double du1 = double(t1[0]) - t0[0], dv1 = double(t1[1]) - t0[1];
  const double du2 = double(t2[0]) - t0[0], dv2 = double(t2[1]) - t0[1];
  const double det = du1 * dv2 - dv1 * du2;
  if (!(std::abs(det) > 1e-20) || !std::isfinite(det)) return false;
  const float inv = float(1.0 / det);
  out.dpdu = (dp1 * float(dv2) - dp2 * float(dv1)) * inv;
  out.dpdv = (dp2 * float(du1) - dp1 * float(du2)) * inv;
  if (down) out.v = 1.0f - out.v, out.dpdv = -out.dpdv;
  return isFinite(out.dpdu) && isFinite(out.dpdv);
}

}  // namespace obscura
