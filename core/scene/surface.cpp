#include "core/scene/surface.h"

#include <obscura/error.h>

#include <emmintrin.h>
#include <xmmintrin.h>

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

// Normals before normalization scale with the scene: a cross product of two
// edges as its size squared, a normal through an instance's cofactor matrix
// likewise, and |n|^2 as the fourth power. For a scene scaled by 1e-12
// |n|^2 (~1e-48) is below float's range and the length came out 0: every
// triangle took the degenerate fallback (facing the ray) and the pass was
// wrong (docs/scenes.md "Scene scale"). Below kTinyNormal2 the vector is
// first divided by its largest component (magnitude 1); above, nothing
// changes, so a render of an ordinary scene keeps its bits.
constexpr float kTinyNormal2 = 0x1p-100f;
Vec3 rescaledIfTiny(Vec3 n) {
  if (!(dot(n, n) < kTinyNormal2)) return n;  // NaN and infinite as they were
  const float m = absMax(n);
  return m > 0.0f ? n * (1.0f / m) : n;
}

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
void subdivisionHit(const Scene& scene, const Primitive& prim, const RayHit& rh, bool albedo, SurfaceHit& out) {
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
  Vec3 ng = rescaledIfTiny(Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z));
  const float ngLen = length(ng);
  ng = (ngLen > 0.0f && std::isfinite(ngLen)) ? ng * (1.0f / ngLen) : normalize(-dir);
  if (dot(ng, dir) > 0.0f) ng = -ng;
  out.ng = ng;

  const SubdivisionSurface& s = *prim.subdivision;
  Vec3 du, dv;
  limitTangents(prim, face, u, v, du, dv);
  Vec3 n = rescaledIfTiny(cross(du, dv));
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
      n = rescaledIfTiny(cross(du + N * ddu, dv + N * ddv));
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
  m.transform.apply(tu, tv);  // KHR_texture_transform, in the file's uv convention
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
// The shading normal a normal map gives (docs/math.md §16). `front`: the
// unit interpolated vertex normal (or the triangle's, without normals) in
// world space, on the side the triangle's winding and its normals agree on,
// before the two-sided flip; ng: the geometric normal facing the ray; dir:
// the unit ray direction. `fallback` (the unmapped shading normal) when the
// tangent frame or the map's normal is degenerate.
Vec3 normalMapped(const Scene& scene, const Primitive& prim, const uint32_t* tri, float u, float v,
                  const Affine* toWorld, Vec3 front, Vec3 ng, Vec3 dir, Vec3 fallback) {
  const Material& m = scene.materials[size_t(prim.material)];
  const float w = 1.0f - u - v;
  const float* q0 = &prim.tangents[size_t(tri[0]) * 4];
  const float* q1 = &prim.tangents[size_t(tri[1]) * 4];
  const float* q2 = &prim.tangents[size_t(tri[2]) * 4];
  Vec3 t(q0[0] * w + q1[0] * u + q2[0] * v, q0[1] * w + q1[1] * u + q2[1] * v, q0[2] * w + q1[2] * u + q2[2] * v);
  float sign = q0[3] * w + q1[3] * u + q2[3] * v < 0.0f ? -1.0f : 1.0f;
  if (toWorld) {
    // Tangents are surface directions (vectors); a mirroring transform
    // reverses cross(N, T) against the transformed bitangent, and the
    // world winding of a mesh without normals against its object-space
    // front (Affine::normal keeps the latter).
    t = toWorld->vector(t);
    if (toWorld->determinant() < 0.0f) {
      sign = -sign;
      if (prim.normals.empty()) front = -front;
    }
  }
  // Gram-Schmidt: T in the plane of the (interpolated) normal.
  t = t - front * dot(front, t);
  const float tLen = length(t);
  if (!(tLen > 0.0f) || !std::isfinite(tLen)) return fallback;
  const Vec3 T = t * (1.0f / tLen);
  const Vec3 B = cross(front, T) * sign;
  // The texture lookup at the primitive's uv (file convention) through the
  // map's KHR_texture_transform.
  const float* u0 = &prim.uvs[size_t(tri[0]) * 2];
  const float* u1 = &prim.uvs[size_t(tri[1]) * 2];
  const float* u2 = &prim.uvs[size_t(tri[2]) * 2];
  float tu = u0[0] * w + u1[0] * u + u2[0] * v, tv = u0[1] * w + u1[1] * u + u2[1] * v;
  m.normalTransform.apply(tu, tv);
  const Vec3 c = scene.dataTextures[size_t(m.normalTexture)]->sample(tu, tv, m.normalWrapS, m.normalWrapT);
  // glTF 2.0 3.9.3: (2r - 1, 2g - 1, 2b - 1), x and y scaled by `scale`.
  const float x = (2.0f * c.x - 1.0f) * m.normalScale, y = (2.0f * c.y - 1.0f) * m.normalScale;
  const float z = 2.0f * c.z - 1.0f;
  // A flat texel (or scale 0) is the interpolated normal itself: returned
  // as it is, so a flat map renders as no map, bit for bit, rather than
  // through a renormalization's rounding.
  if (x == 0.0f && y == 0.0f && z > 0.0f) return fallback;
  // A rotated texture turns the map's axes on the surface by the inverse
  // rotation (docs/math.md §16.3).
  const float cr = m.normalTransform.cosR, sr = m.normalTransform.sinR;
  const float xs = cr * x + sr * y, ys = cr * y - sr * x;
  Vec3 n = T * xs + B * ys + front * z;
  const float nLen = length(n);
  if (!(nLen > 0.0f) || !std::isfinite(nLen)) return fallback;
  n = n * (1.0f / nLen);
  if (dot(front, ng) < 0.0f) n = -n;  // two-sided, as the unmapped normal
  // Keep the view's mirror direction above the geometric surface
  // (docs/math.md §16.4): with I towards the eye and R = 2 (n.I) n - I, a
  // reflection below the plane (R.ng < q) is lifted to elevation q at its
  // azimuth, and n becomes the half vector of I and the lifted R.
  const Vec3 I = -dir;
  const float cosView = dot(ng, I);
  const float q = std::min(0.9f * cosView, 0.01f);
  const Vec3 R = n * (2.0f * dot(n, I)) - I;
  const float rUp = dot(R, ng);
  if (rUp >= q) return n;
  const Vec3 flat = R - ng * rUp;
  const float flatLen = length(flat);
  const Vec3 lifted = flatLen > 0.0f && std::isfinite(flatLen)
                          ? flat * (std::sqrt(std::max(0.0f, 1.0f - q * q)) / flatLen) + ng * q
                          : ng;
  const Vec3 h = I + lifted;
  const float hLen = length(h);
  return hLen > 0.0f && std::isfinite(hLen) ? h * (1.0f / hLen) : ng;
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
  if (prim.subdivision)  // its hit point needs the ray's origin: the RayHit form
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
  Vec3 ng = rescaledIfTiny(cross(v1 - v0, v2 - v0));
  const float ngLen = length(ng);
  ng = (ngLen > 0.0f && std::isfinite(ngLen)) ? ng * (1.0f / ngLen) : normalize(-dir);
  const bool flipped = dot(ng, dir) > 0.0f;
  if (flipped) ng = -ng;
  out.ng = ng;

  Vec3 ns = ng;
  Vec3 front = flipped ? -ng : ng;  // the winding's side, before facing the ray
  if (!prim.normals.empty()) {
    Vec3 n = prim.normals[i0] * w + prim.normals[i1] * u + prim.normals[i2] * v;
    if (toWorld) n = toWorld->normal(n);
    n = rescaledIfTiny(n);
    const float len = length(n);
    if (len > 0.0f && std::isfinite(len)) {
      n = n * (1.0f / len);
      front = n;
      ns = dot(n, ng) < 0.0f ? -n : n;  // two-sided: the side the ray came from
    }
  }
  // Only primitives whose material has a normal map carry tangents (and
  // only when the load kept normal maps).
  if (!prim.tangents.empty()) ns = normalMapped(scene, prim, tri, u, v, toWorld, front, ng, out.dir, ns);
  out.ns = ns;

  if (albedo) out.albedo = primitiveAlbedo(scene, prim, tri, u, v);
}

void computeSurfaceHit(const Scene& scene, const RayHit& rh, bool albedo, SurfaceHit& out) {
  const Affine* toWorld = nullptr;
  const Primitive& prim = scene.primitiveOf(rh.hit.geomID, rh.hit.instID[0], &toWorld);
  if (prim.subdivision) return subdivisionHit(scene, prim, rh, albedo, out);
  computeSurfaceHit(scene, rh.hit.geomID, rh.hit.primID, rh.hit.instID[0], rh.hit.u, rh.hit.v, rh.ray.tfar,
                    Vec3(rh.ray.dir_x, rh.ray.dir_y, rh.ray.dir_z), rh.ray.time, albedo, out);
}

namespace {

// --- computeSurfaceHits: four triangle hits per SSE instruction ------------
//
// The scalar computeSurfaceHit above, with the same operations in the same
// order on four hits at once, so every lane rounds exactly as the scalar
// form does (IEEE add, mul, div and sqrt are correctly rounded in SSE as in
// scalar code; the build targets baseline x86-64, so no FMA contracts
// either form). Where the scalar code picks with a branch, the lanes
// compute both sides and select with a mask. std::max(a, b) is
// `a < b ? b : a`, which is _mm_max_ps(b, a) (it returns its second operand
// when the comparison is false, NaN included). Tested against the scalar
// form hit by hit (FastPaths.SurfaceHitLanesEqualTheScalarForm).

struct V4 {
  __m128 x, y, z;
};
inline V4 load3(const float (*a)[4]) { return {_mm_load_ps(a[0]), _mm_load_ps(a[1]), _mm_load_ps(a[2])}; }
inline V4 add(V4 a, V4 b) { return {_mm_add_ps(a.x, b.x), _mm_add_ps(a.y, b.y), _mm_add_ps(a.z, b.z)}; }
inline V4 sub(V4 a, V4 b) { return {_mm_sub_ps(a.x, b.x), _mm_sub_ps(a.y, b.y), _mm_sub_ps(a.z, b.z)}; }
inline V4 mul(V4 a, __m128 s) { return {_mm_mul_ps(a.x, s), _mm_mul_ps(a.y, s), _mm_mul_ps(a.z, s)}; }
// dot(a, b) = (ax bx + ay by) + az bz, as include/obscura/math.h adds.
inline __m128 dot(V4 a, V4 b) {
  return _mm_add_ps(_mm_add_ps(_mm_mul_ps(a.x, b.x), _mm_mul_ps(a.y, b.y)), _mm_mul_ps(a.z, b.z));
}
inline V4 cross(V4 a, V4 b) {
  return {_mm_sub_ps(_mm_mul_ps(a.y, b.z), _mm_mul_ps(a.z, b.y)), _mm_sub_ps(_mm_mul_ps(a.z, b.x), _mm_mul_ps(a.x, b.z)),
          _mm_sub_ps(_mm_mul_ps(a.x, b.y), _mm_mul_ps(a.y, b.x))};
}
// Flip the sign where mask is set (-a is exact, as is a sign flip).
inline V4 negateWhere(V4 a, __m128 mask) {
  const __m128 sign = _mm_and_ps(mask, _mm_set1_ps(-0.0f));
  return {_mm_xor_ps(a.x, sign), _mm_xor_ps(a.y, sign), _mm_xor_ps(a.z, sign)};
}
inline __m128 select(__m128 mask, __m128 a, __m128 b) { return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b)); }
inline V4 select(__m128 mask, V4 a, V4 b) { return {select(mask, a.x, b.x), select(mask, a.y, b.y), select(mask, a.z, b.z)}; }
inline __m128 absv(__m128 a) { return _mm_andnot_ps(_mm_set1_ps(-0.0f), a); }
// absMax(a) = max(|x|, max(|y|, |z|)) in std::max's operand order.
inline __m128 absMax(V4 a) { return _mm_max_ps(_mm_max_ps(absv(a.z), absv(a.y)), absv(a.x)); }
// The scalar rescaledIfTiny per lane (the same operations: the same bits);
// the division only when a lane needs it.
inline V4 rescaledIfTiny(V4 n) {
  const __m128 d = dot(n, n);
  // !(d < kTinyNormal2) lanes keep n: NaN compares false, as in the scalar test.
  const __m128 tiny = _mm_cmplt_ps(d, _mm_set1_ps(kTinyNormal2));
  if (_mm_movemask_ps(tiny) == 0) return n;
  const __m128 m = absMax(n);
  const __m128 use = _mm_and_ps(tiny, _mm_cmpgt_ps(m, _mm_setzero_ps()));
  const __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), m);
  return select(use, mul(n, inv), n);
}
// Scalar length's test: len > 0 and finite (len = sqrt(...) is never -inf).
inline __m128 usableLength(__m128 len) {
  return _mm_and_ps(_mm_cmpgt_ps(len, _mm_setzero_ps()), _mm_cmplt_ps(len, _mm_set1_ps(kInfinity)));
}

// Four hits' inputs, one row (x, y, z, -) per lane as gathered; transposed
// into structure of arrays (V4) for the arithmetic. Rows are whole __m128
// values: a lane's scalars stored one by one and read back as a vector
// would stall on store forwarding (measured: the first such load took a
// tenth of the stage).
struct HitRows {
  __m128 v0[4], v1[4], v2[4];  // world-space vertices
  __m128 n0[4], n1[4], n2[4];  // vertex normals (0 without)
  __m128 dir[4];               // (dir_x, dir_y, dir_z, time) of the ray as traced
  __m128 hit[4];               // (Ng_z, u, v, primID) of RTCHit: u and v
  int32_t hasNormals[4];       // all ones / zero
};

// (q[0], q[1], q[2], 0), reading nothing past q[2].
inline __m128 loadXyz(const float* q) {
  return _mm_movelh_ps(_mm_loadl_pi(_mm_setzero_ps(), reinterpret_cast<const __m64*>(q)), _mm_load_ss(q + 2));
}
inline __m128 rowOf(Vec3 a) { return _mm_setr_ps(a.x, a.y, a.z, 0.0f); }
// Rows of four lanes -> their first three components as lanes.
inline V4 lanesOf(const __m128 (&r)[4]) {
  __m128 a = r[0], b = r[1], c = r[2], d = r[3];
  _MM_TRANSPOSE4_PS(a, b, c, d);
  return {a, b, c};
}

// Lanes [0, m) of `in` into out[0..m): p, dir, eps, ng, ns as
// computeSurfaceHit (the rest of each SurfaceHit is the caller's).
// toWorld[l]: lane l's instance transform (normals go through its
// cofactor matrix, scalar, between the interpolation and the
// normalization, as in the scalar form), or null.
void triangleLanes(const HitRows& in, const Affine* const* toWorld, int m, SurfaceHit* const* out) {
  const V4 uv = lanesOf(in.hit);
  const __m128 u = uv.y, v = uv.z;
  const __m128 one = _mm_set1_ps(1.0f);
  const __m128 w = _mm_sub_ps(_mm_sub_ps(one, u), v);  // 1 - u - v
  const V4 v0 = lanesOf(in.v0), v1 = lanesOf(in.v1), v2 = lanesOf(in.v2), dir = lanesOf(in.dir);
  // p = v0 w + v1 u + v2 v (barycentrics, not o + t d: docs/architecture.md).
  const V4 p = add(add(mul(v0, w), mul(v1, u)), mul(v2, v));
  const __m128 dirLen = _mm_sqrt_ps(dot(dir, dir));
  const V4 unitDir = mul(dir, _mm_div_ps(one, dirLen));
  // The offset scale (kRayOffsetRelative).
  const __m128 mag = _mm_max_ps(_mm_max_ps(_mm_max_ps(absMax(v2), absMax(v1)), absMax(v0)), absMax(p));
  const __m128 eps =
      _mm_max_ps(_mm_set1_ps(std::numeric_limits<float>::min()), _mm_mul_ps(mag, _mm_set1_ps(kRayOffsetRelative)));
  // Geometric normal facing the ray; degenerate: -unit dir (= normalize(-dir) bit for bit).
  V4 ng = rescaledIfTiny(cross(sub(v1, v0), sub(v2, v0)));
  const __m128 ngLen = _mm_sqrt_ps(dot(ng, ng));
  ng = select(usableLength(ngLen), mul(ng, _mm_div_ps(one, ngLen)), negateWhere(unitDir, _mm_castsi128_ps(_mm_set1_epi32(-1))));
  ng = negateWhere(ng, _mm_cmpgt_ps(dot(ng, dir), _mm_setzero_ps()));
  // Shading normal: interpolated, through an instance's transform, unit,
  // on the ray's side of the surface (docs/math.md §1: AO is defined about it).
  V4 n = add(add(mul(lanesOf(in.n0), w), mul(lanesOf(in.n1), u)), mul(lanesOf(in.n2), v));
  bool anyTransform = false;
  for (int l = 0; l < m; ++l) anyTransform |= toWorld[l] != nullptr;
  if (anyTransform) {
    alignas(16) float t[3][4];
    _mm_store_ps(t[0], n.x), _mm_store_ps(t[1], n.y), _mm_store_ps(t[2], n.z);
    for (int l = 0; l < m; ++l)
      if (toWorld[l]) {
        const Vec3 x = toWorld[l]->normal(Vec3(t[0][l], t[1][l], t[2][l]));
        t[0][l] = x.x, t[1][l] = x.y, t[2][l] = x.z;
      }
    n = {_mm_load_ps(t[0]), _mm_load_ps(t[1]), _mm_load_ps(t[2])};
  }
  n = rescaledIfTiny(n);
  const __m128 nLen = _mm_sqrt_ps(dot(n, n));
  n = mul(n, _mm_div_ps(one, nLen));
  n = negateWhere(n, _mm_cmplt_ps(dot(n, ng), _mm_setzero_ps()));
  const __m128 hasNormals =
      _mm_castsi128_ps(_mm_setr_epi32(in.hasNormals[0], in.hasNormals[1], in.hasNormals[2], in.hasNormals[3]));
  const V4 ns = select(_mm_and_ps(hasNormals, usableLength(nLen)), n, ng);

  alignas(16) float o[13][4];
  const __m128 rows[13] = {p.x, p.y, p.z, unitDir.x, unitDir.y, unitDir.z, ng.x, ng.y, ng.z, ns.x, ns.y, ns.z, eps};
  for (int r = 0; r < 13; ++r) _mm_store_ps(o[r], rows[r]);
  for (int l = 0; l < m; ++l) {
    SurfaceHit& h = *out[l];
    h.p = Vec3(o[0][l], o[1][l], o[2][l]);
    h.dir = Vec3(o[3][l], o[4][l], o[5][l]);
    h.ng = Vec3(o[6][l], o[7][l], o[8][l]);
    h.ns = Vec3(o[9][l], o[10][l], o[11][l]);
    h.eps = o[12][l];
  }
}

}  // namespace

void computeSurfaceHits(const Scene& scene, const RayHit* rays, const uint32_t* lanes, size_t count, bool albedo,
                        SurfaceHit* out) {
  HitRows in;
  const Affine* toWorld[4];
  SurfaceHit* dst[4];
  Affine moved;  // a moving instance's transform (primitiveAt), only compared against
  int m = 0;
  for (size_t i = 0; i < count; ++i) {
    const RayHit& rh = rays[lanes[i]];
    SurfaceHit& h = out[i];
    const unsigned geomID = rh.hit.geomID, instID = rh.hit.instID[0];
    const Affine* xf = nullptr;
    const Primitive& prim = scene.primitiveAt(geomID, instID, rh.ray.time, moved, &xf);
    // Subdivision surfaces, moving instances (a transform per ray time,
    // which primitiveAt puts in `moved`) and normal-mapped primitives (a
    // texture lookup per hit, which dwarfs what the lanes save): the scalar
    // form.
    if (prim.subdivision || xf == &moved || !prim.tangents.empty()) {
      computeSurfaceHit(scene, rh, albedo, h);
      continue;
    }
    // Everything but the SIMD fields, as computeSurfaceHit stores it.
    const float u = rh.hit.u, v = rh.hit.v;
    const uint32_t* tri = prim.indices + size_t(rh.hit.primID) * 3;
    h.t = rh.ray.tfar;
    h.geomID = geomID, h.primID = rh.hit.primID, h.instID = instID;
    h.object = scene.objectOf(geomID, instID);
    h.hitU = u, h.hitV = v;
    h.time = rh.ray.time;
    if (albedo) h.albedo = primitiveAlbedo(scene, prim, tri, u, v);
    // The lane's rows.
    __m128* const vRows[3] = {in.v0, in.v1, in.v2};
    __m128* const nRows[3] = {in.n0, in.n1, in.n2};
    for (int k = 0; k < 3; ++k) {
      const float* q = prim.positions + size_t(tri[k]) * 3;
      vRows[k][m] = xf ? rowOf(xf->point(Vec3(q[0], q[1], q[2]))) : loadXyz(q);
      nRows[k][m] = prim.normals.empty() ? _mm_setzero_ps() : loadXyz(&prim.normals[tri[k]].x);
    }
    in.hasNormals[m] = prim.normals.empty() ? 0 : -1;
    in.dir[m] = _mm_loadu_ps(&rh.ray.dir_x);
    in.hit[m] = _mm_loadu_ps(&rh.hit.Ng_z);
    toWorld[m] = xf;
    dst[m] = &h;
    if (++m == 4) triangleLanes(in, toWorld, 4, dst), m = 0;
  }
  if (m > 0) {
    // Unused lanes repeat lane 0 (finite inputs; their results are dropped).
    for (int l = m; l < 4; ++l) {
      in.v0[l] = in.v0[0], in.v1[l] = in.v1[0], in.v2[l] = in.v2[0];
      in.n0[l] = in.n0[0], in.n1[l] = in.n1[0], in.n2[l] = in.n2[0];
      in.dir[l] = in.dir[0], in.hit[l] = in.hit[0], in.hasNormals[l] = in.hasNormals[0];
    }
    triangleLanes(in, toWorld, m, dst);
  }
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
  float tu = t0[0] * w + t1[0] * h.hitU + t2[0] * h.hitV, tv = t0[1] * w + t1[1] * h.hitU + t2[1] * h.hitV;
  m->roughnessTransform.apply(tu, tv);
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
