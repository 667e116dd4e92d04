#include "core/gltf_loader.h"
#include "core/obj_loader.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>

#include "core/cage.h"
#include "core/error.h"
#include "core/settings.h"

namespace obscura {
namespace {

namespace fs = std::filesystem;
using Matrix4d = std::array<double, 16>;  // column-major, as glTF stores it

Matrix4d identity4() { return {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; }

Matrix4d mul(const Matrix4d& a, const Matrix4d& b) {
  Matrix4d r{};
  for (int c = 0; c < 4; ++c)
    for (int row = 0; row < 4; ++row) {
      double v = 0;
      for (int k = 0; k < 4; ++k) v += a[k * 4 + row] * b[c * 4 + k];
      r[c * 4 + row] = v;
    }
  return r;
}

std::string oneLine(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

// Encoded image bytes handed over by tinygltf, decoded later (lazily).
struct ImageBytes {
  std::map<int, std::vector<unsigned char>> bytes;
};

bool keepImageBytes(tinygltf::Image* image, const int index, std::string*, std::string*, int, int,
                    const unsigned char* data, int size, void* user) {
  auto* store = static_cast<ImageBytes*>(user);
  store->bytes[index].assign(data, data + size);
  image->width = image->height = 0;  // not decoded yet
  return true;
}

class Loader {
 public:
  Loader(std::string path, LoadOptions options) : path_(std::move(path)), options_(options) {}

  std::unique_ptr<Scene> load() {
    readModel();
    scene_ = std::make_unique<Scene>();
    scene_->sourcePath = path_;
    scene_->sourceMeshes = model_.meshes.size();
    warnUnsupported();
    loadMaterials();
    collectNodes();
    buildGeometry();
    scene_->setUvsRunDown();  // glTF's v = 0 is the top row of an image
    scene_->setRobust(options_.robust);
    scene_->commit();
    return std::move(scene_);
  }

 private:
  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw Error(path_ + ": " + field + ": " + what);
  }
  void warn(const std::string& what) const { Log::warnOnce(path_ + ": " + what); }

  void readModel() {
    std::error_code ec;
    if (!fs::exists(path_, ec)) throw Error(path_ + ": cannot open scene: no such file");
    if (fs::is_directory(path_, ec)) throw Error(path_ + ": cannot open scene: is a directory");
    std::ifstream in(path_, std::ios::binary);
    if (!in) throw Error(path_ + ": cannot open scene: " + std::strerror(errno));
    char magic[4] = {};
    in.read(magic, 4);
    const bool binary = in.gcount() == 4 && std::memcmp(magic, "glTF", 4) == 0;
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(keepImageBytes, &images_);
    std::string err, warn;
    const bool ok = binary ? loader.LoadBinaryFromFile(&model_, &err, &warn, path_)
                           : loader.LoadASCIIFromFile(&model_, &err, &warn, path_);
    if (!warn.empty()) Log::warnOnce(path_ + ": " + oneLine(warn));
    if (!ok || !err.empty())
      throw Error(path_ + ": not a valid glTF 2.0 file: " + (err.empty() ? "parse error" : oneLine(err)));
  }

  void warnUnsupported() {
    static const std::set<std::string> harmless = {"KHR_materials_emissive_strength", "KHR_mesh_quantization"};
    for (const auto& e : model_.extensionsUsed)
      if (!harmless.count(e)) warn("extension " + e + " is not supported (ignored)");
    for (const auto& e : model_.extensionsRequired)
      if (e == "KHR_draco_mesh_compression" || e == "EXT_meshopt_compression")
        fail("extensionsRequired", e + " is not supported; decompress the file first");
    if (!model_.skins.empty()) warn("skins are not supported (meshes render in bind pose)");
    if (!model_.animations.empty()) warn("animations are not supported (the static pose is rendered)");
    if (!model_.lights.empty()) warn("KHR_lights_punctual lights are ignored (the sky is the only light)");
  }

  void loadMaterials() {
    std::map<int, int> imageToTexture;
    for (size_t i = 0; i < model_.materials.size(); ++i) {
      const auto& gm = model_.materials[i];
      const std::string field = "materials[" + std::to_string(i) + "]";
      Material m;
      m.name = gm.name;
      const auto& f = gm.pbrMetallicRoughness.baseColorFactor;
      if (f.size() >= 3) {
        m.baseColorFactor = Vec3(float(f[0]), float(f[1]), float(f[2]));
        if (!isFinite(m.baseColorFactor) || m.baseColorFactor.x < 0 || m.baseColorFactor.y < 0 ||
            m.baseColorFactor.z < 0)
          fail(field + ".pbrMetallicRoughness.baseColorFactor", "must be finite and non-negative");
      }
      if (gm.alphaMode == "BLEND" || gm.alphaMode == "MASK")
        warn("alphaMode " + gm.alphaMode + " is not supported (surfaces are opaque)");
      if (gm.emissiveFactor.size() >= 3 && (gm.emissiveFactor[0] > 0 || gm.emissiveFactor[1] > 0 || gm.emissiveFactor[2] > 0))
        warn("emission is ignored by ambient passes");
      const auto& ti = gm.pbrMetallicRoughness.baseColorTexture;
      if (ti.index >= 0) {
        const std::string tfield = field + ".pbrMetallicRoughness.baseColorTexture";
        if (size_t(ti.index) >= model_.textures.size()) fail(tfield + ".index", "texture " + std::to_string(ti.index) + " does not exist");
        if (ti.texCoord != 0) {
          warn("textures on TEXCOORD_" + std::to_string(ti.texCoord) + " are not supported (only TEXCOORD_0; texture ignored)");
        } else {
          if (!ti.extensions.empty()) warn("texture transforms (KHR_texture_transform) are not supported");
          const auto& tex = model_.textures[size_t(ti.index)];
          if (tex.source < 0 || size_t(tex.source) >= model_.images.size())
            fail("textures[" + std::to_string(ti.index) + "].source", "image does not exist");
          auto it = imageToTexture.find(tex.source);
          if (it == imageToTexture.end()) {
            auto bytes = images_.bytes.find(tex.source);
            const auto& img = model_.images[size_t(tex.source)];
            const std::string src = "images[" + std::to_string(tex.source) + "]" + (img.uri.empty() || img.uri.rfind("data:", 0) == 0 ? "" : " '" + img.uri + "'");
            if (bytes == images_.bytes.end() || bytes->second.empty())
              fail(src, "image data is missing");
            scene_->textures.push_back(std::make_unique<Texture>(std::move(bytes->second), path_ + ": " + src, true));
            it = imageToTexture.emplace(tex.source, int(scene_->textures.size()) - 1).first;
          }
          m.texture = it->second;
          if (tex.sampler >= 0 && size_t(tex.sampler) < model_.samplers.size()) {
            const auto wrap = [](int w) {
              return w == 33071 ? WrapMode::ClampToEdge : w == 33648 ? WrapMode::MirroredRepeat : WrapMode::Repeat;
            };
            m.wrapS = wrap(model_.samplers[size_t(tex.sampler)].wrapS);
            m.wrapT = wrap(model_.samplers[size_t(tex.sampler)].wrapT);
          }
        }
      }
      scene_->materials.push_back(std::move(m));
    }
  }

  Matrix4d localMatrix(const tinygltf::Node& n, const std::string& field) const {
    if (n.matrix.size() == 16) {
      Matrix4d m;
      for (int i = 0; i < 16; ++i) m[size_t(i)] = n.matrix[size_t(i)];
      for (double v : m)
        if (!std::isfinite(v)) fail(field + ".matrix", "not finite");
      return m;
    }
    Matrix4d t = identity4(), r = identity4(), s = identity4();
    if (n.translation.size() == 3) {
      t[12] = n.translation[0], t[13] = n.translation[1], t[14] = n.translation[2];
    }
    if (n.rotation.size() == 4) {
      double x = n.rotation[0], y = n.rotation[1], z = n.rotation[2], w = n.rotation[3];
      const double len = std::sqrt(x * x + y * y + z * z + w * w);
      if (!(len > 0) || !std::isfinite(len)) fail(field + ".rotation", "not a valid quaternion");
      x /= len, y /= len, z /= len, w /= len;
      r = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),     0,
           2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),     0,
           2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y), 0,
           0, 0, 0, 1};
    }
    if (n.scale.size() == 3) {
      s[0] = n.scale[0], s[5] = n.scale[1], s[10] = n.scale[2];
    }
    const Matrix4d m = mul(t, mul(r, s));
    for (double v : m)
      if (!std::isfinite(v)) fail(field, "transform is not finite");
    return m;
  }

  struct MeshUse {
    int mesh;
    Matrix4d world;
    std::string node;
    int nodeIndex;
  };

  void visit(int index, const Matrix4d& parent, std::vector<int>& stack) {
    const std::string field = "nodes[" + std::to_string(index) + "]";
    if (index < 0 || size_t(index) >= model_.nodes.size()) fail(field, "node does not exist");
    for (int s : stack)
      if (s == index) fail(field, "cycle in the node hierarchy");
    // glTF requires a tree: a node reached twice has two parents (and a file
    // that lists nodes twice per level would otherwise explode as 2^depth).
    if (visited_[size_t(index)]) fail(field, "node has more than one parent (the hierarchy must be a tree)");
    visited_[size_t(index)] = 1;
    if (stack.size() > 1000) fail(field, "node hierarchy deeper than 1000");
    const tinygltf::Node& n = model_.nodes[size_t(index)];
    const Matrix4d world = mul(parent, localMatrix(n, field));
    if (n.skin >= 0) warn("skinned meshes render in their bind pose");
    if (n.mesh >= 0) {
      if (size_t(n.mesh) >= model_.meshes.size()) fail(field + ".mesh", "mesh " + std::to_string(n.mesh) + " does not exist");
      uses_.push_back({n.mesh, world, n.name.empty() ? field : n.name, index});
    }
    if (n.camera >= 0) addCamera(n, n.camera, world, field);
    stack.push_back(index);
    for (int c : n.children) visit(c, world, stack);
    stack.pop_back();
  }

  void collectNodes() {
    visited_.assign(model_.nodes.size(), 0);
    std::vector<int> roots;
    if (!model_.scenes.empty()) {
      int s = model_.defaultScene >= 0 ? model_.defaultScene : 0;
      if (size_t(s) >= model_.scenes.size()) fail("scene", "scene " + std::to_string(s) + " does not exist");
      if (model_.scenes.size() > 1) warn("file has " + std::to_string(model_.scenes.size()) + " scenes; rendering scene " + std::to_string(s));
      roots = model_.scenes[size_t(s)].nodes;
    } else {
      std::vector<bool> isChild(model_.nodes.size(), false);
      for (const auto& n : model_.nodes)
        for (int c : n.children)
          if (c >= 0 && size_t(c) < isChild.size()) isChild[size_t(c)] = true;
      for (size_t i = 0; i < model_.nodes.size(); ++i)
        if (!isChild[i]) roots.push_back(int(i));
    }
    std::vector<int> stack;
    for (int r : roots) visit(r, identity4(), stack);
    if (model_.scenes.empty())  // every node is reachable from a root unless it sits on a cycle
      for (size_t i = 0; i < model_.nodes.size(); ++i)
        if (!visited_[i]) fail("nodes[" + std::to_string(i) + "]", "cycle in the node hierarchy");
    // `--camera INDEX` means the index in the file's cameras[], whatever the
    // order nodes were visited in.
    std::stable_sort(scene_->cameras.begin(), scene_->cameras.end(),
                     [](const Camera& a, const Camera& b) { return a.fileIndex < b.fileIndex; });
  }

  void addCamera(const tinygltf::Node& node, int index, const Matrix4d& world, const std::string& field) {
    const std::string cfield = "cameras[" + std::to_string(index) + "]";
    if (size_t(index) >= model_.cameras.size()) fail(field + ".camera", "camera " + std::to_string(index) + " does not exist");
    const auto& gc = model_.cameras[size_t(index)];
    if (gc.type != "perspective") {
      warn(cfield + ": " + gc.type + " cameras are not supported (skipped)");
      return;
    }
    Camera c;
    c.fileIndex = index;
    c.name = !gc.name.empty() ? gc.name : !node.name.empty() ? node.name : cfield;
    c.yfov = float(gc.perspective.yfov);
    if (!(c.yfov > 0.0f && c.yfov < kPi)) fail(cfield + ".perspective.yfov", "must be in (0, pi)");
    c.znear = float(gc.perspective.znear);
    if (!(c.znear >= 0.0f) || !std::isfinite(c.znear)) fail(cfield + ".perspective.znear", "must be >= 0");
    c.zfar = gc.perspective.zfar > 0 ? float(gc.perspective.zfar) : kInfinity;
    // Rigid part of the node transform: orthonormalized axes, so a scaled
    // camera node (legal in files, meaningless for a pinhole) still works.
    Affine a = Affine::fromColumnMajor4x4(world.data());
    Vec3 x(a.m[0][0], a.m[1][0], a.m[2][0]), y(a.m[0][1], a.m[1][1], a.m[2][1]);
    if (!(length(x) > 0) || !(length(y) > 0)) fail(field, "camera transform is degenerate");
    x = normalize(x);
    y = normalize(y - x * dot(x, y));
    const Vec3 z = cross(x, y);
    if (!isFinite(z)) fail(field, "camera transform is degenerate");
    for (int r = 0; r < 3; ++r) a.m[r][0] = x[r], a.m[r][1] = y[r], a.m[r][2] = z[r];
    c.toWorld = a;
    scene_->cameras.push_back(std::move(c));
  }

  // --- accessors ---------------------------------------------------------
  struct View {
    const unsigned char* data = nullptr;  // first element
    size_t stride = 0, count = 0;
    int componentType = 0, components = 0;
    bool normalized = false;
  };

  View view(int accessor, const std::string& field) const {
    const std::string f = field + " (accessors[" + std::to_string(accessor) + "])";
    if (accessor < 0 || size_t(accessor) >= model_.accessors.size()) fail(field, "accessor " + std::to_string(accessor) + " does not exist");
    const auto& a = model_.accessors[size_t(accessor)];
    if (a.sparse.isSparse) fail(f, "sparse accessors are not supported");
    View v;
    v.count = a.count;
    v.componentType = a.componentType;
    v.normalized = a.normalized;
    v.components = tinygltf::GetNumComponentsInType(uint32_t(a.type));
    const int csize = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
    if (v.components <= 0 || csize <= 0) fail(f, "invalid type or componentType");
    if (a.bufferView < 0 || size_t(a.bufferView) >= model_.bufferViews.size()) fail(f, "bufferView missing or out of range");
    const auto& bv = model_.bufferViews[size_t(a.bufferView)];
    if (bv.buffer < 0 || size_t(bv.buffer) >= model_.buffers.size()) fail(f, "buffer out of range");
    const auto& buf = model_.buffers[size_t(bv.buffer)];
    const size_t elem = size_t(csize) * size_t(v.components);
    v.stride = bv.byteStride ? bv.byteStride : elem;
    if (v.stride < elem) fail(f, "byteStride smaller than the element");
    if (bv.byteOffset > buf.data.size() || bv.byteLength > buf.data.size() - bv.byteOffset)
      fail("bufferViews[" + std::to_string(a.bufferView) + "]", "extends past the end of its buffer");
    if (v.count > 0) {
      const size_t need = a.byteOffset + (v.count - 1) * v.stride + elem;
      if (a.byteOffset > bv.byteLength || need > bv.byteLength || (v.count - 1) > (SIZE_MAX / v.stride))
        fail(f, "extends past the end of its bufferView");
    }
    v.data = buf.data.data() + bv.byteOffset + a.byteOffset;
    return v;
  }

  static float component(const View& v, size_t i, int c) {
    const unsigned char* p = v.data + i * v.stride;
    switch (v.componentType) {
      case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float f;
        std::memcpy(&f, p + 4 * c, 4);
        return f;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return v.normalized ? p[c] / 255.0f : p[c];
      case TINYGLTF_COMPONENT_TYPE_BYTE: {
        const float x = float(int8_t(p[c]));
        return v.normalized ? std::max(x / 127.0f, -1.0f) : x;
      }
      case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t x;
        std::memcpy(&x, p + 2 * c, 2);
        return v.normalized ? x / 65535.0f : float(x);
      }
      case TINYGLTF_COMPONENT_TYPE_SHORT: {
        int16_t x;
        std::memcpy(&x, p + 2 * c, 2);
        return v.normalized ? std::max(x / 32767.0f, -1.0f) : float(x);
      }
      default: return 0.0f;
    }
  }

  std::vector<Vec3> readVec3(int accessor, const std::string& field) const {
    const View v = view(accessor, field);
    if (v.components != 3) fail(field, "must be VEC3");
    std::vector<Vec3> out(v.count);
    for (size_t i = 0; i < v.count; ++i) {
      out[i] = Vec3(component(v, i, 0), component(v, i, 1), component(v, i, 2));
      if (!isFinite(out[i])) fail(field, "element " + std::to_string(i) + " is NaN or infinite");
    }
    return out;
  }

  std::vector<float> readVec2(int accessor, const std::string& field) const {
    const View v = view(accessor, field);
    if (v.components != 2) fail(field, "must be VEC2");
    std::vector<float> out(v.count * 2);
    for (size_t i = 0; i < v.count; ++i) {
      out[2 * i] = component(v, i, 0);
      out[2 * i + 1] = component(v, i, 1);
      if (!std::isfinite(out[2 * i]) || !std::isfinite(out[2 * i + 1]))
        fail(field, "element " + std::to_string(i) + " is NaN or infinite");
    }
    return out;
  }

  std::vector<uint32_t> readIndices(int accessor, const std::string& field, size_t vertexCount) const {
    const View v = view(accessor, field);
    if (v.components != 1) fail(field, "must be SCALAR");
    std::vector<uint32_t> out(v.count);
    for (size_t i = 0; i < v.count; ++i) {
      const unsigned char* p = v.data + i * v.stride;
      uint32_t x;
      switch (v.componentType) {
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: x = p[0]; break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t s; std::memcpy(&s, p, 2); x = s; break; }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: std::memcpy(&x, p, 4); break;
        default: fail(field, "index componentType must be an unsigned integer type");
      }
      if (x >= vertexCount)
        fail(field, "index " + std::to_string(x) + " at element " + std::to_string(i) + " is out of range (" +
                        std::to_string(vertexCount) + " vertices)");
      out[i] = x;
    }
    return out;
  }

  // One primitive, in object space.
  struct SubdivisionRequest {
    SubdivisionScheme scheme;
    int level;
  };
  struct PrimData {
    std::vector<Vec3> positions, normals;
    std::vector<float> uvs;
    std::vector<uint32_t> indices;
    int material = -1;
    // A subdivided primitive: its cage (object space), how to refine it and
    // what displaces it; refined per use, in world space (buildGeometry).
    std::optional<SubdivisionCage> cage;
    SubdivisionRequest sub{};
    CageDisplacement displacement;
    std::string field;
  };

  // The primitives of meshes[meshIndex], subdivided and displaced when its
  // extras (or the using node's, `nodeIndex`, -1 for none) say so.
  std::vector<PrimData> readMesh(int meshIndex, int nodeIndex) {
    const auto& mesh = model_.meshes[size_t(meshIndex)];
    // An unrefined load (the camera probe of adaptive refinement) keeps
    // flagged meshes as their cage triangles and reads no height map.
    const std::optional<SubdivisionRequest> sub = options_.unrefined ? std::nullopt : subdivisionOf(meshIndex);
    const std::optional<DisplacementRequest> disp =
        options_.unrefined ? std::nullopt : displacementOf(meshIndex, nodeIndex, sub.has_value());
    std::vector<PrimData> out;
    for (size_t pi = 0; pi < mesh.primitives.size(); ++pi) {
      const auto& gp = mesh.primitives[pi];
      const std::string field = "meshes[" + std::to_string(meshIndex) + "].primitives[" + std::to_string(pi) + "]";
      if (gp.mode != TINYGLTF_MODE_TRIANGLES && gp.mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
          gp.mode != TINYGLTF_MODE_TRIANGLE_FAN && gp.mode != -1) {
        warn("point and line primitives are not supported (skipped)");
        continue;
      }
      if (!gp.targets.empty()) warn("morph targets are not supported (base shape rendered)");
      auto pos = gp.attributes.find("POSITION");
      if (pos == gp.attributes.end()) fail(field + ".attributes", "POSITION is missing");
      PrimData d;
      d.positions = readVec3(pos->second, field + ".attributes.POSITION");
      if (auto n = gp.attributes.find("NORMAL"); n != gp.attributes.end()) {
        d.normals = readVec3(n->second, field + ".attributes.NORMAL");
        if (d.normals.size() != d.positions.size()) fail(field + ".attributes.NORMAL", "count differs from POSITION");
      }
      if (gp.attributes.count("COLOR_0")) warn("vertex colors (COLOR_0) are not supported (ignored)");
      if (gp.material >= 0) {
        if (size_t(gp.material) >= scene_->materials.size()) fail(field + ".material", "material " + std::to_string(gp.material) + " does not exist");
        d.material = gp.material;
        if (scene_->materials[size_t(gp.material)].texture >= 0 && !gp.attributes.count("TEXCOORD_0"))
          warn(field + ": textured material without TEXCOORD_0 (texture ignored)");
      }
      // Texture coordinates serve a texture, the displacement of a subdivided
      // mesh and integrators that work in texture space (containment), so
      // they are kept whenever the file has them (8 bytes a vertex).
      if (auto t = gp.attributes.find("TEXCOORD_0"); t != gp.attributes.end()) {
        d.uvs = readVec2(t->second, field + ".attributes.TEXCOORD_0");
        if (d.uvs.size() != 2 * d.positions.size()) fail(field + ".attributes.TEXCOORD_0", "count differs from POSITION");
      }
      if (disp && d.uvs.empty()) fail(field + ".attributes", "TEXCOORD_0 is missing; " + disp->field + " needs it");
      std::vector<uint32_t> idx;
      if (gp.indices >= 0) {
        idx = readIndices(gp.indices, field + ".indices", d.positions.size());
      } else {
        idx.resize(d.positions.size());
        for (size_t i = 0; i < idx.size(); ++i) idx[i] = uint32_t(i);
      }
      // Triangle lists from every triangle mode.
      if (gp.mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t i = 2; i < idx.size(); ++i) {
          const bool odd = i % 2 == 1;
          d.indices.insert(d.indices.end(), {idx[i - 2], odd ? idx[i] : idx[i - 1], odd ? idx[i - 1] : idx[i]});
        }
      } else if (gp.mode == TINYGLTF_MODE_TRIANGLE_FAN) {
        for (size_t i = 2; i < idx.size(); ++i) d.indices.insert(d.indices.end(), {idx[0], idx[i - 1], idx[i]});
      } else {
        if (idx.size() % 3 != 0) fail(field + (gp.indices >= 0 ? ".indices" : ".attributes.POSITION"), "count is not a multiple of 3");
        d.indices = std::move(idx);
      }
      if (d.indices.empty()) continue;
      if (sub) cagePrimitive(d, *sub, disp ? &*disp : nullptr, field);
      out.push_back(std::move(d));
    }
    return out;
  }

  // The object `extras.obscura` of a mesh or node (`owner` names it in
  // errors), or null if there is none.
  const tinygltf::Value* obscuraExtras(const tinygltf::Value& extras, const std::string& owner) const {
    if (!extras.IsObject() || !extras.Has("obscura")) return nullptr;
    const tinygltf::Value& ob = extras.Get("obscura");
    if (!ob.IsObject()) fail(owner + ".extras.obscura", "must be an object");
    return &ob;
  }

  // meshes[i].extras.obscura.subdivision = {"scheme": "catmull-clark"|"loop",
  // "level": N} (README "Scenes"); none if absent.
  std::optional<SubdivisionRequest> subdivisionOf(int meshIndex) {
    const std::string owner = "meshes[" + std::to_string(meshIndex) + "]";
    const tinygltf::Value* ob = obscuraExtras(model_.meshes[size_t(meshIndex)].extras, owner);
    if (!ob || !ob->Has("subdivision")) return std::nullopt;
    const std::string field = owner + ".extras.obscura";
    const tinygltf::Value& sub = ob->Get("subdivision");
    if (!sub.IsObject()) fail(field + ".subdivision", "must be an object");
    SubdivisionRequest r{SubdivisionScheme::CatmullClark, options_.subdivisionLevel};
    if (sub.Has("scheme")) {
      const tinygltf::Value& v = sub.Get("scheme");
      const std::string name = v.IsString() ? v.Get<std::string>() : "";
      if (name == "loop") r.scheme = SubdivisionScheme::Loop;
      else if (name != "catmull-clark") fail(field + ".subdivision.scheme", "expected \"catmull-clark\" or \"loop\"");
    }
    if (sub.Has("level")) {
      const tinygltf::Value& v = sub.Get("level");
      if (!v.IsInt() || v.Get<int>() < 0 || v.Get<int>() > 10) fail(field + ".subdivision.level", "expected an integer in [0, 10]");
      r.level = v.Get<int>();
    }
    return r;
  }

  // A height map displacing a subdivided mesh: from the using node's
  // extras.obscura.displacement, else the mesh's, else the CLI's --displace
  // (README "Scenes"). `field` names where it came from, for errors.
  struct DisplacementRequest {
    std::string map;  // path as written (relative to the .gltf) or as given to --displace
    std::string path;  // the file to read
    double scale, midlevel;
    std::string field;
    std::string scaleField;  // where scale came from, for messages; "" = the displacementScale setting
  };

  // {"map": path, "scale": s, "midlevel": m} at owner.extras.obscura.displacement.
  std::optional<DisplacementRequest> parseDisplacement(const tinygltf::Value& extras, const std::string& owner) const {
    const tinygltf::Value* ob = obscuraExtras(extras, owner);
    if (!ob || !ob->Has("displacement")) return std::nullopt;
    DisplacementRequest r{"", "", options_.displacementScale, options_.displacementMidlevel,
                          owner + ".extras.obscura.displacement"};
    const tinygltf::Value& d = ob->Get("displacement");
    if (!d.IsObject()) fail(r.field, "must be an object");
    const tinygltf::Value& map = d.Get("map");  // a null value when absent
    if (!map.IsString() || map.Get<std::string>().empty()) fail(r.field + ".map", "expected the path of a height map");
    r.map = map.Get<std::string>();
    const fs::path mp(r.map);
    r.path = mp.is_absolute() ? r.map : (fs::path(path_).parent_path() / mp).string();
    for (const auto& [key, value] : {std::pair{"scale", &r.scale}, std::pair{"midlevel", &r.midlevel}}) {
      if (!d.Has(key)) continue;
      const tinygltf::Value& v = d.Get(key);
      if (!v.IsNumber() || !std::isfinite(v.GetNumberAsDouble())) fail(r.field + "." + key, "expected a finite number");
      *value = v.GetNumberAsDouble();
    }
    if (d.Has("scale")) r.scaleField = path_ + ": " + r.field + ".scale";
    return r;
  }

  std::optional<DisplacementRequest> displacementOf(int meshIndex, int nodeIndex, bool subdivided) {
    const std::string mesh = "meshes[" + std::to_string(meshIndex) + "]";
    std::optional<DisplacementRequest> r;
    if (nodeIndex >= 0) r = parseDisplacement(model_.nodes[size_t(nodeIndex)].extras, "nodes[" + std::to_string(nodeIndex) + "]");
    // The mesh's own is checked even when a node overrides it.
    std::optional<DisplacementRequest> own = parseDisplacement(model_.meshes[size_t(meshIndex)].extras, mesh);
    if (!r) r = std::move(own);
    if (r && !subdivided) fail(r->field, "needs a subdivided mesh (" + mesh + ".extras.obscura.subdivision)");
    if (!r && subdivided && !options_.displacementMap.empty()) {
      r = DisplacementRequest{options_.displacementMap, options_.displacementMap, options_.displacementScale,
                              options_.displacementMidlevel, settingName(Setting::Displacement)};
      cliDisplacementUsed_ = true;
    }
    return r;
  }

  // Each file is read once, on first use, however many meshes share it.
  std::shared_ptr<const HeightMap> heightMap(const DisplacementRequest& r) {
    const std::string key = fs::absolute(r.path).lexically_normal().string();
    auto it = heightMaps_.find(key);
    if (it != heightMaps_.end()) return it->second;
    try {
      it = heightMaps_.emplace(key, std::make_shared<const HeightMap>(r.path)).first;
    } catch (const Error& e) {
      if (r.field == settingName(Setting::Displacement)) throw;  // already names the file, as given
      std::string why = e.what();
      if (why.rfind(r.path + ": ", 0) == 0) why.erase(0, r.path.size() + 2);
      fail(r.field + ".map", r.map + ": " + why);
    }
    return it->second;
  }

  // Turns a triangle primitive into a subdivision cage (object space), to be
  // refined and displaced per use (buildGeometry).
  //
  // glTF splits a vertex wherever an attribute differs (a uv seam, a hard
  // normal): taken as they are, those copies would make the cage open along
  // every seam and the refined surface would tear there. So corners at equal
  // positions (every coordinate ==; +0 and -0 alike) are welded into one
  // cage vertex, while each corner keeps its own uv (face-varying). A
  // welded vertex takes one side's uv on the refined mesh (SubdividedMesh),
  // so displacement moves it once and opens no crack.
  void cagePrimitive(PrimData& d, const SubdivisionRequest& r, const DisplacementRequest* disp,
                          const std::string& field) {
    const size_t n = d.positions.size();
    std::vector<uint32_t> order(n);
    for (size_t i = 0; i < n; ++i) order[i] = uint32_t(i);
    const auto less = [&](uint32_t a, uint32_t b) {
      const Vec3 &p = d.positions[a], &q = d.positions[b];
      return p.x != q.x ? p.x < q.x : p.y != q.y ? p.y < q.y : p.z < q.z;
    };
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return less(a, b) || (!less(b, a) && a < b); });
    // representative[i]: the first glTF vertex at i's position.
    std::vector<uint32_t> representative(n);
    for (size_t k = 0; k < n; ++k)
      representative[order[k]] = k > 0 && !less(order[k - 1], order[k]) ? representative[order[k - 1]] : order[k];
    // Cage vertices in the order of their first glTF vertex.
    std::vector<int> cageIndex(n, -1);
    SubdivisionCage cage;
    for (size_t i = 0; i < n; ++i)
      if (representative[i] == i) cageIndex[i] = int(cage.positions.size()), cage.positions.push_back(d.positions[i]);
    cage.faceSizes.assign(d.indices.size() / 3, 3);
    cage.faceIndices.reserve(d.indices.size());
    for (size_t t = 0; t < d.indices.size(); t += 3) {
      for (size_t k = 0; k < 3; ++k) {
        const uint32_t a = d.indices[t + k], b = d.indices[t + (k + 1) % 3];
        if (representative[a] == representative[b])
          fail(field + ".indices", "triangle " + std::to_string(t / 3) + " is degenerate (vertices " + std::to_string(a) +
                                       " and " + std::to_string(b) + (a == b ? " repeated" : " at the same position") +
                                       "); a subdivision cage needs three distinct corners");
        cage.faceIndices.push_back(cageIndex[representative[a]]);
      }
    }
    if (!d.uvs.empty()) {
      cage.uvs = d.uvs;
      cage.uvIndices.assign(d.indices.begin(), d.indices.end());
      const bool textured = d.material >= 0 && scene_->materials[size_t(d.material)].texture >= 0;
      if (textured && options_.backend == SubdivisionBackend::Embree)
        warn(field + ": textures on Embree subdivision surfaces are not supported (the material's factor is used; " +
                     settingName(Setting::SubdivisionBackendOsd) + " keeps them)");
    }
    validateCage(cage, r.scheme, path_ + ": " + field);
    d.sub = r;
    d.field = field;
    if (disp) {
      // glTF's v runs down the image (v = 0 at the top row, as a
      // baseColorTexture is read) while HeightMap puts v = 0 at the bottom
      // (OBJ): the lookup uses (u, 1 - v), so a height map lines up with a
      // texture of the same image. The mesh keeps its uvs as the file has them.
      d.displacement.map = heightMap(*disp);
      d.displacement.scale = disp->scale, d.displacement.midlevel = disp->midlevel;
      d.displacement.flipV = true;
      d.displacement.scaleField = disp->scaleField;
    }
    d.cage = std::move(cage);
    d.positions.clear(), d.normals.clear(), d.uvs.clear(), d.indices.clear();
  }

  // A subdivided primitive's cage, placed by `xf` and refined as the
  // request and the load options say (core/cage.h). Displacement scales are
  // in the mesh's units: they follow the transform's scale (the cube root
  // of its determinant, exact for rotation + uniform scale).
  void addSubdivided(PrimData& p, const Affine& xf) {
    SubdivisionCage c = std::move(*p.cage);
    for (Vec3& v : c.positions) v = xf.point(v);
    LoadOptions o = options_;
    o.scheme = p.sub.scheme;
    o.subdivisionLevel = p.sub.level;
    CageDisplacement d = p.displacement;
    const double det = xf.m[0][0] * (xf.m[1][1] * xf.m[2][2] - xf.m[1][2] * xf.m[2][1]) -
                       xf.m[0][1] * (xf.m[1][0] * xf.m[2][2] - xf.m[1][2] * xf.m[2][0]) +
                       xf.m[0][2] * (xf.m[1][0] * xf.m[2][1] - xf.m[1][1] * xf.m[2][0]);
    d.scale *= std::cbrt(std::abs(det));
    if (det < 0) {
      // A mirroring transform turns the cage inside out: the limit normal
      // dP/du x dP/dv would point into the surface, and displacement with
      // it. Reversing every face's corners (uvs with them) restores it.
      size_t k = 0;
      for (const int n : c.faceSizes) {
        std::reverse(c.faceIndices.begin() + long(k) + 1, c.faceIndices.begin() + long(k) + n);
        if (!c.uvIndices.empty()) std::reverse(c.uvIndices.begin() + long(k) + 1, c.uvIndices.begin() + long(k) + n);
        k += size_t(n);
      }
    }
    addCage(*scene_, c, o, d, p.material, path_ + ": " + p.field);
  }

  void buildGeometry() {
    // A node with a displacement of its own gets its own copy of the mesh:
    // geometry is keyed by (mesh, that node), -1 for the mesh as the file has it.
    const auto key = [&](const MeshUse& u) {
      const tinygltf::Value& extras = model_.nodes[size_t(u.nodeIndex)].extras;
      const std::string owner = "nodes[" + std::to_string(u.nodeIndex) + "]";
      const tinygltf::Value* ob = obscuraExtras(extras, owner);
      return std::pair{u.mesh, ob && ob->Has("displacement") ? u.nodeIndex : -1};
    };
    std::map<std::pair<int, int>, int> useCount;
    for (const auto& u : uses_) ++useCount[key(u)];
    // A subdivided mesh is refined per use, in world space - adaptive
    // refinement and displacement depend on where it is - so it is never
    // instanced.
    for (const auto& u : uses_)
      if (subdivisionOf(u.mesh)) useCount[key(u)] = 1;
    std::map<std::pair<int, int>, int> instanced;  // (glTF mesh, node) -> Scene instanced mesh
    for (const auto& u : uses_) {
      const Affine xf = Affine::fromColumnMajor4x4(u.world.data());
      const auto k = key(u);
      if (useCount[k] == 1) {
        // Used once: bake into world space; no instance traversal at render.
        std::vector<PrimData> prims = readMesh(u.mesh, k.second);
        for (PrimData& p : prims) {
          if (p.cage) {
            addSubdivided(p, xf);
            continue;
          }
          for (Vec3& v : p.positions) v = xf.point(v);
          for (Vec3& n : p.normals) n = xf.normal(n);
          scene_->setPrimitiveName(
              scene_->addWorldPrimitive(p.positions, p.indices, std::move(p.normals), std::move(p.uvs), p.material),
              model_.meshes[size_t(u.mesh)].name);
        }
        if (!prims.empty()) ++scene_->flattenedMeshes;
        continue;
      }
      auto it = instanced.find(k);
      if (it == instanced.end()) {
        std::vector<PrimData> prims = readMesh(u.mesh, k.second);
        const int m = prims.empty() ? -1 : scene_->addInstancedMesh(model_.meshes[size_t(u.mesh)].name);
        for (PrimData& p : prims)
          scene_->addPrimitiveToMesh(m, p.positions, p.indices, std::move(p.normals), std::move(p.uvs), p.material);
        it = instanced.emplace(k, m).first;
      }
      if (it->second >= 0) scene_->addInstance(it->second, xf, u.node);
    }
    if (!options_.displacementMap.empty() && !cliDisplacementUsed_)
      warn(settingName(Setting::Displacement) + " applies to subdivided meshes (extras.obscura.subdivision) without a displacement of their own; "
           "none here (height map unused)");
  }

  std::string path_;
  LoadOptions options_;
  tinygltf::Model model_;
  ImageBytes images_;
  std::unique_ptr<Scene> scene_;
  std::vector<MeshUse> uses_;
  std::vector<char> visited_;
  std::map<std::string, std::shared_ptr<const HeightMap>> heightMaps_;  // by absolute path
  bool cliDisplacementUsed_ = false;
};

}  // namespace

std::unique_ptr<Scene> loadGltf(const std::string& path, const LoadOptions& options) {
  return Loader(path, options).load();
}

std::unique_ptr<Scene> loadScene(const std::string& path, const LoadOptions& options) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".obj") return loadObj(path, options);
  return loadGltf(path, options);
}

}  // namespace obscura
