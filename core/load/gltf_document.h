// A glTF 2.0 file read once and decoded into Obscura's terms: materials
// (with their texture images still encoded), cameras, the node hierarchy
// flattened into mesh uses with world transforms, and each mesh's triangle
// primitives in object space. Nothing here knows Obscura's extras
// (extras.obscura.*) or subdivision: core/load/gltf_loader.cpp builds scenes
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
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/load/animation.h"
#include "core/scene/camera.h"
#include "core/scene/scene.h"

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
    int nodeIndex;  // its ancestors (whose extras it inherits) through parentNode()
    bool animated = false;  // in a pose: the node or an ancestor is the target of a played channel
    // In a pose: the node or an ancestor has a zero scale on all three axes,
    // which glTF 2.0 lets a file use to hide a subtree; the use renders nothing.
    bool hidden = false;
    std::string hiddenBy;  // the node with the zero scale, "nodes[i]" (for the warning)
  };
  // The static pose: the file's node transforms, no animation applied.
  const std::vector<MeshUse>& meshUses() const { return uses_; }

  // The file's animations (core/load/animation.h), checked when the file is read.
  struct AnimationInfo {
    std::string name;   // as the file has it (may be empty)
    double start, end;  // seconds: the earliest and latest key of its channels
    size_t channels;    // channels[] in the file
    std::vector<int> nodes;  // the nodes its (supported) channels target, ascending
  };
  const std::vector<AnimationInfo>& animations() const { return animationInfo_; }
  // nodes[i]'s name, else "nodes[i]".
  std::string nodeLabel(int node) const;
  // The parent of nodes[node] in the default scene's tree, -1 for a root or
  // a node outside the scene. Uses name their node only: a list of
  // ancestors in each use cost 4 bytes per level per use (998 levels over
  // 400k leaves took 3.8 GB).
  int parentNode(int node) const { return parents_[size_t(node)]; }

  // The mesh uses and cameras with the selected animations applied at
  // `seconds` (animations played together: a later animation in the file
  // overrides an earlier one on the same node and path). nullopt: the
  // static pose (meshUses(), cameras()), `animated` false everywhere; the
  // selection is checked all the same. The hierarchy is static, so the
  // order of uses and cameras is the same at every time. `selection`:
  // names or indices (decimal), empty = every animation; an unknown one
  // throws obscura::Error listing the file's animations. A pose costs a walk
  // over the nodes (no accessor is read again).
  struct Pose {
    std::vector<MeshUse> uses;
    std::vector<Camera> cameras;
  };
  Pose pose(std::optional<double> seconds, const std::vector<std::string>& selection) const;
  // The animations `selection` plays, by index (as pose() resolves it).
  std::vector<size_t> selectAnimations(const std::vector<std::string>& selection) const;

  // A triangle primitive in object space (strips and fans as lists).
  struct Primitive {
    std::vector<Vec3> positions, normals;
    std::vector<float> uvs;  // TEXCOORD_0, see mesh()
    // TANGENT (4 per vertex), read only when the material has a normal map.
    std::vector<float> tangents;
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
  void visit(int index, int parent, std::vector<int>& stack, std::vector<char>& visited);
  // A node's transform: its matrix, else translation x rotation x scale.
  Matrix4d localMatrix(int index, const std::string& field) const;
  // True when `m`'s zero scale hides the subtree; throws on a singular one.
  bool checkLinear(const Matrix4d& m, const std::string& field) const;
  Matrix4d trsMatrix(const double t[3], const double r[4], const double s[3], const std::string& field) const;
  std::optional<Camera> makeCamera(int node, int index, const Matrix4d& world, const std::string& field) const;
  friend std::vector<Animation> readAnimations(const GltfDocument& document);
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
  // The default scene's nodes in traversal order (parents first), each with
  // its parent's position in this list (-1 for a root): a pose walks it.
  struct Visit {
    int node, parent;
  };
  std::vector<Visit> visits_;
  std::vector<size_t> useVisits_;  // uses_[i] is at visits_[useVisits_[i]]
  struct CameraVisit {
    size_t visit;
    int camera;  // cameras[] index
  };
  std::vector<CameraVisit> cameraVisits_;
  std::vector<int> parents_;           // by node index: parentNode()
  std::vector<Matrix4d> staticLocal_;  // by node index (identity for nodes outside the scene)
  std::vector<Animation> animations_;
  std::vector<AnimationInfo> animationInfo_;
  mutable std::map<int, std::vector<Primitive>> meshes_;
};

// The files `path` (.gltf or .glb) names besides itself, as (field, path):
// buffers[i] and images[i] with a uri that is not data: (textures and
// cut-outs), and nodes[i]/meshes[i].extras.obscura.displacement.map, each
// resolved against the file's folder. Read without tinygltf and without
// checking more than needs be: for refusing outputs over them and for a
// checkpoint's fingerprint, before or after loading. Empty for a file
// that cannot be read or parsed (loading it says why).
std::vector<std::pair<std::string, std::string>> gltfExternalFiles(const std::string& path);

}  // namespace obscura
