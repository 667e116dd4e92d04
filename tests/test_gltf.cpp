// The glTF loader: files written here (JSON + .bin, or .glb) with known
// content, checked against numbers computed independently in double
// precision: node hierarchy and transforms, instancing, primitive modes and
// index types, cameras (also through the CLI), materials and textures, the
// bundled third-party scenes, and warnings for unsupported features.
#include <embree3/rtcore.h>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "core/scene/camera.h"
#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "core/scene/scene.h"
#include "core/scene/surface.h"
#include "core/image/texture.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

namespace fs = std::filesystem;

// --- double-precision reference math ---------------------------------------

using D3 = std::array<double, 3>;
D3 add(D3 a, D3 b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
D3 sub(D3 a, D3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
D3 mulS(D3 a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double dotD(D3 a, D3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
D3 crossD(D3 a, D3 b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
D3 unit(D3 a) { return mulS(a, 1.0 / std::sqrt(dotD(a, a))); }
D3 toD(Vec3 v) { return {v.x, v.y, v.z}; }

// Row-major affine map x -> A x + t.
struct Xf {
  double a[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  D3 t{0, 0, 0};
  D3 point(D3 p) const { return add(vector(p), t); }
  D3 vector(D3 v) const {
    return {a[0][0] * v[0] + a[0][1] * v[1] + a[0][2] * v[2], a[1][0] * v[0] + a[1][1] * v[1] + a[1][2] * v[2],
            a[2][0] * v[0] + a[2][1] * v[1] + a[2][2] * v[2]};
  }
  // Normal: inverse transpose (by the adjugate, positive determinant here).
  D3 normal(D3 n) const {
    const D3 c0{a[0][0], a[1][0], a[2][0]}, c1{a[0][1], a[1][1], a[2][1]}, c2{a[0][2], a[1][2], a[2][2]};
    const D3 r0 = crossD(c1, c2), r1 = crossD(c2, c0), r2 = crossD(c0, c1);
    return unit(add(add(mulS(r0, n[0]), mulS(r1, n[1])), mulS(r2, n[2])));
  }
  D3 column(int c) const { return {a[0][c], a[1][c], a[2][c]}; }
};

Xf operator*(const Xf& p, const Xf& c) {  // p after c
  Xf r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.a[i][j] = p.a[i][0] * c.a[0][j] + p.a[i][1] * c.a[1][j] + p.a[i][2] * c.a[2][j];
  r.t = p.point(c.t);
  return r;
}

// Rotation by the unit quaternion (x, y, z, w), built by rotating the basis
// vectors with v' = v + 2w (q x v) + 2 q x (q x v) (a different route from
// the loader's closed-form matrix).
Xf rotation(std::array<double, 4> q) {
  const double len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const D3 qv{q[0] / len, q[1] / len, q[2] / len};
  const double w = q[3] / len;
  Xf r;
  for (int c = 0; c < 3; ++c) {
    D3 e{0, 0, 0};
    e[size_t(c)] = 1;
    const D3 qxv = crossD(qv, e);
    const D3 v = add(e, add(mulS(qxv, 2 * w), mulS(crossD(qv, qxv), 2)));
    for (int i = 0; i < 3; ++i) r.a[i][c] = v[size_t(i)];
  }
  return r;
}
Xf translation(D3 t) {
  Xf r;
  r.t = t;
  return r;
}
Xf scaling(D3 s) {
  Xf r;
  for (int i = 0; i < 3; ++i) r.a[i][i] = s[size_t(i)];
  return r;
}
Xf trs(D3 t, std::array<double, 4> q, D3 s) { return translation(t) * rotation(q) * scaling(s); }
std::array<double, 4> axisAngle(D3 axis, double angle) {
  const D3 a = unit(axis);
  const double s = std::sin(0.5 * angle);
  return {a[0] * s, a[1] * s, a[2] * s, std::cos(0.5 * angle)};
}
// glTF's column-major 4x4 of an affine map.
json columnMajor(const Xf& x) {
  json m = json::array();
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) m.push_back(r == 3 ? (c == 3 ? 1.0 : 0.0) : (c == 3 ? x.t[size_t(r)] : x.a[r][c]));
  return m;
}
json toJson(std::array<double, 4> v) { return json::array({v[0], v[1], v[2], v[3]}); }

double srgbToLinearRef(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

// --- files ---------------------------------------------------------------

// An RGB8 PNG written by OpenImageIO; returns the file's bytes.
std::vector<unsigned char> writePng(const std::string& path, int w, int h, const std::vector<unsigned char>& rgb) {
  auto out = OIIO::ImageOutput::create(path);
  EXPECT_TRUE(out) << OIIO::geterror();
  if (!out) return {};
  OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::UINT8);
  EXPECT_TRUE(out->open(path, spec)) << out->geterror();
  EXPECT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, rgb.data())) << out->geterror();
  out->close();
  return readBytes(path);
}

// --- Embree queries -----------------------------------------------------

struct Hit {
  bool hit = false;
  float t = 0, u = 0, v = 0;
  unsigned geomID = RTC_INVALID_GEOMETRY_ID, primID = RTC_INVALID_GEOMETRY_ID, instID = RTC_INVALID_GEOMETRY_ID;
};
Hit traceRay(const Scene& scene, D3 org, D3 dir) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RayHit rh;
  std::memset(&rh, 0, sizeof rh);
  rh.ray.org_x = float(org[0]), rh.ray.org_y = float(org[1]), rh.ray.org_z = float(org[2]);
  rh.ray.dir_x = float(dir[0]), rh.ray.dir_y = float(dir[1]), rh.ray.dir_z = float(dir[2]);
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = kInfinity;
  rh.ray.mask = 0xffffffffU;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene.rtcScene(), &ctx, Tracer::embree(&rh));
  Hit h;
  h.hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
  h.t = rh.ray.tfar, h.u = rh.hit.u, h.v = rh.hit.v;
  h.geomID = rh.hit.geomID, h.primID = rh.hit.primID, h.instID = rh.hit.instID[0];
  return h;
}

void expectNear3(D3 got, D3 want, double tol, const std::string& what) {
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(got[size_t(i)], want[size_t(i)], tol * (1 + std::abs(want[size_t(i)])))
        << what << " component " << i;
}

// --- node hierarchy and transforms ------------------------------------------

TEST(GltfTransforms, HierarchyWithTrsAndMatrixIsBakedIntoWorldSpace) {
  const std::string dir = tempDir("gltf_hierarchy");
  // A unit quaternion, as glTF requires.
  const double ql = std::sqrt(0.2 * 0.2 + 0.4 * 0.4 + 0.3 * 0.3 + 0.8 * 0.8);
  const std::array<double, 4> q = {0.2 / ql, -0.4 / ql, 0.3 / ql, 0.8 / ql};
  const Xf parent = trs({1.5, -2.0, 0.25}, q, {2.0, 0.5, 1.5});
  // The child's matrix: a rotation about X, a shear and a translation.
  Xf child = rotation(axisAngle({1, 0, 0}, 0.5));
  child.a[0][1] += 0.2;
  child.t = {0.3, 0.1, -0.7};
  const Xf world = parent * child;

  const std::vector<Vec3> local = {{-1, -1, 0.2f}, {1, -1, 0.2f}, {1, 1, 0.2f}, {-1, 1, 0.2f}};
  const Vec3 nLocal = normalize(Vec3(0.3f, 0.0f, 1.0f));
  GltfBuilder g;
  const int pos = g.positions(local);
  const int nrm = g.vec3({nLocal, nLocal, nLocal, nLocal});
  const int idx = g.indices(std::vector<uint16_t>{0, 1, 2, 0, 2, 3});
  g.push("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", pos}, {"NORMAL", nrm}}}, {"indices", idx}}})}});
  g.node({{"name", "parent"}, {"translation", {1.5, -2.0, 0.25}}, {"rotation", toJson(q)}, {"scale", {2.0, 0.5, 1.5}}, {"children", {1}}});
  g.node({{"name", "child"}, {"matrix", columnMajor(child)}, {"mesh", 0}});
  g.scene({0});
  const std::string path = g.writeGltf(dir, "hierarchy");

  WarningCapture warnings;
  auto scene = loadGltf(path);
  EXPECT_TRUE(warnings.messages.empty()) << warnings.all();

  // Used by one node: baked, not instanced.
  EXPECT_TRUE(scene->instances().empty());
  EXPECT_TRUE(scene->instancedMeshes().empty());
  const SceneStats st = scene->stats();
  EXPECT_EQ(st.flattenedMeshes, 1u);
  EXPECT_EQ(st.primitives, 1u);
  EXPECT_EQ(st.uniqueTriangles, 2u);
  EXPECT_EQ(st.renderedTriangles, 2u);

  std::vector<D3> w;
  D3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const Vec3& v : local) {
    w.push_back(world.point(toD(v)));
    for (int i = 0; i < 3; ++i) {
      lo[size_t(i)] = std::min(lo[size_t(i)], w.back()[size_t(i)]);
      hi[size_t(i)] = std::max(hi[size_t(i)], w.back()[size_t(i)]);
    }
  }
  expectNear3(toD(scene->bounds().lo), lo, 1e-5, "bounds.lo");
  expectNear3(toD(scene->bounds().hi), hi, 1e-5, "bounds.hi");

  // Rays along the world normal at each triangle's centroid hit at distance 3.
  const D3 n = unit(crossD(sub(w[1], w[0]), sub(w[2], w[0])));
  const std::array<std::array<int, 3>, 2> tris = {{{0, 1, 2}, {0, 2, 3}}};
  for (unsigned t = 0; t < 2; ++t) {
    const D3 c = mulS(add(add(w[size_t(tris[t][0])], w[size_t(tris[t][1])]), w[size_t(tris[t][2])]), 1.0 / 3.0);
    const D3 org = add(c, mulS(n, 3.0));
    const Hit h = traceRay(*scene, org, mulS(n, -1.0));
    ASSERT_TRUE(h.hit) << "triangle " << t;
    EXPECT_EQ(h.primID, t);
    EXPECT_EQ(h.instID, RTC_INVALID_GEOMETRY_ID);
    EXPECT_NEAR(h.t, 3.0, 1e-4);
    EXPECT_NEAR(h.u, 1.0 / 3.0, 1e-4);
    EXPECT_NEAR(h.v, 1.0 / 3.0, 1e-4);

    // The shading normal is the file's normal under the inverse transpose.
    SurfaceHit sh{};
    computeSurfaceHit(*scene, h.geomID, h.primID, h.instID, h.u, h.v, h.t,
                      Vec3(float(-n[0]), float(-n[1]), float(-n[2])), 0.0f, false, sh);
    expectNear3(toD(sh.p), c, 1e-5, "hit point");
    D3 ns = world.normal(toD(nLocal));
    if (dotD(ns, n) < 0) ns = mulS(ns, -1.0);  // facing the ray's side
    expectNear3(toD(sh.ns), ns, 1e-5, "shading normal");
  }
  // Just outside the quad (local x = 1.2): a miss.
  const D3 outside = world.point({1.2, 0.0, 0.2});
  EXPECT_FALSE(traceRay(*scene, add(outside, mulS(n, 3.0)), mulS(n, -1.0)).hit);
}

TEST(GltfTransforms, MeshUsedByThreeNodesIsInstancedOnce) {
  const std::string dir = tempDir("gltf_instancing");
  GltfBuilder g;
  const int quad = g.quadMesh(0.5f);
  const int tri = g.push("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", g.positions({{10, 10, -5}, {11, 10, -5}, {10, 11, -5}})}}}}})}});
  const std::array<Xf, 3> xf = {translation({0, 0, 0}), translation({3, 0, 0}),
                                trs({-3, 1, 2}, axisAngle({0, 1, 0}, 0.785398), {2, 2, 2})};
  g.node({{"name", "a"}, {"mesh", quad}});
  g.node({{"name", "b"}, {"mesh", quad}, {"translation", {3, 0, 0}}});
  g.node({{"name", "c"}, {"mesh", quad}, {"translation", {-3, 1, 2}}, {"rotation", toJson(axisAngle({0, 1, 0}, 0.785398))}, {"scale", {2, 2, 2}}});
  g.node({{"name", "single"}, {"mesh", tri}});
  g.scene({0, 1, 2, 3});
  auto scene = loadGltf(g.writeGltf(dir, "instancing"));

  ASSERT_EQ(scene->instances().size(), 3u);
  ASSERT_EQ(scene->instancedMeshes().size(), 1u);
  const SceneStats st = scene->stats();
  EXPECT_EQ(st.instances, 3u);
  EXPECT_EQ(st.flattenedMeshes, 1u);  // the triangle mesh, used once
  EXPECT_EQ(st.meshes, 2u);
  EXPECT_EQ(st.primitives, 2u);
  EXPECT_EQ(st.uniqueTriangles, 2u + 1u);
  EXPECT_EQ(st.renderedTriangles, 3u * 2u + 1u);
  const char* names[3] = {"a", "b", "c"};
  for (int k = 0; k < 3; ++k) EXPECT_EQ(scene->instances()[size_t(k)].node, names[k]);

  // Bounds: the union of the three placed quads and the triangle.
  D3 lo{10, 10, -5}, hi{11, 11, -5};
  for (const Xf& x : xf)
    for (D3 c : {D3{-0.5, -0.5, 0}, D3{0.5, -0.5, 0}, D3{0.5, 0.5, 0}, D3{-0.5, 0.5, 0}}) {
      const D3 p = x.point(c);
      for (int i = 0; i < 3; ++i) lo[size_t(i)] = std::min(lo[size_t(i)], p[size_t(i)]), hi[size_t(i)] = std::max(hi[size_t(i)], p[size_t(i)]);
    }
  expectNear3(toD(scene->bounds().lo), lo, 1e-5, "bounds.lo");
  expectNear3(toD(scene->bounds().hi), hi, 1e-5, "bounds.hi");

  for (int k = 0; k < 3; ++k) {
    SCOPED_TRACE("instance " + std::string(names[k]));
    const D3 n = xf[size_t(k)].normal({0, 0, 1});
    // Inside: local (0.4, 0.4); outside: local (0.6, 0) (scale applies).
    const D3 in = xf[size_t(k)].point({0.4, 0.4, 0});
    const Hit h = traceRay(*scene, add(in, mulS(n, 5.0)), mulS(n, -1.0));
    ASSERT_TRUE(h.hit);
    EXPECT_NEAR(h.t, 5.0, 1e-4);
    ASSERT_NE(h.instID, RTC_INVALID_GEOMETRY_ID);
    const Affine* toWorld = nullptr;
    scene->primitiveOf(h.geomID, h.instID, &toWorld);
    EXPECT_EQ(toWorld, &scene->instances()[size_t(k)].toWorld) << "the hit belongs to another instance";
    SurfaceHit sh{};
    computeSurfaceHit(*scene, h.geomID, h.primID, h.instID, h.u, h.v, h.t,
                      Vec3(float(-n[0]), float(-n[1]), float(-n[2])), 0.0f, false, sh);
    expectNear3(toD(sh.p), in, 1e-5, "hit point");
    const D3 out = xf[size_t(k)].point({0.6, 0.0, 0});
    EXPECT_FALSE(traceRay(*scene, add(out, mulS(n, 5.0)), mulS(n, -1.0)).hit);
  }
  // The single-use mesh is in world space.
  const Hit h = traceRay(*scene, {10.25, 10.25, -3}, {0, 0, -1});
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(h.instID, RTC_INVALID_GEOMETRY_ID);
  EXPECT_NEAR(h.t, 2.0, 1e-5);
}

// --- primitives -------------------------------------------------------------

TEST(GltfPrimitives, ModesAndIndexTypesGiveTheExpectedTriangles) {
  const std::string dir = tempDir("gltf_primitives");
  GltfBuilder g;
  // n distinct vertices along a zigzag (the geometry is irrelevant here).
  const auto verts = [](size_t n, float z) {
    std::vector<Vec3> p;
    for (size_t i = 0; i < n; ++i) p.emplace_back(float(i), float(i % 2), z);
    return p;
  };
  using Tri = std::array<uint32_t, 3>;
  struct Expect {
    std::string what;
    std::vector<Tri> tris;
  };
  std::vector<Expect> expect;
  json prims = json::array();
  // TRIANGLES, uint8 indices.
  prims.push_back({{"attributes", {{"POSITION", g.positions(verts(4, 0))}}}, {"indices", g.indices(std::vector<uint8_t>{0, 1, 2, 2, 1, 3})}});
  expect.push_back({"TRIANGLES ubyte", {{0, 1, 2}, {2, 1, 3}}});
  // TRIANGLES, uint16 indices above 255.
  prims.push_back({{"attributes", {{"POSITION", g.positions(verts(400, 1))}}},
                   {"indices", g.indices(std::vector<uint16_t>{0, 1, 300, 1, 399, 300, 399, 4, 300})}});
  expect.push_back({"TRIANGLES ushort", {{0, 1, 300}, {1, 399, 300}, {399, 4, 300}}});
  // TRIANGLES, uint32 indices above 65535.
  prims.push_back({{"attributes", {{"POSITION", g.positions(verts(70000, 2))}}},
                   {"indices", g.indices(std::vector<uint32_t>{69999, 65536, 0})}});
  expect.push_back({"TRIANGLES uint", {{69999, 65536, 0}}});
  // TRIANGLES, not indexed (mode given explicitly).
  prims.push_back({{"attributes", {{"POSITION", g.positions(verts(6, 3))}}}, {"mode", 4}});
  expect.push_back({"TRIANGLES non-indexed", {{0, 1, 2}, {3, 4, 5}}});
  // TRIANGLE_STRIP, uint16 indices: n - 2 triangles, alternating winding
  // (glTF 2.0 section 3.7.2.1: p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}}).
  prims.push_back({{"attributes", {{"POSITION", g.positions(verts(6, 4))}}},
                   {"indices", g.indices(std::vector<uint16_t>{0, 1, 2, 3, 4, 5})}, {"mode", kStrip}});
  expect.push_back({"TRIANGLE_STRIP", {{0, 1, 2}, {1, 3, 2}, {2, 3, 4}, {3, 5, 4}}});
  // TRIANGLE_FAN, not indexed: p_i = {v_{i+1}, v_{i+2}, v_0}.
  prims.push_back({{"attributes", {{"POSITION", g.positions(verts(5, 5))}}}, {"mode", kFan}});
  expect.push_back({"TRIANGLE_FAN non-indexed", {{1, 2, 0}, {2, 3, 0}, {3, 4, 0}}});
  // TRIANGLE_FAN, uint32 indices.
  prims.push_back({{"attributes", {{"POSITION", g.positions(verts(5, 6))}}},
                   {"indices", g.indices(std::vector<uint32_t>{4, 3, 2, 1, 0})}, {"mode", kFan}});
  expect.push_back({"TRIANGLE_FAN uint", {{3, 2, 4}, {2, 1, 4}, {1, 0, 4}}});
  // A strip of two vertices has no triangle: dropped, not an error.
  prims.push_back({{"attributes", {{"POSITION", g.positions(verts(2, 7))}}}, {"mode", kStrip}});
  g.push("meshes", {{"primitives", prims}});
  g.node({{"mesh", 0}});
  g.scene({0});
  WarningCapture warnings;
  auto scene = loadGltf(g.writeGltf(dir, "primitives"));
  EXPECT_TRUE(warnings.messages.empty()) << warnings.all();

  size_t total = 0;
  for (const auto& e : expect) total += e.tris.size();
  const SceneStats st = scene->stats();
  EXPECT_EQ(st.uniqueTriangles, total);  // 2 + 3 + 1 + 2 + 4 + 3 + 3 = 18
  EXPECT_EQ(total, 18u);
  ASSERT_EQ(st.primitives, expect.size());
  // World primitives get top-level geomIDs in file order.
  const auto rotateToSmallest = [](Tri t) {  // same triangle, same winding
    while (t[0] > t[1] || t[0] > t[2]) t = {t[1], t[2], t[0]};
    return t;
  };
  for (size_t k = 0; k < expect.size(); ++k) {
    SCOPED_TRACE(expect[k].what);
    const Affine* xf = nullptr;
    const Primitive& p = scene->primitiveOf(unsigned(k), RTC_INVALID_GEOMETRY_ID, &xf);
    EXPECT_EQ(xf, nullptr);
    ASSERT_EQ(p.triangleCount, expect[k].tris.size());
    for (size_t t = 0; t < expect[k].tris.size(); ++t) {
      const Tri got = {p.indices[3 * t], p.indices[3 * t + 1], p.indices[3 * t + 2]};
      EXPECT_EQ(rotateToSmallest(got), rotateToSmallest(expect[k].tris[t])) << "triangle " << t;
    }
  }
}

// --- cameras ----------------------------------------------------------------

// Two perspective cameras: "alpha" (cameras[0]) on a plain node and "beta"
// (cameras[1]) on a scaled TRS node under a rotated parent; a ground quad.
// With betaFirst the beta node comes first in the node traversal.
std::string writeTwoCameraScene(const std::string& dir, bool betaFirst, Xf* betaWorld, Xf* alphaWorld) {
  GltfBuilder g;
  g.push("cameras", perspective("alpha", 0.6, 0.1, 50));
  g.push("cameras", perspective("beta", 0.9, 0.25));
  const int quad = g.quadMesh(20.0f);
  const Xf rig = trs({10, 0, 0}, axisAngle({0, 1, 0}, 1.2), {1, 1, 1});
  const Xf betaLocal = trs({0, 1, 5}, axisAngle({1, 0, 0}, -0.35), {2, 2, 2});
  if (betaWorld) *betaWorld = rig * betaLocal;
  if (alphaWorld) *alphaWorld = trs({0, 0, 10}, axisAngle({0, 0, 1}, 0.3), {1, 1, 1});
  const int alphaNode = g.node({{"name", "alpha_node"}, {"camera", 0}, {"translation", {0, 0, 10}}, {"rotation", toJson(axisAngle({0, 0, 1}, 0.3))}});
  const int rigNode = g.node({{"name", "rig"}, {"translation", {10, 0, 0}}, {"rotation", toJson(axisAngle({0, 1, 0}, 1.2))}, {"children", {2}}});
  g.node({{"name", "beta_node"}, {"camera", 1}, {"translation", {0, 1, 5}}, {"rotation", toJson(axisAngle({1, 0, 0}, -0.35))}, {"scale", {2, 2, 2}}});
  const int ground = g.node({{"name", "ground"}, {"mesh", quad}});
  g.scene(betaFirst ? std::vector<int>{rigNode, alphaNode, ground} : std::vector<int>{alphaNode, rigNode, ground});
  return g.writeGltf(dir, betaFirst ? "cameras_beta_first" : "cameras");
}

TEST(GltfCameras, CamerasLoadWithNodeTransformNameFovAndNear) {
  const std::string dir = tempDir("gltf_cameras");
  Xf betaWorld, alphaWorld;
  auto scene = loadGltf(writeTwoCameraScene(dir, false, &betaWorld, &alphaWorld));
  ASSERT_EQ(scene->cameras.size(), 2u);
  const Camera* alpha = nullptr;
  const Camera* beta = nullptr;
  for (const Camera& c : scene->cameras) (c.name == "alpha" ? alpha : beta) = &c;
  ASSERT_TRUE(alpha && beta);
  EXPECT_EQ(beta->name, "beta");
  EXPECT_FLOAT_EQ(alpha->yfov, 0.6f);
  EXPECT_FLOAT_EQ(alpha->znear, 0.1f);
  EXPECT_FLOAT_EQ(alpha->zfar, 50.0f);
  EXPECT_FLOAT_EQ(beta->yfov, 0.9f);
  EXPECT_FLOAT_EQ(beta->znear, 0.25f);
  EXPECT_EQ(beta->zfar, kInfinity);  // no zfar: infinite projection

  for (const auto& [cam, world] : {std::pair{alpha, alphaWorld}, std::pair{beta, betaWorld}}) {
    SCOPED_TRACE(cam->name);
    expectNear3(toD(cam->position()), world.t, 1e-6, "position");
    // Rigid: unit axes (beta's node scale of 2 is removed), directions of
    // the node's world axes.
    for (int c = 0; c < 3; ++c) {
      const D3 axis = toD(cam->toWorld.vector(Vec3(c == 0, c == 1, c == 2)));
      expectNear3(axis, unit(world.column(c)), 1e-6, "axis " + std::to_string(c));
    }
    // The centre ray looks down the node's -Z.
    Vec3 org, dir;
    cam->generateRay(4.0f, 4.0f, 8, 8, org, dir);
    expectNear3(toD(dir), mulS(unit(world.column(2)), -1.0), 1e-6, "view direction");
  }
}

TEST(GltfCameras, CliSelectsCameraByNameAndIndex) {
  const std::string dir = tempDir("gltf_camera_cli");
  const std::string scene = writeTwoCameraScene(dir, false, nullptr, nullptr);
  struct Case {
    std::vector<std::string> select;
    std::string expect;
  };
  const std::vector<Case> cases = {{{"--camera", "beta"}, "beta"}, {{"--camera", "1"}, "beta"}, {{}, "alpha"}};
  int k = 0;
  for (const Case& c : cases) {
    const std::string out = dir + "/out" + std::to_string(k++) + ".exr";
    std::vector<std::string> args = {"render", scene, "-o", out, "--res", "8x8", "--spp", "1", "-q"};
    args.insert(args.end(), c.select.begin(), c.select.end());
    const CliResult r = runCli(args, dir + "/stderr.txt");
    SCOPED_TRACE(c.select.empty() ? "(default)" : c.select[1]);
    ASSERT_EQ(r.exitCode, 0) << r.stderrText;
    EXPECT_EQ(r.stderrText, "");
    EXPECT_EQ(readExr(out).spec.get_string_attribute("obscura:camera", "<missing>"), c.expect);
  }
}

// `--camera INDEX` and the default ("the first camera") refer to the file's
// cameras[] array, whatever order the nodes are visited in.
// NOTE: fails as of this writing: the loader appends cameras to
// Scene::cameras in node-traversal order and app/main.cpp selectCamera()
// indexes that vector, so here `--camera 0` and the default pick "beta"
// (cameras[1]). See the report: the fix belongs in core/load/gltf_loader.cpp.
TEST(GltfCameras, CameraIndexIsTheIndexInTheFile) {
  const std::string dir = tempDir("gltf_camera_index");
  const std::string scene = writeTwoCameraScene(dir, true, nullptr, nullptr);
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--camera", "0"}, "alpha"}, {{"--camera", "1"}, "beta"}, {{}, "alpha"}};
  int k = 0;
  for (const auto& [select, expect] : cases) {
    const std::string out = dir + "/out" + std::to_string(k++) + ".exr";
    std::vector<std::string> args = {"render", scene, "-o", out, "--res", "8x8", "--spp", "1", "-q"};
    args.insert(args.end(), select.begin(), select.end());
    const CliResult r = runCli(args, dir + "/stderr.txt");
    SCOPED_TRACE(select.empty() ? "(default)" : select[1]);
    ASSERT_EQ(r.exitCode, 0) << r.stderrText;
    EXPECT_EQ(readExr(out).spec.get_string_attribute("obscura:camera", "<missing>"), expect);
  }
}

// Projects a world point with a world-to-camera matrix in row-vector form
// (EXR convention, p' = p M); returns false if behind the camera.
bool project(const float* m, D3 p, double& x, double& y) {
  double c[3];
  for (int j = 0; j < 3; ++j) c[j] = p[0] * m[0 * 4 + j] + p[1] * m[1 * 4 + j] + p[2] * m[2 * 4 + j] + m[3 * 4 + j];
  if (!(c[2] < 0)) return false;
  x = c[0] / -c[2];
  y = c[1] / -c[2];
  return true;
}

// World-to-camera in row-vector form, from a camera's toWorld (rigid).
std::array<float, 16> worldToCamera(const Camera& cam) {
  std::array<float, 16> m{};
  const D3 t = toD(cam.position());
  for (int c = 0; c < 3; ++c) {
    const D3 axis = toD(cam.toWorld.vector(Vec3(c == 0, c == 1, c == 2)));
    for (int k = 0; k < 3; ++k) m[size_t(k * 4 + c)] = float(axis[size_t(k)]);
    m[size_t(12 + c)] = float(-dotD(axis, t));
  }
  m[15] = 1;
  return m;
}

// All 8 corners of `b` project inside the image of aspect `aspect` (and the
// framing is not absurdly loose).
void expectBoundsInView(const float* w2c, double yfov, double aspect, const Bounds3& b) {
  const double th = std::tan(0.5 * yfov), tw = th * aspect;
  double widest = 0;
  for (int c = 0; c < 8; ++c) {
    const D3 p{c & 1 ? b.hi.x : b.lo.x, c & 2 ? b.hi.y : b.lo.y, c & 4 ? b.hi.z : b.lo.z};
    double x = 0, y = 0;
    ASSERT_TRUE(project(w2c, p, x, y)) << "corner " << c << " is behind the camera";
    EXPECT_LE(std::abs(x), tw) << "corner " << c << " is outside the image horizontally";
    EXPECT_LE(std::abs(y), th) << "corner " << c << " is outside the image vertically";
    widest = std::max({widest, std::abs(x) / tw, std::abs(y) / th});
  }
  EXPECT_GT(widest, 0.3) << "the scene covers almost nothing of the view";
}

TEST(GltfCameras, NoCameraInFileRendersWithAutoCameraFramingEverything) {
  const std::string dir = tempDir("gltf_auto_camera");
  GltfBuilder g;
  const int quad = g.quadMesh(1.0f);
  g.node({{"mesh", quad}, {"translation", {-5, 0, 0}}});
  g.node({{"mesh", quad}, {"translation", {4, 3, -2}}, {"rotation", toJson(axisAngle({1, 1, 0}, 0.7))}});
  g.node({{"mesh", quad}, {"translation", {0, -2, 6}}, {"scale", {3, 1, 1}}});
  g.scene({0, 1, 2});
  const std::string path = g.writeGltf(dir, "nocamera");
  auto scene = loadGltf(path);
  ASSERT_TRUE(scene->cameras.empty());
  const Bounds3 b = scene->bounds();
  ASSERT_FALSE(b.empty());

  // In process, for wide, square and tall images.
  for (double aspect : {3.0, 1.0, 0.5}) {
    SCOPED_TRACE("aspect " + std::to_string(aspect));
    const Camera cam = makeAutoCamera(b, float(aspect));
    EXPECT_EQ(cam.name, "auto");
    const auto m = worldToCamera(cam);
    expectBoundsInView(m.data(), cam.yfov, aspect, b);
  }

  // Through the CLI: the header names the auto camera and its matrix frames
  // the scene.
  const std::string out = dir + "/auto.exr";
  const CliResult r = runCli({"render", path, "-o", out, "--res", "16x8", "--spp", "1", "-q"}, dir + "/stderr.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack image = readExr(out);
  ASSERT_TRUE(image.ok);
  const OIIO::ImageSpec& spec = image.spec;
  EXPECT_EQ(spec.get_string_attribute("obscura:camera"), "auto");
  const OIIO::ParamValue* w2c = spec.find_attribute("worldToCamera", OIIO::TypeMatrix44);
  ASSERT_NE(w2c, nullptr);
  // The header's matrix is OpenEXR's (+Z ahead, tests/test_exr_conventions.cpp):
  // back to glTF's camera frame (-Z ahead) by negating its third column.
  std::array<float, 16> m;
  std::copy_n(static_cast<const float*>(w2c->data()), 16, m.begin());
  for (int k = 0; k < 4; ++k) m[size_t(k * 4 + 2)] = -m[size_t(k * 4 + 2)];
  const Camera cam = makeAutoCamera(b, 2.0f);
  const auto expected = worldToCamera(cam);
  for (int i = 0; i < 16; ++i) EXPECT_NEAR(m[i], expected[size_t(i)], 1e-4 * (1 + std::abs(expected[size_t(i)]))) << i;
  expectBoundsInView(m.data(), cam.yfov, 2.0, b);
  // And the render saw geometry.
  ASSERT_TRUE(image.planes.count("A"));
  double coverage = 0;
  for (float a : image.planes.at("A")) coverage += a;
  EXPECT_GT(coverage, 0.0);
}

// --- materials and textures -------------------------------------------------

// A quad of half-size 50 at z = 0 seen from (0,0,1) looking down -Z: it
// fills the view. `material` is added to the builder by the caller.
void addViewFillingQuad(GltfBuilder& g, int material, bool withUv) {
  g.push("cameras", perspective("front", 0.5, 0.01));
  const int quad = g.quadMesh(50.0f, material, withUv);
  g.node({{"mesh", quad}});
  g.node({{"camera", 0}, {"translation", {0, 0, 1}}});
  g.scene({0, 1});
}

// Renders the file's camera at 8x8 with AOVs and checks every pixel's albedo.
void expectUniformAlbedo(const Scene& scene, D3 expect) {
  ASSERT_EQ(scene.cameras.size(), 1u);
  RenderSettings s;
  s.width = s.height = 8;
  s.spp = 2;
  s.aovs = true;
  const Film film = renderWith(scene, scene.cameras[0], "ao", {}, s);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) {
      ASSERT_EQ(film.at(kA, x, y), 1.0f) << x << "," << y;
      EXPECT_NEAR(film.at(kAlbedoR, x, y), expect[0], 2e-6) << x << "," << y;
      EXPECT_NEAR(film.at(kAlbedoG, x, y), expect[1], 2e-6) << x << "," << y;
      EXPECT_NEAR(film.at(kAlbedoB, x, y), expect[2], 2e-6) << x << "," << y;
    }
}

TEST(GltfMaterials, BaseColorFactorIsTheAlbedo) {
  const std::string dir = tempDir("gltf_factor");
  GltfBuilder g;
  const int mat = g.push("materials", {{"name", "paint"}, {"pbrMetallicRoughness", {{"baseColorFactor", {0.2, 0.4, 0.6, 1.0}}}}});
  addViewFillingQuad(g, mat, false);
  auto scene = loadGltf(g.writeGltf(dir, "factor"));
  ASSERT_EQ(scene->materials.size(), 1u);
  EXPECT_EQ(scene->materials[0].name, "paint");
  EXPECT_EQ(scene->materials[0].texture, -1);
  expectUniformAlbedo(*scene, {0.2, 0.4, 0.6});

  // No material at all: albedo 1.
  GltfBuilder plain;
  addViewFillingQuad(plain, -1, false);
  auto white = loadGltf(plain.writeGltf(dir, "plain"));
  expectUniformAlbedo(*white, {1, 1, 1});
}

TEST(GltfMaterials, BaseColorTextureTimesFactorInLinearRgb) {
  const std::string dir = tempDir("gltf_texture");
  const unsigned char r = 200, gg = 100, b = 50;  // sRGB-encoded texel
  std::vector<unsigned char> rgb;
  for (int i = 0; i < 4; ++i) rgb.insert(rgb.end(), {r, gg, b});
  const std::vector<unsigned char> png = writePng(dir + "/albedo.png", 2, 2, rgb);
  ASSERT_FALSE(png.empty());
  const D3 factor{0.5, 0.8, 0.25};
  const D3 expect{factor[0] * srgbToLinearRef(r / 255.0), factor[1] * srgbToLinearRef(gg / 255.0),
                  factor[2] * srgbToLinearRef(b / 255.0)};

  const auto build = [&](GltfBuilder& g, bool embedImage) {
    g.push("samplers", {{"wrapS", 33071}, {"wrapT", 33071}});  // CLAMP_TO_EDGE
    if (embedImage)
      g.push("images", {{"bufferView", g.bufferView(png.data(), png.size())}, {"mimeType", "image/png"}});
    else
      g.push("images", {{"uri", "albedo.png"}});
    g.push("textures", {{"sampler", 0}, {"source", 0}});
    const int mat = g.push("materials", {{"pbrMetallicRoughness",
                                          {{"baseColorFactor", {factor[0], factor[1], factor[2], 1.0}},
                                           {"baseColorTexture", {{"index", 0}}}}}});
    addViewFillingQuad(g, mat, true);
  };
  {
    SCOPED_TRACE(".gltf, image by uri");
    GltfBuilder g;
    build(g, false);
    auto scene = loadGltf(g.writeGltf(dir, "textured"));
    ASSERT_EQ(scene->textures.size(), 1u);
    ASSERT_EQ(scene->materials.size(), 1u);
    EXPECT_EQ(scene->materials[0].texture, 0);
    EXPECT_EQ(scene->materials[0].wrapS, WrapMode::ClampToEdge);
    EXPECT_EQ(scene->materials[0].wrapT, WrapMode::ClampToEdge);
    expectUniformAlbedo(*scene, expect);
    EXPECT_EQ(scene->textures[0]->width(), 2);
    EXPECT_EQ(scene->textures[0]->height(), 2);
  }
  {
    SCOPED_TRACE(".glb, image in a bufferView");
    GltfBuilder g;
    build(g, true);
    auto scene = loadGltf(g.writeGlb(dir, "textured"));
    ASSERT_EQ(scene->textures.size(), 1u);
    expectUniformAlbedo(*scene, expect);
  }
}

TEST(GltfMaterials, SamplerWrapModesReachTheMaterial) {
  const std::string dir = tempDir("gltf_wrap");
  std::vector<unsigned char> rgb = {0, 0, 0, 255, 255, 255};
  writePng(dir + "/t.png", 2, 1, rgb);
  GltfBuilder g;
  g.push("images", {{"uri", "t.png"}});
  g.push("samplers", {{"wrapS", 33648}, {"wrapT", 10497}});  // MIRRORED_REPEAT, REPEAT
  g.push("samplers", {{"wrapS", 10497}, {"wrapT", 33071}});  // REPEAT, CLAMP_TO_EDGE
  g.push("textures", {{"sampler", 0}, {"source", 0}});
  g.push("textures", {{"sampler", 1}, {"source", 0}});
  g.push("textures", {{"source", 0}});  // no sampler: REPEAT both ways
  for (int t = 0; t < 3; ++t) g.push("materials", {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", t}}}}}});
  g.quadMesh(1.0f, 0, true);
  g.node({{"mesh", 0}});
  g.scene({0});
  auto scene = loadGltf(g.writeGltf(dir, "wrap"));
  ASSERT_EQ(scene->materials.size(), 3u);
  EXPECT_EQ(scene->textures.size(), 1u) << "one image used by three textures is decoded once";
  EXPECT_EQ(scene->materials[0].wrapS, WrapMode::MirroredRepeat);
  EXPECT_EQ(scene->materials[0].wrapT, WrapMode::Repeat);
  EXPECT_EQ(scene->materials[1].wrapS, WrapMode::Repeat);
  EXPECT_EQ(scene->materials[1].wrapT, WrapMode::ClampToEdge);
  EXPECT_EQ(scene->materials[2].wrapS, WrapMode::Repeat);
  EXPECT_EQ(scene->materials[2].wrapT, WrapMode::Repeat);
}

TEST(GltfMaterials, RepeatAndMirroredRepeatSampleTheRightTexel) {
  const std::string dir = tempDir("gltf_texture_sample");
  // 2x1: texel 0 = A, texel 1 = B (sRGB bytes).
  const std::array<unsigned char, 3> A = {10, 60, 120}, B = {240, 180, 30};
  const std::vector<unsigned char> png = writePng(dir + "/ab.png", 2, 1, {A[0], A[1], A[2], B[0], B[1], B[2]});
  Texture tex(png, "ab.png", true);
  tex.decode();
  ASSERT_EQ(tex.width(), 2);
  ASSERT_EQ(tex.height(), 1);
  const D3 a{srgbToLinearRef(A[0] / 255.0), srgbToLinearRef(A[1] / 255.0), srgbToLinearRef(A[2] / 255.0)};
  const D3 bb{srgbToLinearRef(B[0] / 255.0), srgbToLinearRef(B[1] / 255.0), srgbToLinearRef(B[2] / 255.0)};
  const D3 mid = mulS(add(a, bb), 0.5);
  // u values chosen to land on texel centres of the wrapped texture (or
  // halfway between the two), so the bilinear weights are exact.
  struct Case {
    float u;
    WrapMode mode;
    D3 expect;
  };
  const std::vector<Case> cases = {
      {0.25f, WrapMode::Repeat, a},          {0.75f, WrapMode::Repeat, bb},
      {1.25f, WrapMode::Repeat, a},          {1.75f, WrapMode::Repeat, bb},
      {-0.25f, WrapMode::Repeat, bb},        {5.25f, WrapMode::Repeat, a},
      {0.25f, WrapMode::MirroredRepeat, a},  {0.75f, WrapMode::MirroredRepeat, bb},
      {1.25f, WrapMode::MirroredRepeat, bb}, {1.75f, WrapMode::MirroredRepeat, a},
      {-0.25f, WrapMode::MirroredRepeat, a}, {2.25f, WrapMode::MirroredRepeat, a},
      {-1.25f, WrapMode::MirroredRepeat, bb},
      {1.25f, WrapMode::ClampToEdge, bb},    {-0.75f, WrapMode::ClampToEdge, a},
      {0.5f, WrapMode::Repeat, mid},         {1.0f, WrapMode::MirroredRepeat, bb},
      {1.0f, WrapMode::Repeat, mid},
  };
  const char* names[] = {"Repeat", "ClampToEdge", "MirroredRepeat"};
  for (const Case& c : cases) {
    // v is irrelevant for a one-row texture with any wrap mode.
    const Vec3 got = tex.sample(c.u, 0.3f, c.mode, WrapMode::Repeat);
    expectNear3(toD(got), c.expect, 1e-6, std::string(names[int(c.mode)]) + " u=" + std::to_string(c.u));
  }
}

// --- the bundled third-party scenes -----------------------------------------

// Skips (or, under OBSCURA_REQUIRE_SCENES, fails) the calling test when a
// scene is absent; otherwise its path.
#define SHARED(var, rel)                     \
  const std::string var = sharedScene(rel); \
  OBSCURA_NEED_SHARED_SCENE(var)

TEST(GltfSharedScenes, VikingRoomGlbLoads) {
  SHARED(path, "viking_room/viking_room.glb");
  WarningCapture warnings;
  auto scene = loadGltf(path);
  const SceneStats st = scene->stats();
  EXPECT_EQ(st.uniqueTriangles, 3828u);
  EXPECT_TRUE(scene->cameras.empty());
  // README: [-0.59,-0.72,-0.11]-[0.74,0.74,0.92].
  expectNear3(toD(scene->bounds().lo), {-0.59, -0.72, -0.11}, 0.01, "bounds.lo");
  expectNear3(toD(scene->bounds().hi), {0.74, 0.74, 0.92}, 0.01, "bounds.hi");
  for (const auto& t : scene->textures) EXPECT_NO_THROW(t->decode()) << t->source();
}

TEST(GltfSharedScenes, CornellBoxesLoad) {
  SHARED(classicPath, "cornell_box_classic/cornell-box.gltf");
  SHARED(suzannePath, "cornell_box_suzanne/cornell-box.glb");
  WarningCapture warnings;
  auto classic = loadGltf(classicPath);
  EXPECT_EQ(classic->cameras.size(), 1u);
  EXPECT_EQ(classic->stats().uniqueTriangles, 32u);
  expectNear3(toD(classic->bounds().lo), {0, 0, 0}, 0.01, "classic bounds.lo");
  expectNear3(toD(classic->bounds().hi), {5.56, 5.488, 5.592}, 0.01, "classic bounds.hi");
  auto suzanne = loadGltf(suzannePath);
  EXPECT_EQ(suzanne->stats().uniqueTriangles, 1040u);
  EXPECT_TRUE(suzanne->cameras.empty());
}

TEST(GltfSharedScenes, DamagedHelmetLoadsWithItsTextures) {
  SHARED(path, "damaged_helmet/DamagedHelmet.gltf");
  WarningCapture warnings;
  auto scene = loadGltf(path);
  EXPECT_EQ(scene->stats().uniqueTriangles, 15452u);
  ASSERT_EQ(scene->materials.size(), 1u);
  // Only the base colour texture matters for albedo.
  ASSERT_EQ(scene->textures.size(), 1u);
  EXPECT_GE(scene->materials[0].texture, 0);
  for (const auto& t : scene->textures) {
    ASSERT_NO_THROW(t->decode()) << t->source();
    EXPECT_EQ(t->width(), 2048);
    EXPECT_EQ(t->height(), 2048);
    EXPECT_NE(t->source().find("Default_albedo.jpg"), std::string::npos) << t->source();
  }
  // Its emissive material is reported (once).
  EXPECT_EQ(warnings.count("emission"), 1u) << warnings.all();
}

TEST(GltfSharedScenes, SuzanneLoadsWithItsTexture) {
  SHARED(path, "suzanne/Suzanne.gltf");
  WarningCapture warnings;
  auto scene = loadGltf(path);
  EXPECT_EQ(scene->stats().uniqueTriangles, 3936u);
  ASSERT_EQ(scene->textures.size(), 1u);
  ASSERT_NO_THROW(scene->textures[0]->decode());
  EXPECT_EQ(scene->textures[0]->width(), 1024);
}

// --- unsupported features: one warning each ---------------------------------

TEST(GltfWarnings, LinePrimitivesWarnOnce) {
  const std::string dir = tempDir("gltf_lines");
  GltfBuilder g;
  json prims = json::array();
  prims.push_back({{"attributes", {{"POSITION", g.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}})}}}, {"mode", kLines}});
  prims.push_back({{"attributes", {{"POSITION", g.positions({{0, 0, 1}, {1, 0, 1}})}}}, {"mode", kLines}});
  prims.push_back({{"attributes", {{"POSITION", g.positions({{0, 0, 2}, {1, 0, 2}, {0, 1, 2}})}}}});
  g.push("meshes", {{"primitives", prims}});
  g.node({{"mesh", 0}});
  g.scene({0});
  const std::string path = g.writeGltf(dir, "lines");
  WarningCapture warnings;
  auto scene = loadGltf(path);
  ASSERT_EQ(warnings.messages.size(), 1u) << warnings.all();
  EXPECT_NE(warnings.messages[0].find("line"), std::string::npos) << warnings.messages[0];
  EXPECT_NE(warnings.messages[0].find(path), std::string::npos) << warnings.messages[0];
  EXPECT_EQ(scene->stats().uniqueTriangles, 1u);
  EXPECT_EQ(scene->stats().primitives, 1u);
}

TEST(GltfWarnings, OrthographicCameraWarnsAndIsSkipped) {
  const std::string dir = tempDir("gltf_ortho");
  GltfBuilder g;
  g.push("cameras", {{"type", "orthographic"}, {"name", "ortho"}, {"orthographic", {{"xmag", 1.0}, {"ymag", 1.0}, {"znear", 0.01}, {"zfar", 100.0}}}});
  g.quadMesh(1.0f);
  g.node({{"mesh", 0}});
  g.node({{"camera", 0}, {"translation", {0, 0, 5}}});
  g.scene({0, 1});
  const std::string path = g.writeGltf(dir, "ortho");
  WarningCapture warnings;
  auto scene = loadGltf(path);
  ASSERT_EQ(warnings.messages.size(), 1u) << warnings.all();
  EXPECT_NE(warnings.messages[0].find("orthographic"), std::string::npos) << warnings.messages[0];
  EXPECT_NE(warnings.messages[0].find("cameras[0]"), std::string::npos) << warnings.messages[0];
  EXPECT_TRUE(scene->cameras.empty());
}

TEST(GltfWarnings, EachUnsupportedFeatureWarnsExactlyOnce) {
  const std::string dir = tempDir("gltf_unsupported");
  GltfBuilder g;
  g.doc["extensionsUsed"] = {"KHR_materials_clearcoat"};
  g.push("materials", {{"emissiveFactor", {1, 0, 0}}});
  g.push("materials", {{"emissiveFactor", {0, 1, 0}}});
  json prims = json::array();
  for (int k = 0; k < 2; ++k) {
    const float z = float(k);
    prims.push_back({{"attributes", {{"POSITION", g.positions({{0, 0, z}, {1, 0, z}, {0, 1, z}})},
                                     {"COLOR_0", g.vec4({{1, 0, 0, 1}, {0, 1, 0, 1}, {0, 0, 1, 1}})}}},
                     {"material", k}});
  }
  g.push("meshes", {{"primitives", prims}});
  g.node({{"mesh", 0}});
  g.scene({0});
  WarningCapture warnings;
  auto scene = loadGltf(g.writeGltf(dir, "unsupported"));
  EXPECT_EQ(warnings.count("KHR_materials_clearcoat"), 1u) << warnings.all();
  EXPECT_EQ(warnings.count("emission is ignored"), 1u) << warnings.all();
  EXPECT_EQ(warnings.count("COLOR_0"), 1u) << warnings.all();
  EXPECT_EQ(warnings.messages.size(), 3u) << warnings.all();
  EXPECT_EQ(scene->stats().uniqueTriangles, 2u);
}

}  // namespace
}  // namespace obscura::test
