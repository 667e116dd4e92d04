// Regression tests for what fuzzing the loaders and the parameter parser
// found (fuzz/, docs/testing.md "Fuzzing"), the parse-once scene source, and the
// fuzz seed corpus. In process: each test builds its file with GltfBuilder.
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "app/options.h"
#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "core/image/image_io.h"
#include <obscura/integrator.h>
#include <obscura/params.h>
#include "tests/fuzz_seeds.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// The message loading `path` throws ("" if it loads).
std::string loadError(const std::string& path, const LoadOptions& options = {}) {
  try {
    loadScene(path, options);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

std::string readText(const std::string& path) {
  const std::vector<unsigned char> b = readBytes(path);
  return std::string(b.begin(), b.end());
}

// Every byte printable: no control byte, as the CLI prints the line.
bool printableLine(const std::string& s) {
  for (const char c : s)
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return false;
  return true;
}

// A quad (accessor 0 = POSITION, 1 = indices) under node 0, scene 0.
GltfBuilder quadScene() {
  GltfBuilder g;
  const int m = g.quadMesh(1);
  g.scene({g.node({{"mesh", m}})});
  return g;
}

// --- accessors ----------------------------------------------------------------

// count x stride overflowing size_t used to pass the bounds check and stop
// only at the allocation ("cannot create std::vector larger than max_size()").
TEST(LoaderHardening, AccessorCountOverflowIsNamed) {
  const std::string dir = tempDir("hard_count");
  GltfBuilder g = quadScene();
  g.doc["accessors"][0]["count"] = 2305843009213693951ULL;  // 2^61 - 1: x 12 wraps around 2^64
  const std::string path = g.writeGltf(dir, "scene");
  EXPECT_EQ(loadError(path), path + ": meshes[0].primitives[0].attributes.POSITION (accessors[0]): count 2305843009213693951 x "
                                    "stride 12 from byteOffset 0 extends past the end of its bufferView (bufferViews[0], "
                                    "byteLength 48)");
  // One element too many, the smallest overrun.
  g.doc["accessors"][0]["count"] = 5;
  EXPECT_NE(loadError(g.writeGltf(dir, "five")).find("count 5 x stride 12"), std::string::npos);
  // byteOffset past the view's end.
  g.doc["accessors"][0]["count"] = 4;
  g.doc["accessors"][0]["byteOffset"] = 4;
  EXPECT_NE(loadError(g.writeGltf(dir, "offset")).find("from byteOffset 4 extends past"), std::string::npos);
}

// --- buffers and images that are not files ---------------------------------------

// A buffer uri "." names the scene's directory: tinygltf reported "out of memory".
TEST(LoaderHardening, BufferUriThatIsADirectory) {
  const std::string dir = tempDir("hard_uri");
  GltfBuilder g = quadScene();
  g.doc["buffers"] = json::array({{{"uri", "."}, {"byteLength", g.bin.size()}}});
  const std::string path = g.writeGltf(dir, "dot");
  EXPECT_EQ(loadError(path), path + ": buffers[0].uri: '.' is not a file (a directory)");
  g.doc["buffers"][0]["uri"] = "sub%20dir";  // percent-escaped, as tinygltf decodes it
  std::filesystem::create_directories(dir + "/sub dir");
  EXPECT_EQ(loadError(g.writeGltf(dir, "escaped")), dir + "/escaped.gltf: buffers[0].uri: 'sub%20dir' is not a file (a directory)");
  g.doc["buffers"][0]["uri"] = "/dev/null";  // a device is no file either
  EXPECT_NE(loadError(g.writeGltf(dir, "device")).find("buffers[0].uri: '/dev/null' is not a file"), std::string::npos);
  g.doc["buffers"][0].erase("uri");
  g.doc["images"] = json::array({{{"uri", "."}}});
  EXPECT_NE(loadError(g.writeGltf(dir, "image")).find("images[0].uri: '.' is not a file (a directory)"), std::string::npos);
}

// "%zz.bin" said only "out of memory": tinygltf decoded "%zz" to a NUL byte,
// which named the scene's directory, and read it. A malformed escape is now
// named; and whatever tinygltf's own decoding makes of a uri ("a+b" is "a b"
// to it, not to the check above), its read refuses what is not a file.
TEST(LoaderHardening, MalformedUriEscapeAndTinygltfDecodingAreNamed) {
  const std::string dir = tempDir("hard_uri_escape");
  GltfBuilder g = quadScene();
  g.doc["buffers"] = json::array({{{"uri", "%zz.bin"}, {"byteLength", g.bin.size()}}});
  const std::string path = g.writeGltf(dir, "zz");
  EXPECT_EQ(loadError(path), path + ": buffers[0].uri: '%zz.bin' has a malformed percent escape at character 0 "
                                    "(a '%' takes two hex digits: %20 for a space)");
  std::filesystem::create_directories(dir + "/a b.bin");
  g.doc["buffers"][0]["uri"] = "a+b.bin";
  const std::string plus = g.writeGltf(dir, "plus");
  const std::string m = loadError(plus);
  EXPECT_EQ(m.rfind(plus + ": ", 0), 0u) << m;
  EXPECT_NE(m.find("a b.bin' is not a regular file (a directory)"), std::string::npos) << m;
  EXPECT_EQ(m.find("memory"), std::string::npos) << m;
}

// --- JSON types tinygltf silently ignores ---------------------------------------

// Each used to load with the field dropped (the mesh, the transform, the
// indices...): now an error naming it.
TEST(LoaderHardening, WrongJsonTypesAreErrors) {
  const std::string dir = tempDir("hard_types");
  struct Case {
    std::function<void(json&)> edit;
    std::string expected;
  };
  const std::vector<Case> cases = {
      {[](json& d) { d["nodes"][0]["mesh"] = "0"; }, "nodes[0].mesh: expected a non-negative integer, got a string"},
      {[](json& d) { d["nodes"][0]["mesh"] = -1; }, "nodes[0].mesh: expected a non-negative integer, got the integer -1"},
      {[](json& d) { d["nodes"][0]["mesh"] = 4294967296LL; },
       "nodes[0].mesh: expected a non-negative integer, got the integer 4294967296"},
      {[](json& d) { d["nodes"][0]["matrix"] = json::array({"1", 0}); }, "nodes[0].matrix[0]: expected a number, got a string"},
      {[](json& d) { d["nodes"][0]["translation"] = 1; }, "nodes[0].translation: expected an array of numbers, got the integer 1"},
      {[](json& d) { d["nodes"][0]["children"] = json::array({1.5}); },
       "nodes[0].children[0]: expected a non-negative integer, got the number 1.5"},
      {[](json& d) { d["meshes"][0]["primitives"][0]["indices"] = "1"; },
       "meshes[0].primitives[0].indices: expected a non-negative integer, got a string"},
      {[](json& d) { d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json::object(); },
       "meshes[0].primitives[0].attributes.POSITION: expected a non-negative integer, got an object"},
      {[](json& d) { d["meshes"][0]["primitives"][0]["mode"] = "4"; }, "meshes[0].primitives[0].mode: expected an integer, got a string"},
      {[](json& d) { d["meshes"][0]["primitives"] = json::array({1}); }, "meshes[0].primitives[0]: expected an object, got the integer 1"},
      {[](json& d) { d["accessors"][1]["bufferView"] = true; }, "accessors[1].bufferView: expected a non-negative integer, got a boolean"},
      {[](json& d) { d["bufferViews"][0]["byteOffset"] = "0"; }, "bufferViews[0].byteOffset: expected a non-negative integer, got a string"},
      {[](json& d) { d["scenes"][0]["nodes"] = 0; }, "scenes[0].nodes: expected an array of non-negative integers, got the integer 0"},
      {[](json& d) { d["scene"] = "0"; }, "scene: expected a non-negative integer, got a string"},
      {[](json& d) { d["nodes"] = json::object(); }, "nodes: expected an array of objects, got an object"},
      {[](json& d) { d["materials"] = json::array({{{"pbrMetallicRoughness", {{"baseColorFactor", "red"}}}}}); },
       "materials[0].pbrMetallicRoughness.baseColorFactor: expected an array of numbers, got a string"},
      {[](json& d) { d["cameras"] = json::array({{{"type", "perspective"}, {"perspective", {{"yfov", "wide"}}}}}); },
       "cameras[0].perspective.yfov: expected a number, got a string"},
      {[](json& d) { d["textures"] = json::array({{{"source", nullptr}}}); }, "textures[0].source: expected a non-negative integer, got null"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    GltfBuilder g = quadScene();
    cases[i].edit(g.doc);
    const std::string path = g.writeGltf(dir, "case" + std::to_string(i));
    EXPECT_EQ(loadError(path), path + ": " + cases[i].expected) << "case " << i;
    // The same check reads a .glb's JSON chunk.
    const std::string glb = g.writeGlb(dir, "case" + std::to_string(i));
    EXPECT_EQ(loadError(glb), glb + ": " + cases[i].expected) << "case " << i << " (glb)";
  }
  // Extras are the application's: any type.
  GltfBuilder g = quadScene();
  g.doc["nodes"][0]["extras"] = {{"mesh", "anything"}};
  EXPECT_EQ(loadError(g.writeGltf(dir, "extras")), "");
}

// --- nothing to render ---------------------------------------------------------

TEST(LoaderHardening, SceneWithoutTrianglesIsRefused) {
  const std::string dir = tempDir("hard_empty");
  GltfBuilder none;
  none.scene({none.node({{"name", "empty"}})});
  const std::string path = none.writeGltf(dir, "none");
  EXPECT_EQ(loadError(path), path + ": the scene has no triangles to render");
  // Only a line primitive (skipped with a warning): nothing either.
  GltfBuilder lines;
  lines.push("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", lines.positions({{0, 0, 0}, {1, 0, 0}})}}},
                                                      {"mode", kLines}}})}});
  lines.scene({lines.node({{"mesh", 0}})});
  WarningCapture warnings;
  const std::string lpath = lines.writeGltf(dir, "lines");
  EXPECT_EQ(loadError(lpath), lpath + ": the scene has no triangles to render");
}

// --- printable error lines -------------------------------------------------------

TEST(LoaderHardening, ErrorLinesArePrintable) {
  EXPECT_EQ(printable("a\x07z"), "a\\x07z");
  EXPECT_EQ(printable("line\nbreak\ttab\r"), "line break tab");
  EXPECT_EQ(printable("caf\xc3\xa9 \xff \x7f"), "caf\xc3\xa9 \\xff \\x7f");  // UTF-8 kept, stray bytes escaped
  EXPECT_EQ(printable("cut \xe2\x82"), "cut \\xe2\\x82");                  // a truncated sequence
  EXPECT_EQ(std::string(Error("x\x01y").what()), "x\\x01y");
  // A JSON parse error quoting control bytes from the file.
  const std::string dir = tempDir("hard_printable");
  const std::string path = dir + "/bell.gltf";
  writeText(path, std::string("{\"asset\": {\"version\": \"2.0\"}, \x07\x01\x1b[31m"));
  const std::string e = loadError(path);
  EXPECT_NE(e.find(path + ": not a valid glTF 2.0 file"), std::string::npos) << e;
  EXPECT_TRUE(printableLine(e)) << e;
  // A warning too.
  WarningCapture warnings;
  Log::warn("w\x07");
  ASSERT_EQ(warnings.messages.size(), 1u);
  EXPECT_EQ(warnings.messages[0], "w\\x07");
}

// --- the range Embree traces -----------------------------------------------------

// A vertex at 1e20 made the auto camera land beyond Embree's range, and
// Embree aborted on an invalid ray (its assertion ray.valid()).
TEST(LoaderHardening, CoordinatesBeyondEmbreeRange) {
  const std::string dir = tempDir("hard_range");
  GltfBuilder g;
  const int pos = g.positions({{0, 0, 0}, {1e20f, 0, 0}, {0, 1, 0}});
  g.push("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", pos}}}}})}});
  g.scene({g.node({{"mesh", 0}})});
  std::string path = g.writeGltf(dir, "far");
  EXPECT_EQ(loadError(path), path + ": meshes[0].primitives[0].attributes.POSITION (accessors[0]): vertex 1 coordinate 1e+20 "
                                    "is outside the range Embree traces (|x| <= 1e+16)");
  // Within range in the mesh, beyond it after the node's scale...
  GltfBuilder s = quadScene();
  s.doc["nodes"][0]["scale"] = {1e17, 1, 1};
  path = s.writeGltf(dir, "scaled");
  EXPECT_EQ(loadError(path), path + ": the scene's bounds reach -1e+17 (after node transforms), outside the range Embree traces "
                                    "(|x| <= 1e+16)");
  // ... or an instance's translation (a mesh used twice is instanced).
  GltfBuilder inst = quadScene();
  inst.doc["scenes"][0]["nodes"].push_back(inst.node({{"mesh", 0}, {"translation", {0, 3e16, 0}}}));
  EXPECT_NE(loadError(inst.writeGltf(dir, "instance")).find("the scene's bounds reach 3e+16"), std::string::npos);
  // At the limit it loads.
  GltfBuilder edge = quadScene();
  edge.doc["nodes"][0]["scale"] = {1e16, 1e16, 1};
  EXPECT_EQ(loadError(edge.writeGltf(dir, "edge")), "");
}

TEST(LoaderHardening, CameraBeyondEmbreeRange) {
  const std::string dir = tempDir("hard_camera");
  GltfBuilder g = quadScene();
  g.push("cameras", perspective("far", 0.8, 0.1));
  g.doc["scenes"][0]["nodes"].push_back(g.node({{"camera", 0}, {"translation", {0, 0, 1e17}}}));
  std::string path = g.writeGltf(dir, "far");
  EXPECT_EQ(loadError(path), path + ": nodes[1] (cameras[0]): camera position (0, 0, 1e+17) is outside the range Embree traces "
                                    "(|x| <= 1e+16)");
  g.doc["nodes"][1]["translation"] = {0, 0, 3};
  g.doc["cameras"][0]["perspective"]["znear"] = 1e20;
  path = g.writeGltf(dir, "znear");
  EXPECT_EQ(loadError(path), path + ": cameras[0].perspective.znear: 1e+20 is outside the range Embree traces (<= 1e+16)");
  // A zfar beyond the range is as good as none (no geometry lies beyond it).
  g.doc["cameras"][0]["perspective"]["znear"] = 0.1;
  g.doc["cameras"][0]["perspective"]["zfar"] = 1e30;
  auto scene = loadScene(g.writeGltf(dir, "zfar"));
  ASSERT_EQ(scene->cameras.size(), 1u);
  EXPECT_EQ(scene->cameras[0].zfar, kInfinity);

  // The automatic camera framing a scene near the limit through a very
  // narrow image would stand ~1.5e5 bounding radii away: refused.
  GltfBuilder big = quadScene();
  big.doc["nodes"][0]["scale"] = {1e15, 1e15, 1};
  path = big.writeGltf(dir, "big");
  auto bigScene = loadScene(path);
  EXPECT_NO_THROW(selectCamera(*bigScene, "auto", 16.0f / 9.0f));
  try {
    selectCamera(*bigScene, "auto", 1.0f / 65536.0f);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": the automatic camera (--camera auto): camera position ("), std::string::npos)
        << e.what();
  }
}

// --- parse once ------------------------------------------------------------------

// SceneSource parses the file once: scenes build from it after the file is
// gone, unrefined (the adaptive camera probe) and refined, and equal what a
// fresh load gives.
TEST(LoaderHardening, SceneSourceParsesOnce) {
  const std::string dir = tempDir("hard_once");
  GltfBuilder g;
  const int m = g.quadMesh(1, -1, true);
  g.doc["meshes"][size_t(m)]["extras"] = {{"obscura", {{"subdivision", {{"scheme", "catmull-clark"}, {"level", 2}}}}}};
  g.scene({g.node({{"mesh", m}})});
  const std::string path = g.writeGlb(dir, "sub");
  const auto fresh = loadScene(path);
  LoadOptions probe;
  probe.unrefined = true;
  const auto freshProbe = loadScene(path, probe);
  const SceneSource source(path);
  std::filesystem::remove(path);
  const auto unrefined = source.build(probe);
  const auto refined = source.build({});
  EXPECT_EQ(unrefined->stats().renderedTriangles, freshProbe->stats().renderedTriangles);
  EXPECT_EQ(unrefined->stats().renderedTriangles, 2u);  // the cage's two triangles
  EXPECT_EQ(refined->stats().renderedTriangles, fresh->stats().renderedTriangles);
  EXPECT_GT(refined->stats().renderedTriangles, 2u);
}

// --- parameters ------------------------------------------------------------------

// Every value a parameter set reports (the EXR header's text) parses back to
// itself, for each integrator's defaults.
TEST(LoaderHardening, ParameterValuesRoundTrip) {
  for (const IntegratorDescriptor& d : IntegratorRegistry::instance().all()) {
    ParamSet p(d.params, d.name), q(d.params, d.name);
    for (const auto& [key, value] : p.values()) q.set(key, value);
    EXPECT_EQ(p.values(), q.values()) << d.name;
  }
}

// An Int parameter declared without a range (as a plugin may) took any
// long long and converted it to int: "n=4294967297" became n = 1.
TEST(LoaderHardening, IntParameterBeyondIntIsOutOfRange) {
  ParamSpec n;
  n.name = "n";
  n.type = ParamType::Int;
  n.defaultValue = "0";
  ParamSet p({n}, "plugin");
  p.set("n", "2147483647");
  EXPECT_EQ(p.getInt("n"), 2147483647);
  p.set("n", "-2147483648");
  EXPECT_EQ(p.getInt("n"), -2147483647 - 1);
  for (const std::string v : {"2147483648", "4294967297", "-2147483649"}) {
    try {
      p.set("n", v);
      ADD_FAILURE() << v << " accepted as " << p.getInt("n");
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()), "integrator 'plugin': parameter 'n': out of range (got '" + v + "', expected int [-inf, inf])");
    }
  }
}

// --- the fuzz seed corpus --------------------------------------------------------

// Every seed is a valid input: the glTF scenes and OBJ cages load (with the
// height map the displacement extras name), every parameter seed parses.
TEST(LoaderHardening, FuzzSeedsAreValid) {
  const std::string dir = tempDir("hard_seeds");
  writeFuzzSeeds(dir);
  std::vector<unsigned char> rgb(4 * 4 * 3, 128);
  writePngRgb8(dir + "/gltf/height.png", 4, 4, rgb.data());
  size_t gltf = 0, obj = 0, params = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir + "/gltf")) {
    if (e.path().extension() == ".png") continue;
    SCOPED_TRACE(e.path().string());
    auto scene = loadScene(e.path().string());
    EXPECT_GT(scene->stats().renderedTriangles, 0u);
    ++gltf;
  }
  size_t badObj = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir + "/obj")) {
    SCOPED_TRACE(e.path().string());
    const std::string text = readText(e.path().string());
    ASSERT_FALSE(text.empty());
    const std::string path = dir + "/cage.obj";
    writeText(path, text.substr(1));
    LoadOptions o;
    o.subdivision = true;
    o.scheme = text[0] & 1 ? SubdivisionScheme::Loop : SubdivisionScheme::CatmullClark;
    o.subdivisionLevel = (text[0] >> 1) & 3;
    if (e.path().filename().string().rfind("bad_", 0) == 0) {  // the error path's seeds
      EXPECT_THROW(loadScene(path, o), Error);
      ++badObj;
      continue;
    }
    WarningCapture quiet;  // mtllib names a file that is not there
    EXPECT_GT(loadScene(path, o)->stats().renderedTriangles, 0u);
    ++obj;
  }
  // fuzz/fuzz_json.cpp's whole documents (mode byte even) load; the extras
  // seeds are JSON values.
  size_t jsonSeeds = 0, cameraSeeds = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir + "/json")) {
    SCOPED_TRACE(e.path().string());
    const std::string text = readText(e.path().string());
    ASSERT_FALSE(text.empty());
    ++jsonSeeds;
    if (text[0] % 2) {
      EXPECT_FALSE(nlohmann::json::parse(text.substr(1), nullptr, false).is_discarded());
      continue;
    }
    writeText(dir + "/doc.gltf", text.substr(1));
    WarningCapture quiet;
    EXPECT_GT(loadScene(dir + "/doc.gltf")->stats().renderedTriangles, 0u);
  }
  for (const auto& e : std::filesystem::directory_iterator(dir + "/camera")) {
    EXPECT_EQ((readText(e.path().string()).size() - 1) % 8, 0u) << e.path();
    ++cameraSeeds;
  }
  EXPECT_EQ(badObj, 4u);
  EXPECT_EQ(jsonSeeds, 7u);
  EXPECT_EQ(cameraSeeds, 12u);
  for (const auto& e : std::filesystem::directory_iterator(dir + "/params")) {
    SCOPED_TRACE(e.path().string());
    std::istringstream in(readText(e.path().string()));
    std::string name, line;
    std::getline(in, name);
    const IntegratorDescriptor& d = IntegratorRegistry::instance().find(name);
    ParamSet p(d.params, d.name);
    while (std::getline(in, line)) EXPECT_NO_THROW(p.setAssignment(line)) << line;
    ++params;
  }
  EXPECT_EQ(gltf, 5u);
  EXPECT_EQ(obj, 14u);
  EXPECT_GE(params, IntegratorRegistry::instance().all().size());
}

}  // namespace
}  // namespace obscura::test

namespace obscura::test {
namespace {

// A bufferView longer than its buffer is refused before tinygltf reads it
// (an image in such a view was copied past the buffer's end: a fuzz finding).
TEST(LoaderHardening, BufferViewPastItsBufferIsRefused) {
  const std::string dir = tempDir("loader_view_past_buffer");
  const std::string path = dir + "/view.gltf";
  std::ofstream(path) << R"({"asset":{"version":"2.0"},)"
                      << R"("buffers":[{"byteLength":4,"uri":"data:application/octet-stream;base64,AAAAAA=="}],)"
                      << R"("bufferViews":[{"buffer":0,"byteOffset":2,"byteLength":8}]})";
  EXPECT_EQ(loadError(path), path + ": bufferViews[0]: byteOffset 2 + byteLength 8 runs past buffers[0].byteLength 4");
}

}  // namespace
}  // namespace obscura::test
