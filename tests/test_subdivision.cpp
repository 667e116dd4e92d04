// Subdivision surfaces (core/subd/subdivision.h, core/load/obj_loader.h) against
// known limits: the Catmull-Clark limit of a cube's corner, convergence of
// area and volume, closed surfaces staying closed, and bad cages refused.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>

#include <obscura/error.h>
#include "core/load/obj_loader.h"
#include "core/subd/subdivision.h"
#include "core/load/gltf_loader.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

SubdivisionCage cube() { return cubeCage(); }

constexpr size_t kBudget = size_t(1) << 30;

// The limit of a valence-n vertex v with edge neighbours e_j and face-opposite
// vertices f_j is (n^2 v + 4 Sum e_j + Sum f_j) / (n (n + 5)) (Halstead et al.
// 1993); for the cube's corner (1,1,1), n = 3: (9 + 4 - 1) / 24 = 1/2 per
// axis. By symmetry the limit surface's extreme point along (1,1,1) is that
// corner's limit, with normal (1,1,1)/sqrt 3: at every level the refined
// vertex there is exactly on the limit.
TEST(Subdivision, CubeCornerReachesTheCatmullClarkLimit) {
  for (int level = 1; level <= 5; ++level) {
    const SubdividedMesh m = subdivide(cube(), SubdivisionScheme::CatmullClark, level, kBudget, "cube");
    size_t best = 0;
    for (size_t i = 0; i < m.positions.size(); ++i) {
      const Vec3 p = m.positions[i], q = m.positions[best];
      if (p.x + p.y + p.z > q.x + q.y + q.z) best = i;
    }
    const Vec3 p = m.positions[best];
    EXPECT_NEAR(p.x, 0.5, 1e-6) << "level " << level;
    EXPECT_NEAR(p.y, 0.5, 1e-6);
    EXPECT_NEAR(p.z, 0.5, 1e-6);
    const Vec3 n = m.normals[best];
    EXPECT_NEAR(std::abs(n.x), 1 / std::sqrt(3.0), 1e-5);
    EXPECT_NEAR(std::abs(n.y), 1 / std::sqrt(3.0), 1e-5);
    EXPECT_NEAR(std::abs(n.z), 1 / std::sqrt(3.0), 1e-5);
    EXPECT_EQ(m.triangles.size(), 6u * (size_t(1) << (2 * level)) * 2 * 3);
  }
}

void areaVolume(const SubdividedMesh& m, double& area, double& volume) {
  area = volume = 0;
  for (size_t t = 0; t < m.triangles.size(); t += 3) {
    const Vec3 a = m.positions[m.triangles[t]], b = m.positions[m.triangles[t + 1]], c = m.positions[m.triangles[t + 2]];
    const Vec3 n = cross(b - a, c - a);
    area += 0.5 * double(length(n));
    volume += double(dot(a, cross(b, c))) / 6.0;
  }
}

// Area and volume of the triangulated limit converge to the limit surface's:
// the error against a level-7 reference shrinks at least 2.5x per level
// (the chord error of a smooth surface is O(h^2): 4x per halving of h).
TEST(Subdivision, AreaAndVolumeConverge) {
  double refA, refV;
  areaVolume(subdivide(cube(), SubdivisionScheme::CatmullClark, 7, kBudget, "cube"), refA, refV);
  EXPECT_GT(refV, 0.0) << "outward orientation";
  double prevA = INFINITY, prevV = INFINITY;
  for (int level = 2; level <= 5; ++level) {
    double A, V;
    areaVolume(subdivide(cube(), SubdivisionScheme::CatmullClark, level, kBudget, "cube"), A, V);
    const double eA = std::abs(A - refA), eV = std::abs(V - refV);
    if (level > 2) {
      EXPECT_LT(eA * 2.5, prevA) << "level " << level;
      EXPECT_LT(eV * 2.5, prevV) << "level " << level;
    }
    prevA = eA, prevV = eV;
  }
  // The limit is inside the cage (convex hull property) and not degenerate.
  EXPECT_LT(refV, 8.0);
  EXPECT_GT(refV, 4.0 / 3.0 * M_PI * 0.5 * 0.5 * 0.5);
}

// A closed cage gives a closed triangle mesh (every edge in exactly two
// triangles), and from inside it no ray escapes: AO is exactly 0.
TEST(Subdivision, ClosedCageStaysWatertight) {
  for (const SubdivisionScheme scheme : {SubdivisionScheme::CatmullClark, SubdivisionScheme::Loop}) {
    SubdivisionCage c = cube();
    if (scheme == SubdivisionScheme::Loop) {  // the cube's quads split into triangles
      SubdivisionCage t;
      t.positions = c.positions;
      for (size_t f = 0; f < 6; ++f) {
        const int* q = &c.faceIndices[f * 4];
        t.faceIndices.insert(t.faceIndices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
        t.faceSizes.insert(t.faceSizes.end(), {3, 3});
      }
      c = t;
    }
    const SubdividedMesh m = subdivide(c, scheme, 3, kBudget, "cube");
    std::map<std::pair<uint32_t, uint32_t>, int> edges;
    for (size_t t = 0; t < m.triangles.size(); t += 3)
      for (int k = 0; k < 3; ++k) {
        uint32_t a = m.triangles[t + k], b = m.triangles[t + (k + 1) % 3];
        if (a > b) std::swap(a, b);
        ++edges[{a, b}];
      }
    for (const auto& [e, count] : edges) ASSERT_EQ(count, 2) << "edge " << e.first << "-" << e.second;
    expectNoRayEscapes(m);
  }
}

TEST(Subdivision, BadCagesAreRefusedWithTheFace) {
  const auto expectError = [](SubdivisionCage c, SubdivisionScheme s, const std::string& needle) {
    try {
      subdivide(c, s, 2, kBudget, "cage.obj");
      ADD_FAILURE() << "accepted: " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).rfind("cage.obj: ", 0), 0u) << e.what();
    }
  };
  SubdivisionCage c = cube();
  c.faceIndices[5] = 4;  // face 1 = 4,4,7,6
  expectError(c, SubdivisionScheme::CatmullClark, "face 1 repeats vertex 4");
  c = cube();
  c.faceIndices[9] = 8;
  expectError(c, SubdivisionScheme::CatmullClark, "face 2 refers to vertex 8 of 8");
  c = cube();
  c.positions[3].y = NAN;
  expectError(c, SubdivisionScheme::CatmullClark, "vertex 3 is not finite");
  expectError(cube(), SubdivisionScheme::Loop, "Loop subdivision needs triangles");
  c = cube();
  c.faceSizes = {2};
  expectError(c, SubdivisionScheme::CatmullClark, "face 0 has 2 vertices");
  // The memory budget: level 10 of a cube is ~6M quads.
  try {
    subdivide(cube(), SubdivisionScheme::CatmullClark, 10, size_t(64) << 20, "cube");
    ADD_FAILURE() << "level 10 within 64 MiB";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("maxMemoryBytes"), std::string::npos) << e.what();
  }
}

// The Spot cage of ../shared/scenes renders subdivided through the CLI, and
// a malformed OBJ gives one error line.
TEST(Subdivision, SpotCageRendersAndBadObjIsRefused) {
  const std::string dir = tempDir("subdiv_cli");
  const std::string spot = sharedScene("spot_cage/spot_control_mesh.obj");
  OBSCURA_NEED_SHARED_SCENE(spot);
  const CliResult r = runCli({"render", spot, "--subdiv", "catmull-clark", "--subdiv-level", "2", "-o", dir + "/spot.exr",
                              "--res", "64x48", "--spp", "2", "-q", "-i", "transfer"},
                             dir + "/err.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack img = readExr(dir + "/spot.exr");
  double covered = 0;
  for (const float a : img.planes.at("A")) covered += a;
  EXPECT_GT(covered, 64.0 * 48 * 0.05);
  writeText(dir + "/bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2\n");
  const CliResult bad = runCli({"render", dir + "/bad.obj", "--subdiv", "loop", "-o", dir + "/bad.exr", "-q"},
                               dir + "/err2.txt");
  EXPECT_EQ(bad.exitCode, 1);
  EXPECT_NE(bad.stderrText.find("bad.obj: face 0 repeats vertex 1"), std::string::npos) << bad.stderrText;
  EXPECT_EQ(std::count(bad.stderrText.begin(), bad.stderrText.end(), '\n'), 1) << bad.stderrText;
}

// Displacement moves each vertex along the limit normal by
// scale (h(uv) - midlevel): on a flat cage (limit = the plane, normal +z)
// z equals that at every vertex; the height map is sampled at texel centres
// with v = 0 at the bottom, so it agrees with the analytic cos(4 pi u) to the
// bilinear interpolation bound (1/64)^2 / 8 * max|h''| = 0.0024.
TEST(Subdivision, DisplacementFollowsTheHeightMap) {
  const std::string dir = tempDir("subdiv_displace");
  const HeightMap hm(writeRipples(dir));
  SubdividedMesh m = subdivide(planeCage(4), SubdivisionScheme::CatmullClark, 4, kBudget, "plane");
  ASSERT_EQ(m.uvs.size(), m.positions.size() * 2);
  const std::vector<Vec3> before = m.positions;
  displace(m, hm, 0.2, 0.5);
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const float u = m.uvs[2 * i], v = m.uvs[2 * i + 1];
    ASSERT_NEAR(u, before[i].x, 1e-6);  // the uv of a plane with uv = xy is xy
    ASSERT_NEAR(v, before[i].y, 1e-6);
    ASSERT_NEAR(m.positions[i].z, 0.2 * (hm.sample(u, v) - 0.5), 1e-6) << i;
    EXPECT_NEAR(hm.sample(u, v), 0.5 + 0.5 * std::cos(4 * M_PI * u), 0.0025) << "u " << u;
    EXPECT_GT(m.normals[i].z, 0.0f);
  }
}

// A cube cage whose faces each have their own uvs (seams on every edge),
// displaced: every vertex moves once, so no crack opens - from inside, AO is 0.
TEST(Subdivision, DisplacedCageHasNoCracks) {
  const std::string dir = tempDir("subdiv_cracks");
  const HeightMap hm(writeRipples(dir));
  SubdivisionCage c = cube();
  c.uvs = {0, 0, 1, 0, 1, 1, 0, 1};
  for (size_t f = 0; f < 6; ++f) c.uvIndices.insert(c.uvIndices.end(), {0, 1, 2, 3});
  SubdividedMesh m = subdivide(c, SubdivisionScheme::CatmullClark, 4, kBudget, "cube");
  displace(m, hm, 0.15, 0.5);
  expectNoRayEscapes(m);
}

// glTF meshes flagged with extras.obscura.subdivision are subdivided (the
// triangle list is the cage); bad flags name the field.
TEST(Subdivision, GltfExtrasFlagAMeshForSubdivision) {
  const std::string dir = tempDir("subdiv_gltf");
  const auto write = [&](const json& sub, const std::string& name) {
    SubdivisionCage c = cube();
    std::vector<uint32_t> tris;
    for (size_t f = 0; f < 6; ++f) {
      const int* q = &c.faceIndices[f * 4];
      for (const int k : {0, 1, 2, 0, 2, 3}) tris.push_back(uint32_t(q[k]));
    }
    GltfBuilder g;
    const json prim = {{"attributes", {{"POSITION", g.positions(c.positions)}}}, {"indices", g.indices(tris)}};
    json mesh = {{"primitives", json::array({prim})}};
    if (!sub.is_null()) mesh["extras"] = {{"obscura", {{"subdivision", sub}}}};
    g.push("meshes", mesh);
    g.scene({g.node({{"mesh", 0}})});
    return g.writeGltf(dir, name);
  };
  const auto plain = loadGltf(write(nullptr, "plain"));
  EXPECT_EQ(plain->stats().renderedTriangles, 12u);
  const auto loop = loadGltf(write({{"scheme", "loop"}, {"level", 3}}, "loop"));
  EXPECT_EQ(loop->stats().renderedTriangles, 12u * 64u);
  const auto cc = loadGltf(write({{"level", 2}}, "cc"));  // catmull-clark: each triangle -> 3 quads -> x4
  EXPECT_EQ(cc->stats().renderedTriangles, 12u * 3u * 4u * 2u);
  for (const auto& [bad, needle] : std::vector<std::pair<json, std::string>>{
           {{{"level", 11}}, "meshes[0].extras.obscura.subdivision.level: expected an integer in [0, 10]"},
           {{{"scheme", "butterfly"}}, "meshes[0].extras.obscura.subdivision.scheme"},
           {json(3), "meshes[0].extras.obscura.subdivision: must be an object"}}) {
    try {
      loadGltf(write(bad, "bad"));
      ADD_FAILURE() << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace obscura::test
