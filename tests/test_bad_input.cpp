// Bad input: every malformed file or argument gives one clear error naming
// the file and the field (obscura::Error in process; one "obscura: error:"
// line and a non-zero exit from the CLI), never a crash, and never a
// damaged or half-written output file.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "core/scene/scene.h"
#include "core/image/texture.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

namespace fs = std::filesystem;

// accessors[0] = 4 positions (without min/max), accessors[1] = 6 indices:
// one quad mesh, placed by nodes[0] in scenes[0].
GltfBuilder quad(std::vector<Vec3> p = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                 std::vector<uint16_t> i = {0, 1, 2, 0, 2, 3}) {
  GltfBuilder d;
  const int pos = d.vec3(p);
  const int idx = d.indices(i);
  d.push("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}})}});
  d.node({{"mesh", 0}});
  d.scene({0});
  return d;
}

// quad() with uvs and a material whose base colour texture is the image at
// `uri`.
GltfBuilder texturedQuad(const std::string& uri) {
  GltfBuilder d = quad();
  d.push("images", {{"uri", uri}});
  d.push("textures", {{"source", 0}});
  d.push("materials", {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}});
  d.primitive()["material"] = 0;
  d.primitive()["attributes"]["TEXCOORD_0"] = d.vec2(std::vector<std::array<float, 2>>(4, {0.5f, 0.5f}));
  return d;
}

// Loading `path` must throw obscura::Error whose one-line message contains
// every needle (the file's path is always one of them).
void expectLoadError(const std::string& path, const std::vector<std::string>& needles) {
  WarningCapture quiet;
  try {
    auto scene = loadGltf(path);
    ADD_FAILURE() << path << " loaded without an error";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(path), std::string::npos) << "message does not name the file: " << m;
    for (const auto& n : needles) EXPECT_NE(m.find(n), std::string::npos) << "message lacks '" << n << "': " << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << "message is not one line: " << m;
  } catch (const std::exception& e) {
    ADD_FAILURE() << path << ": not an obscura::Error: " << e.what();
  }
}

// --- files, in process ----------------------------------------------------

TEST(BadInputFile, MissingFile) {
  const std::string dir = tempDir("bad_missing");
  expectLoadError(dir + "/nope.gltf", {"no such file"});
}

TEST(BadInputFile, Directory) {
  const std::string dir = tempDir("bad_directory");
  fs::create_directories(dir + "/scene.gltf");
  expectLoadError(dir + "/scene.gltf", {"directory"});
}

TEST(BadInputFile, EmptyAndGarbageGltf) {
  const std::string dir = tempDir("bad_garbage");
  writeText(dir + "/empty.gltf", "");
  expectLoadError(dir + "/empty.gltf", {"glTF"});
  writeText(dir + "/garbage.gltf", "this is { not json at all ]\n\x01\x02");
  expectLoadError(dir + "/garbage.gltf", {"glTF"});
  writeText(dir + "/array.gltf", "[1, 2, 3]");
  expectLoadError(dir + "/array.gltf", {"glTF"});
}

TEST(BadInputFile, CorruptAndTruncatedGlb) {
  const std::string dir = tempDir("bad_glb");
  const std::vector<unsigned char> good = quad().glbBytes();
  // The untouched file loads.
  writeBytes(dir + "/good.glb", good.data(), good.size());
  EXPECT_NO_THROW(loadGltf(dir + "/good.glb"));
  // Truncated in the header, in the JSON chunk and in the BIN chunk.
  for (size_t n : {size_t(4), size_t(11), size_t(20), good.size() / 2, good.size() - 8, good.size() - 1}) {
    SCOPED_TRACE("truncated to " + std::to_string(n) + " of " + std::to_string(good.size()) + " bytes");
    const std::string p = dir + "/trunc" + std::to_string(n) + ".glb";
    writeBytes(p, good.data(), n);
    expectLoadError(p, {"glTF"});
  }
  // Magic, then garbage.
  std::vector<unsigned char> bad = {'g', 'l', 'T', 'F'};
  for (int k = 0; k < 200; ++k) bad.push_back((unsigned char)(k * 37 + 11));
  writeBytes(dir + "/garbage.glb", bad.data(), bad.size());
  expectLoadError(dir + "/garbage.glb", {"glTF"});
  // A JSON chunk length beyond the file.
  std::vector<unsigned char> longChunk = good;
  longChunk[12] = 0xff, longChunk[13] = 0xff, longChunk[14] = 0x00;
  writeBytes(dir + "/longchunk.glb", longChunk.data(), longChunk.size());
  expectLoadError(dir + "/longchunk.glb", {"glTF"});
}

// Every prefix of a valid .glb: an Error or (never, here) a scene; no crash.
TEST(BadInputFile, EveryTruncationOfAGlbIsAnError) {
  const std::string dir = tempDir("bad_glb_prefixes");
  const std::vector<unsigned char> good = quad().glbBytes();
  const std::string p = dir + "/t.glb";
  WarningCapture quiet;
  for (size_t n = 0; n < good.size(); ++n) {
    writeBytes(p, good.data(), n);
    try {
      loadGltf(p);
      ADD_FAILURE() << "a " << n << "-byte prefix of a " << good.size() << "-byte .glb loaded";
    } catch (const Error&) {
    } catch (const std::exception& e) {
      ADD_FAILURE() << n << " bytes: not an obscura::Error: " << e.what();
    }
  }
}

TEST(BadInputFile, IndexOutOfRange) {
  const std::string dir = tempDir("bad_index");
  expectLoadError(quad({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {0, 1, 2, 0, 2, 7}).writeGltf(dir, "m"),
                  {"meshes[0].primitives[0].indices", "index 7", "element 5"});
}

TEST(BadInputFile, IndexCountNotAMultipleOfThree) {
  const std::string dir = tempDir("bad_index_count");
  expectLoadError(quad({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {0, 1, 2, 0}).writeGltf(dir, "m"),
                  {"meshes[0].primitives[0].indices", "multiple of 3"});
}

TEST(BadInputFile, NaNAndInfinityInPosition) {
  const std::string dir = tempDir("bad_nan");
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  expectLoadError(quad({{0, 0, 0}, {1, nan, 0}, {1, 1, 0}, {0, 1, 0}}).writeGltf(dir, "nan"),
                  {"meshes[0].primitives[0].attributes.POSITION", "element 1"});
  expectLoadError(quad({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, -inf}}).writeGltf(dir, "inf"),
                  {"attributes.POSITION", "element 3"});
}

TEST(BadInputFile, AccessorPastItsBufferView) {
  const std::string dir = tempDir("bad_accessor");
  GltfBuilder d = quad();
  d.doc["accessors"][0]["count"] = 5;  // 60 bytes in a 48-byte view
  expectLoadError(d.writeGltf(dir, "count"), {"accessors[0]", "POSITION", "bufferView"});
  GltfBuilder o = quad();
  o.doc["accessors"][1]["byteOffset"] = 4;  // 6 indices from byte 4 of a 12-byte view
  expectLoadError(o.writeGltf(dir, "offset"), {"accessors[1]", "indices", "bufferView"});
  // A count whose byte size overflows size_t.
  GltfBuilder h = quad();
  h.doc["accessors"][0]["count"] = uint64_t(1) << 62;
  expectLoadError(h.writeGltf(dir, "huge"), {"accessors[0]", "POSITION"});
  // A stride smaller than the element.
  GltfBuilder s = quad();
  s.doc["bufferViews"][0]["byteStride"] = 4;
  expectLoadError(s.writeGltf(dir, "stride"), {"accessors[0]", "byteStride"});
}

TEST(BadInputFile, BufferViewPastItsBuffer) {
  const std::string dir = tempDir("bad_bufferview");
  GltfBuilder d = quad();
  d.doc["bufferViews"][1]["byteLength"] = 4096;
  expectLoadError(d.writeGltf(dir, "len"), {"bufferViews[1]"});
  GltfBuilder o = quad();
  o.doc["bufferViews"][0]["byteOffset"] = 1000;
  expectLoadError(o.writeGltf(dir, "off"), {"bufferViews[0]"});
}

TEST(BadInputFile, WrongAccessorTypesAndMissingAttributes) {
  const std::string dir = tempDir("bad_types");
  GltfBuilder v2 = quad();
  v2.doc["accessors"][0]["type"] = "VEC2";
  expectLoadError(v2.writeGltf(dir, "vec2"), {"POSITION", "VEC3"});
  GltfBuilder noPos = quad();
  noPos.primitive()["attributes"] = {{"NORMAL", 0}};
  expectLoadError(noPos.writeGltf(dir, "nopos"), {"meshes[0].primitives[0]", "POSITION"});
  GltfBuilder badAcc = quad();
  badAcc.primitive()["attributes"]["POSITION"] = 42;
  expectLoadError(badAcc.writeGltf(dir, "badacc"), {"POSITION", "42"});
  GltfBuilder floatIdx = quad();
  floatIdx.doc["accessors"][1]["componentType"] = kFloat;
  floatIdx.doc["accessors"][1]["count"] = 3;
  expectLoadError(floatIdx.writeGltf(dir, "floatidx"), {"indices"});
  GltfBuilder normals = quad();
  normals.primitive()["attributes"]["NORMAL"] = normals.vec3({{0, 0, 1}, {0, 0, 1}});
  expectLoadError(normals.writeGltf(dir, "normals"), {"NORMAL", "count"});
}

TEST(BadInputFile, MissingBin) {
  const std::string dir = tempDir("bad_bin");
  const std::string path = quad().writeGltf(dir, "mesh");
  fs::remove(dir + "/mesh.bin");
  expectLoadError(path, {"mesh.bin"});
  // Present but shorter than buffers[0].byteLength.
  GltfBuilder d = quad();
  const std::string p2 = d.writeGltf(dir, "short");
  fs::resize_file(dir + "/short.bin", d.bin.size() - 4);
  expectLoadError(p2, {"short.bin"});
}

TEST(BadInputFile, MissingTextureImage) {
  const std::string dir = tempDir("bad_image");
  expectLoadError(texturedQuad("missing_albedo.png").writeGltf(dir, "m"), {"images[0]", "missing_albedo.png"});
}

TEST(BadInputFile, CorruptTextureImageFailsToDecodeNamingIt) {
  const std::string dir = tempDir("bad_image_data");
  writeText(dir + "/broken.png", "\x89PNG\r\n\x1a\n this is not really a png");
  const std::string path = texturedQuad("broken.png").writeGltf(dir, "m");
  WarningCapture quiet;
  auto scene = loadGltf(path);  // decoding is lazy
  ASSERT_EQ(scene->textures.size(), 1u);
  try {
    scene->textures[0]->decode();
    ADD_FAILURE() << "a broken PNG decoded";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find("images[0]"), std::string::npos) << m;
    EXPECT_NE(m.find("broken.png"), std::string::npos) << m;
  }
  // Rendering with albedo reports it as well (and again on a second try).
  RenderSettings s;
  s.width = s.height = 4;
  s.spp = 1;
  const Camera cam = makeAutoCamera(scene->bounds(), 1.0f);
  EXPECT_THROW(renderWith(*scene, cam, "ao", {}, s), Error);
  EXPECT_THROW(renderWith(*scene, cam, "ao", {}, s), Error);
}

TEST(BadInputFile, TextureAndCameraIndicesOutOfRange) {
  const std::string dir = tempDir("bad_refs");
  GltfBuilder t = quad();
  t.push("materials", {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 3}}}}}});
  expectLoadError(t.writeGltf(dir, "texture"), {"materials[0].pbrMetallicRoughness.baseColorTexture"});
  GltfBuilder c = quad();
  c.doc["nodes"][0]["camera"] = 2;
  expectLoadError(c.writeGltf(dir, "camera"), {"nodes[0].camera"});
  GltfBuilder f = quad();
  f.push("cameras", perspective("", 0.0, 0.1));
  f.doc["nodes"][0]["camera"] = 0;
  expectLoadError(f.writeGltf(dir, "yfov"), {"cameras[0]", "yfov"});
  GltfBuilder s = quad();
  s.doc["scene"] = 4;
  expectLoadError(s.writeGltf(dir, "scene"), {"scene"});
}

TEST(BadInputFile, NodeCycle) {
  const std::string dir = tempDir("bad_cycle");
  GltfBuilder d = quad();
  d.doc["nodes"][0]["children"] = {1};
  d.push("nodes", {{"children", {0}}});
  expectLoadError(d.writeGltf(dir, "cycle"), {"nodes[", "cycle"});
  GltfBuilder self = quad();
  self.doc["nodes"][0]["children"] = {0};
  expectLoadError(self.writeGltf(dir, "self"), {"nodes[0]", "cycle"});
}

// Without `scenes`, the loader renders the root nodes; a hierarchy that is
// all cycle has no root.
// NOTE: fails as of this writing: core/load/gltf_loader.cpp collectNodes() finds
// no root, visits nothing and returns an empty scene without a word.
TEST(BadInputFile, NodeCycleWithoutScenes) {
  const std::string dir = tempDir("bad_cycle_noscene");
  GltfBuilder d = quad();
  d.doc.erase("scenes");
  d.doc.erase("scene");
  d.doc["nodes"][0]["children"] = {1};
  d.push("nodes", {{"children", {0}}});
  expectLoadError(d.writeGltf(dir, "cycle"), {"nodes[", "cycle"});
}

// glTF 2.0 section 3.5.3: "each node MUST have zero or one parent node".
// NOTE: fails as of this writing: visit() in core/load/gltf_loader.cpp only
// detects cycles on the current path, so a node shared by two parents is
// silently rendered twice - and a DAG that shares at every level (each node
// listing the next one twice) is visited 2^depth times: 40 such nodes hang
// the loader and exhaust memory. Kept to two parents here so it stays fast.
TEST(BadInputFile, NodeWithTwoParents) {
  const std::string dir = tempDir("bad_two_parents");
  GltfBuilder d = quad();
  d.push("nodes", {{"children", {0}}});
  d.push("nodes", {{"children", {0}}});
  d.doc["scenes"][0]["nodes"] = {1, 2};
  expectLoadError(d.writeGltf(dir, "dag"), {"nodes[0]"});
}

TEST(BadInputFile, NodeHierarchyTooDeep) {
  const std::string dir = tempDir("bad_deep");
  GltfBuilder d = quad();
  for (int k = 1; k <= 1100; ++k) d.push("nodes", {{"children", {k - 1}}});
  d.doc["scenes"][0]["nodes"] = {1100};
  expectLoadError(d.writeGltf(dir, "deep"), {"nodes[", "deeper"});
}

TEST(BadInputFile, MeshAndMaterialIndexOutOfRange) {
  const std::string dir = tempDir("bad_mesh_index");
  GltfBuilder m = quad();
  m.doc["nodes"][0]["mesh"] = 3;
  expectLoadError(m.writeGltf(dir, "mesh"), {"nodes[0].mesh", "3"});
  GltfBuilder c = quad();
  c.doc["nodes"][0]["children"] = {9};
  expectLoadError(c.writeGltf(dir, "child"), {"nodes[9]"});
  GltfBuilder mat = quad();
  mat.primitive()["material"] = 2;
  expectLoadError(mat.writeGltf(dir, "material"), {"meshes[0].primitives[0].material", "2"});
  GltfBuilder neg = quad();
  neg.doc["accessors"][0]["componentType"] = 9999;
  expectLoadError(neg.writeGltf(dir, "componenttype"), {"ccessor"});
}

TEST(BadInputFile, RequiredCompressionExtension) {
  const std::string dir = tempDir("bad_draco");
  GltfBuilder d = quad();
  d.doc["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  d.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  expectLoadError(d.writeGltf(dir, "draco"), {"extensionsRequired", "KHR_draco_mesh_compression"});
}

// --- issue #37: malformed fields that rendered a plausible wrong pass ---------

// tinygltf keeps a transform array of the wrong length and the decoding took
// it as absent: a 15-number matrix, a 4-number translation, a 3-number
// rotation placed the node at the identity without a word.
TEST(BadInputFile, NodeTransformArrayOfTheWrongLengthIsRefused) {
  const std::string dir = tempDir("bad_trs_length");
  const std::vector<std::tuple<const char*, size_t, const char*>> cases = {
      {"matrix", 15, "expected 16 numbers, got 15"},
      {"translation", 4, "expected 3 numbers, got 4"},
      {"rotation", 3, "expected 4 numbers, got 3"},
      {"scale", 2, "expected 3 numbers, got 2"}};
  for (const auto& [key, n, why] : cases) {
    GltfBuilder d = quad();
    std::vector<double> v(n, 0.0);
    v[0] = 1.0;
    d.doc["nodes"][0][key] = v;
    expectLoadError(d.writeGltf(dir, key), {std::string("nodes[0].") + key, why});
  }
  GltfBuilder both = quad();
  both.doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  both.doc["nodes"][0]["translation"] = {1, 2, 3};
  expectLoadError(both.writeGltf(dir, "both"), {"nodes[0].translation", "matrix"});
}

// tinygltf wraps an integer beyond int in extras: a subdivision level of
// 4294967298 became 2 and refined the mesh twice.
TEST(BadInputFile, ExtrasIntegerBeyondIntIsRefused) {
  const std::string dir = tempDir("bad_extras_int");
  GltfBuilder d = quad();
  d.doc["meshes"][0]["extras"] = {{"obscura", {{"subdivision", {{"level", 4294967298ULL}}}}}};
  expectLoadError(d.writeGltf(dir, "level"), {"meshes[0].extras.obscura.subdivision.level", "4294967298", "2147483647"});
  GltfBuilder neg = quad();
  neg.doc["nodes"][0]["extras"] = {{"tool", {{"id", -3000000000LL}}}};
  expectLoadError(neg.writeGltf(dir, "negative"), {"nodes[0].extras.tool.id", "-3000000000"});
}

// A misspelt extras.obscura key ("occludr") was ignored: the object kept
// its default roles and the pass looked right.
TEST(BadInputFile, UnknownObscuraExtrasKeyIsRefusedWithTheNearestKey) {
  const std::string dir = tempDir("bad_extras_key");
  GltfBuilder d = quad();
  d.doc["nodes"][0]["extras"] = {{"obscura", {{"occludr", false}}}};
  expectLoadError(d.writeGltf(dir, "node"), {"nodes[0].extras.obscura.occludr", "did you mean 'occluder'"});
  GltfBuilder m = quad();
  m.doc["meshes"][0]["extras"] = {{"obscura", {{"subdivision", {{"levle", 2}}}}}};
  expectLoadError(m.writeGltf(dir, "mesh"), {"meshes[0].extras.obscura.subdivision.levle", "did you mean 'level'"});
  GltfBuilder far = quad();
  far.doc["nodes"][0]["extras"] = {{"obscura", {{"xyzzy", 1}}}};
  expectLoadError(far.writeGltf(dir, "far"), {"nodes[0].extras.obscura.xyzzy", "one of: displacement, occluder"});
}

// glTF 2.0 §3.12: a loader MUST fail on a required extension it does not
// support; it only warned, and rendered without it.
TEST(BadInputFile, UnsupportedRequiredExtensionIsAnError) {
  const std::string dir = tempDir("bad_required_ext");
  GltfBuilder d = quad();
  d.doc["extensionsUsed"] = {"KHR_materials_variants"};
  d.doc["extensionsRequired"] = {"KHR_materials_variants"};
  expectLoadError(d.writeGltf(dir, "variants"),
                  {"extensionsRequired[0]", "KHR_materials_variants is not supported", "KHR_mesh_quantization", "KHR_texture_transform"});
  GltfBuilder ok = quad();
  ok.doc["extensionsUsed"] = {"KHR_mesh_quantization", "KHR_texture_transform"};
  ok.doc["extensionsRequired"] = {"KHR_mesh_quantization", "KHR_texture_transform"};
  WarningCapture quiet;
  EXPECT_NO_THROW(loadGltf(ok.writeGltf(dir, "quantized")));
}

// zfar at or before znear clipped every camera ray: an empty pass, exit 0.
TEST(BadInputFile, ZfarNotBeyondZnearIsRefused) {
  const std::string dir = tempDir("bad_zfar");
  GltfBuilder d = quad();
  d.push("cameras", perspective("c", 0.8, 1.0, 0.5));
  d.push("nodes", {{"camera", 0}, {"translation", {0, 0, 3}}});
  d.doc["scenes"][0]["nodes"] = {0, 1};
  expectLoadError(d.writeGltf(dir, "zfar"), {"cameras[0].perspective.zfar", "greater than znear (1)", "0.5"});
}

// A zero scale on every axis hides the node and its children (glTF 2.0's
// animation note): skipped with a warning naming it; when it hides every
// mesh the load fails saying so. Before, the collapsed mesh rendered as an
// empty pass with exit status 0.
TEST(BadInputFile, ZeroScaleHidesTheNodeWithAWarning) {
  const std::string dir = tempDir("bad_zero_scale");
  GltfBuilder d = quad();
  d.node({{"mesh", 0}, {"scale", {0, 0, 0}}, {"translation", {3, 0, 0}}});
  d.doc["scenes"][0]["nodes"] = {0, 1};
  {
    WarningCapture w;
    const auto scene = loadGltf(d.writeGltf(dir, "one_hidden"));
    EXPECT_EQ(scene->stats().renderedTriangles, 2u);
    EXPECT_EQ(w.count("nodes[1] has a zero scale on every axis"), 1u) << w.all();
  }
  GltfBuilder all = quad();
  all.doc["nodes"][0]["scale"] = {0, 0, 0};
  expectLoadError(all.writeGltf(dir, "all_hidden"), {"no triangles", "hidden by a zero scale"});
}

// A singular transform that is not a zero scale flattens the meshes below
// into a plane or a line: refused naming the node.
TEST(BadInputFile, SingularTransformIsRefusedNamingTheNode) {
  const std::string dir = tempDir("bad_singular");
  GltfBuilder d = quad();
  d.doc["nodes"][0]["scale"] = {1, 0, 1};
  expectLoadError(d.writeGltf(dir, "flat"), {"nodes[0]", "singular"});
  GltfBuilder m = quad();
  m.doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 0, 0, 0, 1};  // z axis in the xy plane
  expectLoadError(m.writeGltf(dir, "coplanar"), {"nodes[0]", "singular"});
}

// tinyobjloader wrapped an index beyond int: 99999999999999999999 rendered,
// 2147483648 was reported as -2147483644.
TEST(BadInputFile, ObjIndexBeyondIntIsRefusedNamingTheLine) {
  const std::string dir = tempDir("bad_obj_index");
  const std::string head = "v 0 0 0\nv 1 0 0\nv 1 1 0\n";
  for (const std::string index : {"99999999999999999999", "2147483648", "-2147483648"}) {
    const std::string path = dir + "/i" + index.substr(0, 3) + ".obj";
    writeText(path, head + "f 1 2 " + index + "\n");
    try {
      loadScene(path);
      ADD_FAILURE() << index << " loaded";
    } catch (const Error& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(path + ": line 4"), std::string::npos) << m;
      EXPECT_NE(m.find("'" + index + "'"), std::string::npos) << m;
      EXPECT_NE(m.find("2147483647"), std::string::npos) << m;
    }
  }
  const std::string slashes = dir + "/slashes.obj";
  writeText(slashes, head + "vn 0 0 1\nf 1//1 2//1 3//1\n");
  EXPECT_NO_THROW(loadScene(slashes));
}

// Random damage to the binary buffer (positions and indices) and to numbers
// in the JSON: every outcome is a scene or an obscura::Error.
TEST(BadInputFile, RandomDamageNeverCrashes) {
  const std::string dir = tempDir("bad_random");
  std::mt19937 rng(12345);
  WarningCapture quiet;
  size_t errors = 0, loads = 0;
  for (int trial = 0; trial < 300; ++trial) {
    GltfBuilder d = quad();
    if (trial % 2 == 0) {
      for (int k = 0; k < 3; ++k) d.bin[rng() % d.bin.size()] = (unsigned char)(rng());
    } else {
      const char* arrays[] = {"accessors", "bufferViews"};
      const char* fields[][4] = {{"count", "byteOffset", "componentType", "bufferView"},
                                 {"byteLength", "byteOffset", "byteStride", "buffer"}};
      const int a = int(rng() % 2), f = int(rng() % 4);
      const int64_t values[] = {-1, 0, 1, 3, 4, 7, 12, 255, 65536, int64_t(1) << 31, int64_t(1) << 40};
      d.doc[arrays[a]][rng() % 2][fields[a][f]] = values[rng() % std::size(values)];
    }
    const std::string p = d.writeGltf(dir, "r");
    try {
      loadGltf(p);
      ++loads;
    } catch (const Error&) {
      ++errors;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "trial " << trial << ": not an obscura::Error: " << e.what();
    }
  }
  EXPECT_GT(errors, 0u);
  EXPECT_GT(loads, 0u);
}

// --- the CLI ----------------------------------------------------------------

// One CLI run: what it is, and how it ended.
struct CliRun : CliResult {
  std::string name;
  std::vector<std::string> args;
  std::string output;   // must not exist afterwards ("" = not checked)
  std::string mention;  // must appear in the error line
};

// Runs the processes, a few at a time; stderr goes to dir/stderr<i>.txt.
void runAll(std::vector<CliRun>& runs, const std::string& dir) {
  std::vector<std::vector<std::string>> args;
  for (const CliRun& r : runs) args.push_back(r.args);
  const std::vector<CliResult> results = runClis(args, dir);
  for (size_t i = 0; i < runs.size(); ++i) static_cast<CliResult&>(runs[i]) = results[i];
}

void expectOneErrorLine(const CliRun& r) {
  SCOPED_TRACE(r.name);
  EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << "; stderr:\n" << r.stderrText;
  EXPECT_NE(r.exitCode, 0) << "stderr:\n" << r.stderrText;
  EXPECT_EQ(r.stderrText.rfind("obscura: error:", 0), 0u) << "stderr:\n" << r.stderrText;
  EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1)
      << "not exactly one line:\n" << r.stderrText;
  if (!r.stderrText.empty()) {
    EXPECT_EQ(r.stderrText.back(), '\n') << r.stderrText;
  }
  EXPECT_NE(r.stderrText.find(r.mention), std::string::npos)
      << "does not mention '" << r.mention << "':\n" << r.stderrText;
  if (!r.output.empty()) {
    EXPECT_FALSE(fs::exists(r.output)) << r.output << " was created";
  }
}

// A valid one-camera scene with a quad in view.
std::string writeGoodScene(const std::string& dir) {
  GltfBuilder d = quad({{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}});
  d.push("cameras", perspective("only", 0.8, 0.01));
  d.push("nodes", {{"camera", 0}, {"translation", {0, 0, 3}}});
  d.doc["scenes"][0]["nodes"] = {0, 1};
  return d.writeGltf(dir, "good");
}

TEST(BadInputCli, EveryBadArgumentIsOneErrorLineAndNoOutput) {
  const std::string dir = tempDir("bad_cli");
  const std::string scene = writeGoodScene(dir);
  const std::string garbage = dir + "/garbage.gltf";
  writeText(garbage, "not a gltf file");
  std::vector<CliRun> runs;
  int k = 0;
  const auto add = [&](std::string name, std::vector<std::string> extra, std::string mention,
                       std::string sceneArg = "", std::string out = "") {
    CliRun r;
    r.name = std::move(name);
    r.output = out.empty() ? dir + "/out" + std::to_string(k++) + ".exr" : out;
    r.args = {"render", sceneArg.empty() ? scene : sceneArg, "-o", r.output, "-q"};
    // Options may be given once: the defaults only where the case has none.
    for (const char* opt : {"--res", "--spp"})
      if (std::find(extra.begin(), extra.end(), opt) == extra.end())
        r.args.insert(r.args.end(), {opt, std::string(opt) == "--res" ? "8x8" : "1"});
    r.args.insert(r.args.end(), extra.begin(), extra.end());
    r.mention = std::move(mention);
    runs.push_back(std::move(r));
  };
  add("unknown integrator", {"-i", "nope"}, "nope");
  add("unknown parameter", {"-p", "foo=1"}, "foo");
  add("negative distance", {"-p", "distance=-1"}, "distance");
  add("non-numeric distance", {"-p", "distance=abc"}, "distance");
  add("zero rays", {"-p", "rays=0"}, "rays");
  add("zero spp", {"--spp", "0"}, "--spp");
  add("non-numeric spp", {"--spp", "abc"}, "--spp");
  add("resolution without x", {"--res", "100"}, "--res");
  add("zero width", {"--res", "0x10"}, "--res");
  add("letters in resolution", {"--res", "axb"}, "--res");
  add("camera index out of range", {"--camera", "7"}, "--camera");
  add("unknown camera name", {"--camera", "nosuch"}, "nosuch");
  add("missing scene", {}, dir + "/missing.gltf", dir + "/missing.gltf");
  add("garbage scene", {}, garbage, garbage);
  add("output directory missing", {}, dir + "/no_such_dir/out.exr", "", dir + "/no_such_dir/out.exr");
  add("output directory unwritable", {}, "/proc/obscura_test_out.exr", "", "/proc/obscura_test_out.exr");
  runAll(runs, dir);
  for (const CliRun& r : runs) expectOneErrorLine(r);
  // Nothing left behind: only the scene, its .bin, the garbage file and the
  // captured stderr files.
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    EXPECT_TRUE(name == "good.gltf" || name == "good.bin" || name == "garbage.gltf" || name.rfind("stderr", 0) == 0)
        << "unexpected file left behind: " << name;
  }
}

// `n` arrays nested in one another, the innermost holding 1.
std::string nestedArrays(size_t n) { return std::string(n, '[') + "1" + std::string(n, ']'); }

// quad() with nodes[0].extras replaced by `extras` (raw JSON text), as a
// .gltf (or .glb) in dir: written as text, since nlohmann's dump recurses.
std::string withRawExtras(const std::string& dir, const std::string& name, const std::string& extras, bool glb) {
  GltfBuilder d = quad();
  d.doc["nodes"][0]["extras"] = "EXTRAS_PLACEHOLDER";
  const std::string marker = "\"EXTRAS_PLACEHOLDER\"";
  if (!glb) {
    const std::string path = d.writeGltf(dir, name);
    const std::vector<unsigned char> bytes = readBytes(path);
    std::string text(bytes.begin(), bytes.end());
    text.replace(text.find(marker), marker.size(), extras);
    writeText(path, text);
    return path;
  }
  std::vector<unsigned char> b = d.glbBytes();
  uint32_t length = 0;
  std::memcpy(&length, b.data() + 12, 4);
  std::string text(b.begin() + 20, b.begin() + 20 + length);
  text.replace(text.find(marker), marker.size(), extras);
  while (text.size() % 4) text += ' ';
  std::vector<unsigned char> out(b.begin(), b.begin() + 20);
  out.insert(out.end(), text.begin(), text.end());
  out.insert(out.end(), b.begin() + 20 + length, b.end());
  const uint32_t total = uint32_t(out.size()), jsonLength = uint32_t(text.size());
  std::memcpy(out.data() + 8, &total, 4);
  std::memcpy(out.data() + 12, &jsonLength, 4);
  const std::string path = dir + "/" + name + ".glb";
  writeBytes(path, out.data(), out.size());
  return path;
}

// 30,000 arrays nested in `extras` overflowed the stack inside tinygltf
// (SIGSEGV in render, info and Python): refused before any parser runs,
// past 512 levels (docs/scenes.md "What the loader refuses").
TEST(BadInputFile, DeeplyNestedJsonIsRefused) {
  const std::string dir = tempDir("bad_deep_json");
  // root {, nodes [, nodes[0] {: three levels before extras.
  for (const bool glb : {false, true})
    expectLoadError(withRawExtras(dir, glb ? "deep_glb" : "deep", nestedArrays(30000), glb),
                    {"the JSON nests 30003 arrays and objects deep", "at most 512 levels"});
  expectLoadError(withRawExtras(dir, "limit_plus_one", nestedArrays(510), false), {"nests 513", "512"});
  // At the limit, and brackets inside strings (with escaped quotes) do not count.
  WarningCapture quiet;
  EXPECT_NO_THROW(loadGltf(withRawExtras(dir, "at_limit", nestedArrays(509), false)));
  EXPECT_NO_THROW(loadGltf(withRawExtras(dir, "in_string", "[\"\\\"" + std::string(5000, '[') + "\"]", true)));
  // The CLI: one error line from render and info, no crash.
  const std::string deep = dir + "/deep.gltf";
  std::vector<CliRun> runs(2);
  runs[0].name = "render";
  runs[0].args = {"render", deep, "-o", dir + "/out.exr", "-q", "--res", "8x8", "--spp", "1"};
  runs[0].output = dir + "/out.exr";
  runs[1].name = "info";
  runs[1].args = {"info", deep};
  for (CliRun& r : runs) r.mention = deep + ": the JSON nests 30003";
  runAll(runs, dir);
  for (const CliRun& r : runs) expectOneErrorLine(r);
}

// A scene of no size leaves the automatic camera no distance to stand back
// (its look-at frame was NaN and Embree aborted on ray.valid(), exit 134):
// one error line naming the file, exit non-zero.
TEST(BadInputCli, DegenerateSceneWithAutomaticCameraIsOneErrorLine) {
  const std::string dir = tempDir("bad_cli_degenerate_camera");
  std::vector<std::string> scenes;
  scenes.push_back(dir + "/point.obj");  // a triangle whose three vertices are equal
  writeText(scenes.back(), "v 1 2 3\nv 1 2 3\nv 1 2 3\nf 1 2 3\n");
  scenes.push_back(dir + "/far.obj");  // 10 cm at 1e7: the coordinates collapse to one float
  writeText(scenes.back(), "v 1e7 1e7 1e7\nv 10000000.1 1e7 1e7\nv 1e7 10000000.1 1e7\nf 1 2 3\n");
  for (const double s : {0.0, 1e-25}) {
    GltfBuilder d = quad();
    d.doc["nodes"][0]["scale"] = {s, s, s};
    scenes.push_back(d.writeGltf(dir, s == 0 ? "scale0" : "scale1e-25"));
  }
  // Each is now refused by the load, before a camera is chosen: a scene
  // without extent, or below 2^-40 across, by its size (docs/scenes.md
  // "Scene scale"); a zero scale hides the mesh (docs/scenes.md "What the
  // loader refuses").
  const std::vector<std::string> why = {"the scene is 0 across (its largest extent), below 9.09495e-13",
                                        "the scene is 0 across (its largest extent), below 9.09495e-13",
                                        "the scene has no triangles to render (every mesh is hidden by a zero scale)",
                                        "the scene is 1e-25 across (its largest extent), below 9.09495e-13"};
  std::vector<CliRun> runs;
  for (const std::string& sc : scenes) {
    CliRun r;
    r.name = sc;
    r.output = dir + "/out" + std::to_string(runs.size()) + ".exr";
    r.args = {"render", sc, "-o", r.output, "-q", "--res", "8x8", "--spp", "1"};
    r.mention = sc + ": " + why[runs.size()];
    runs.push_back(r);
  }
  // info selects the camera too (for --subdiv-edge), and says the same.
  CliRun info = runs[0];
  info.name = "info";
  info.args = {"info", scenes[0]};
  info.output = "";
  runs.push_back(info);
  runAll(runs, dir);
  for (const CliRun& r : runs) expectOneErrorLine(r);
}

// TBB crashed (SIGSEGV) with a parallelism limit above 65536, and
// 2147483647 took all memory: every subcommand taking --threads refuses
// more than kMaxThreads (4096) before loading anything.
TEST(BadInputCli, ThreadsAboveTheLimitAreRefused) {
  const std::string dir = tempDir("bad_cli_threads");
  const std::string scene = writeGoodScene(dir);
  std::vector<CliRun> runs;
  for (const std::string n : {"4097", "65537", "2147483647"}) {
    CliRun r;
    r.mention = "--threads: at most 4096 (0 = all cores), got " + n;
    r.name = "render " + n;
    r.output = dir + "/out" + n + ".exr";
    r.args = {"render", scene, "-o", r.output, "-q", "--res", "8x8", "--spp", "1", "--threads", n};
    runs.push_back(r);
    r.name = "compare " + n;
    r.output = dir + "/cmp" + n;
    r.args = {"compare", scene, "-o", r.output, "-c", "ao", "-q", "--res", "8x8", "--spp", "1", "--threads", n};
    runs.push_back(r);
    r.name = "fit " + n;
    r.output = dir + "/fit" + n + ".json";
    r.args = {"fit", scene, "-o", r.output, "-q", "--res", "8x8", "--spp", "1", "--threads", n};
    runs.push_back(r);
  }
  runAll(runs, dir);
  for (const CliRun& r : runs) expectOneErrorLine(r);
}

TEST(BadInputCli, FailedRenderLeavesTheExistingOutputUntouched) {
  const std::string dir = tempDir("bad_cli_overwrite");
  const std::string scene = writeGoodScene(dir);
  const std::string out = dir + "/pass.exr";
  std::vector<CliRun> first(1);
  first[0].name = "good render";
  first[0].args = {"render", scene, "-o", out, "--res", "8x8", "--spp", "1", "-q"};
  runAll(first, dir);
  ASSERT_EQ(first[0].exitCode, 0) << first[0].stderrText;
  ASSERT_EQ(first[0].stderrText, "");
  const std::vector<unsigned char> before = readBytes(out);
  ASSERT_FALSE(before.empty());

  const std::string garbage = dir + "/garbage.gltf";
  writeText(garbage, "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [{\"mesh\": 5}]}");
  std::vector<CliRun> runs(3);
  runs[0].name = "bad scene";
  runs[0].args = {"render", garbage, "-o", out, "--res", "8x8", "--spp", "1", "-q"};
  runs[0].mention = "nodes[0].mesh";
  runs[1].name = "missing scene";
  runs[1].args = {"render", dir + "/missing.gltf", "-o", out, "--res", "8x8", "--spp", "1", "-q"};
  runs[1].mention = "missing.gltf";
  runs[2].name = "bad camera";
  runs[2].args = {"render", scene, "-o", out, "--res", "8x8", "--spp", "1", "-q", "--camera", "9"};
  runs[2].mention = "--camera";
  runAll(runs, dir);
  for (const CliRun& r : runs) {
    expectOneErrorLine(r);
    EXPECT_EQ(readBytes(out), before) << r.name << ": the existing output changed";
  }
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    EXPECT_EQ(name.find(".tmp"), std::string::npos) << "temporary file left behind: " << name;
  }
}

// Messages that did not say what was wrong: a checkpoint path that is a
// directory (a libstdc++ message), --target-error 1e300 ("must be finite"),
// an empty --frame (taken as no frame: out.####.exr written literally).
TEST(BadInputCli, UnclearMessagesNameTheOptionAndTheLimit) {
  const std::string dir = tempDir("bad_cli_messages");
  const std::string scene = writeGoodScene(dir);
  fs::create_directories(dir + "/cp.exr.checkpoint");
  std::vector<CliRun> runs(3);
  runs[0].name = "checkpoint is a directory";
  runs[0].args = {"render", scene, "-o", dir + "/cp.exr", "--res", "8x8", "--spp", "1", "-q", "--checkpoint", "0"};
  runs[0].output = dir + "/cp.exr";
  runs[0].mention = "cp.exr.checkpoint: is a directory, not a regular file";
  runs[1].name = "target error beyond float";
  runs[1].args = {"render", scene, "-o", dir + "/te.exr", "--res", "8x8", "--spp", "1", "-q", "--target-error", "1e300"};
  runs[1].output = dir + "/te.exr";
  runs[1].mention = "--target-error: 1e+300 is above the largest standard error a pass holds (3.40282";
  runs[2].name = "empty frame";
  runs[2].args = {"render", scene, "-o", dir + "/f.####.exr", "--res", "8x8", "--spp", "1", "-q", "--frame", ""};
  runs[2].output = dir + "/f.####.exr";
  runs[2].mention = "--frame";
  runAll(runs, dir);
  for (const CliRun& r : runs) expectOneErrorLine(r);
  EXPECT_NE(runs[2].stderrText.find("empty frame number"), std::string::npos) << runs[2].stderrText;
}

}  // namespace
}  // namespace obscura::test
