// The Embree subdivision backend (Scene::addSubdivisionSurface, core/load/cage.h)
// against the OpenSubdiv one and against Embree's own interpolation: the same
// limit surface, the same displacement, no cracks, adaptive rates from the
// camera, and the budget.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <filesystem>
#include <map>

#include "core/load/cage.h"
#include <obscura/error.h>
#include "core/scene/surface.h"
#include "core/subd/subdivision.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr size_t kBudget = size_t(1) << 30;

// The cube [-1, 1]^3 as six outward quads, each face with the whole [0,1]^2
// of uv (a seam along every edge) when `uvs`.
SubdivisionCage cube(bool uvs) {
  SubdivisionCage c = cubeCage();
  if (uvs) {
    c.uvs = {0, 0, 1, 0, 1, 1, 0, 1};
    for (size_t f = 0; f < 6; ++f) c.uvIndices.insert(c.uvIndices.end(), {0, 1, 2, 3});
  }
  return c;
}

// An open, bumpy cage with a pentagon, a triangle and quads around a centre
// vertex, uv = xy (no seams).
SubdivisionCage mixedCage() {
  SubdivisionCage c;
  c.positions = {{0, 0, 0.3f}, {1, 0, 0}, {1.2f, 0.9f, 0.1f}, {0.2f, 1.3f, 0}, {-0.9f, 0.8f, -0.1f},
                 {-1, -0.4f, 0}, {-0.2f, -1.1f, 0.2f}};
  c.faceSizes = {5, 3, 4};
  c.faceIndices = {0, 1, 2, 3, 4, 0, 4, 5, 0, 5, 6, 1};  // pentagon, triangle, quad 0-5-6-1
  for (const Vec3& p : c.positions) c.uvs.insert(c.uvs.end(), {0.5f + 0.3f * p.x, 0.5f + 0.3f * p.y});
  c.uvIndices = c.faceIndices;
  return c;
}

struct Hit {
  bool hit = false;
  float t = 0;
  RayHit rh;  // as traced
};
Hit trace(const Scene& scene, Vec3 org, Vec3 dir) {
  const RayHit rh = traceClosest(scene, org, dir);
  return {rh.hit.geomID != RTC_INVALID_GEOMETRY_ID, rh.ray.tfar, rh};
}

std::unique_ptr<Scene> build(const SubdivisionCage& c, SubdivisionBackend backend, int level,
                             const CageDisplacement& d = {}) {
  auto scene = std::make_unique<Scene>();
  LoadOptions o;
  o.subdivision = true;
  o.backend = backend;
  o.subdivisionLevel = level;
  o.maxMemoryBytes = kBudget;
  addCage(*scene, c, o, d, -1, "cage");
  scene->setRobust(true);
  scene->commit();
  return scene;
}

// Rays from a sphere of radius 4 towards points near the origin: pairs of
// (origin, unit direction), deterministic.
std::vector<std::pair<Vec3, Vec3>> probeRays(int n) {
  std::vector<std::pair<Vec3, Vec3>> r;
  for (int i = 0; i < n; ++i) {
    const double z = 1 - 2 * (i + 0.5) / n, phi = 2.399963 * i, s = std::sqrt(1 - z * z);
    const Vec3 o(float(4 * s * std::cos(phi)), float(4 * s * std::sin(phi)), float(4 * z));
    const Vec3 target(float(0.3 * std::sin(3.0 * i)), float(0.3 * std::cos(5.0 * i)), float(0.2 * std::sin(7.0 * i)));
    r.emplace_back(o, normalize(target - o));
  }
  return r;
}

template <class F>
std::shared_ptr<const HeightMap> heightMap(const std::string& dir, const std::string& name, int w, int h, F f) {
  return std::make_shared<HeightMap>(writeHeightMap(dir + "/" + name + ".exr", w, h, f));
}

// CageUvs maps Embree patch coordinates - including the sub-quad encoding of
// pentagons and triangles - to the uv that Embree's own linear interpolation
// (a second topology in PIN_ALL mode: linear subdivision) gives. On quads
// that is the bilinear map everywhere. On other faces Embree's pinned patch
// is linear along the sub-quad's sides but not bilinear inside it (it departs
// by up to 3e-3 there, and by up to 5e-5 along its lu = 0 side, measured),
// so those are checked, to 1e-4, where linear
// subdivision fixes the value: the sub-quad's corners (cage corner, edge
// midpoints, centre) and its two sides on the cage's edges - which is what
// pins down the sub-quad order and orientation, the convention the
// displacement depends on.
TEST(EmbreeSubdivision, PatchUvsMatchEmbreeLinearInterpolation) {
  const SubdivisionCage c = mixedCage();
  const CageUvs uvs(c);
  Scene scene;  // for its device only
  RTCGeometry g = rtcNewGeometry(scene.device(), RTC_GEOMETRY_TYPE_SUBDIVISION);
  auto* fb = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_FACE, 0, RTC_FORMAT_UINT, 4, c.faceSizes.size()));
  auto* ib = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT, 4, c.faceIndices.size()));
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 16, c.positions.size()));
  rtcSetGeometryTopologyCount(g, 2);
  auto* ib1 = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 1, RTC_FORMAT_UINT, 4, c.uvIndices.size()));
  rtcSetGeometrySubdivisionMode(g, 1, RTC_SUBDIVISION_MODE_PIN_ALL);
  rtcSetGeometryVertexAttributeCount(g, 1);
  rtcSetGeometryVertexAttributeTopology(g, 0, 1);
  // Padded to 4 floats: Embree evaluates SSE vectors and asserts every lane is valid.
  auto* ub = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX_ATTRIBUTE, 0, RTC_FORMAT_FLOAT4, 16, c.uvs.size() / 2));
  for (size_t f = 0; f < c.faceSizes.size(); ++f) fb[f] = uint32_t(c.faceSizes[f]);
  for (size_t k = 0; k < c.faceIndices.size(); ++k) ib[k] = uint32_t(c.faceIndices[k]), ib1[k] = uint32_t(c.uvIndices[k]);
  for (size_t i = 0; i < c.positions.size(); ++i)
    vb[4 * i] = c.positions[i].x, vb[4 * i + 1] = c.positions[i].y, vb[4 * i + 2] = c.positions[i].z, vb[4 * i + 3] = 0;
  for (size_t i = 0; i < c.uvs.size() / 2; ++i) ub[4 * i] = c.uvs[2 * i], ub[4 * i + 1] = c.uvs[2 * i + 1], ub[4 * i + 2] = ub[4 * i + 3] = 0;
  rtcCommitGeometry(g);
  RTCScene s = rtcNewScene(scene.device());
  rtcAttachGeometry(s, g);
  rtcCommitScene(s);
  int checked = 0;
  for (uint32_t f = 0; f < 3; ++f) {
    const int n = c.faceSizes[f];
    for (int i = 0; i < (n == 4 ? 1 : n); ++i)
      for (const float a : {0.0f, 0.13f, 0.5f, 0.77f, 1.0f})
        for (const float b : {0.0f, 0.21f, 0.5f, 0.9f, 1.0f}) {
          // Patch coordinates: a quad's own, or sub-quad i's encoded.
          const float u = n == 4 ? a : float(2 * (i % 4)) + 0.5f + a;
          const float v = n == 4 ? b : float(2 * (i / 4)) + 0.5f + b;
          float ref[4];
          rtcInterpolate1(g, f, u, v, RTC_BUFFER_TYPE_VERTEX_ATTRIBUTE, 0, ref, nullptr, nullptr, 4);
          float s0, t0;
          uvs.at(f, u, v, s0, t0);
          const bool fixedByLinear = n == 4 || a == 0 || b == 0 || ((a == 0 || a == 1) && (b == 0 || b == 1));
          if (!fixedByLinear) continue;
          const double tol = n == 4 ? 2e-6 : 1e-4;
          EXPECT_NEAR(s0, ref[0], tol) << "face " << f << " sub " << i << " at " << a << "," << b;
          EXPECT_NEAR(t0, ref[1], tol) << "face " << f << " sub " << i << " at " << a << "," << b;
          ++checked;
        }
  }
  EXPECT_EQ(checked, 25 + (5 + 3) * 10);
  rtcReleaseScene(s);
  rtcReleaseGeometry(g);
}

// Both backends tessellate the same Catmull-Clark limit, so a ray meets
// both within the two tessellations' chord errors: a smooth surface's chord
// error is at most kappa h^2 / 8 for edge length h and curvature kappa; at
// 2^6 segments per cage edge of length <= 2, h <= 2/64 and the rounded cube
// and the bumpy cage bend with kappa < 4 (radius > 1/4), so each is within
// 4 (1/32)^2 / 8 = 4.9e-4, along the ray within that over the cosine of the
// incidence (rays hitting at < 75 degrees: / 0.26): 3.8e-3 for the pair.
// Boundaries too: Embree's PIN_CORNERS mode is OpenSubdiv's EDGE_AND_CORNER.
TEST(EmbreeSubdivision, LimitSurfaceMatchesOpenSubdiv) {
  for (const SubdivisionCage& c : {cube(false), mixedCage()}) {
    const auto osd = build(c, SubdivisionBackend::OpenSubdiv, 6);
    const auto emb = build(c, SubdivisionBackend::Embree, 6);
    int hits = 0;
    for (const auto& [o, d] : probeRays(400)) {
      const Hit a = trace(*osd, o, d), b = trace(*emb, o, d);
      ASSERT_EQ(a.hit, b.hit) << "ray from " << o.x << "," << o.y << "," << o.z;
      if (!a.hit) continue;
      SurfaceHit h{};
      computeSurfaceHit(*emb, b.rh, false, h);
      if (std::abs(dot(h.ns, d)) < 0.26f) continue;  // grazing: the bound does not hold
      EXPECT_NEAR(a.t, b.t, 3.8e-3) << "ray from " << o.x << "," << o.y << "," << o.z;
      ++hits;
    }
    EXPECT_GT(hits, 100);
  }
}

// Displacement moves both backends' surfaces alike: a constant height of 1
// with midlevel 0 and scale 0.1 offsets the limit surface by 0.1 along its
// normal - outwards on the cube - and the two offset surfaces meet a ray
// within the chord bound above (the offset surface of the rounded cube
// bends less than the cube's limit).
TEST(EmbreeSubdivision, DisplacementMatchesOpenSubdiv) {
  const std::string dir = tempDir("embree_displace");
  CageDisplacement d;
  d.map = heightMap(dir, "one", 2, 2, [](double, double) { return 1.0; });
  d.scale = 0.1, d.midlevel = 0.0;
  const auto plain = build(cube(true), SubdivisionBackend::Embree, 6);
  const auto osd = build(cube(true), SubdivisionBackend::OpenSubdiv, 6, d);
  const auto emb = build(cube(true), SubdivisionBackend::Embree, 6, d);
  // Along the x axis the limit's face centre is met head-on: exactly 0.1 earlier.
  const Vec3 o(4, 0, 0), minusX(-1, 0, 0);
  EXPECT_NEAR(trace(*plain, o, minusX).t - trace(*emb, o, minusX).t, 0.1, 1e-4);
  for (const auto& [o, dir3] : probeRays(200)) {
    const Hit a = trace(*osd, o, dir3), b = trace(*emb, o, dir3), p = trace(*plain, o, dir3);
    ASSERT_EQ(a.hit, b.hit);
    if (!a.hit || !p.hit) continue;
    EXPECT_NEAR(a.t, b.t, 3.8e-3);
    EXPECT_LT(b.t, p.t);  // outwards: met earlier
  }
}

// A displaced closed cage whose faces each have their own uvs (a seam on
// every edge): the canonical edge uvs keep the surface closed, at uniform
// and at camera-adaptive rates, so from inside no AO ray escapes.
TEST(EmbreeSubdivision, DisplacedClosedCageHasNoCracks) {
  const std::string dir = tempDir("embree_cracks");
  CageDisplacement d;
  d.map = heightMap(dir, "ripples", 64, 64, [](double u, double v) { return 0.5 + 0.5 * std::cos(4 * M_PI * u) * std::cos(2 * M_PI * v); });
  d.scale = 0.15, d.midlevel = 0.5;
  for (const bool adaptive : {false, true}) {
    Scene scene;
    LoadOptions o;
    o.subdivision = true;
    o.backend = SubdivisionBackend::Embree;
    o.subdivisionLevel = 4;
    if (adaptive) {
      o.maxEdgePixels = 2;
      o.camera = makeLookAtCamera(Vec3(5, -3, 2), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.6f, "view");
      o.imageWidth = 320, o.imageHeight = 240;
    }
    addCage(scene, cube(true), o, d, -1, "cube");
    scene.setRobust(true);
    scene.commit();
    SCOPED_TRACE(adaptive ? "adaptive" : "uniform");
    expectNoRayEscapes(scene);
  }
}

// Edge lengths in pixels: with a 90-degree vertical field of view on a
// 100-pixel-high image, a pixel at distance z spans z / 50; a unit edge
// facing the camera at distance 10 spans 5 pixels (measured from its nearer
// end, at sqrt(10^2 + 0.5^2): 4.994), so 1-pixel edges need level 3
// (2^3 = 8 >= 5 > 4). Both half-edges of an edge agree.
TEST(EmbreeSubdivision, EdgeLengthsInPixelsFromTheCamera) {
  SubdivisionCage c;
  c.positions = {{-0.5f, 0, -10}, {0.5f, 0, -10}, {0.5f, 1, -10}, {-0.5f, 1, -10}, {0.5f, 2, -10}, {-0.5f, 2, -10}};
  c.faceSizes = {4, 4};
  c.faceIndices = {0, 1, 2, 3, 3, 2, 4, 5};
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 1, 0), float(M_PI / 2), "front");
  const std::vector<float> px = edgePixelLengths(c, cam, 200, 100);
  ASSERT_EQ(px.size(), 8u);
  EXPECT_NEAR(px[0], 1.0 / (std::sqrt(100.25) / 50.0), 1e-4);  // edge 0-1, its ends at distance sqrt(10^2 + 0.5^2)
  EXPECT_EQ(px[2], px[4]);                                   // edge 2-3 from both faces
  EXPECT_NEAR(px[2], 1.0 / (std::sqrt(100.25 + 1) / 50), 1e-3);  // its nearer end at (0.5, 1, -10)
  EXPECT_EQ(levelForEdgeLength(px, 1.0), 3);
  EXPECT_EQ(levelForEdgeLength(px, 5.5), 0);
  EXPECT_EQ(levelForEdgeLength({1e30f}, 1e-3), 10);
}

// What the Embree backend refuses, naming the cage: Loop, faces over 15
// vertices, and tessellations over the memory budget.
TEST(EmbreeSubdivision, RefusesWhatItCannotDo) {
  const auto expectError = [](const SubdivisionCage& c, LoadOptions o, const std::string& needle) {
    Scene scene;
    try {
      addCage(scene, c, o, {}, -1, "cage.obj");
      ADD_FAILURE() << "accepted: " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).rfind("cage.obj: ", 0), 0u) << e.what();
    }
  };
  LoadOptions o;
  o.subdivision = true;
  o.backend = SubdivisionBackend::Embree;
  LoadOptions loop = o;
  loop.scheme = SubdivisionScheme::Loop;
  expectError(cube(false), loop, "Catmull-Clark only");
  SubdivisionCage big;
  for (int i = 0; i < 16; ++i) {
    big.positions.emplace_back(float(std::cos(i * M_PI / 8)), float(std::sin(i * M_PI / 8)), 0.0f);
    big.faceIndices.push_back(i);
  }
  big.faceSizes = {16};
  expectError(big, o, "has 16 vertices");
  LoadOptions tight = o;
  tight.subdivisionLevel = 10;
  tight.maxMemoryBytes = size_t(64) << 20;
  expectError(cube(false), tight, "maxMemoryBytes");
}


// The README's Spot command, with either backend, uniform and adaptive: the
// cage renders subdivided and displaced by the lava height map, the header
// records how, and the two backends cover the same pixels but for the
// silhouette's outline (the same limit surface and displacement, tessellated
// alike: 2^3 segments per cage edge).
TEST(EmbreeSubdivision, SpotRendersDisplacedWithEitherBackend) {
  const std::string spot = sharedScene("spot_cage/spot_control_mesh.obj");
  const std::string lava = sharedScene("lava_heightmap/lava_01_height_1k.png");
  OBSCURA_NEED_SHARED_SCENE(spot);
  OBSCURA_NEED_SHARED_SCENE(lava);
  const std::string dir = tempDir("spot_backends");
  std::map<std::string, std::vector<float>> alpha;
  for (const std::string backend : {"osd", "embree"}) {
    for (const bool adaptive : {false, true}) {
      const std::string out = dir + "/" + backend + (adaptive ? "_edge" : "") + ".exr";
      std::vector<std::string> args = {"render", spot, "--subdiv", "catmull-clark", "--subdiv-backend", backend,
                                       "--displace", lava, "--displace-scale", "0.03", "-o", out, "--res", "64x48",
                                       "--spp", "2", "-q"};
      if (adaptive) args.insert(args.end(), {"--subdiv-edge", "4"});
      else args.insert(args.end(), {"--subdiv-level", "3"});
      const CliResult r = runCli(args, dir + "/err.txt");
      ASSERT_EQ(r.exitCode, 0) << backend << ": " << r.stderrText;
      const ReadBack img = readExr(out);
      EXPECT_EQ(img.spec.get_string_attribute("obscura:subdivBackend"), backend);
      EXPECT_EQ(img.spec.get_string_attribute("obscura:displaceScale"), "0.03");
      double covered = 0;
      for (const float a : img.planes.at("A")) covered += a;
      EXPECT_GT(covered, 64.0 * 48 * 0.05) << backend;
      if (!adaptive) alpha[backend] = img.planes.at("A");
    }
  }
  int differ = 0;
  for (size_t i = 0; i < alpha["osd"].size(); ++i) differ += std::abs(alpha["osd"][i] - alpha["embree"][i]) > 0.5f;
  EXPECT_LT(differ, 64 * 48 / 50) << "pixels whose coverage differs between the backends";
  // `info` takes the same scene options (and measures adaptive edges too).
  const CliResult info = runCli({"info", spot, "--subdiv", "catmull-clark", "--subdiv-backend", "embree", "--subdiv-edge", "3",
                                 "--displace", lava}, dir + "/info.txt");
  EXPECT_EQ(info.exitCode, 0) << info.stderrText;
  const CliResult bad = runCli({"render", spot, "--subdiv", "loop", "--subdiv-backend", "embree", "-o", dir + "/x.exr", "-q"},
                               dir + "/err2.txt");
  EXPECT_EQ(bad.exitCode, 1);
  EXPECT_NE(bad.stderrText.find("Catmull-Clark only"), std::string::npos) << bad.stderrText;
  EXPECT_EQ(std::count(bad.stderrText.begin(), bad.stderrText.end(), '\n'), 1) << bad.stderrText;
}


// Cages that are odd but not malformed are subdivided as they are, by both
// backends, to finite passes (the documented repair is none needed): a
// non-manifold edge shared by three quads (both libraries refine
// non-manifold topology, the edge treated as a boundary of each face) and a
// zero-area face (three collinear corners; its limit normal falls back to
// the geometric one).
TEST(EmbreeSubdivision, NonManifoldAndZeroAreaCagesRenderFinite) {
  SubdivisionCage fin;  // three quads on the edge 0-1
  fin.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, -1, 0}, {1, -1, 0}};
  fin.faceSizes = {4, 4, 4};
  fin.faceIndices = {0, 1, 2, 3, 1, 0, 4, 5, 0, 1, 7, 6};
  SubdivisionCage flat;  // a zero-area triangle beside a good one
  flat.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {1, 1, 0}};
  flat.faceSizes = {3, 3};
  flat.faceIndices = {0, 1, 2, 0, 2, 3};
  for (const SubdivisionCage* c : {&fin, &flat})
    for (const SubdivisionBackend b : {SubdivisionBackend::OpenSubdiv, SubdivisionBackend::Embree}) {
      const auto scene = build(*c, b, 3);
      const Camera cam = makeAutoCamera(scene->bounds(), 1.0f);
      const Film f = renderWith(*scene, cam, "ao", {"rays=4"}, passSettings(24, 24, 4));
      size_t covered = 0;
      for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 24; ++x) {
          ASSERT_TRUE(std::isfinite(f.at(kR, x, y))) << x << "," << y;
          covered += f.at(kA, x, y) > 0;
        }
      EXPECT_GT(covered, 24u * 24u / 20) << (b == SubdivisionBackend::Embree ? "embree" : "osd");
    }
}


// Shading normals of the displaced surface, both backends, against the
// analytic one. A flat cage with uv = xy displaced by
// d(x) = s (h - 1/2), h = 1/2 + 1/2 cos(4 pi x): the surface z = d(x) has
// normal (-d'(x), 0, 1) / |.|, d'(x) = -2 pi s sin(4 pi x). Tolerance 0.005
// per component: the height map's bilinear interpolation (1024 texels)
// errs in slope by up to d'' dx / 2 = s (4 pi)^2 / 2 / 1024 / 2 = 1.9e-3
// at s = 0.05; Embree's central difference over one tessellation step
// (level 6: 2^6 segments per cage edge of 1/4) by d''' dt^2 / 6 = 3e-5;
// OpenSubdiv's area-weighted vertex normals, interpolated across a
// triangle, by O(h^2 n'') = 5e-5 - so a tilt of the wrong sign or size
// (0.3 at the steepest) cannot pass.
TEST(EmbreeSubdivision, DisplacedShadingNormalsMatchTheSurface) {
  const std::string dir = tempDir("embree_normals");
  const double s = 0.05;
  CageDisplacement d;
  d.map = heightMap(dir, "wave", 1024, 2, [](double u, double) { return 0.5 + 0.5 * std::cos(4 * M_PI * u); });
  d.scale = s, d.midlevel = 0.5;
  for (const SubdivisionBackend b : {SubdivisionBackend::OpenSubdiv, SubdivisionBackend::Embree}) {
    const auto scene = build(planeCage(4), b, 6, d);
    int checked = 0;
    for (double x = 0.3; x <= 0.7; x += 0.0137) {
      const RayHit rh = traceClosest(*scene, Vec3(float(x), 0.43f, 2.0f), Vec3(0, 0, -1));
      ASSERT_NE(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID);
      SurfaceHit h{};
      computeSurfaceHit(*scene, rh, false, h);
      const double slope = -2 * M_PI * s * std::sin(4 * M_PI * x);
      const double len = std::sqrt(1 + slope * slope);
      EXPECT_NEAR(h.ns.x, -slope / len, 0.005) << (b == SubdivisionBackend::Embree ? "embree" : "osd") << " x " << x;
      EXPECT_NEAR(h.ns.y, 0.0, 0.005);
      EXPECT_NEAR(h.ns.z, 1 / len, 0.005);
      // The point: d within the chord error h^2 / 8 |d| = 7.5e-6 (h = 1/256) and float rounding.
      EXPECT_NEAR(h.p.z, s * 0.5 * std::cos(4 * M_PI * x), 5e-5) << "x " << x;
      ++checked;
    }
    EXPECT_GT(checked, 25);
  }
}


// The uv frame of an Embree subdivision surface (integrators that work in
// texture space, e.g. containment): on a regular flat grid with uv = xy the
// limit is the plane parametrized linearly, so at interior hits uv is the
// hit's (x, y) and dP/du, dP/dv are the unit axes - up to the tessellation's
// chord offset of the hit point (nil on a plane) and rounding.
TEST(EmbreeSubdivision, UvFrameOnAFlatGrid) {
  const auto scene = build(planeCage(4), SubdivisionBackend::Embree, 3);
  int checked = 0;
  for (double x = 0.3; x <= 0.7; x += 0.071)
    for (double y = 0.3; y <= 0.7; y += 0.083) {
      const RayHit rh = traceClosest(*scene, Vec3(float(x), float(y), 1), Vec3(0, 0, -1));
      ASSERT_NE(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID);
      SurfaceHit h{};
      computeSurfaceHit(*scene, rh, false, h);
      UvFrame f;
      ASSERT_TRUE(surfaceUvFrame(*scene, h, f));
      EXPECT_NEAR(f.u, x, 1e-5);
      EXPECT_NEAR(f.v, y, 1e-5);
      EXPECT_LT(length(f.dpdu - Vec3(1, 0, 0)), 1e-3f) << f.dpdu.x << "," << f.dpdu.y << "," << f.dpdu.z;
      EXPECT_LT(length(f.dpdv - Vec3(0, 1, 0)), 1e-3f) << f.dpdv.x << "," << f.dpdv.y << "," << f.dpdv.z;
      ++checked;
    }
  EXPECT_GT(checked, 20);
}

}  // namespace
}  // namespace obscura::test
