#include "tests/fuzz_seeds.h"

#include <filesystem>

#include "core/image/image_io.h"
#include <obscura/integrator.h>
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

std::string base64(const std::vector<unsigned char>& b) {
  static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < b.size(); i += 3) {
    const uint32_t n = uint32_t(b[i]) << 16 | (i + 1 < b.size() ? uint32_t(b[i + 1]) << 8 : 0) |
                       (i + 2 < b.size() ? uint32_t(b[i + 2]) : 0);
    out += abc[n >> 18 & 63];
    out += abc[n >> 12 & 63];
    out += i + 1 < b.size() ? abc[n >> 6 & 63] : '=';
    out += i + 2 < b.size() ? abc[n & 63] : '=';
  }
  return out;
}

// A camera looking at the origin from +Z, as a node.
int cameraNode(GltfBuilder& g) {
  const int c = g.push("cameras", perspective("front", 0.8, 0.01, 100));
  return g.node({{"camera", c}, {"translation", {0, 0, 3}}});
}

// A 2x2 PNG's bytes (a texture).
std::vector<unsigned char> tinyPng(const std::string& dir) {
  const unsigned char rgb[12] = {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255};
  const std::string path = dir + "/tiny.png";
  writePngRgb8(path, 2, 2, rgb);
  std::vector<unsigned char> bytes = readBytes(path);
  std::filesystem::remove(path);
  return bytes;
}

void gltfSeeds(const std::string& dir) {
  {  // a quad and a camera, .glb and .gltf with its buffer embedded
    GltfBuilder g;
    const int m = g.quadMesh(1);
    g.scene({g.node({{"mesh", m}}), cameraNode(g)});
    g.writeGlb(dir, "quad");
    g.doc["buffers"] = json::array({{{"byteLength", g.bin.size()},
                                     {"uri", "data:application/octet-stream;base64," + base64(g.bin)}}});
    g.writeGltf(dir, "quad_embedded");
  }
  {  // one mesh used twice (an instance), TRS and matrix nodes, a hierarchy,
     // strips and fans, uint8/uint32 indices, normals, a textured material
    GltfBuilder g;
    const std::vector<unsigned char> png = tinyPng(dir);
    const int view = g.bufferView(png.data(), png.size());
    g.push("images", {{"bufferView", view}, {"mimeType", "image/png"}});
    g.push("samplers", {{"wrapS", 33071}, {"wrapT", 33648}});
    g.push("textures", {{"source", 0}, {"sampler", 0}});
    g.push("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {0.8, 0.7, 0.6, 1}}, {"baseColorTexture", {{"index", 0}}}}}});
    const int quad = g.quadMesh(0.5f, 0, true);
    const int pos = g.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0, 2, 0}});
    const int nrm = g.vec3({{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}});
    json strip = {{"attributes", {{"POSITION", pos}, {"NORMAL", nrm}}}, {"mode", kStrip},
                  {"indices", g.indices(std::vector<uint8_t>{0, 1, 2, 3, 4})}};
    json fan = {{"attributes", {{"POSITION", pos}}}, {"mode", kFan}, {"indices", g.indices(std::vector<uint32_t>{0, 1, 3, 4})}};
    const int mixed = g.push("meshes", {{"primitives", json::array({strip, fan})}});
    const int child = g.node({{"mesh", quad}, {"rotation", {0, 0.3826834, 0, 0.9238795}}, {"scale", {1, 2, 1}}});
    const int parent = g.node({{"children", {child}}, {"translation", {1, 0, -1}}});
    const int other = g.node({{"mesh", quad}, {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -1, 0, 0, 1}}});
    g.scene({parent, other, g.node({{"mesh", mixed}}), cameraNode(g)});
    g.writeGlb(dir, "instances_modes_texture");
  }
  {  // subdivision and displacement extras (the mesh's and a node's own)
    GltfBuilder g;
    const int cc = g.quadMesh(1, -1, true);
    g.doc["meshes"][size_t(cc)]["extras"] = {
        {"obscura", {{"subdivision", {{"scheme", "catmull-clark"}, {"level", 1}}},
                     {"displacement", {{"map", "height.png"}, {"scale", 0.05}, {"midlevel", 0.5}}}}}};
    const int loop = g.quadMesh(1, -1, true);
    g.doc["meshes"][size_t(loop)]["extras"] = {{"obscura", {{"subdivision", {{"scheme", "loop"}, {"level", 1}}}}}};
    const int a = g.node({{"mesh", cc}});
    const int b = g.node({{"mesh", loop}, {"translation", {2.5, 0, 0}},
                          {"extras", {{"obscura", {{"displacement", {{"map", "height.png"}, {"scale", 0.1}}}}}}}});
    g.scene({a, b});  // no camera: the auto camera frames it
    g.writeGlb(dir, "subdivision_displacement");
  }
  {  // objects' roles (inherited, every role) and alpha: MASK with an RGBA
     // texture on an instanced mesh, BLEND by factor
    GltfBuilder g;
    const std::string pngPath = writeAlphaTexture(dir + "/alpha.png", 4, 4, [](int x, int y) { return ((x + y) & 1) ? 1.0 : 0.2; });
    const std::vector<unsigned char> png = readBytes(pngPath);
    std::filesystem::remove(pngPath);
    g.push("images", {{"bufferView", g.bufferView(png.data(), png.size())}, {"mimeType", "image/png"}});
    g.push("textures", {{"source", 0}});
    g.push("materials", {{"alphaMode", "MASK"}, {"alphaCutoff", 0.4}, {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}});
    g.push("materials", {{"alphaMode", "BLEND"}, {"pbrMetallicRoughness", {{"baseColorFactor", {1, 1, 1, 0.5}}}}});
    const int leaf = g.quadMesh(0.5f, 0, true);
    const int veil = g.quadMesh(1, 1, true);
    const int floor = g.quadMesh(2);
    const auto roles = [](json r) { return json{{"obscura", std::move(r)}}; };
    const int l1 = g.node({{"name", "leaf1"}, {"mesh", leaf}, {"translation", {0, 0, 0.5}}, {"extras", roles({{"occlusion", "self"}})}});
    const int l2 = g.node({{"name", "leaf2"}, {"mesh", leaf}, {"translation", {0.5, 0, 1}}});
    const int group = g.node({{"name", "leaves"}, {"children", {l1, l2}}, {"extras", roles({{"occlusion", "others"}, {"matte", true}})}});
    const int v = g.node({{"name", "veil"}, {"mesh", veil}, {"translation", {0, 0, 1.5}}, {"extras", roles({{"camera", false}})}});
    const int f = g.node({{"name", "floor"}, {"mesh", floor}, {"extras", roles({{"occluder", false}})}});
    g.scene({group, v, f, cameraNode(g)});
    g.writeGlb(dir, "roles_alpha");
  }
}

void objSeeds(const std::string& dir) {
  const std::string cube =
      "v -1 -1 -1\nv 1 -1 -1\nv -1 1 -1\nv 1 1 -1\nv -1 -1 1\nv 1 -1 1\nv -1 1 1\nv 1 1 1\n"
      "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
  const std::string tetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
  std::string grid = "# a 2x2 grid of quads with uvs and a crease\n";
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 3; ++x)
      grid += "v " + std::to_string(x) + " " + std::to_string(y) + " 0\nvt " + std::to_string(x * 0.5) + " " +
              std::to_string(y * 0.5) + "\n";
  grid += "f 1/1 2/2 5/5 4/4\nf 2/2 3/3 6/6 5/5\nf 4/4 5/5 8/8 7/7\nf 5/5 6/6 9/9 8/8\nt crease 2/1 4 5 2.5\n";
  // Mode byte (fuzz/fuzz_obj.cpp): bit 0 loop, bits 1-2 level, bit 3 adaptive.
  const auto seed = [&](const std::string& name, char mode, const std::string& text) { writeText(dir + "/" + name, mode + text); };
  seed("cube_cc1", 2, cube);
  seed("cube_cc2", 4, cube);
  seed("tetra_loop1", 1 | 2, tetra);
  seed("tetra_cc_adaptive", 8, tetra);
  seed("grid_cc0", 0, grid);
  seed("grid_cc1", 2, grid);
  // Issue #37: the corners of the OBJ syntax tinyobjloader reads, each a
  // valid cage unless named bad_ (refused: the error path is fuzzed too).
  const std::string quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
  seed("negative_indices_cc1", 2, cube.substr(0, cube.find('f')) + "f -8 -6 -5 -7\nf -4 -3 -1 -2\nf -8 -7 -3 -4\n"
                                   "f -6 -2 -1 -5\nf -8 -4 -2 -6\nf -7 -5 -1 -3\n");
  seed("normals_and_uvs_cc0", 0, quad + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/4/1\n");
  seed("normals_only_cc0", 0, quad + "vn 0 0 1\nf 1//1 2//1 3//1 4//1\n");
  seed("mtllib_groups_cc1", 2, "mtllib missing.mtl\no cube\ng side\nusemtl grey\ns 1\n" + cube);
  seed("corner_and_crease_tags_cc2", 4, cube + "t crease 2/1 1 2 4.0\nt corner 1/1 1 3.0\nt interpolateboundary 1/0 1\n");
  seed("pentagon_and_triangle_cc1", 2, "v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 2 0\nv -1 1 0\nv 1 -1 1\nf 1 2 3 4 5\nf 2 1 6\n");
  seed("weights_and_comments_cc0", 0, "# comment\nv 0 0 0 1.0\nv 1 0 0 1.0 # trailing\nv 1 1 0\nv 0 1 0\n\nf 1 2 3 4\n");
  seed("exponents_adaptive", 8, "v 0e0 0 0\nv 1e+0 0 0\nv 1 1.0E0 0\nv 0 +1 -0\nf 1 2 3 4\n");
  seed("bad_index_beyond_int", 2, quad + "f 1 2 3 99999999999999999999\n");
  seed("bad_index_2147483648", 2, quad + "f 1 2 3 2147483648\n");
  seed("bad_index_zero", 0, quad + "f 0 1 2\n");
  seed("bad_index_past_the_end", 0, quad + "f 1 2 9\n");
}

// fuzz/fuzz_json.cpp: byte 0 even, a whole document; odd, a node's extras.
void jsonSeeds(const std::string& dir) {
  const auto seed = [&](const std::string& name, char mode, const std::string& text) { writeText(dir + "/" + name, mode + text); };
  GltfBuilder g;
  const int q = g.quadMesh(1);
  g.doc["meshes"][size_t(q)]["extras"] = {{"obscura", {{"subdivision", {{"scheme", "loop"}, {"level", 1}}}}}};
  g.scene({g.node({{"mesh", q}, {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}}}), cameraNode(g)});
  g.doc["buffers"] = json::array({{{"byteLength", g.bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(g.bin)}}});
  seed("document", 0, g.doc.dump());
  seed("document_extensions", 0, [&] {
    json d = g.doc;
    d["extensionsUsed"] = {"KHR_mesh_quantization", "KHR_texture_transform"};
    d["extensionsRequired"] = {"KHR_mesh_quantization"};
    d["nodes"][0]["extensions"] = {{"EXT_x", {{"a", {1, {2, {3, {4}}}}}}}};
    return d.dump();
  }());
  seed("extras_roles", 1, R"({"obscura": {"occluder": false, "occlusion": "self"}, "tool": {"id": 7}})");
  seed("extras_nested_64", 1, std::string(64, '[') + "1" + std::string(64, ']'));
  seed("extras_nested_objects", 1, [] {
    std::string t;
    for (int i = 0; i < 40; ++i) t += "{\"k\": ";
    return t + "null" + std::string(40, '}');
  }());
  seed("extras_big_integer", 1, R"({"obscura": {"occluder": true}, "n": 4294967298})");
  seed("extras_misspelt_key", 1, R"({"obscura": {"occludr": true}})");
}

// fuzz/fuzz_camera.cpp: a mode byte, then doubles (yfov, znear, zfar,
// camera translation, rotation, root scale, quad scale, second quad's place).
void cameraSeeds(const std::string& dir) {
  const auto seed = [&](const std::string& name, char mode, std::vector<double> v) {
    std::string bytes(1, mode);
    bytes.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(double));
    writeText(dir + "/" + name, bytes);
  };
  const std::vector<double> base = {0.8, 0.01, 0, 0, 0, 3, 0, 0, 0, 1, 1, 1, 2, 0, 0};
  const auto with = [&](std::initializer_list<std::pair<size_t, double>> changes) {
    std::vector<double> v = base;
    for (const auto& [i, x] : changes) v[i] = x;
    return v;
  };
  seed("file_camera", 0, base);
  seed("auto_camera_two_quads", 1 | 2, base);
  seed("tiny_scene_1e-12", 0, with({{10, 1e-12}}));
  seed("tiny_scene_auto", 1, with({{10, 1e-12}}));
  seed("huge_translation", 0, with({{5, 1e15}}));
  seed("yfov_near_pi", 0, with({{0, 3.14159}}));
  seed("znear_beyond_scene", 0, with({{1, 1e17}}));
  seed("zfar_before_znear", 0, with({{1, 1.0}, {2, 0.5}}));
  seed("zero_quaternion", 0, with({{6, 0}, {7, 0}, {8, 0}, {9, 0}}));
  seed("zero_root_scale_auto", 1, with({{10, 0}}));
  seed("far_apart_auto", 1 | 2, with({{12, 1e15}}));
  seed("short_input", 1, {0.5});
}

void paramSeeds(const std::string& dir) {
  for (const IntegratorDescriptor& d : IntegratorRegistry::instance().all()) {
    std::string text = d.name + "\n";
    for (const ParamSpec& s : d.params) text += s.name + "=" + s.defaultValue + "\n";
    writeText(dir + "/" + d.name + "_defaults", text);
  }
  writeText(dir + "/ao", "ao\ndistance=inf\nrays=4\n");
  writeText(dir + "/obscurance", "obscurance\nfalloff=sqrt\ndistance=0.5\nestimator=occlusion\nsigma=2.5e-3\n");
  writeText(dir + "/transfer", "transfer\ndepth=2\ntail=zero\nfalloff=exponential\n");
  writeText(dir + "/gi", "gi\nmax-depth=3\nsigma=0.5\nrays=2\n");
  writeText(dir + "/multibounce", "multibounce\nmapping=improved\ndistance=1e3\n");
}

}  // namespace

void writeFuzzSeeds(const std::string& dir) {
  for (const char* sub : {"gltf", "obj", "params", "json", "camera"}) std::filesystem::create_directories(dir + "/" + sub);
  gltfSeeds(dir + "/gltf");
  objSeeds(dir + "/obj");
  jsonSeeds(dir + "/json");
  cameraSeeds(dir + "/camera");
  paramSeeds(dir + "/params");
}

}  // namespace obscura::test
