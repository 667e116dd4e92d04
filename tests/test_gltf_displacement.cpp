// Texture coordinates and displacement through glTF subdivision
// (core/load/gltf_loader.cpp, extras.obscura.subdivision / .displacement):
// uvs stay face-varying across a welded seam, a displaced glTF plane moves
// exactly like the same cage loaded from OBJ, welding closes seams so a
// displaced closed mesh stays watertight, and bad fields name themselves.
//
// The face-varying interpolation inside a cage face may be smooth or
// bilinear (the two subdivision backends differ there), so uvs are compared
// with positions only where both agree: along the cage's boundary, whose
// refined vertices are equally spaced in position and in uv either way.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "core/load/obj_loader.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr int kGrid = 4;  // quads per side of the plane [0, 1]^2

// The world-space primitive of a scene whose one mesh is used once.
const Primitive& onlyPrimitive(const Scene& scene) {
  const Affine* xf = nullptr;
  EXPECT_EQ(scene.stats().primitives, 1u);
  return scene.primitiveOf(0, RTC_INVALID_GEOMETRY_ID, &xf);
}

// The plane [0, 1]^2 at z = 0 as kGrid x kGrid quads split into triangles
// (counter-clockwise from +z), uv = (x, 1 - y) (glTF's v runs down the
// image). With `seam`, the right half takes u = x + 10 and the vertices on
// x = 1/2 are duplicated for it: a uv seam as glTF exporters write it.
struct PlaneData {
  std::vector<Vec3> positions;
  std::vector<std::array<float, 2>> uvs;
  std::vector<uint32_t> triangles;
};
PlaneData plane(bool seam) {
  PlaneData p;
  const auto at = [](int i, int j) { return uint32_t(j * (kGrid + 1) + i); };
  for (int j = 0; j <= kGrid; ++j)
    for (int i = 0; i <= kGrid; ++i) {
      p.positions.emplace_back(float(i) / kGrid, float(j) / kGrid, 0.0f);
      p.uvs.push_back({float(i) / kGrid, 1.0f - float(j) / kGrid});
    }
  const uint32_t copies = uint32_t(p.positions.size());
  if (seam) {
    for (int j = 0; j <= kGrid; ++j) {
      p.positions.push_back(p.positions[at(kGrid / 2, j)]);
      p.uvs.push_back({p.uvs[at(kGrid / 2, j)][0] + 10.0f, p.uvs[at(kGrid / 2, j)][1]});
      for (int i = kGrid / 2 + 1; i <= kGrid; ++i) p.uvs[at(i, j)][0] += 10.0f;
    }
  }
  // Corner (i, j) of a quad whose lower-left corner is in column `column`.
  const auto corner = [&](int i, int j, int column) {
    return seam && i == kGrid / 2 && column >= kGrid / 2 ? copies + uint32_t(j) : at(i, j);
  };
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i) {
      const uint32_t a = corner(i, j, i), b = corner(i + 1, j, i), c = corner(i + 1, j + 1, i), d = corner(i, j + 1, i);
      p.triangles.insert(p.triangles.end(), {a, b, c, a, c, d});
    }
  return p;
}

// dir/name.gltf: the plane as one mesh with `meshExtras` as its
// extras.obscura, under one node with `nodeExtras` (when not null).
std::string writePlane(const std::string& dir, const std::string& name, const json& meshExtras,
                       const json& nodeExtras = nullptr, bool seam = false, bool withUv = true) {
  const PlaneData p = plane(seam);
  GltfBuilder g;
  json prim = {{"attributes", {{"POSITION", g.positions(p.positions)}}}, {"indices", g.indices(p.triangles)}};
  if (withUv) prim["attributes"]["TEXCOORD_0"] = g.vec2(p.uvs);
  json mesh = {{"primitives", json::array({prim})}};
  if (!meshExtras.is_null()) mesh["extras"] = {{"obscura", meshExtras}};
  g.push("meshes", mesh);
  json node = {{"mesh", 0}};
  if (!nodeExtras.is_null()) node["extras"] = {{"obscura", nodeExtras}};
  g.scene({g.node(node)});
  return g.writeGltf(dir, name);
}

const json kSubdivide = {{"level", 2}};

// The plane as an OBJ cage: the same triangles and, per glTF vertex, one vt
// (glTF's (u, v) is OBJ's (u, 1 - v): OBJ's v runs up the image); the seam's
// copies are the same `v` with another vt, so the cage is the one the glTF
// loader builds by welding (in the same vertex order: first occurrence).
std::string writePlaneObj(const std::string& dir, bool seam) {
  const PlaneData p = plane(seam);
  const size_t grid = size_t(kGrid + 1) * (kGrid + 1);
  std::string obj;
  for (size_t i = 0; i < grid; ++i) obj += "v " + std::to_string(p.positions[i].x) + " " + std::to_string(p.positions[i].y) + " 0\n";
  for (const auto& uv : p.uvs) obj += "vt " + std::to_string(uv[0]) + " " + std::to_string(1.0f - uv[1]) + "\n";
  for (size_t t = 0; t < p.triangles.size(); t += 3) {
    obj += "f";
    for (size_t k = 0; k < 3; ++k) {
      const uint32_t i = p.triangles[t + k];
      const size_t v = i < grid ? i : size_t(kGrid / 2) + (i - grid) * size_t(kGrid + 1);  // a copy's original
      obj += " " + std::to_string(v + 1) + "/" + std::to_string(i + 1);
    }
    obj += "\n";
  }
  writeText(dir + "/plane.obj", obj);
  return dir + "/plane.obj";
}

LoadOptions objSubdivision() {
  LoadOptions o;
  o.subdivision = true;
  o.subdivisionLevel = 2;
  return o;
}

// A seam of duplicated vertices is welded: the halves share their refined
// positions - a position appears twice only as a seam vertex's two copies,
// one per side's uv (SubdividedMesh::weld), never as an open seam. The uvs come through
// face-varying, exactly as the same cage's vt do from an OBJ file; whatever
// the interpolation inside a face, no refined uv mixes the halves' values
// (left u <= 1/2, right u >= 10.5), and at the cage's two one-face corners,
// (1, 0) and (0, 1), the uv is the corner's own.
TEST(GltfDisplacement, UvsStayFaceVaryingAcrossAWeldedSeam) {
  const std::string dir = tempDir("gltf_uv_seam");
  const auto scene = loadGltf(writePlane(dir, "seam", {{"subdivision", kSubdivide}}, nullptr, true));
  const auto obj = loadObj(writePlaneObj(dir, true), objSubdivision());
  const Primitive &p = onlyPrimitive(*scene), &o = onlyPrimitive(*obj);
  ASSERT_EQ(p.uvs.size(), size_t(p.vertexCount) * 2);
  ASSERT_EQ(p.vertexCount, o.vertexCount);
  // Catmull-Clark turns each of the 2 kGrid^2 triangles into 3 quads, then
  // x4 per further level: 2 triangles each.
  EXPECT_EQ(p.triangleCount, 2u * kGrid * kGrid * 3u * 4u * 2u);
  std::map<std::array<float, 3>, std::set<std::array<float, 2>>> seen;  // position -> its copies' uvs
  int corners = 0;
  for (uint32_t i = 0; i < p.vertexCount; ++i) {
    const Vec3 x(p.positions[3 * i], p.positions[3 * i + 1], p.positions[3 * i + 2]);
    const std::array<float, 3> key{x.x, x.y, x.z};
    const std::array<float, 2> uv{p.uvs[2 * i], p.uvs[2 * i + 1]};
    ASSERT_TRUE(seen[key].insert(uv).second) << "refined vertex " << i << " repeats a position and its uv: the seam is open";
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(p.positions[3 * i + k], o.positions[3 * i + k], 1e-6) << "vertex " << i;
    const float u = p.uvs[2 * i], v = p.uvs[2 * i + 1];
    EXPECT_NEAR(u, o.uvs[2 * i], 1e-5) << "vertex " << i;
    EXPECT_NEAR(v, 1.0f - o.uvs[2 * i + 1], 1e-6) << "vertex " << i;
    // (Slack: float rounding of convex combinations. The seam's refined
    // vertices may take either side's uv, and Catmull-Clark on a triangle
    // cage moves them a little off x = 1/2 - by 2e-4 here - so the halves
    // are told apart 0.01 away, well inside the refined spacing 1/16.)
    if (x.x < 0.49f) {
      EXPECT_TRUE(u >= -1e-6f && u <= 0.5f + 1e-6f) << "vertex " << i << " u " << u;
    }
    if (x.x > 0.51f) {
      EXPECT_TRUE(u >= 10.5f - 1e-5f && u <= 11.0f + 1e-5f) << "vertex " << i << " u " << u;
    }
    EXPECT_TRUE(v >= -1e-6f && v <= 1.0f + 1e-6f) << "vertex " << i << " v " << v;
    if ((x.x == 1.0f && x.y == 0.0f) || (x.x == 0.0f && x.y == 1.0f)) {
      ++corners;
      EXPECT_EQ(u, x.x + (x.x == 1.0f ? 10.0f : 0.0f));
      EXPECT_EQ(v, 1.0f - x.y);
    }
  }
  EXPECT_EQ(corners, 2);
}

// h(u, v) = 0.5 + 0.25 cos(4 pi u) + 0.25 sin(2 pi v), 64 x 64 texels:
// varies along both axes, so a flipped v would show.
std::string writeWaves(const std::string& dir) {
  return writeHeightMap(dir + "/waves.exr", 64, 64, [](double u, double v) {
    return 0.5 + 0.25 * std::cos(4 * M_PI * u) + 0.25 * std::sin(2 * M_PI * v);
  });
}

// A displaced glTF plane moves its vertices exactly as the OBJ path moves
// the same cage, each by scale (h - midlevel) along the plane's normal +z,
// with h read at the vertex's uv with v flipped (glTF's v = 0 is the image's
// top row, as for textures; HeightMap's is the bottom). A node's
// displacement overrides the mesh's; the CLI's --displace (LoadOptions)
// applies only to a mesh without one, and a map nobody uses is never read.
TEST(GltfDisplacement, DisplacedPlaneMovesLikeTheObjPath) {
  const std::string dir = tempDir("gltf_displace_plane");
  const HeightMap hm(writeWaves(dir));
  const double scale = 0.2, mid = 0.5;
  const json disp = {{"map", "waves.exr"}, {"scale", scale}, {"midlevel", mid}};
  const auto gltf = loadGltf(writePlane(dir, "plane", {{"subdivision", kSubdivide}, {"displacement", disp}}));
  LoadOptions objOptions = objSubdivision();
  objOptions.displacementMap = dir + "/waves.exr";
  objOptions.displacementScale = scale;
  objOptions.displacementMidlevel = mid;
  const auto obj = loadObj(writePlaneObj(dir, false), objOptions);
  const Primitive &g = onlyPrimitive(*gltf), &o = onlyPrimitive(*obj);
  ASSERT_EQ(g.vertexCount, o.vertexCount);
  ASSERT_EQ(g.triangleCount, o.triangleCount);
  double zmin = INFINITY, zmax = -INFINITY;
  for (uint32_t i = 0; i < g.vertexCount; ++i) {
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(g.positions[3 * i + k], o.positions[3 * i + k], 1e-6) << "vertex " << i;
    const float z = g.positions[3 * i + 2], u = g.uvs[2 * i], v = g.uvs[2 * i + 1];
    ASSERT_NEAR(z, scale * (hm.sample(u, 1.0f - v) - mid), 1e-6) << "vertex " << i;
    zmin = std::min(zmin, double(z)), zmax = std::max(zmax, double(z));
  }
  EXPECT_GT(zmax - zmin, scale * 0.8);  // it did move, by most of the map's range

  // Precedence: the node's scale (twice the mesh's) wins; z doubles exactly.
  WarningCapture warnings;
  LoadOptions cli;
  cli.displacementMap = dir + "/absent.exr";  // never read: every mesh here has its own
  const auto node = loadGltf(writePlane(dir, "node", {{"subdivision", kSubdivide}, {"displacement", disp}},
                                        {{"displacement", {{"map", "waves.exr"}, {"scale", 2 * scale}, {"midlevel", mid}}}}),
                             cli);
  const Primitive& n = onlyPrimitive(*node);
  ASSERT_EQ(n.vertexCount, g.vertexCount);
  for (uint32_t i = 0; i < n.vertexCount; ++i) ASSERT_NEAR(n.positions[3 * i + 2], 2 * g.positions[3 * i + 2], 1e-6);
  EXPECT_EQ(warnings.count("height map unused"), 1u) << warnings.all();

  // The CLI's map on a subdivided mesh without a displacement of its own.
  cli.displacementMap = dir + "/waves.exr";
  cli.displacementScale = scale;
  cli.displacementMidlevel = mid;
  const auto fromCli = loadGltf(writePlane(dir, "cli", {{"subdivision", kSubdivide}}), cli);
  const Primitive& c = onlyPrimitive(*fromCli);
  ASSERT_EQ(c.vertexCount, g.vertexCount);
  for (uint32_t i = 0; i < 3 * c.vertexCount; ++i) ASSERT_EQ(c.positions[i], g.positions[i]);
}

// The cube as glTF exporters write it: every face its own four vertices
// with the whole [0,1]^2 of uv, two triangles each.
void exporterCube(std::vector<Vec3>& positions, std::vector<std::array<float, 2>>& uvs, std::vector<uint32_t>& triangles) {
  const SubdivisionCage cube = cubeCage();
  for (size_t f = 0; f < 6; ++f) {
    const uint32_t base = uint32_t(positions.size());
    const std::array<float, 2> corners[4] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    for (int k = 0; k < 4; ++k) positions.push_back(cube.positions[size_t(cube.faceIndices[f * 4 + size_t(k)])]), uvs.push_back(corners[k]);
    triangles.insert(triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  }
}

// A cube written as glTF exporters write it - every face its own four
// vertices, for per-face uvs - subdivided and displaced: welding makes it one
// closed cage, each vertex moves once, and from inside no ray escapes.
TEST(GltfDisplacement, WeldedSeamsLeaveNoCrack) {
  const std::string dir = tempDir("gltf_displace_cube");
  writeRipples(dir);
  std::vector<Vec3> positions;
  std::vector<std::array<float, 2>> uvs;
  std::vector<uint32_t> triangles;
  exporterCube(positions, uvs, triangles);
  GltfBuilder g;
  const json prim = {{"attributes", {{"POSITION", g.positions(positions)}, {"TEXCOORD_0", g.vec2(uvs)}}},
                     {"indices", g.indices(triangles)}};
  g.push("meshes", {{"primitives", json::array({prim})},
                    {"extras", {{"obscura", {{"subdivision", {{"level", 3}}},
                                             {"displacement", {{"map", "ripples.exr"}, {"scale", 0.15}}}}}}}});
  g.scene({g.node({{"mesh", 0}})});
  LoadOptions robust;
  robust.robust = true;
  const auto scene = loadGltf(g.writeGltf(dir, "cube"), robust);
  // One closed surface: every refined edge - by its ends' positions, since a
  // vertex on a uv seam is split into copies at one position - is shared by
  // exactly two triangles.
  const Primitive& p = onlyPrimitive(*scene);
  const auto at = [&](uint32_t i) { return std::array<float, 3>{p.positions[3 * i], p.positions[3 * i + 1], p.positions[3 * i + 2]}; };
  std::map<std::pair<std::array<float, 3>, std::array<float, 3>>, int> edges;
  for (uint32_t t = 0; t < p.triangleCount; ++t)
    for (int k = 0; k < 3; ++k) {
      const auto a = at(p.indices[3 * t + k]), b = at(p.indices[3 * t + (k + 1) % 3]);
      ++edges[{std::min(a, b), std::max(a, b)}];
    }
  for (const auto& [e, count] : edges) ASSERT_EQ(count, 2) << "an edge at " << e.first[0] << "," << e.first[1] << "," << e.first[2];
  expectNoRayEscapes(*scene);
}

// Every malformed displacement field is refused with one line naming the
// file and the field; the same through the CLI.
TEST(GltfDisplacement, BadFieldsNameTheField) {
  const std::string dir = tempDir("gltf_displace_bad");
  writeRipples(dir);
  const json ok = {{"map", "ripples.exr"}};
  const auto sub = [](const json& disp) { return json{{"subdivision", kSubdivide}, {"displacement", disp}}; };
  const struct {
    std::string path, needle;
  } cases[] = {
      {writePlane(dir, "notobject", sub(3)), "meshes[0].extras.obscura.displacement: must be an object"},
      {writePlane(dir, "nomap", sub({{"scale", 1}})), "meshes[0].extras.obscura.displacement.map: expected the path of a height map"},
      {writePlane(dir, "absent", sub({{"map", "absent.exr"}})),
       "meshes[0].extras.obscura.displacement.map: absent.exr: cannot read the height map"},
      {writePlane(dir, "scale", sub({{"map", "ripples.exr"}, {"scale", "big"}})),
       "meshes[0].extras.obscura.displacement.scale: expected a finite number"},
      {writePlane(dir, "midlevel", sub({{"map", "ripples.exr"}, {"midlevel", true}})),
       "meshes[0].extras.obscura.displacement.midlevel: expected a finite number"},
      {writePlane(dir, "nosub", {{"displacement", ok}}),
       "meshes[0].extras.obscura.displacement: needs a subdivided mesh (meshes[0].extras.obscura.subdivision)"},
      {writePlane(dir, "nouv", sub(ok), nullptr, false, false),
       "meshes[0].primitives[0].attributes: TEXCOORD_0 is missing; meshes[0].extras.obscura.displacement needs it"},
      {writePlane(dir, "node", {{"subdivision", kSubdivide}}, {{"displacement", {{"map", 5}}}}),
       "nodes[0].extras.obscura.displacement.map: expected the path of a height map"},
      {writePlane(dir, "nodesub", json::object(), {{"displacement", ok}}),
       "nodes[0].extras.obscura.displacement: needs a subdivided mesh (meshes[0].extras.obscura.subdivision)"},
      {writePlane(dir, "nodeobscura", {{"subdivision", kSubdivide}}, 1), "nodes[0].extras.obscura: must be an object"},
  };
  for (const auto& c : cases) {
    try {
      loadGltf(c.path);
      ADD_FAILURE() << "accepted: " << c.needle;
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(c.path + ": " + c.needle, 0), 0u) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
  // A cage triangle whose corners weld together is degenerate.
  GltfBuilder g;
  const json prim = {{"attributes", {{"POSITION", g.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 0, 0}})}}},
                     {"indices", g.indices(std::vector<uint8_t>{0, 1, 3})}};
  g.push("meshes", {{"primitives", json::array({prim})}, {"extras", {{"obscura", {{"subdivision", kSubdivide}}}}}});
  g.scene({g.node({{"mesh", 0}})});
  try {
    loadGltf(g.writeGltf(dir, "weld"));
    ADD_FAILURE() << "a triangle with two corners at one position was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("meshes[0].primitives[0].indices: triangle 0 is degenerate (vertices 1 and 3 at "
                                         "the same position)"),
              std::string::npos)
        << e.what();
  }
  const CliResult r = runCli({"render", dir + "/absent.gltf", "-o", dir + "/out.exr", "-q"}, dir + "/err.txt");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.stderrText.find("obscura: error: " + dir + "/absent.gltf: meshes[0].extras.obscura.displacement.map: absent.exr"),
            std::string::npos)
      << r.stderrText;
  EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
}


// A mirroring node (scale (-1, 1, 1)) turns a cage inside out; the loader
// reverses its faces so that displacement still pushes outwards. A cube
// displaced by a constant height (1, midlevel 0, scale 0.1) is mirror
// symmetric, so the mirrored and the plain node must meet the +x axis ray at
// the same distance - with either backend - and 0.1 before the undisplaced
// surface.
TEST(GltfDisplacement, MirroredNodesDisplaceOutwards) {
  const std::string dir = tempDir("gltf_mirror");
  writeHeightMap(dir + "/one.exr", 2, 2, [](double, double) { return 1.0; });
  std::vector<Vec3> positions;
  std::vector<std::array<float, 2>> uvs;
  std::vector<uint32_t> triangles;
  exporterCube(positions, uvs, triangles);
  const auto write = [&](const std::string& name, double sx, bool displaced) {
    GltfBuilder g;
    const json prim = {{"attributes", {{"POSITION", g.positions(positions)}, {"TEXCOORD_0", g.vec2(uvs)}}},
                       {"indices", g.indices(triangles)}};
    json ob = {{"subdivision", {{"level", 4}}}};
    if (displaced) ob["displacement"] = {{"map", "one.exr"}, {"scale", 0.1}, {"midlevel", 0.0}};
    g.push("meshes", {{"primitives", json::array({prim})}, {"extras", {{"obscura", ob}}}});
    g.scene({g.node({{"mesh", 0}, {"scale", {sx, 1.0, 1.0}}})});
    return g.writeGltf(dir, name);
  };
  const auto axisHit = [](const Scene& scene) {
    const RayHit rh = traceClosest(scene, Vec3(4, 0, 0), Vec3(-1, 0, 0));
    EXPECT_NE(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID);
    return double(rh.ray.tfar);
  };
  for (const SubdivisionBackend b : {SubdivisionBackend::OpenSubdiv, SubdivisionBackend::Embree}) {
    LoadOptions o;
    o.backend = b;
    const double plain = axisHit(*loadGltf(write("plain", 1, true), o));
    const double mirrored = axisHit(*loadGltf(write("mirrored", -1, true), o));
    const double bare = axisHit(*loadGltf(write("bare", -1, false), o));
    EXPECT_NEAR(mirrored, plain, 1e-4) << (b == SubdivisionBackend::Embree ? "embree" : "osd");
    EXPECT_NEAR(bare - mirrored, 0.1, 1e-4) << (b == SubdivisionBackend::Embree ? "embree" : "osd");
  }
}

}  // namespace
}  // namespace obscura::test
