// A glTF 2.0 file read once and decoded into Obscura's terms: materials
// (with their texture images still encoded), cameras, the node hierarchy
// flattened into mesh uses with world transforms, and each mesh's triangle
// primitives in object space. Nothing here knows Obscura's extras
// (extras.obscura.*) or subdivision: core/gltf_loader.cpp builds scenes
// from a document, as often as it needs (the adaptive subdivision's camera
// probe and the scene itself), without reading the file again.
//
// Before tinygltf sees the file, its JSON is checked for the fields the
// decoding relies on having the type glTF prescribes (tinygltf silently
// ignores a wrong type, e.g. `"mesh": "0"`, which would drop geometry), and
// for buffer and image uris that are not regular files (tinygltf's reading
// of a directory fails as "out of memory"). Every problem throws
// obscura::Error naming the file and the field.
#pragma once

#include <array>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/scene.h"

namespace tinygltf {
class Model;
}

namespace obscura {

using Matrix4d = std::array<double, 16>;  // column-major, as glTF stores it

class GltfDocument {
 public:
  // Reads, checks and parses `path` (.glb when it starts with the glb magic),
  // then decodes its materials and nodes.
  explicit GltfDocument(std::string path);
  ~GltfDocument();
  GltfDocument(const GltfDocument&) = delete;
  GltfDocument& operator=(const GltfDocument&) = delete;

  const std::string& path() const { return path_; }
  // The parsed file (for the extras, which the loader reads).
  const tinygltf::Model& model() const { return *model_; }
  [[noreturn]] void fail(const std::string& field, const std::string& what) const;
  void warn(const std::string& what) const;

  // materials[i] as Obscura uses them; Material::texture indexes textures()
  // (sRGB colour), Material::roughnessTexture dataTextures().
  const std::vector<Material>& materials() const { return materials_; }
  struct TextureImage {
    std::vector<unsigned char> encoded;
    std::string name;  // "FILE: images[i] 'uri'", for errors
  };
  const std::vector<TextureImage>& textures() const { return textures_; }
  // The images of metallicRoughness textures, linear data: Material::roughnessTexture
  // indexes these.
  const std::vector<TextureImage>& dataTextures() const { return dataTextures_; }
  // Perspective cameras placed by their nodes, ordered by cameras[] index.
  const std::vector<Camera>& cameras() const { return cameras_; }

  // Each node with a mesh, in traversal order of the default scene.
  struct MeshUse {
    int mesh;
    Matrix4d world;
    std::string node;  // its name, else its mesh's name, else "nodes[i]"
    int nodeIndex;
    std::vector<int> ancestors;  // the node's ancestors, root first (their extras are inherited)
  };
  const std::vector<MeshUse>& meshUses() const { return uses_; }

  // A triangle primitive in object space (strips and fans as lists).
  struct Primitive {
    std::vector<Vec3> positions, normals;
    std::vector<float> uvs;  // TEXCOORD_0, see mesh()
    std::vector<uint32_t> indices;
    int material = -1;
    std::string field;  // "meshes[i].primitives[j]"
  };
  // The triangle primitives of meshes[index] (point and line primitives
  // skipped with a warning, empty ones dropped), decoded on first use.
  // TEXCOORD_0 is read whenever the primitive has it: it serves a texture,
  // the displacement of a subdivided mesh and integrators that work in
  // texture space (containment) - 8 bytes a vertex.
  const std::vector<Primitive>& mesh(int index) const;

 private:
  void read();
  void warnUnsupported();
  void decodeMaterials();
  void decodeNodes();
  void visit(int index, const Matrix4d& parent, std::vector<int>& stack, std::vector<char>& visited);
  Matrix4d localMatrix(int index, const std::string& field) const;
  void addCamera(int node, int index, const Matrix4d& world, const std::string& field);
  std::vector<Primitive> decodeMesh(int index) const;

  struct View;
  View view(int accessor, const std::string& field) const;
  // count x n floats of a VECn accessor, each finite.
  std::vector<float> readFloats(int accessor, const std::string& field, int n) const;
  // VEC3s; `positions` also checks the range Embree traces.
  std::vector<Vec3> readVec3(int accessor, const std::string& field, bool positions) const;
  std::vector<uint32_t> readIndices(int accessor, const std::string& field, size_t vertexCount) const;

  std::string path_;
  std::unique_ptr<tinygltf::Model> model_;
  std::map<int, std::vector<unsigned char>> imageBytes_;  // encoded, by images[] index
  std::vector<Material> materials_;
  std::vector<TextureImage> textures_, dataTextures_;
  std::vector<Camera> cameras_;
  std::vector<MeshUse> uses_;
  mutable std::map<int, std::vector<Primitive>> meshes_;
};

}  // namespace obscura
