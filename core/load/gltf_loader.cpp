#include "core/load/gltf_loader.h"

#include "core/scene/tangents.h"
#include "core/load/obj_loader.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <optional>

#include "core/load/cage.h"
#include "core/image/texture_size.h"
#include <obscura/error.h>
#include "core/scene/motion.h"
#include "core/util/memory_budget.h"
#include "core/util/option_names.h"

namespace obscura {
namespace {

namespace fs = std::filesystem;

// Builds a Scene from a decoded document (core/load/gltf_document.h) as the load
// options say, adding what is Obscura's own: the mesh and node extras
// (extras.obscura.subdivision, .displacement; docs/scenes.md "Scenes") turned into
// subdivision cages, refined and displaced per use.
class Builder {
 public:
  Builder(const GltfDocument& doc, const LoadOptions& options) : doc_(doc), options_(options) {}

  std::unique_ptr<Scene> build() {
    // Refused before any of it is allocated (core/util/memory_budget.h).
    if (!options_.unrefined) requireMemory(estimateSceneMemory(doc_, options_), doc_.path());
    scene_ = std::make_unique<Scene>();
    scene_->sourcePath = doc_.path();
    scene_->sourceMeshes = doc_.model().meshes.size();
    scene_->materials = doc_.materials();
    // --normal-maps off: the scene has no normal map, so no tangent is read
    // or made and no normal image decoded (renders as without the maps).
    if (!options_.normalMaps)
      for (Material& m : scene_->materials) m.normalTexture = -1;
    for (const auto& t : doc_.textures()) scene_->textures.push_back(std::make_unique<Texture>(t.encoded, t.name, true));
    for (const auto& t : doc_.dataTextures())
      scene_->dataTextures.push_back(std::make_unique<Texture>(t.encoded, t.name, false));
    // The nodes as the animations place them at the time asked for (the
    // static pose without one); the hierarchy itself does not move.
    pose_ = doc_.pose(options_.time, options_.animations);
    scene_->cameras = pose_.cameras;
    sampleShutter();
    buildGeometry();
    moveCameras();
    applyObjectOverrides(scene_->objects, options_.objectOverrides);
    scene_->setUvsRunDown();  // glTF's v = 0 is the top row of an image
    scene_->setRobust(options_.robust);
    scene_->commit();
    const SceneStats s = scene_->stats();
    // An empty pass with exit status 0 would pass for a render: refused.
    if (s.renderedTriangles == 0 && s.subdivisionFaces == 0)
      throw Error(doc_.path() + ": the scene has no triangles to render" +
                  (hidden_.empty() ? "" : " (every mesh is hidden by a zero scale)"));
    // Warned once the scene is known to render (else the error says it all).
    for (const std::string& w : hidden_) warn(w);
    return std::move(scene_);
  }

 private:
  [[noreturn]] void fail(const std::string& field, const std::string& what) const { doc_.fail(field, what); }
  void warn(const std::string& what) const { doc_.warn(what); }

  struct SubdivisionRequest {
    SubdivisionScheme scheme;
    int level;
  };
  // One primitive in object space and, when subdivided, its cage (object
  // space), how to refine it and what displaces it; refined per use, in
  // world space (buildGeometry).
  struct PrimData : GltfDocument::Primitive {
    std::optional<SubdivisionCage> cage;
    SubdivisionRequest sub{};
    CageDisplacement displacement;
  };

  // The primitives of meshes[meshIndex], subdivided and displaced when its
  // extras (or the using node's, `nodeIndex`, -1 for none) say so.
  std::vector<PrimData> primitives(int meshIndex, int nodeIndex) {
    // An unrefined load (the camera probe of adaptive refinement) keeps
    // flagged meshes as their cage triangles and reads no height map.
    const std::optional<SubdivisionRequest> sub = options_.unrefined ? std::nullopt : subdivisionOf(meshIndex);
    const std::optional<DisplacementRequest> disp =
        options_.unrefined ? std::nullopt : displacementOf(meshIndex, nodeIndex, sub.has_value());
    std::vector<PrimData> out;
    for (const GltfDocument::Primitive& p : doc_.mesh(meshIndex)) {
      PrimData d;
      static_cast<GltfDocument::Primitive&>(d) = p;
      if (disp && d.uvs.empty()) fail(d.field + ".attributes", "TEXCOORD_0 is missing; " + disp->field + " needs it");
      if (sub) cagePrimitive(d, *sub, disp ? &*disp : nullptr, d.field);
      else attachTangents(d);
      out.push_back(std::move(d));
    }
    return out;
  }

  // A triangle primitive's tangents: kept (the file's TANGENT) or generated
  // (core/scene/tangents.h) when its material bends normals by a map and the
  // primitive has the uvs the map is read at; dropped otherwise.
  void attachTangents(PrimData& d) {
    const Material* m = d.material >= 0 ? &scene_->materials[size_t(d.material)] : nullptr;
    if (!m || m->normalTexture < 0) {
      d.tangents.clear();
      return;
    }
    if (d.uvs.empty()) {
      warn(d.field + ": normal-mapped material without TEXCOORD_0 (normal map ignored)");
      d.tangents.clear();
      return;
    }
    if (d.tangents.empty()) d.tangents = generateTangents(d.positions, d.normals, d.uvs, d.indices, true);
  }

  // The object `extras.obscura` of a mesh or node (`owner` names it in
  // errors), or null if there is none.
  // Every key is one Obscura reads for that owner (a mesh or a node): a
  // misspelt one ("occludr") used to be ignored, a render without the role
  // that looked right.
  const tinygltf::Value* obscuraExtras(const tinygltf::Value& extras, const std::string& owner) const {
    if (!extras.IsObject() || !extras.Has("obscura")) return nullptr;
    const tinygltf::Value& ob = extras.Get("obscura");
    const std::string field = owner + ".extras.obscura";
    if (!ob.IsObject()) fail(field, "must be an object");
    static const std::vector<std::string> meshKeys = {"subdivision", "displacement"},
                                          nodeKeys = {"displacement", "occluder", "camera", "matte", "occlusion"};
    knownKeys(ob, field, owner.rfind("meshes[", 0) == 0 ? meshKeys : nodeKeys);
    return &ob;
  }
  void knownKeys(const tinygltf::Value& object, const std::string& field, const std::vector<std::string>& known) const {
    for (const std::string& key : object.Keys())
      if (std::find(known.begin(), known.end(), key) == known.end())
        fail(field + "." + key, "unknown key" + nearestNameHint(key, known));
  }

  // meshes[i].extras.obscura.subdivision = {"scheme": "catmull-clark"|"loop",
  // "level": N} (docs/scenes.md "Scenes"); none if absent.
  std::optional<SubdivisionRequest> subdivisionOf(int meshIndex) {
    const std::string owner = "meshes[" + std::to_string(meshIndex) + "]";
    const tinygltf::Value* ob = obscuraExtras(doc_.model().meshes[size_t(meshIndex)].extras, owner);
    if (!ob || !ob->Has("subdivision")) return std::nullopt;
    const std::string field = owner + ".extras.obscura";
    const tinygltf::Value& sub = ob->Get("subdivision");
    if (!sub.IsObject()) fail(field + ".subdivision", "must be an object");
    knownKeys(sub, field + ".subdivision", {"scheme", "level"});
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
  // (docs/scenes.md "Scenes"). `field` names where it came from, for errors.
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
                          owner + ".extras.obscura.displacement", ""};
    const tinygltf::Value& d = ob->Get("displacement");
    if (!d.IsObject()) fail(r.field, "must be an object");
    knownKeys(d, r.field, {"map", "scale", "midlevel"});
    const tinygltf::Value& map = d.Get("map");  // a null value when absent
    if (!map.IsString() || map.Get<std::string>().empty()) fail(r.field + ".map", "expected the path of a height map");
    r.map = map.Get<std::string>();
    const fs::path mp(r.map);
    r.path = mp.is_absolute() ? r.map : (fs::path(doc_.path()).parent_path() / mp).string();
    for (const auto& [key, value] : {std::pair{"scale", &r.scale}, std::pair{"midlevel", &r.midlevel}}) {
      if (!d.Has(key)) continue;
      const tinygltf::Value& v = d.Get(key);
      if (!v.IsNumber() || !std::isfinite(v.GetNumberAsDouble())) fail(r.field + "." + key, "expected a finite number");
      *value = v.GetNumberAsDouble();
    }
    if (d.Has("scale")) r.scaleField = doc_.path() + ": " + r.field + ".scale";
    return r;
  }

  std::optional<DisplacementRequest> displacementOf(int meshIndex, int nodeIndex, bool subdivided) {
    const std::string mesh = "meshes[" + std::to_string(meshIndex) + "]";
    std::optional<DisplacementRequest> r;
    if (nodeIndex >= 0) r = parseDisplacement(doc_.model().nodes[size_t(nodeIndex)].extras, "nodes[" + std::to_string(nodeIndex) + "]");
    // The mesh's own is checked even when a node overrides it.
    std::optional<DisplacementRequest> own = parseDisplacement(doc_.model().meshes[size_t(meshIndex)].extras, mesh);
    if (!r) r = std::move(own);
    if (r && !subdivided) fail(r->field, "needs a subdivided mesh (" + mesh + ".extras.obscura.subdivision)");
    if (!r && subdivided && !options_.displacementMap.empty()) {
      r = DisplacementRequest{options_.displacementMap, options_.displacementMap, options_.displacementScale,
                              options_.displacementMidlevel, settingName(Setting::Displacement), ""};
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
      const Material* m = d.material >= 0 ? &doc_.materials()[size_t(d.material)] : nullptr;
      const bool textured = m && (m->texture >= 0 || m->roughnessTexture >= 0);
      if (textured && options_.backend == SubdivisionBackend::Embree)
        warn(field + ": textures on Embree subdivision surfaces are not supported (the material's factor is used; " +
                     settingName(Setting::SubdivisionBackendOsd) + " keeps them)");
    }
    validateCage(cage, r.scheme, doc_.path() + ": " + field);
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
    const Material* nm = d.material >= 0 ? &scene_->materials[size_t(d.material)] : nullptr;
    if (nm && nm->normalTexture >= 0)
      warn(field + ": normal maps on subdivided meshes are not supported (the limit surface's normal is used)");
    d.positions.clear(), d.normals.clear(), d.uvs.clear(), d.indices.clear(), d.tangents.clear();
  }

  // A subdivided primitive's cage, placed by `xf` and refined as the
  // request and the load options say (core/load/cage.h). Displacement scales are
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
    addCage(*scene_, c, o, d, p.material, doc_.path() + ": " + p.field);
  }

  // The roles node `index` sets in its extras.obscura (docs/production.md "Objects and
  // roles"): booleans occluder, camera, matte and the string occlusion.
  RoleSettings nodeRoles(int index) const {
    const std::string owner = "nodes[" + std::to_string(index) + "]";
    RoleSettings r;
    const tinygltf::Value* ob = obscuraExtras(doc_.model().nodes[size_t(index)].extras, owner);
    if (!ob) return r;
    const std::string where = doc_.path() + ": " + owner + ".extras.obscura";
    for (const char* key : {"occluder", "camera", "matte"}) {
      if (!ob->Has(key)) continue;
      const tinygltf::Value& v = ob->Get(key);
      if (!v.IsBool()) fail(owner + ".extras.obscura." + key, "expected true or false");
      r.set(key, v.Get<bool>() ? "true" : "false", where);
    }
    if (ob->Has("occlusion")) {
      const tinygltf::Value& v = ob->Get("occlusion");
      if (!v.IsString()) fail(owner + ".extras.obscura.occlusion", "expected \"all\", \"self\" or \"others\"");
      r.set("occlusion", v.Get<std::string>(), where);
    }
    return r;
  }

  // The roles nodes[node] passes down: its ancestors' extras root first,
  // then its own (a child overrides its parent). Computed once per node, so
  // that the leaves of a deep hierarchy do not each walk it again.
  const ObjectRoles& inheritedRoles(int node) {
    if (inherited_.empty()) inherited_.resize(doc_.model().nodes.size());
    std::vector<int> chain;  // the nodes still to compute, deepest first
    for (int n = node; n >= 0 && !inherited_[size_t(n)]; n = doc_.parentNode(n)) chain.push_back(n);
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      const int parent = doc_.parentNode(*it);
      ObjectRoles r = parent >= 0 ? *inherited_[size_t(parent)] : ObjectRoles{};
      nodeRoles(*it).applyTo(r);
      inherited_[size_t(*it)] = r;
    }
    return *inherited_[size_t(node)];
  }

  // Each mesh use is an object named by its node, with the roles its node
  // inherits (inheritedRoles).
  uint32_t addObject(const GltfDocument::MeshUse& u) {
    SceneObject o;
    o.name = u.node;
    o.roles = inheritedRoles(u.nodeIndex);
    scene_->objects.push_back(std::move(o));
    return uint32_t(scene_->objects.size() - 1);
  }

  void buildGeometry() {
    // A node with a displacement of its own gets its own copy of the mesh:
    // geometry is keyed by (mesh, that node), -1 for the mesh as the file has it.
    const auto key = [&](const GltfDocument::MeshUse& u) {
      const tinygltf::Value& extras = doc_.model().nodes[size_t(u.nodeIndex)].extras;
      const std::string owner = "nodes[" + std::to_string(u.nodeIndex) + "]";
      const tinygltf::Value* ob = obscuraExtras(extras, owner);
      return std::pair{u.mesh, ob && ob->Has("displacement") ? u.nodeIndex : -1};
    };
    std::map<std::pair<int, int>, int> useCount;
    for (const auto& u : pose_.uses) ++useCount[key(u)];
    // A subdivided mesh is refined per use, in world space - adaptive
    // refinement and displacement depend on where it is - so it is never
    // instanced.
    for (const auto& u : pose_.uses)
      if (subdivisionOf(u.mesh)) useCount[key(u)] = 1;
    std::map<std::pair<int, int>, int> instanced;  // (glTF mesh, node) -> Scene instanced mesh
    // The object-space mesh of key k, built on its first use (-1: no triangles).
    const auto instancedMesh = [&](const GltfDocument::MeshUse& u, const std::pair<int, int>& k) {
      auto it = instanced.find(k);
      if (it == instanced.end()) {
        std::vector<PrimData> prims = primitives(u.mesh, k.second);
        const int m = prims.empty() ? -1 : scene_->addInstancedMesh(doc_.model().meshes[size_t(u.mesh)].name);
        for (PrimData& p : prims)
          scene_->addPrimitiveToMesh(m, p.positions, p.indices, std::move(p.normals), std::move(p.uvs), p.material,
                                     std::move(p.tangents));
        it = instanced.emplace(k, m).first;
      }
      return it->second;
    };
    for (size_t i = 0; i < pose_.uses.size(); ++i) {
      const GltfDocument::MeshUse& u = pose_.uses[i];
      if (u.hidden) {  // a zero scale on every axis (GltfDocument::checkLinear): glTF's way to hide a subtree
        hidden_.push_back(u.hiddenBy + " has a zero scale on every axis: " + u.node + " (meshes[" + std::to_string(u.mesh) +
                          "]) is hidden and not rendered");
        continue;
      }
      scene_->setCurrentObject(addObject(u));
      Affine xf = Affine::fromColumnMajor4x4(u.world.data());
      const auto k = key(u);
      if (!useGrid_.empty() && !useGrid_[i].empty()) {
        // Animated, with a shutter: keyed as finely as its path needs
        // (core/scene/motion.h). Moving, it is an instance whose transform Embree
        // blends at each ray's time; still over the shutter, it is placed
        // like any other use.
        const std::vector<Affine> steps = shutterSteps(useGrid_[i], meshBox(u.mesh));
        if (steps.size() > 1) {
          if (subdivisionOf(u.mesh))
            fail("nodes[" + std::to_string(u.nodeIndex) + "]",
                 "moves within the shutter, and motion blur of subdivided meshes is not supported; render without " +
                     settingName(Setting::Shutter));
          const int m = instancedMesh(u, k);
          if (m >= 0) scene_->addMovingInstance(m, steps, u.node);
          continue;
        }
        xf = steps[0];
      }
      if (useCount[k] == 1) {
        // Used once: bake into world space; no instance traversal at render.
        std::vector<PrimData> prims = primitives(u.mesh, k.second);
        for (PrimData& p : prims) {
          if (p.cage) {
            addSubdivided(p, xf);
            continue;
          }
          for (Vec3& v : p.positions) v = xf.point(v);
          for (Vec3& n : p.normals) n = xf.normal(n);
          // Tangents are surface directions; a mirroring transform reverses
          // the bitangent's sign against cross(N, T) (as for instances,
          // core/scene/surface.cpp normalMapped).
          // Its winding is reversed too, so that a mesh without normals keeps
          // the front the normal map's frame is built on (the mirrored
          // winding would face the other way). Only normal-mapped primitives:
          // every other one keeps its bits.
          const bool mirrors = xf.determinant() < 0.0f;
          for (size_t t = 0; t + 3 < p.tangents.size(); t += 4) {
            const Vec3 v = xf.vector(Vec3(p.tangents[t], p.tangents[t + 1], p.tangents[t + 2]));
            p.tangents[t] = v.x, p.tangents[t + 1] = v.y, p.tangents[t + 2] = v.z;
            if (mirrors) p.tangents[t + 3] = -p.tangents[t + 3];
          }
          if (mirrors && !p.tangents.empty())
            for (size_t t = 0; t + 2 < p.indices.size(); t += 3) std::swap(p.indices[t + 1], p.indices[t + 2]);
          scene_->setPrimitiveName(
              scene_->addWorldPrimitive(p.positions, p.indices, std::move(p.normals), std::move(p.uvs), p.material,
                                        std::move(p.tangents)),
              doc_.model().meshes[size_t(u.mesh)].name);
        }
        if (!prims.empty()) ++scene_->flattenedMeshes;
        continue;
      }
      const int m = instancedMesh(u, k);
      if (m >= 0) scene_->addInstance(m, xf, u.node);
    }
    scene_->setCurrentObject(kNoObject);
    if (!options_.displacementMap.empty() && !cliDisplacementUsed_)
      warn(settingName(Setting::Displacement) + " applies to subdivided meshes (extras.obscura.subdivision) without a displacement of their own; "
           "none here (height map unused)");
  }

  // Motion blur (LoadOptions::shutter): the placement of every animated
  // mesh use and camera at the kMotionGrid + 1 evenly spaced times of the
  // shutter (core/scene/motion.h), from which their steps are chosen. Nothing is
  // sampled without a shutter, or when nothing is animated.
  void sampleShutter() {
    if (!options_.shutter || options_.unrefined) return;
    const auto isAnimated = [](const auto& x) { return x.animated; };
    if (std::none_of(pose_.uses.begin(), pose_.uses.end(), isAnimated) &&
        std::none_of(pose_.cameras.begin(), pose_.cameras.end(), isAnimated))
      return;
    const auto [open, close] = *options_.shutter;
    useGrid_.assign(pose_.uses.size(), {});
    cameraGrid_.assign(pose_.cameras.size(), {});
    // Each grid at its final size: grown by push_back, a grid of 513 ends
    // with room for 1024, after copies at every doubling on the way.
    for (size_t i = 0; i < pose_.uses.size(); ++i)
      if (pose_.uses[i].animated) useGrid_[i].reserve(kMotionGrid + 1);
    for (size_t c = 0; c < pose_.cameras.size(); ++c)
      if (pose_.cameras[c].animated) cameraGrid_[c].reserve(kMotionGrid + 1);
    for (int j = 0; j <= kMotionGrid; ++j) {
      const GltfDocument::Pose p = doc_.pose(open + (close - open) * double(j) / kMotionGrid, options_.animations);
      for (size_t i = 0; i < p.uses.size(); ++i)
        if (p.uses[i].animated) useGrid_[i].push_back(Affine::fromColumnMajor4x4(p.uses[i].world.data()));
      for (size_t c = 0; c < p.cameras.size(); ++c)
        if (p.cameras[c].animated) cameraGrid_[c].push_back(p.cameras[c].toWorld);
    }
  }

  // The steps of a placement sampled on the grid, with the tolerance
  // relative to the placed box's size (kMotionTolerance).
  static std::vector<Affine> shutterSteps(const std::vector<Affine>& grid, const Bounds3& box) {
    if (box.empty()) return {grid[0]};
    const double size = placedDiagonal(grid, box);
    return motionSteps(grid, box, kMotionTolerance * (size > 0 ? size : 1.0));
  }

  // meshes[index]'s bounds in object space (its triangles, or its cage).
  Bounds3 meshBox(int index) const {
    Bounds3 b;
    for (const GltfDocument::Primitive& p : doc_.mesh(index))
      for (const Vec3& v : p.positions) b.extend(v);
    return b;
  }

  // A camera animated within the shutter gets its motion steps; the box
  // it is tested with spans the scene's radius around it, so its rotation
  // is followed to kMotionTolerance of what it sees at that distance.
  void moveCameras() {
    if (cameraGrid_.empty()) return;
    const Bounds3& b = scene_->bounds();
    float r = b.empty() ? 1.0f : 0.5f * length(b.diagonal());
    if (!(r > 0.0f) || !std::isfinite(r)) r = 1.0f;
    Bounds3 box;
    box.extend(Vec3(-r, -r, -r));
    box.extend(Vec3(r, r, r));
    for (size_t c = 0; c < cameraGrid_.size(); ++c) {
      if (cameraGrid_[c].empty()) continue;
      std::vector<Affine> steps = shutterSteps(cameraGrid_[c], box);
      if (steps.size() > 1) scene_->cameras[c].motion = std::move(steps);
      else scene_->cameras[c].toWorld = steps[0];
    }
  }

  const GltfDocument& doc_;
  LoadOptions options_;
  GltfDocument::Pose pose_;
  std::vector<std::vector<Affine>> useGrid_, cameraGrid_;  // by use / camera; empty: not sampled
  std::unique_ptr<Scene> scene_;
  std::map<std::string, std::shared_ptr<const HeightMap>> heightMaps_;  // by absolute path
  bool cliDisplacementUsed_ = false;
  std::vector<std::optional<ObjectRoles>> inherited_;  // by node index: inheritedRoles()
  std::vector<std::string> hidden_;  // a warning per mesh use a zero scale hides
};

}  // namespace

MemoryEstimate estimateSceneMemory(const GltfDocument& doc, const LoadOptions& options) {
  MemoryEstimate e;
  // Textures as decode() will hold them, from their headers, and the
  // largest decoder buffer: each is freed as its decode ends, and textures
  // decode one at a time unless threads meet two first uses at once.
  uint64_t transient = 0;
  for (const auto* list : {&doc.textures(), &doc.dataTextures()})
    for (const auto& t : *list) {
      const DecodedImageSize d = decodedImageSize(t.encoded);
      e.add("textures", d.kept);
      transient = std::max(transient, d.transient);
    }
  e.add("textures", transient);
  // The parsed file, held for the extras (tinygltf's node records dominate
  // a large hierarchy).
  e.add("parsed file", uint64_t(doc.model().nodes.size()) * sizeof(tinygltf::Node));
  // The mesh uses: the document's and a pose's tables, an object and an
  // instance each (their names beyond the string's own buffer counted).
  const auto& uses = doc.meshUses();
  uint64_t names = 0;
  for (const auto& u : uses) names += u.node.capacity() > 15 ? u.node.capacity() + 1 : 0;
  e.add("node tables", uint64_t(uses.size()) * (2 * sizeof(GltfDocument::MeshUse) + sizeof(SceneObject) + sizeof(Instance)) +
                           3 * names);
  // Triangles as the file declares them (each use of a mesh baked or
  // instanced): positions, indices, normals and uvs, and the BVH over them
  // (docs/cli.md "Memory" gives the per-triangle figure's origin).
  uint64_t triangles = 0, vertices = 0;
  std::vector<uint64_t> meshTriangles(doc.model().meshes.size(), 0), meshVertices(doc.model().meshes.size(), 0);
  for (size_t m = 0; m < doc.model().meshes.size(); ++m)
    for (const auto& p : doc.model().meshes[m].primitives) {
      const auto pos = p.attributes.find("POSITION");
      const auto count = [&](int a) -> uint64_t {
        return a >= 0 && size_t(a) < doc.model().accessors.size() ? doc.model().accessors[size_t(a)].count : 0;
      };
      const uint64_t v = pos == p.attributes.end() ? 0 : count(pos->second);
      meshVertices[m] += v;
      meshTriangles[m] += (p.indices >= 0 ? count(p.indices) : v) / 3;
    }
  std::vector<char> seen(doc.model().meshes.size(), 0);
  for (const auto& u : uses) {
    if (seen[size_t(u.mesh)]) continue;  // instanced: its triangles once
    seen[size_t(u.mesh)] = 1;
    triangles += meshTriangles[size_t(u.mesh)];
    vertices += meshVertices[size_t(u.mesh)];
  }
  e.add("geometry", vertices * (2 * sizeof(Vec3) + 2 * sizeof(float)) + triangles * 3 * sizeof(uint32_t));
  e.add("BVH", (triangles + uses.size()) * kBvhBytesPerPrimitive);
  // Motion blur: every animated use sampled at kMotionGrid + 1 times.
  if (options.shutter && !options.unrefined) {
    const GltfDocument::Pose p = doc.pose(options.time, options.animations);
    uint64_t animated = 0;
    for (const auto& u : p.uses) animated += u.animated ? 1 : 0;
    e.add("motion grids", animated * (kMotionGrid + 1) * sizeof(Affine));
  }
  return e;
}

std::unique_ptr<Scene> buildGltfScene(const GltfDocument& doc, const LoadOptions& options) {
  return Builder(doc, options).build();
}

std::unique_ptr<Scene> loadGltf(const std::string& path, const LoadOptions& options) {
  return buildGltfScene(GltfDocument(path), options);
}

SceneSource::SceneSource(std::string path) : path_(std::move(path)) {
  std::string ext = fs::path(path_).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".obj") gltf_ = std::make_unique<GltfDocument>(path_);
}

SceneSource::~SceneSource() = default;

std::unique_ptr<Scene> SceneSource::build(const LoadOptions& options) const {
  if (!gltf_ && options.time)
    throw Error(path_ + ": " + settingName(Setting::Time) + ": an OBJ file has no animation (frames are glTF only)");
  if (!gltf_ && !options.animations.empty())
    throw Error(path_ + ": " + settingName(Setting::Animations) + ": an OBJ file has no animations");
  return gltf_ ? buildGltfScene(*gltf_, options) : loadObj(path_, options);
}

std::unique_ptr<Scene> loadScene(const std::string& path, const LoadOptions& options) {
  return SceneSource(path).build(options);
}

}  // namespace obscura
