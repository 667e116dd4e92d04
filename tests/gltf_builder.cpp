#include "tests/gltf_builder.h"

#include "tests/support.h"

namespace obscura::test {

int GltfBuilder::push(const char* array, json obj) {
  json& a = doc[array];
  if (!a.is_array()) a = json::array();
  a.push_back(std::move(obj));
  return int(a.size()) - 1;
}

int GltfBuilder::bufferView(const void* data, size_t bytes) {
  while (bin.size() % 4) bin.push_back(0);
  const size_t offset = bin.size();
  const auto* p = static_cast<const unsigned char*>(data);
  bin.insert(bin.end(), p, p + bytes);
  return push("bufferViews", {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}});
}

int GltfBuilder::accessor(int view, int componentType, size_t count, const char* type) {
  return push("accessors", {{"bufferView", view}, {"componentType", componentType}, {"count", count}, {"type", type}});
}

int GltfBuilder::positions(const std::vector<Vec3>& p) {
  const int a = vec3(p);
  Bounds3 b;
  bool finite = true;
  for (const Vec3& v : p) b.extend(v), finite = finite && isFinite(v);
  if (finite && !p.empty()) {
    doc["accessors"][size_t(a)]["min"] = {b.lo.x, b.lo.y, b.lo.z};
    doc["accessors"][size_t(a)]["max"] = {b.hi.x, b.hi.y, b.hi.z};
  }
  return a;
}

int GltfBuilder::vec3(const std::vector<Vec3>& v) {
  return accessor(bufferView(v.data(), v.size() * sizeof(Vec3)), kFloat, v.size(), "VEC3");
}

int GltfBuilder::vec2(const std::vector<std::array<float, 2>>& v) {
  return accessor(bufferView(v.data(), v.size() * 8), kFloat, v.size(), "VEC2");
}

int GltfBuilder::vec4(const std::vector<std::array<float, 4>>& v) {
  return accessor(bufferView(v.data(), v.size() * 16), kFloat, v.size(), "VEC4");
}

int GltfBuilder::scalars(const std::vector<float>& v) {
  return accessor(bufferView(v.data(), v.size() * 4), kFloat, v.size(), "SCALAR");
}

int GltfBuilder::floats(const std::vector<float>& v, const char* type) {
  const size_t n = std::string(type) == "VEC4" ? 4 : std::string(type) == "VEC2" ? 2 : std::string(type) == "SCALAR" ? 1 : 3;
  return accessor(bufferView(v.data(), v.size() * 4), kFloat, v.size() / n, type);
}

int GltfBuilder::animation(const std::string& name, const std::vector<Channel>& channels) {
  json samplers = json::array(), chans = json::array();
  for (const Channel& c : channels) {
    const int input = scalars(c.times);
    const int output = floats(c.values, c.path == "rotation" ? "VEC4" : c.path == "weights" ? "SCALAR" : "VEC3");
    chans.push_back({{"sampler", samplers.size()}, {"target", {{"node", c.node}, {"path", c.path}}}});
    samplers.push_back({{"input", input}, {"output", output}, {"interpolation", c.interpolation}});
  }
  json a = {{"samplers", samplers}, {"channels", chans}};
  if (!name.empty()) a["name"] = name;
  return push("animations", std::move(a));
}

int GltfBuilder::quadMesh(float h, int material, bool withUv) {
  json prim = {{"attributes", {{"POSITION", positions({{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}})}}},
               {"indices", indices(std::vector<uint16_t>{0, 1, 2, 0, 2, 3})}};
  if (withUv) prim["attributes"]["TEXCOORD_0"] = vec2({{0, 1}, {1, 1}, {1, 0}, {0, 0}});
  if (material >= 0) prim["material"] = material;
  return push("meshes", {{"primitives", json::array({prim})}});
}

void GltfBuilder::scene(std::vector<int> roots) {
  doc["scenes"] = json::array({{{"nodes", roots}}});
  doc["scene"] = 0;
}

std::string GltfBuilder::writeGltf(const std::string& dir, const std::string& name) const {
  json d = doc;
  if (!bin.empty() && !d.contains("buffers")) {
    d["buffers"] = json::array({{{"uri", name + ".bin"}, {"byteLength", bin.size()}}});
    writeBytes(dir + "/" + name + ".bin", bin.data(), bin.size());
  }
  const std::string path = dir + "/" + name + ".gltf";
  writeText(path, d.dump(1));
  return path;
}

std::vector<unsigned char> GltfBuilder::glbBytes() const {
  json d = doc;
  std::vector<unsigned char> b = bin;
  while (b.size() % 4) b.push_back(0);
  if (!b.empty()) d["buffers"] = json::array({{{"byteLength", bin.size()}}});
  std::string text = d.dump();
  while (text.size() % 4) text.push_back(' ');
  std::vector<unsigned char> out;
  const auto u32 = [&](uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back((unsigned char)(v >> (8 * i)));
  };
  const uint32_t total = uint32_t(12 + 8 + text.size() + (b.empty() ? 0 : 8 + b.size()));
  out.insert(out.end(), {'g', 'l', 'T', 'F'});
  u32(2);
  u32(total);
  u32(uint32_t(text.size()));
  u32(0x4E4F534A);  // JSON
  out.insert(out.end(), text.begin(), text.end());
  if (!b.empty()) {
    u32(uint32_t(b.size()));
    u32(0x004E4942);  // BIN
    out.insert(out.end(), b.begin(), b.end());
  }
  return out;
}

std::string GltfBuilder::writeGlb(const std::string& dir, const std::string& name) const {
  const std::vector<unsigned char> bytes = glbBytes();
  const std::string path = dir + "/" + name + ".glb";
  writeBytes(path, bytes.data(), bytes.size());
  return path;
}

json perspective(const std::string& name, double yfov, double znear, double zfar) {
  json c = {{"type", "perspective"}, {"perspective", {{"yfov", yfov}, {"znear", znear}}}};
  if (zfar > 0) c["perspective"]["zfar"] = zfar;
  if (!name.empty()) c["name"] = name;
  return c;
}

}  // namespace obscura::test
