// Bad input: every malformed file or argument gives one clear error naming
// the file and the field (obscura::Error in process; one "obscura: error:"
// line and a non-zero exit from the CLI), never a crash, and never a
// damaged or half-written output file.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "core/error.h"
#include "core/gltf_loader.h"
#include "core/scene.h"
#include "core/texture.h"
#include "tests/support.h"

extern char** environ;

namespace obscura::test {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::vector<unsigned char> readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void writeAll(const std::string& path, const void* data, size_t n) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(static_cast<const char*>(data), std::streamsize(n));
  ASSERT_TRUE(out.good()) << path;
}
void writeAll(const std::string& path, const std::string& s) { writeAll(path, s.data(), s.size()); }

constexpr int kFloat = 5126, kUShort = 5123;

// A minimal glTF writer: JSON document plus one binary buffer.
struct Doc {
  json j = {{"asset", {{"version", "2.0"}}}};
  std::vector<unsigned char> bin;

  int push(const char* array, json obj) {
    json& a = j[array];
    if (!a.is_array()) a = json::array();
    a.push_back(std::move(obj));
    return int(a.size()) - 1;
  }
  int view(const void* data, size_t bytes) {
    while (bin.size() % 4) bin.push_back(0);
    const size_t off = bin.size();
    bin.insert(bin.end(), static_cast<const unsigned char*>(data), static_cast<const unsigned char*>(data) + bytes);
    return push("bufferViews", {{"buffer", 0}, {"byteOffset", off}, {"byteLength", bytes}});
  }
  int accessor(int bufferView, int componentType, size_t count, const char* type) {
    return push("accessors", {{"bufferView", bufferView}, {"componentType", componentType}, {"count", count}, {"type", type}});
  }
  int positions(const std::vector<Vec3>& p) { return accessor(view(p.data(), p.size() * 12), kFloat, p.size(), "VEC3"); }
  int indices(const std::vector<uint16_t>& i) { return accessor(view(i.data(), i.size() * 2), kUShort, i.size(), "SCALAR"); }
  // accessors[0] = 4 positions, accessors[1] = 6 indices: one quad mesh,
  // placed by nodes[0] in scenes[0].
  static Doc quad(std::vector<Vec3> p = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                  std::vector<uint16_t> i = {0, 1, 2, 0, 2, 3}) {
    Doc d;
    const int pos = d.positions(p);
    const int idx = d.indices(i);
    d.push("meshes", {{"primitives", json::array({{{"attributes", {{"POSITION", pos}}}, {"indices", idx}}})}});
    d.push("nodes", {{"mesh", 0}});
    d.j["scenes"] = json::array({{{"nodes", {0}}}});
    d.j["scene"] = 0;
    return d;
  }
  json& prim() { return j["meshes"][0]["primitives"][0]; }

  std::string writeGltf(const std::string& dir, const std::string& name) const {
    json d = j;
    if (!bin.empty() && !d.contains("buffers")) {
      d["buffers"] = json::array({{{"uri", name + ".bin"}, {"byteLength", bin.size()}}});
      writeAll(dir + "/" + name + ".bin", bin.data(), bin.size());
    }
    writeAll(dir + "/" + name + ".gltf", d.dump(1));
    return dir + "/" + name + ".gltf";
  }
  std::vector<unsigned char> glbBytes() const {
    json d = j;
    std::vector<unsigned char> b = bin;
    while (b.size() % 4) b.push_back(0);
    d["buffers"] = json::array({{{"byteLength", bin.size()}}});
    std::string text = d.dump();
    while (text.size() % 4) text.push_back(' ');
    std::vector<unsigned char> out;
    const auto u32 = [&](uint32_t v) {
      for (int k = 0; k < 4; ++k) out.push_back((unsigned char)(v >> (8 * k)));
    };
    out.insert(out.end(), {'g', 'l', 'T', 'F'});
    u32(2);
    u32(uint32_t(12 + 8 + text.size() + 8 + b.size()));
    u32(uint32_t(text.size()));
    u32(0x4E4F534A);
    out.insert(out.end(), text.begin(), text.end());
    u32(uint32_t(b.size()));
    u32(0x004E4942);
    out.insert(out.end(), b.begin(), b.end());
    return out;
  }
};

// Silences (and counts) warnings for the lifetime of the object.
struct QuietWarnings {
  std::vector<std::string> messages;
  QuietWarnings() {
    Log::resetOnce();
    Log::setWarningSink([this](const std::string& m) { messages.push_back(m); });
  }
  ~QuietWarnings() { Log::setWarningSink(nullptr); }
};

// Loading `path` must throw obscura::Error whose one-line message contains
// every needle (the file's path is always one of them).
void expectLoadError(const std::string& path, const std::vector<std::string>& needles) {
  QuietWarnings quiet;
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
  writeAll(dir + "/empty.gltf", "");
  expectLoadError(dir + "/empty.gltf", {"glTF"});
  writeAll(dir + "/garbage.gltf", "this is { not json at all ]\n\x01\x02");
  expectLoadError(dir + "/garbage.gltf", {"glTF"});
  writeAll(dir + "/array.gltf", "[1, 2, 3]");
  expectLoadError(dir + "/array.gltf", {"glTF"});
}

TEST(BadInputFile, CorruptAndTruncatedGlb) {
  const std::string dir = tempDir("bad_glb");
  const std::vector<unsigned char> good = Doc::quad().glbBytes();
  // The untouched file loads.
  writeAll(dir + "/good.glb", good.data(), good.size());
  EXPECT_NO_THROW(loadGltf(dir + "/good.glb"));
  // Truncated in the header, in the JSON chunk and in the BIN chunk.
  for (size_t n : {size_t(4), size_t(11), size_t(20), good.size() / 2, good.size() - 8, good.size() - 1}) {
    SCOPED_TRACE("truncated to " + std::to_string(n) + " of " + std::to_string(good.size()) + " bytes");
    const std::string p = dir + "/trunc" + std::to_string(n) + ".glb";
    writeAll(p, good.data(), n);
    expectLoadError(p, {"glTF"});
  }
  // Magic, then garbage.
  std::vector<unsigned char> bad = {'g', 'l', 'T', 'F'};
  for (int k = 0; k < 200; ++k) bad.push_back((unsigned char)(k * 37 + 11));
  writeAll(dir + "/garbage.glb", bad.data(), bad.size());
  expectLoadError(dir + "/garbage.glb", {"glTF"});
  // A JSON chunk length beyond the file.
  std::vector<unsigned char> longChunk = good;
  longChunk[12] = 0xff, longChunk[13] = 0xff, longChunk[14] = 0x00;
  writeAll(dir + "/longchunk.glb", longChunk.data(), longChunk.size());
  expectLoadError(dir + "/longchunk.glb", {"glTF"});
}

// Every prefix of a valid .glb: an Error or (never, here) a scene; no crash.
TEST(BadInputFile, EveryTruncationOfAGlbIsAnError) {
  const std::string dir = tempDir("bad_glb_prefixes");
  const std::vector<unsigned char> good = Doc::quad().glbBytes();
  const std::string p = dir + "/t.glb";
  QuietWarnings quiet;
  for (size_t n = 0; n < good.size(); ++n) {
    writeAll(p, good.data(), n);
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
  expectLoadError(Doc::quad({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {0, 1, 2, 0, 2, 7}).writeGltf(dir, "m"),
                  {"meshes[0].primitives[0].indices", "index 7", "element 5"});
}

TEST(BadInputFile, IndexCountNotAMultipleOfThree) {
  const std::string dir = tempDir("bad_index_count");
  expectLoadError(Doc::quad({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {0, 1, 2, 0}).writeGltf(dir, "m"),
                  {"meshes[0].primitives[0].indices", "multiple of 3"});
}

TEST(BadInputFile, NaNAndInfinityInPosition) {
  const std::string dir = tempDir("bad_nan");
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  expectLoadError(Doc::quad({{0, 0, 0}, {1, nan, 0}, {1, 1, 0}, {0, 1, 0}}).writeGltf(dir, "nan"),
                  {"meshes[0].primitives[0].attributes.POSITION", "element 1"});
  expectLoadError(Doc::quad({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, -inf}}).writeGltf(dir, "inf"),
                  {"attributes.POSITION", "element 3"});
}

TEST(BadInputFile, AccessorPastItsBufferView) {
  const std::string dir = tempDir("bad_accessor");
  Doc d = Doc::quad();
  d.j["accessors"][0]["count"] = 5;  // 60 bytes in a 48-byte view
  expectLoadError(d.writeGltf(dir, "count"), {"accessors[0]", "POSITION", "bufferView"});
  Doc o = Doc::quad();
  o.j["accessors"][1]["byteOffset"] = 4;  // 6 indices from byte 4 of a 12-byte view
  expectLoadError(o.writeGltf(dir, "offset"), {"accessors[1]", "indices", "bufferView"});
  // A count whose byte size overflows size_t.
  Doc h = Doc::quad();
  h.j["accessors"][0]["count"] = uint64_t(1) << 62;
  expectLoadError(h.writeGltf(dir, "huge"), {"accessors[0]", "POSITION"});
  // A stride smaller than the element.
  Doc s = Doc::quad();
  s.j["bufferViews"][0]["byteStride"] = 4;
  expectLoadError(s.writeGltf(dir, "stride"), {"accessors[0]", "byteStride"});
}

TEST(BadInputFile, BufferViewPastItsBuffer) {
  const std::string dir = tempDir("bad_bufferview");
  Doc d = Doc::quad();
  d.j["bufferViews"][1]["byteLength"] = 4096;
  expectLoadError(d.writeGltf(dir, "len"), {"bufferViews[1]"});
  Doc o = Doc::quad();
  o.j["bufferViews"][0]["byteOffset"] = 1000;
  expectLoadError(o.writeGltf(dir, "off"), {"bufferViews[0]"});
}

TEST(BadInputFile, WrongAccessorTypesAndMissingAttributes) {
  const std::string dir = tempDir("bad_types");
  Doc v2 = Doc::quad();
  v2.j["accessors"][0]["type"] = "VEC2";
  expectLoadError(v2.writeGltf(dir, "vec2"), {"POSITION", "VEC3"});
  Doc noPos = Doc::quad();
  noPos.prim()["attributes"] = {{"NORMAL", 0}};
  expectLoadError(noPos.writeGltf(dir, "nopos"), {"meshes[0].primitives[0]", "POSITION"});
  Doc badAcc = Doc::quad();
  badAcc.prim()["attributes"]["POSITION"] = 42;
  expectLoadError(badAcc.writeGltf(dir, "badacc"), {"POSITION", "42"});
  Doc floatIdx = Doc::quad();
  floatIdx.j["accessors"][1]["componentType"] = kFloat;
  floatIdx.j["accessors"][1]["count"] = 3;
  expectLoadError(floatIdx.writeGltf(dir, "floatidx"), {"indices"});
  Doc normals = Doc::quad();
  normals.prim()["attributes"]["NORMAL"] = normals.positions({{0, 0, 1}, {0, 0, 1}});
  expectLoadError(normals.writeGltf(dir, "normals"), {"NORMAL", "count"});
}

TEST(BadInputFile, MissingBin) {
  const std::string dir = tempDir("bad_bin");
  const std::string path = Doc::quad().writeGltf(dir, "mesh");
  fs::remove(dir + "/mesh.bin");
  expectLoadError(path, {"mesh.bin"});
  // Present but shorter than buffers[0].byteLength.
  Doc d = Doc::quad();
  const std::string p2 = d.writeGltf(dir, "short");
  fs::resize_file(dir + "/short.bin", d.bin.size() - 4);
  expectLoadError(p2, {"short.bin"});
}

TEST(BadInputFile, MissingTextureImage) {
  const std::string dir = tempDir("bad_image");
  Doc d = Doc::quad();
  d.push("images", {{"uri", "missing_albedo.png"}});
  d.push("textures", {{"source", 0}});
  d.push("materials", {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}});
  d.prim()["material"] = 0;
  d.prim()["attributes"]["TEXCOORD_0"] = d.accessor(d.view(std::vector<float>(8, 0.5f).data(), 32), kFloat, 4, "VEC2");
  expectLoadError(d.writeGltf(dir, "m"), {"images[0]", "missing_albedo.png"});
}

TEST(BadInputFile, CorruptTextureImageFailsToDecodeNamingIt) {
  const std::string dir = tempDir("bad_image_data");
  writeAll(dir + "/broken.png", "\x89PNG\r\n\x1a\n this is not really a png");
  Doc d = Doc::quad();
  d.push("images", {{"uri", "broken.png"}});
  d.push("textures", {{"source", 0}});
  d.push("materials", {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}});
  d.prim()["material"] = 0;
  d.prim()["attributes"]["TEXCOORD_0"] = d.accessor(d.view(std::vector<float>(8, 0.5f).data(), 32), kFloat, 4, "VEC2");
  const std::string path = d.writeGltf(dir, "m");
  QuietWarnings quiet;
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
  Doc t = Doc::quad();
  t.push("materials", {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 3}}}}}});
  expectLoadError(t.writeGltf(dir, "texture"), {"materials[0].pbrMetallicRoughness.baseColorTexture"});
  Doc c = Doc::quad();
  c.j["nodes"][0]["camera"] = 2;
  expectLoadError(c.writeGltf(dir, "camera"), {"nodes[0].camera"});
  Doc f = Doc::quad();
  f.push("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 0.0}, {"znear", 0.1}}}});
  f.j["nodes"][0]["camera"] = 0;
  expectLoadError(f.writeGltf(dir, "yfov"), {"cameras[0]", "yfov"});
  Doc s = Doc::quad();
  s.j["scene"] = 4;
  expectLoadError(s.writeGltf(dir, "scene"), {"scene"});
}

TEST(BadInputFile, NodeCycle) {
  const std::string dir = tempDir("bad_cycle");
  Doc d = Doc::quad();
  d.j["nodes"][0]["children"] = {1};
  d.push("nodes", {{"children", {0}}});
  expectLoadError(d.writeGltf(dir, "cycle"), {"nodes[", "cycle"});
  Doc self = Doc::quad();
  self.j["nodes"][0]["children"] = {0};
  expectLoadError(self.writeGltf(dir, "self"), {"nodes[0]", "cycle"});
}

// Without `scenes`, the loader renders the root nodes; a hierarchy that is
// all cycle has no root.
// NOTE: fails as of this writing: core/gltf_loader.cpp collectNodes() finds
// no root, visits nothing and returns an empty scene without a word.
TEST(BadInputFile, NodeCycleWithoutScenes) {
  const std::string dir = tempDir("bad_cycle_noscene");
  Doc d = Doc::quad();
  d.j.erase("scenes");
  d.j.erase("scene");
  d.j["nodes"][0]["children"] = {1};
  d.push("nodes", {{"children", {0}}});
  expectLoadError(d.writeGltf(dir, "cycle"), {"nodes[", "cycle"});
}

// glTF 2.0 section 3.5.3: "each node MUST have zero or one parent node".
// NOTE: fails as of this writing: visit() in core/gltf_loader.cpp only
// detects cycles on the current path, so a node shared by two parents is
// silently rendered twice - and a DAG that shares at every level (each node
// listing the next one twice) is visited 2^depth times: 40 such nodes hang
// the loader and exhaust memory. Kept to two parents here so it stays fast.
TEST(BadInputFile, NodeWithTwoParents) {
  const std::string dir = tempDir("bad_two_parents");
  Doc d = Doc::quad();
  d.push("nodes", {{"children", {0}}});
  d.push("nodes", {{"children", {0}}});
  d.j["scenes"][0]["nodes"] = {1, 2};
  expectLoadError(d.writeGltf(dir, "dag"), {"nodes[0]"});
}

TEST(BadInputFile, NodeHierarchyTooDeep) {
  const std::string dir = tempDir("bad_deep");
  Doc d = Doc::quad();
  for (int k = 1; k <= 1100; ++k) d.push("nodes", {{"children", {k - 1}}});
  d.j["scenes"][0]["nodes"] = {1100};
  expectLoadError(d.writeGltf(dir, "deep"), {"nodes[", "deeper"});
}

TEST(BadInputFile, MeshAndMaterialIndexOutOfRange) {
  const std::string dir = tempDir("bad_mesh_index");
  Doc m = Doc::quad();
  m.j["nodes"][0]["mesh"] = 3;
  expectLoadError(m.writeGltf(dir, "mesh"), {"nodes[0].mesh", "3"});
  Doc c = Doc::quad();
  c.j["nodes"][0]["children"] = {9};
  expectLoadError(c.writeGltf(dir, "child"), {"nodes[9]"});
  Doc mat = Doc::quad();
  mat.prim()["material"] = 2;
  expectLoadError(mat.writeGltf(dir, "material"), {"meshes[0].primitives[0].material", "2"});
  Doc neg = Doc::quad();
  neg.j["accessors"][0]["componentType"] = 9999;
  expectLoadError(neg.writeGltf(dir, "componenttype"), {"ccessor"});
}

TEST(BadInputFile, RequiredCompressionExtension) {
  const std::string dir = tempDir("bad_draco");
  Doc d = Doc::quad();
  d.j["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  d.j["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  expectLoadError(d.writeGltf(dir, "draco"), {"extensionsRequired", "KHR_draco_mesh_compression"});
}

// Random damage to the binary buffer (positions and indices) and to numbers
// in the JSON: every outcome is a scene or an obscura::Error.
TEST(BadInputFile, RandomDamageNeverCrashes) {
  const std::string dir = tempDir("bad_random");
  std::mt19937 rng(12345);
  QuietWarnings quiet;
  size_t errors = 0, loads = 0;
  for (int trial = 0; trial < 300; ++trial) {
    Doc d = Doc::quad();
    if (trial % 2 == 0) {
      for (int k = 0; k < 3; ++k) d.bin[rng() % d.bin.size()] = (unsigned char)(rng());
    } else {
      const char* arrays[] = {"accessors", "bufferViews"};
      const char* fields[][4] = {{"count", "byteOffset", "componentType", "bufferView"},
                                 {"byteLength", "byteOffset", "byteStride", "buffer"}};
      const int a = int(rng() % 2), f = int(rng() % 4);
      const int64_t values[] = {-1, 0, 1, 3, 4, 7, 12, 255, 65536, int64_t(1) << 31, int64_t(1) << 40};
      d.j[arrays[a]][rng() % 2][fields[a][f]] = values[rng() % std::size(values)];
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

struct CliRun {
  std::string name;
  std::vector<std::string> args;
  std::string output;   // must not exist afterwards ("" = not checked)
  std::string mention;  // must appear in the error line
  pid_t pid = -1;
  int exitCode = -1;
  int signal = 0;
  std::string err;
};

void start(CliRun& r, const std::string& errPath) {
  std::vector<std::string> all = {OBSCURA_BINARY};
  all.insert(all.end(), r.args.begin(), r.args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 2, errPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  const int rc = posix_spawn(&r.pid, OBSCURA_BINARY, &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    r.pid = -1;
    r.err = std::string("posix_spawn: ") + std::strerror(rc);
  }
}
void finish(CliRun& r, const std::string& errPath) {
  if (r.pid < 0) return;
  int status = 0;
  while (waitpid(r.pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status)) r.exitCode = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  const auto b = readAll(errPath);
  r.err.assign(b.begin(), b.end());
}

// Runs the processes, a few at a time (each start costs ~0.4 s).
void runAll(std::vector<CliRun>& runs, const std::string& dir) {
  const size_t width = std::max(2u, std::thread::hardware_concurrency());
  for (size_t begin = 0; begin < runs.size(); begin += width) {
    const size_t end = std::min(runs.size(), begin + width);
    for (size_t i = begin; i < end; ++i) start(runs[i], dir + "/stderr" + std::to_string(i) + ".txt");
    for (size_t i = begin; i < end; ++i) finish(runs[i], dir + "/stderr" + std::to_string(i) + ".txt");
  }
}

void expectOneErrorLine(const CliRun& r) {
  SCOPED_TRACE(r.name);
  EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << "; stderr:\n" << r.err;
  EXPECT_NE(r.exitCode, 0) << "stderr:\n" << r.err;
  EXPECT_EQ(r.err.rfind("obscura: error:", 0), 0u) << "stderr:\n" << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << "not exactly one line:\n" << r.err;
  if (!r.err.empty()) {
    EXPECT_EQ(r.err.back(), '\n') << r.err;
  }
  EXPECT_NE(r.err.find(r.mention), std::string::npos) << "does not mention '" << r.mention << "':\n" << r.err;
  if (!r.output.empty()) {
    EXPECT_FALSE(fs::exists(r.output)) << r.output << " was created";
  }
}

// A valid one-camera scene with a quad in view.
std::string writeGoodScene(const std::string& dir) {
  Doc d = Doc::quad({{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}});
  d.push("cameras", {{"type", "perspective"}, {"name", "only"}, {"perspective", {{"yfov", 0.8}, {"znear", 0.01}}}});
  d.push("nodes", {{"camera", 0}, {"translation", {0, 0, 3}}});
  d.j["scenes"][0]["nodes"] = {0, 1};
  return d.writeGltf(dir, "good");
}

TEST(BadInputCli, EveryBadArgumentIsOneErrorLineAndNoOutput) {
  const std::string dir = tempDir("bad_cli");
  const std::string scene = writeGoodScene(dir);
  const std::string garbage = dir + "/garbage.gltf";
  writeAll(garbage, "not a gltf file");
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

TEST(BadInputCli, FailedRenderLeavesTheExistingOutputUntouched) {
  const std::string dir = tempDir("bad_cli_overwrite");
  const std::string scene = writeGoodScene(dir);
  const std::string out = dir + "/pass.exr";
  std::vector<CliRun> first(1);
  first[0].name = "good render";
  first[0].args = {"render", scene, "-o", out, "--res", "8x8", "--spp", "1", "-q"};
  runAll(first, dir);
  ASSERT_EQ(first[0].exitCode, 0) << first[0].err;
  ASSERT_EQ(first[0].err, "");
  const std::vector<unsigned char> before = readAll(out);
  ASSERT_FALSE(before.empty());

  const std::string garbage = dir + "/garbage.gltf";
  writeAll(garbage, "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [{\"mesh\": 5}]}");
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
    EXPECT_EQ(readAll(out), before) << r.name << ": the existing output changed";
  }
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    EXPECT_EQ(name.find(".tmp"), std::string::npos) << "temporary file left behind: " << name;
  }
}

}  // namespace
}  // namespace obscura::test
