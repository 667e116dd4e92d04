// The scene: triangle geometry in Embree, the attributes shading needs, the
// materials and the cameras.
//
// A glTF mesh referenced by one node is baked into world space as plain
// triangle geometries of the top-level Embree scene (no instance traversal
// cost); a mesh referenced by several nodes is built once as its own Embree
// scene and placed by instance geometries. Attributes stay where Embree keeps
// the vertices, so nothing is stored twice.
#pragma once

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/scene/camera.h"
#include <obscura/math.h>
#include "core/scene/objects.h"
#include "core/subd/subdivision.h"
#include "core/image/texture.h"
#include "core/scene/tracer.h"

namespace obscura {

// glTF's alphaMode: OPAQUE ignores alpha; MASK cuts out where alpha <
// alphaCutoff; BLEND lets a ray through with probability 1 - alpha
// (docs/production.md "Objects and roles").
enum class AlphaMode : uint8_t { Opaque, Mask, Blend };

struct Material {
  std::string name;
  Vec3 baseColorFactor{1, 1, 1};
  int texture = -1;  // index into Scene::textures, -1 = none
  WrapMode wrapS = WrapMode::Repeat, wrapT = WrapMode::Repeat;
  UvTransform transform;  // the base colour texture's (also its alpha's)
  // Coverage: alpha = alpha factor (baseColorFactor's 4th component) x the
  // texture's alpha channel.
  AlphaMode alphaMode = AlphaMode::Opaque;
  float alpha = 1.0f;
  float alphaCutoff = 0.5f;
  // Roughness (glTF pbrMetallicRoughness, read by `reflocc` only):
  // roughnessFactor x the G channel of metallicRoughnessTexture, which holds
  // linear data (never sRGB-decoded). glTF's default is 1.
  float roughnessFactor = 1.0f;
  int roughnessTexture = -1;  // index into Scene::dataTextures, -1 = none
  WrapMode roughnessWrapS = WrapMode::Repeat, roughnessWrapT = WrapMode::Repeat;
  UvTransform roughnessTransform;
  // glTF normalTexture: a tangent-space normal map (linear data) bending
  // the shading normal (core/scene/surface.cpp applyNormalMap, docs/math.md
  // §16); normalScale scales its x and y. -1 when the file has none or the
  // load turned normal maps off (LoadOptions::normalMaps).
  int normalTexture = -1;  // index into Scene::dataTextures
  float normalScale = 1.0f;
  WrapMode normalWrapS = WrapMode::Repeat, normalWrapT = WrapMode::Repeat;
  UvTransform normalTransform;
  // Does anything a ray meets depend on alpha? (OPAQUE never; MASK and
  // BLEND unless alpha is 1 everywhere.)
  bool cutsOut(bool textureHasAlpha) const {
    if (alphaMode == AlphaMode::Opaque) return false;
    if (alphaMode == AlphaMode::Mask) return textureHasAlpha || !(alpha >= alphaCutoff);
    return textureHasAlpha || alpha < 1.0f;
  }
};

// An Embree subdivision surface's own data: what its displacement callback
// and the hit reconstruction read.
struct SubdivisionSurface {
  CageUvs uvs;                             // the cage's uvs (displacement, uv frames); empty without
  std::shared_ptr<const HeightMap> height;  // null: not displaced
  float scale = 0, midlevel = 0;
  bool flipV = false;           // look up (u, 1 - v)
  std::vector<float> faceRate;  // per face, the finest tessellation rate of its edges
  // scale * (h(uv) - midlevel) at patch coordinates (u, v) of face f.
  float displacement(uint32_t face, float u, float v) const {
    float s, t;
    uvs.at(face, u, v, s, t);
    return scale * float(height->sample(s, flipV ? 1.0f - t : t) - midlevel);
  }
};

// One triangle list (a glTF primitive), or one Embree subdivision surface.
// Triangle positions live in Embree's buffer.
struct Primitive {
  RTCGeometry geometry = nullptr;     // owned by the Embree scene it is attached to
  const float* positions = nullptr;  // xyz, stride 3 floats, in Embree's vertex buffer
  const uint32_t* indices = nullptr;  // 3 per triangle, in Embree's index buffer
  uint32_t vertexCount = 0, triangleCount = 0;
  std::vector<Vec3> normals;  // per vertex, empty if the file has none
  std::vector<float> uvs;     // 2 per vertex, empty if none
  // 4 per vertex (xyz, w = the bitangent's sign, as glTF's TANGENT), in the
  // primitive's space; only when its material has a normal map (and uvs):
  // the file's TANGENT or generated (core/scene/tangents.h).
  std::vector<float> tangents;
  int material = -1;          // -1 = default material (albedo 1)
  // Set for an Embree subdivision surface (positions, indices, normals and
  // uvs are then empty: hits are evaluated on the patches).
  std::shared_ptr<const SubdivisionSurface> subdivision;
  uint32_t faceCount = 0;     // subdivision faces
  // uvs with v = 0 at the top of an image (glTF); false: at the bottom (OBJ,
  // and the height maps' convention).
  bool uvsRunDown = false;
  std::string name;  // for messages: the mesh or file it came from ("" if unknown)
};

// A mesh placed more than once: its own Embree scene, shared by instances.
struct InstancedMesh {
  std::string name;
  RTCScene rtcScene = nullptr;
  std::vector<Primitive> primitives;  // indexed by Embree geomID in rtcScene
  Bounds3 objectBounds;
};

struct Instance {
  int mesh = -1;  // index into Scene::instancedMeshes
  Affine toWorld;  // a moving instance: its transform at shutter open
  std::string node;
  // A moving instance (docs/architecture.md "Motion blur through Embree's
  // own motion, keyed by a measured rule"): its transform at steps k = 0..n-1, at times k / (n - 1) across the
  // shutter; empty for a still one.
  std::vector<Affine> motion;
  // The transform at ray time `time` in [0, 1]: as Embree places the
  // instance, linear in the matrix between the two steps around `time`.
  Affine toWorldAt(float time) const {
    if (motion.empty()) return toWorld;
    const float segments = float(motion.size() - 1);
    const float x = std::clamp(time, 0.0f, 1.0f) * segments;
    const size_t k = std::min(size_t(x), motion.size() - 2);
    const float f = x - float(k);
    Affine a;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) a.m[r][c] = (1.0f - f) * motion[k].m[r][c] + f * motion[k + 1].m[r][c];
    return a;
  }
};

// What the top-level Embree geomID refers to.
struct TopLevelGeometry {
  int primitive = -1;  // index into Scene::worldPrimitives, or -1
  int instance = -1;   // index into Scene::instances, or -1
  uint32_t object = kNoObject;  // index into Scene::objects
};

// What a hit on a cut-out surface needs to find its alpha (Embree's filter
// functions get it as the geometry's user data): core/scene/alpha.cpp.
struct AlphaSurface;

// Counts for `obscura info` and the EXR header.
struct SceneStats {
  size_t meshes = 0, primitives = 0, uniqueTriangles = 0, renderedTriangles = 0,
         instances = 0, flattenedMeshes = 0, subdivisionFaces = 0,
         movingInstances = 0;  // instances that move within the shutter (motion blur)
};

class Scene {
 public:
  Scene();
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  RTCDevice device() const { return device_; }
  RTCScene rtcScene() const { return top_; }

  // Watertight traversal (RTC_SCENE_FLAG_ROBUST): no ray slips between
  // triangles sharing an edge or a vertex, at some cost in speed. Set before
  // commit().
  void setRobust(bool robust) { robust_ = robust; }
  bool robust() const { return robust_; }

  // Builds the BVHs. Called once after all geometry is added.
  void commit();
  double buildSeconds() const { return buildSeconds_; }
  // Memory Embree holds for this scene (geometry buffers, tessellation,
  // BVHs), from its memory monitor: now and at most so far.
  int64_t embreeBytes() const { return memory_->current.load(std::memory_order_relaxed); }
  int64_t embreePeakBytes() const { return memory_->peak.load(std::memory_order_relaxed); }

  // Geometry construction (used by the glTF loader and by tests).
  // Adds a world-space triangle list to the top-level scene.
  // `tangents`: Primitive::tangents (empty: none).
  int addWorldPrimitive(const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices,
                        std::vector<Vec3> normals, std::vector<float> uvs, int material,
                        std::vector<float> tangents = {});
  // Adds a Catmull-Clark cage as an Embree subdivision surface in world
  // space. edgeLevels: the tessellation rate of each face corner's outgoing
  // edge (parallel to cage.faceIndices; shared edges must agree, or cracks
  // open), or one value for all. With a height map (cage.uvs needed) the
  // surface is displaced along its limit normal by scale * (h - midlevel).
  int addSubdivisionSurface(const SubdivisionCage& cage, const std::vector<float>& edgeLevels,
                            std::shared_ptr<const HeightMap> height, float scale, float midlevel, bool flipV,
                            int material);
  // Objects (core/scene/objects.h): geometry added after setCurrentObject(i)
  // belongs to objects[i] (an instance: the placement; a world primitive:
  // itself); kNoObject (the default) = to none, which has the default roles.
  // The loaders set roles before commit(), which turns them into masks and
  // filters.
  std::vector<SceneObject> objects;
  void setCurrentObject(uint32_t object) { currentObject_ = object; }
  // The object a hit belongs to (kNoObject if none).
  uint32_t objectOf(unsigned geomID, unsigned instID) const {
    return topLevel_[instID != RTC_INVALID_GEOMETRY_ID ? instID : geomID].object;
  }
  // After commit(): does any object hold out (matte), and is this one of them?
  bool hasMattes() const { return !matte_.empty(); }
  bool isMatte(uint32_t object) const { return object < matte_.size() && matte_[object]; }
  // Does object o occlude (kNoObject: yes), and does any object not?
  bool objectOccludes(uint32_t o) const { return o >= objects.size() || objects[o].roles.occluder; }
  bool hasNonOccluders() const {
    for (const SceneObject& o : objects)
      if (!o.roles.occluder) return true;
    return false;
  }
  // After commit(): what the tracer needs for objects whose occlusion is
  // self or others, or null when there are none (core/scene/tracer.h).
  const OcclusionScopes* occlusionScopes() const { return scopes_.objectCount ? &scopes_ : nullptr; }
  // After commit(): how many primitives cut out by alpha (filter functions).
  size_t alphaPrimitives() const { return alphaSurfaces_.size(); }

  // Adds an instanced mesh (object space) and returns its index.
  int addInstancedMesh(std::string name);
  void addPrimitiveToMesh(int mesh, const std::vector<Vec3>& positions,
                          const std::vector<uint32_t>& indices, std::vector<Vec3> normals,
                          std::vector<float> uvs, int material, std::vector<float> tangents = {});
  void addInstance(int mesh, const Affine& toWorld, std::string node);
  // A moving instance: `steps` are its transforms at uniformly spaced times
  // across the shutter (2..129 of them, Embree's limit; Instance::motion).
  void addMovingInstance(int mesh, std::span<const Affine> steps, std::string node);
  // Does anything move within the shutter (a moving instance)?
  bool hasMotion() const { return moving_ > 0; }
  // Names world primitive `primitive` (addWorldPrimitive's result) for messages.
  void setPrimitiveName(int primitive, std::string name) { worldPrimitives_.at(size_t(primitive)).name = std::move(name); }
  // What a hit's surface is called in messages: its mesh's name (and node,
  // for an instance), or "an unnamed mesh".
  std::string surfaceName(unsigned geomID, unsigned instID) const;
  // Marks every primitive's uvs as running down the image (glTF).
  void setUvsRunDown();

  std::vector<Material> materials;
  std::vector<std::unique_ptr<Texture>> textures;  // sRGB colour (albedo, alpha)
  // Linear data images (metallicRoughness): decoded only when an integrator
  // reads roughness, never by the albedo path.
  std::vector<std::unique_ptr<Texture>> dataTextures;
  std::vector<Camera> cameras;
  std::string sourcePath;
  size_t sourceMeshes = 0;     // meshes in the source file (glTF meshes)
  size_t flattenedMeshes = 0;  // meshes used once and baked into world space

  const Bounds3& bounds() const { return bounds_; }
  // Bytes of the per-vertex attributes kept beside Embree's buffers
  // (normals, uvs, subdivision surfaces' corner uvs).
  size_t attributeBytes() const;
  SceneStats stats() const;

  // Hit lookup: the primitive a hit refers to and, for instances, its
  // object-to-world transform (nullptr for world-space primitives).
  const Primitive& primitiveOf(unsigned geomID, unsigned instID, const Affine** toWorld) const {
    if (instID == RTC_INVALID_GEOMETRY_ID) {
      *toWorld = nullptr;
      return worldPrimitives_[topLevel_[geomID].primitive];
    }
    const Instance& inst = instances_[topLevel_[instID].instance];
    *toWorld = &inst.toWorld;
    return meshes_[inst.mesh].primitives[geomID];
  }
  // The same with the transform where a ray at `time` met it: a moving
  // instance's is interpolated into `moved` (*toWorld then points to it).
  const Primitive& primitiveAt(unsigned geomID, unsigned instID, float time, Affine& moved, const Affine** toWorld) const {
    const Primitive& p = primitiveOf(geomID, instID, toWorld);
    if (instID != RTC_INVALID_GEOMETRY_ID) {
      const Instance& inst = instances_[topLevel_[instID].instance];
      if (!inst.motion.empty()) moved = inst.toWorldAt(time), *toWorld = &moved;
    }
    return p;
  }
  const Material* materialOf(const Primitive& p) const {
    return p.material >= 0 ? &materials[p.material] : nullptr;
  }
  bool anyTextures() const { return !textures.empty(); }
  // Does any primitive bend its shading normal by a normal map (has
  // tangents)? Set by the primitives added.
  bool hasNormalMaps() const { return normalMapped_ > 0; }
  // Decodes the normal maps' images (once; throws obscura::Error on a
  // corrupt one): before a render loop, which then never blocks on it.
  void decodeNormalMaps() const;
  const std::vector<Instance>& instances() const { return instances_; }
  const std::vector<InstancedMesh>& instancedMeshes() const { return meshes_; }

 // The memory monitor's counters (public for its C callback).
  struct MemoryCounter {
    std::atomic<int64_t> current{0}, peak{0};
  };

 private:
  void applyObjectRoles();
  void attachAlphaFilters();
  Primitive makePrimitive(RTCScene target, const std::vector<Vec3>& positions,
                          const std::vector<uint32_t>& indices, std::vector<Vec3> normals,
                          std::vector<float> uvs, int material, std::vector<float> tangents, unsigned* geomID);
  std::unique_ptr<MemoryCounter> memory_ = std::make_unique<MemoryCounter>();
  RTCDevice device_ = nullptr;
  RTCScene top_ = nullptr;
  std::vector<Primitive> worldPrimitives_;
  std::vector<InstancedMesh> meshes_;
  std::vector<Instance> instances_;
  std::vector<TopLevelGeometry> topLevel_;  // indexed by top-level geomID
  Bounds3 bounds_;
  Bounds3 cageBounds_;  // of Embree subdivision surfaces' cages, for the range check
  double buildSeconds_ = 0;
  bool committed_ = false;
  bool robust_ = false;
  bool hasSubdivision_ = false;
  size_t moving_ = 0;  // moving instances
  size_t normalMapped_ = 0;  // primitives with tangents
  uint32_t currentObject_ = kNoObject;
  std::vector<uint8_t> matte_;           // per object, when any is a matte
  std::vector<uint32_t> objectOfTop_;    // per top-level geomID, when scopes are on
  std::vector<uint8_t> scopeOfObject_;   // OcclusionScope per object, when scopes are on
  OcclusionScopes scopes_;
  std::vector<std::unique_ptr<AlphaSurface>> alphaSurfaces_;
};

}  // namespace obscura
