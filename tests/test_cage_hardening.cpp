// Cages and inputs that used to crash or corrupt silently (issue 11):
// OpenSubdiv's limit masks at a non-manifold edge shared by many faces, OBJ
// faces of more than 255 vertices and non-finite vertices (tinyobjloader),
// OpenSubdiv's messages on stdout, displacement beyond what Embree takes,
// uvs kept for texture-space integrators, and the tangent-direction rule.
#include <gtest/gtest.h>

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include <obscura/error.h>
#include "core/scene/camera.h"
#include "core/load/gltf_loader.h"
#include "core/load/obj_loader.h"
#include "core/subd/subdivision.h"
#include "core/scene/surface.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

// LeakSanitizer (the ASan suite): OpenImageIO 2.4's PNG reader leaks its
// error text (31 bytes) whenever a file fails to read - inside the library,
// whether or not the error is fetched (checked with a bare ImageInput
// program) - which TruncatedPngHeightMapIsOneErrorLine provokes on purpose.
// The sanitizer runtime calls this hook, if defined, for its suppressions;
// without a sanitizer it is an unused function.
extern "C" const char* __lsan_default_suppressions() { return "leak:libOpenImageIO.so\n"; }

namespace obscura::test {
namespace {

// --- non-manifold edges --------------------------------------------------------

// N triangles (0, 1, 2 + k) around the edge (0,0,0)-(0,0,1), rim points on
// the unit circle at z = 1/2: the fan that corrupted memory from N = 11.
SubdivisionCage fanCage(int n) {
  SubdivisionCage c;
  c.positions = {Vec3(0, 0, 0), Vec3(0, 0, 1)};
  for (int k = 0; k < n; ++k) {
    const double a = 2 * M_PI * k / n;
    c.positions.emplace_back(float(std::cos(a)), float(std::sin(a)), 0.5f);
    c.faceSizes.push_back(3);
    c.faceIndices.insert(c.faceIndices.end(), {0, 1, 2 + k});
  }
  return c;
}

std::string fanObj(int n) {
  std::string s = "v 0 0 0\nv 0 0 1\n";
  for (int k = 0; k < n; ++k) {
    const double a = 2 * M_PI * k / n;
    s += "v " + std::to_string(std::cos(a)) + " " + std::to_string(std::sin(a)) + " 0.5\n";
  }
  for (int k = 0; k < n; ++k) s += "f 1 2 " + std::to_string(k + 3) + "\n";
  return s;
}

// N = 10 is the last fan OpenSubdiv 3.5's Limit survived (3N + 2 neighbour
// indices against its 33-entry buffer), N = 11 the first it corrupted; 3 the
// first whose masks overlapped. Every refined vertex must come out finite,
// the shared edge's limit is the segment itself (its ends are corners, so
// its crease curve is the straight B-spline between them), and a
// non-manifold vertex gets no shading normal (several sheets meet there).
TEST(CageHardening, CatmullClarkFanAroundOneEdge) {
  for (const int n : {3, 10, 11, 12, 16, 40}) {
    for (const int level : {1, 2}) {
      SCOPED_TRACE("N = " + std::to_string(n) + ", level " + std::to_string(level));
      const SubdividedMesh m = subdivide(fanCage(n), SubdivisionScheme::CatmullClark, level, size_t(1) << 30, "fan");
      size_t onEdge = 0;
      for (size_t i = 0; i < m.positions.size(); ++i) {
        const Vec3 p = m.positions[i];
        ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) << "vertex " << i;
        ASSERT_TRUE(std::isfinite(m.normals[i].x) && std::isfinite(m.normals[i].y) && std::isfinite(m.normals[i].z));
        if (std::hypot(p.x, p.y) < 1e-6) {
          ++onEdge;
          EXPECT_GE(p.z, -1e-6f);
          EXPECT_LE(p.z, 1 + 1e-6f);
          EXPECT_EQ(length(m.normals[i]), 0.0f) << "a non-manifold vertex has no single normal";
        }
      }
      // 2^level + 1 refined vertices lie on the edge (and only those reach x = y = 0:
      // every other limit point is pulled towards its own rim vertex).
      EXPECT_EQ(onEdge, size_t(1 << level) + 1);
    }
  }
}

// The same masks as OpenSubdiv's Limit where that is sound: on manifold
// cages (a cube, with a crease; a plane with boundaries) the positions and
// normals equal Far::PrimvarRefiner::Limit's to float rounding.
TEST(CageHardening, LimitMatchesOpenSubdivOnManifoldCages) {
  using namespace OpenSubdiv;
  SubdivisionCage cube = cubeCage();
  cube.creaseEdges = {0, 1};
  cube.creaseWeights = {2.0f};
  const SubdivisionCage plane = planeCage(3);
  for (const SubdivisionCage* cage : {static_cast<const SubdivisionCage*>(&cube), &plane}) {
    const int level = 2;
    const SubdividedMesh m = subdivide(*cage, SubdivisionScheme::CatmullClark, level, size_t(1) << 30, "cage");
    Far::TopologyDescriptor d;
    d.numVertices = int(cage->positions.size());
    d.numFaces = int(cage->faceSizes.size());
    d.numVertsPerFace = cage->faceSizes.data();
    d.vertIndicesPerFace = cage->faceIndices.data();
    d.numCreases = int(cage->creaseWeights.size());
    d.creaseVertexIndexPairs = cage->creaseEdges.empty() ? nullptr : cage->creaseEdges.data();
    d.creaseWeights = cage->creaseWeights.empty() ? nullptr : cage->creaseWeights.data();
    Sdc::Options o;
    o.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    std::unique_ptr<Far::TopologyRefiner> r(Far::TopologyRefinerFactory<Far::TopologyDescriptor>::Create(
        d, Far::TopologyRefinerFactory<Far::TopologyDescriptor>::Options(Sdc::SCHEME_CATMARK, o)));
    Far::TopologyRefiner::UniformOptions u(level);
    u.fullTopologyInLastLevel = true;
    r->RefineUniform(u);
    struct P {
      double p[3];
      void Clear(void* = nullptr) { p[0] = p[1] = p[2] = 0; }
      void AddWithWeight(const P& s, float w) {
        for (int i = 0; i < 3; ++i) p[i] += double(w) * s.p[i];
      }
    };
    std::vector<P> b(static_cast<size_t>(r->GetNumVerticesTotal()));
    for (size_t i = 0; i < cage->positions.size(); ++i)
      b[i] = {{cage->positions[i].x, cage->positions[i].y, cage->positions[i].z}};
    Far::PrimvarRefiner pr(*r);
    P* src = b.data();
    for (int l = 1; l <= level; ++l) {
      P* dst = src + r->GetLevel(l - 1).GetNumVertices();
      pr.Interpolate(l, src, dst);
      src = dst;
    }
    const int nv = r->GetLevel(level).GetNumVertices();
    std::vector<P> lp(static_cast<size_t>(nv)), t1(static_cast<size_t>(nv)), t2(static_cast<size_t>(nv));
    pr.Limit(src, lp, t1, t2);
    for (int i = 0; i < nv; ++i) {
      const P &a = t1[size_t(i)], &c = t2[size_t(i)];
      Vec3 n(float(a.p[1] * c.p[2] - a.p[2] * c.p[1]), float(a.p[2] * c.p[0] - a.p[0] * c.p[2]),
             float(a.p[0] * c.p[1] - a.p[1] * c.p[0]));
      if (length(n) > 0) n = n * (1.0f / length(n));
      // Float masks there, double masks rounded to float here: a few ulps of
      // unit-sized coordinates.
      for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(m.positions[size_t(i)][k], lp[size_t(i)].p[k], 1e-6) << "vertex " << i;
        EXPECT_NEAR(m.normals[size_t(i)][k], n[k], 1e-5) << "vertex " << i;
      }
    }
  }
}

// The crash reached through the CLI paths' loaders: OBJ with
// --subdiv catmull-clark and a glTF mesh with the subdivision extras.
TEST(CageHardening, FanLoadsFromObjAndGltf) {
  const std::string dir = tempDir("cage_hardening_fan");
  writeText(dir + "/fan.obj", fanObj(12));
  LoadOptions o;
  o.subdivision = true;
  o.subdivisionLevel = 1;
  EXPECT_NO_THROW(loadObj(dir + "/fan.obj", o));

  const SubdivisionCage c = fanCage(12);
  GltfBuilder g;
  std::vector<uint32_t> idx(c.faceIndices.begin(), c.faceIndices.end());
  json prim = {{"attributes", {{"POSITION", g.positions(c.positions)}}}, {"indices", g.indices(idx)}};
  g.push("meshes", {{"primitives", json::array({prim})},
                    {"extras", {{"obscura", {{"subdivision", {{"scheme", "catmull-clark"}, {"level", 1}}}}}}}});
  g.scene({g.node({{"mesh", 0}})});
  EXPECT_NO_THROW(loadGltf(g.writeGltf(dir, "fan"), LoadOptions{}));
}

// --- OBJ text that tinyobjloader misreads ------------------------------------------

// An n-gon in the plane z = 0 (a regular polygon) as OBJ text, the face on
// line n + 1.
std::string polygonObj(int n) {
  std::string s;
  for (int k = 0; k < n; ++k) {
    const double a = 2 * M_PI * k / n;
    s += "v " + std::to_string(std::cos(a)) + " " + std::to_string(std::sin(a)) + " 0\n";
  }
  s += "f";
  for (int k = 1; k <= n; ++k) s += " " + std::to_string(k);
  return s + "\n";
}

std::string objError(const std::string& path, const LoadOptions& o = {}) {
  try {
    loadObj(path, o);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

// 255 vertices is the most tinyobjloader's byte holds: that face loads
// whole (255 - 2 fan triangles); 256 and 259 are refused naming the line.
TEST(CageHardening, ObjFacesOfMoreThan255VerticesAreRefused) {
  const std::string dir = tempDir("cage_hardening_ngon");
  writeText(dir + "/p255.obj", polygonObj(255));
  const auto scene = loadObj(dir + "/p255.obj");
  EXPECT_EQ(scene->stats().uniqueTriangles, 253u);
  for (const int n : {256, 259}) {
    const std::string path = dir + "/p" + std::to_string(n) + ".obj";
    writeText(path, polygonObj(n));
    EXPECT_EQ(objError(path), path + ": line " + std::to_string(n + 1) + ": face has " + std::to_string(n) +
                                  " vertices (at most 255)");
  }
}

TEST(CageHardening, ObjNonFiniteOrMalformedNumbersAreRefused) {
  const std::string dir = tempDir("cage_hardening_nan");
  const std::string faces = "f 1 2 3\n";
  const struct {
    std::string text, why;
  } cases[] = {
      {"v nan 1 0\nv 1 0 0\nv 0 1 0\n", "line 1: vertex coordinate 'nan' is not a finite number"},
      {"v 0 0 0\nv inf 0 0\nv 0 1 0\n", "line 2: vertex coordinate 'inf' is not a finite number"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 1e999\n", "line 3: vertex coordinate '1e999' is not a finite number"},
      {"v 0 0 0\nv 1 0 0\nv 0 1x 0\n", "line 3: vertex coordinate '1x' is not a finite number"},
      {"v 0 0 0\nv 1 0 0\nv 0 1\n", "line 3: a vertex needs 3 coordinates"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 NaN\n", "line 4: texture coordinate 'NaN' is not a finite number"},
  };
  int i = 0;
  for (const auto& c : cases) {
    const std::string path = dir + "/bad" + std::to_string(i++) + ".obj";
    writeText(path, c.text + faces);
    EXPECT_EQ(objError(path), path + ": " + c.why);
  }
  // What is fine stays fine: signs, exponents, comments, a w and colours.
  writeText(dir + "/good.obj", "# ok\nv +0 -0 0 1\nv 1e0 0 0 # x\nv 0 1 0 0.5 0.5 0.5\n\tvt 0 0\n" + faces);
  EXPECT_EQ(objError(dir + "/good.obj"), "");
}

// --- OpenSubdiv's and libpng's messages ------------------------------------------------

// A crease tag on two vertices without an edge between them: OpenSubdiv
// warns (it used to print to stdout); the warning names the file, on stderr.
TEST(CageHardening, OpenSubdivWarningsGoToTheWarningSink) {
  const std::string dir = tempDir("cage_hardening_osd_warning");
  writeText(dir + "/quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nt crease 2/1 0 2 5\n");
  LoadOptions o;
  o.subdivision = true;
  o.subdivisionLevel = 1;
  WarningCapture warnings;
  testing::internal::CaptureStdout();
  EXPECT_NO_THROW(loadObj(dir + "/quad.obj", o));
  EXPECT_EQ(testing::internal::GetCapturedStdout(), "");
  ASSERT_EQ(warnings.messages.size(), 1u) << warnings.all();
  EXPECT_EQ(warnings.messages[0].rfind(dir + "/quad.obj: OpenSubdiv: ", 0), 0u) << warnings.all();
  EXPECT_EQ(warnings.messages[0].find('\n'), std::string::npos);
}

// A truncated PNG height map: one error line, no "libpng error" lines.
TEST(CageHardening, TruncatedPngHeightMapIsOneErrorLine) {
  const std::string dir = tempDir("cage_hardening_png");
  // A 64 x 64 8-bit PNG written by OpenImageIO, then cut in half.
  {
    std::vector<unsigned char> px(64 * 64);
    for (size_t i = 0; i < px.size(); ++i) px[i] = static_cast<unsigned char>((i * 7919) % 251);
    auto out = OIIO::ImageOutput::create(dir + "/h.png");
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(dir + "/h.png", OIIO::ImageSpec(64, 64, 1, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px.data()));
    out->close();
  }
  std::vector<unsigned char> bytes = readBytes(dir + "/h.png");
  ASSERT_GT(bytes.size(), 200u);
  // Cut within the pixel data (the read fails) and just after the header
  // chunk (opening fails).
  for (const size_t keep : {bytes.size() / 2, size_t(40)}) {
    SCOPED_TRACE("kept " + std::to_string(keep) + " bytes");
    writeBytes(dir + "/cut.png", bytes.data(), keep);
    testing::internal::CaptureStderr();
    std::string error;
    try {
      HeightMap map(dir + "/cut.png");
    } catch (const Error& e) {
      error = e.what();
    }
    const std::string stderrText = testing::internal::GetCapturedStderr();
    EXPECT_EQ(error.rfind(dir + "/cut.png: cannot read the height map: ", 0), 0u) << error;
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;
    EXPECT_EQ(stderrText.find("libpng"), std::string::npos) << stderrText;
  }
}

// --- displacement within what Embree traces ------------------------------------------------

// The unit square as one quad with uv = xy, and a constant height map h = 1:
// with midlevel 0.5 the surface moves by scale / 2, so the farthest point is
// 1 + |scale| / 2 from the origin; the bound 1e12 falls at scale 2e12 - 2.
TEST(CageHardening, DisplacementBeyondTheTraceableRangeIsRefused) {
  const std::string dir = tempDir("cage_hardening_displace");
  writeText(dir + "/quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n");
  const std::string map = writeHeightMap(dir + "/one.exr", 4, 4, [](double, double) { return 1.0; });
  for (const SubdivisionBackend backend : {SubdivisionBackend::Embree, SubdivisionBackend::OpenSubdiv}) {
    LoadOptions o;
    o.subdivision = true;
    o.subdivisionLevel = 1;
    o.backend = backend;
    o.displacementMap = map;
    o.displacementScale = 1.9e12;
    EXPECT_EQ(objError(dir + "/quad.obj", o), "");
    o.displacementScale = -2.1e12;
    EXPECT_EQ(objError(dir + "/quad.obj", o).rfind("displacementScale: -2.1e+12 moves the surface up to 1.05e+12", 0), 0u)
        << objError(dir + "/quad.obj", o);
  }
  // glTF: the field that set the scale is named. (In process the setting is
  // named as the library calls it; the CLI names its flag, --displace-scale:
  // tests/test_setting_names.cpp.)
  GltfBuilder g;
  g.quadMesh(0.5f, -1, true);
  g.doc["meshes"][0]["extras"] = {
      {"obscura", {{"subdivision", {{"level", 1}}}, {"displacement", {{"map", "one.exr"}, {"scale", 3e12}}}}}};
  g.scene({g.node({{"mesh", 0}})});
  const std::string path = g.writeGltf(dir, "quad");
  LoadOptions o;
  o.backend = SubdivisionBackend::Embree;
  std::string error;
  try {
    loadGltf(path, o);
  } catch (const Error& e) {
    error = e.what();
  }
  EXPECT_EQ(error.rfind(path + ": meshes[0].extras.obscura.displacement.scale: 3e+12 moves", 0), 0u) << error;
}

// --- texture coordinates for containment ------------------------------------------------

// The uv frame at a hit on (x, y) of a plane whose uvs are its xy.
UvFrame frameAt(const Scene& scene, float x, float y, bool* ok) {
  const RayHit rh = traceClosest(scene, Vec3(x, y, 1), Vec3(0, 0, -1));
  SurfaceHit h{};
  UvFrame f{};
  *ok = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
  if (*ok) {
    computeSurfaceHit(scene, rh, false, h);
    *ok = surfaceUvFrame(scene, h, f);
  }
  return f;
}

TEST(CageHardening, UvsAreKeptWithoutSubdivisionOrTexture) {
  const std::string dir = tempDir("cage_hardening_uvs");
  // OBJ, no --subdiv: a seam (vertex 2 and 3 take other uvs in the second
  // triangle) splits vertices, each triangle keeping its own chart.
  writeText(dir + "/quad.obj",
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 5 0\nvt 5 1\n"
            "f 1/1 2/2 3/3\nf 1/5 3/6 4/4\n");
  bool ok = false;
  const auto obj = loadObj(dir + "/quad.obj");
  UvFrame f = frameAt(*obj, 0.7f, 0.2f, &ok);  // first triangle: uv = xy
  ASSERT_TRUE(ok);
  EXPECT_NEAR(f.u, 0.7f, 1e-5f);
  EXPECT_NEAR(f.v, 0.2f, 1e-5f);
  f = frameAt(*obj, 0.2f, 0.7f, &ok);  // the second triangle, in its own chart
  ASSERT_TRUE(ok);
  // Corners (0,0) uv (5,0), (1,1) uv (5,1), (0,1) uv (0,1): p = a p1 + b p3 + c p4
  // gives b = x, c = y - x, so uv = (5 (a + b), b + c) = (5 (1 - y + x), y).
  EXPECT_NEAR(f.u, 5.0f * (1 - 0.7f + 0.2f), 1e-4f);
  EXPECT_NEAR(f.v, 0.7f, 1e-5f);

  // glTF with TEXCOORD_0 and no material: the uvs are kept.
  GltfBuilder g;
  g.quadMesh(0.5f, -1, true);
  g.scene({g.node({{"mesh", 0}})});
  const auto gltf = loadGltf(g.writeGltf(dir, "quad"));
  f = frameAt(*gltf, 0.1f, -0.3f, &ok);
  ASSERT_TRUE(ok);
  EXPECT_NEAR(f.u, 0.6f, 1e-5f);  // u = x + 1/2; the frame's v runs up: y + 1/2
  EXPECT_NEAR(f.v, 0.2f, 1e-5f);
}

// containment on a mesh without uvs: plain obscurance, and one warning
// naming the mesh however many hits lack them.
TEST(CageHardening, ContainmentWarnsOnceAboutAMeshWithoutUvs) {
  const std::string dir = tempDir("cage_hardening_nouv");
  writeText(dir + "/quad.obj", "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3 4\n");
  const auto scene = loadObj(dir + "/quad.obj");
  const std::string map = writeRipples(dir);
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 3), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.5f, "top");
  WarningCapture warnings;
  renderWith(*scene, cam, "containment", {"map=" + map, "distance=0.5"}, passSettings(8, 8, 2));
  EXPECT_EQ(warnings.count("has no usable texture coordinates"), 1u) << warnings.all();
  EXPECT_EQ(warnings.count("mesh '" + dir + "/quad.obj'"), 1u) << warnings.all();
}

// --- Catmull-Clark against Loop on a triangle cage ------------------------------------------

// Why Catmull-Clark distorts displacement on triangle cages: on a flat cage
// whose uvs are its xy, an affine parametrization puts every refined vertex
// at uv = xy. Loop on a regular triangulation has linear precision, so it
// does (to float rounding). Catmull-Clark splits each triangle into three
// quads around a valence-3 vertex; its vertex rules then move points within
// the plane (not linearly precise there), while FVAR_LINEAR_ALL interpolates
// the uvs by plain averages - so positions and uvs part, and a height map is
// read at the wrong place: ripples compress and stretch.
TEST(CageHardening, CatmullClarkOnTrianglesPartsPositionsFromUvs) {
  const SubdivisionCage quads = planeCage(4);
  SubdivisionCage tris = quads;
  tris.faceSizes.clear(), tris.faceIndices.clear(), tris.uvIndices.clear();
  for (size_t f = 0; f < quads.faceSizes.size(); ++f) {
    const int* q = &quads.faceIndices[4 * f];
    for (const int i : {q[0], q[1], q[2], q[0], q[2], q[3]}) tris.faceIndices.push_back(i), tris.uvIndices.push_back(i);
    tris.faceSizes.insert(tris.faceSizes.end(), {3, 3});
  }
  const auto drift = [&](SubdivisionScheme scheme) {
    const SubdividedMesh m = subdivide(tris, scheme, 4, size_t(1) << 30, "triangles");
    double worst = 0;
    // Away from the boundary (one cage cell, 0.25): there the pinned corners
    // end the B-spline boundary curves non-uniformly in either scheme.
    for (size_t i = 0; i < m.positions.size(); ++i)
      if (std::min({m.positions[i].x, m.positions[i].y, 1 - m.positions[i].x, 1 - m.positions[i].y}) > 0.3f)
        worst = std::max({worst, std::abs(double(m.uvs[2 * i]) - m.positions[i].x),
                          std::abs(double(m.uvs[2 * i + 1]) - m.positions[i].y)});
    return worst;
  };
  const double loop = drift(SubdivisionScheme::Loop), cc = drift(SubdivisionScheme::CatmullClark);
  RecordProperty("loop_drift", std::to_string(loop));
  RecordProperty("catmull_clark_drift", std::to_string(cc));
  std::printf("largest |uv - xy| inside a flat triangle cage of 4 x 4 x 2 triangles (cell 0.25), level 4: "
              "loop %.3g, catmull-clark %.3g\n", loop, cc);
  EXPECT_LT(loop, 1e-6);  // float rounding of unit coordinates
  EXPECT_GT(cc, 100 * loop);
}

// --- the tangent direction ----------------------------------------------------------

// A direction in the geometric plane is blocked, like those below it; the
// smallest positive elevation is open; NaN is blocked. Every integrator
// decides through intoSurface/openDirection, so this pins all of them.
TEST(CageHardening, TangentDirectionsAreBlocked) {
  SurfaceHit h{};
  h.ng = Vec3(0, 0, 1);
  h.ns = Vec3(0, 0, 1);
  EXPECT_TRUE(intoSurface(h, Vec3(1, 0, 0)));
  EXPECT_TRUE(intoSurface(h, Vec3(0.6f, -0.8f, -0.0f)));
  EXPECT_TRUE(intoSurface(h, Vec3(1, 0, -1e-30f)));
  EXPECT_FALSE(intoSurface(h, Vec3(1, 0, 1e-30f)));
  EXPECT_FALSE(intoSurface(h, Vec3(1, 0, std::numeric_limits<float>::denorm_min())));
  EXPECT_TRUE(intoSurface(h, Vec3(std::nanf(""), 0, 1)));
}

}  // namespace
}  // namespace obscura::test
