// Builds glTF 2.0 files for tests: a JSON document and its one binary
// buffer, written as .gltf + .bin or as a .glb container.
#pragma once

#include <nlohmann/json.hpp>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <obscura/math.h>

namespace obscura::test {

using json = nlohmann::json;

// glTF accessor component types and primitive modes.
constexpr int kFloat = 5126, kUByte = 5121, kUShort = 5123, kUInt = 5125;
constexpr int kLines = 1, kStrip = 5, kFan = 6;

class GltfBuilder {
 public:
  GltfBuilder() { doc["asset"] = {{"version", "2.0"}}; }
  json doc;
  std::vector<unsigned char> bin;

  // Appends obj to the top-level array `array`; returns its index.
  int push(const char* array, json obj);
  // Appends the bytes to the buffer (4-byte aligned) as a new bufferView.
  int bufferView(const void* data, size_t bytes);
  int accessor(int view, int componentType, size_t count, const char* type);
  // A VEC3 float accessor with min/max (when every point is finite), as
  // glTF requires for POSITION.
  int positions(const std::vector<Vec3>& p);
  // Float accessors without min/max.
  int vec3(const std::vector<Vec3>& v);
  int vec2(const std::vector<std::array<float, 2>>& v);
  int vec4(const std::vector<std::array<float, 4>>& v);
  // A float SCALAR accessor (keyframe times).
  int scalars(const std::vector<float>& v);
  // A float accessor of `type` ("VEC3", "VEC4") from flat components.
  int floats(const std::vector<float>& v, const char* type);

  // One channel of an animation, with a sampler of its own: `values` are
  // flat (3 per key for translation/scale, 4 for rotation; times 3 as many
  // for CUBICSPLINE: in-tangent, value, out-tangent per key).
  struct Channel {
    int node;
    std::string path;  // translation, rotation, scale, weights
    std::vector<float> times, values;
    std::string interpolation = "LINEAR";
  };
  // Appends animations[] {name (if not empty), samplers, channels}; returns its index.
  int animation(const std::string& name, const std::vector<Channel>& channels);
  // An index accessor whose component type follows T (uint8/16/32).
  template <class T>
  int indices(const std::vector<T>& idx) {
    const int type = sizeof(T) == 1 ? kUByte : sizeof(T) == 2 ? kUShort : kUInt;
    return accessor(bufferView(idx.data(), idx.size() * sizeof(T)), type, idx.size(), "SCALAR");
  }
  // A square [-h,h]^2 in the plane z = 0 with uvs (0,0)..(1,1), as a mesh.
  int quadMesh(float h, int material = -1, bool withUv = false);
  int node(json n) { return push("nodes", std::move(n)); }
  // scenes[0] with these root nodes, the default scene.
  void scene(std::vector<int> roots);
  // meshes[mesh].primitives[prim].
  json& primitive(int mesh = 0, int prim = 0) { return doc["meshes"][size_t(mesh)]["primitives"][size_t(prim)]; }

  // Writes dir/name.gltf (+ dir/name.bin unless the document already has
  // its buffers); returns the .gltf path.
  std::string writeGltf(const std::string& dir, const std::string& name) const;
  // The .glb container: JSON chunk, then the BIN chunk if there is a buffer.
  std::vector<unsigned char> glbBytes() const;
  // Writes dir/name.glb; returns its path.
  std::string writeGlb(const std::string& dir, const std::string& name) const;
};

// A perspective camera object for cameras[] (no zfar if zfar <= 0, no name
// if name is empty).
json perspective(const std::string& name, double yfov, double znear, double zfar = 0);

}  // namespace obscura::test
