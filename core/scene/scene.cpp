#include "core/scene/scene.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>

#include "core/scene/alpha.h"
#include <obscura/error.h>

namespace obscura {
namespace {
void embreeErrorCallback(void*, RTCError code, const char* str) {
  if (code == RTC_ERROR_NONE) return;
  // Embree reports out-of-memory and invalid use here; turn the first into a
  // user-facing error at the next check, the rest into warnings.
  Log::warn(std::string("Embree: ") + (str ? str : "unknown error"));
}
// Embree's memory monitor: called once per allocation (bytes > 0) or free
// (bytes < 0), before or after it; never refusing, so every call counts.
bool embreeMemoryMonitor(void* user, ssize_t bytes, bool /*post*/) {
  auto* c = static_cast<Scene::MemoryCounter*>(user);
  const int64_t now = c->current.fetch_add(int64_t(bytes), std::memory_order_relaxed) + int64_t(bytes);
  int64_t peak = c->peak.load(std::memory_order_relaxed);
  while (now > peak && !c->peak.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
  }
  return true;
}
}  // namespace

Scene::Scene() {
  device_ = rtcNewDevice(nullptr);
  if (!device_) throw Error("cannot create the Embree device (error " + std::to_string(rtcGetDeviceError(nullptr)) + ")");
  rtcSetDeviceErrorFunction(device_, embreeErrorCallback, nullptr);
  rtcSetDeviceMemoryMonitorFunction(device_, embreeMemoryMonitor, memory_.get());
  top_ = rtcNewScene(device_);
}

Scene::~Scene() {
  for (auto& m : meshes_)
    if (m.rtcScene) rtcReleaseScene(m.rtcScene);
  if (top_) rtcReleaseScene(top_);
  if (device_) rtcReleaseDevice(device_);
}

Primitive Scene::makePrimitive(RTCScene target, const std::vector<Vec3>& positions,
                               const std::vector<uint32_t>& indices, std::vector<Vec3> normals,
                               std::vector<float> uvs, int material, std::vector<float> tangents,
                               unsigned* geomID) {
  if (!tangents.empty() && (tangents.size() != 4 * positions.size() || uvs.size() != 2 * positions.size()))
    throw Error("internal: tangents need 4 floats and a uv per vertex");
  Primitive p;
  p.vertexCount = uint32_t(positions.size());
  p.triangleCount = uint32_t(indices.size() / 3);
  RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
  // Embree allocates both buffers with the padding its SIMD loads need.
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                         3 * sizeof(float), positions.size()));
  auto* ib = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                            3 * sizeof(uint32_t), p.triangleCount));
  if (!vb || !ib) {
    rtcReleaseGeometry(g);
    throw Error("out of memory building geometry");
  }
  std::memcpy(vb, positions.data(), positions.size() * sizeof(Vec3));
  std::memcpy(ib, indices.data(), size_t(p.triangleCount) * 3 * sizeof(uint32_t));
  rtcCommitGeometry(g);
  *geomID = rtcAttachGeometry(target, g);
  rtcReleaseGeometry(g);  // the scene holds the reference now
  p.geometry = g;
  p.positions = vb;
  p.indices = ib;
  p.normals = std::move(normals);
  p.uvs = std::move(uvs);
  p.tangents = std::move(tangents);
  if (!p.tangents.empty()) ++normalMapped_;
  p.material = material;
  return p;
}

int Scene::addWorldPrimitive(const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices,
                             std::vector<Vec3> normals, std::vector<float> uvs, int material,
                             std::vector<float> tangents) {
  unsigned id = 0;
  Primitive p =
      makePrimitive(top_, positions, indices, std::move(normals), std::move(uvs), material, std::move(tangents), &id);
  for (const Vec3& v : positions) bounds_.extend(v);
  if (topLevel_.size() <= id) topLevel_.resize(id + 1);
  topLevel_[id].primitive = int(worldPrimitives_.size());
  topLevel_[id].object = currentObject_;
  worldPrimitives_.push_back(std::move(p));
  return int(worldPrimitives_.size()) - 1;
}

std::string Scene::surfaceName(unsigned geomID, unsigned instID) const {
  const auto quoted = [](const std::string& n) { return n.empty() ? std::string("an unnamed mesh") : "mesh '" + n + "'"; };
  if (instID != RTC_INVALID_GEOMETRY_ID) {
    const Instance& inst = instances_[size_t(topLevel_[instID].instance)];
    return quoted(meshes_[size_t(inst.mesh)].name) + (inst.node.empty() ? "" : " (node '" + inst.node + "')");
  }
  return quoted(worldPrimitives_[size_t(topLevel_[geomID].primitive)].name);
}

namespace {
// Embree's displacement callback: moves the tessellation's points along the
// limit normal Embree passes (unit length), by the height map at the
// points' cage uv.
void displaceSubdivision(const RTCDisplacementFunctionNArguments* a) {
  const auto* s = static_cast<const SubdivisionSurface*>(a->geometryUserPtr);
  for (unsigned i = 0; i < a->N; ++i) {
    const float d = s->displacement(a->primID, a->u[i], a->v[i]);
    a->P_x[i] += d * a->Ng_x[i];
    a->P_y[i] += d * a->Ng_y[i];
    a->P_z[i] += d * a->Ng_z[i];
  }
}
}  // namespace

int Scene::addSubdivisionSurface(const SubdivisionCage& cage, const std::vector<float>& edgeLevels,
                                 std::shared_ptr<const HeightMap> height, float scale, float midlevel, bool flipV,
                                 int material) {
  auto surface = std::make_shared<SubdivisionSurface>();
  const size_t corners = cage.faceIndices.size(), faces = cage.faceSizes.size();
  if (edgeLevels.size() != 1 && edgeLevels.size() != corners) throw Error("internal: edge levels do not match the cage");
  if (height && cage.uvIndices.size() != corners) throw Error("internal: a displaced subdivision surface needs uvs at every corner");
  for (const Vec3& v : cage.positions) cageBounds_.extend(v);  // the limit surface lies in the cage's hull
  const auto level = [&](size_t k) { return std::clamp(edgeLevels.size() == 1 ? edgeLevels[0] : edgeLevels[k], 1.0f, 4096.0f); };
  surface->faceRate.resize(faces);
  for (size_t f = 0, k = 0; f < faces; ++f) {
    float r = 1;
    for (int j = 0; j < cage.faceSizes[f]; ++j, ++k) r = std::max(r, level(k));
    surface->faceRate[f] = r;
  }
  if (cage.uvIndices.size() == corners) surface->uvs = CageUvs(cage);  // displacement, uv frames
  if (height) {
    surface->height = std::move(height);
    surface->scale = scale;
    surface->midlevel = midlevel;
    surface->flipV = flipV;
  }

  RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_SUBDIVISION);
  auto* fb = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_FACE, 0, RTC_FORMAT_UINT, sizeof(uint32_t), faces));
  auto* ib = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT, sizeof(uint32_t), corners));
  // Stride 16 with w = 0: Embree's patch evaluation loads whole SSE
  // vectors and (in Debian's build, which keeps assertions) checks every lane
  // is a valid number, padding included.
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 4 * sizeof(float),
                                                         cage.positions.size()));
  auto* lb = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_LEVEL, 0, RTC_FORMAT_FLOAT, sizeof(float), corners));
  if (!fb || !ib || !vb || !lb) {
    rtcReleaseGeometry(g);
    throw Error("out of memory building a subdivision surface");
  }
  for (size_t f = 0; f < faces; ++f) fb[f] = uint32_t(cage.faceSizes[f]);
  for (size_t k = 0; k < corners; ++k) ib[k] = uint32_t(cage.faceIndices[k]), lb[k] = level(k);
  for (size_t i = 0; i < cage.positions.size(); ++i)
    vb[4 * i] = cage.positions[i].x, vb[4 * i + 1] = cage.positions[i].y, vb[4 * i + 2] = cage.positions[i].z, vb[4 * i + 3] = 0;
  if (!cage.creaseWeights.empty()) {
    auto* ci = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_EDGE_CREASE_INDEX, 0, RTC_FORMAT_UINT2,
                                                              2 * sizeof(uint32_t), cage.creaseWeights.size()));
    auto* cw = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_EDGE_CREASE_WEIGHT, 0, RTC_FORMAT_FLOAT,
                                                           sizeof(float), cage.creaseWeights.size()));
    if (!ci || !cw) {
      rtcReleaseGeometry(g);
      throw Error("out of memory building a subdivision surface");
    }
    for (size_t i = 0; i < cage.creaseWeights.size(); ++i) {
      ci[2 * i] = uint32_t(cage.creaseEdges[2 * i]), ci[2 * i + 1] = uint32_t(cage.creaseEdges[2 * i + 1]);
      // OpenSubdiv's sharpness >= 10 is infinitely sharp; Embree takes infinity.
      cw[i] = cage.creaseWeights[i] >= 10.0f ? kInfinity : cage.creaseWeights[i];
    }
  }
  // Boundaries as the OpenSubdiv backend has them (VTX_BOUNDARY_EDGE_AND_CORNER):
  // boundary edges are B-spline curves, corners stay where the cage puts them.
  rtcSetGeometrySubdivisionMode(g, 0, RTC_SUBDIVISION_MODE_PIN_CORNERS);
  if (surface->height) {
    rtcSetGeometryUserData(g, surface.get());
    rtcSetGeometryDisplacementFunction(g, displaceSubdivision);
  }
  rtcCommitGeometry(g);
  const unsigned id = rtcAttachGeometry(top_, g);
  rtcReleaseGeometry(g);

  Primitive p;
  p.geometry = g;
  p.material = material;
  p.faceCount = uint32_t(faces);
  p.subdivision = std::move(surface);
  // Bounds: commit() takes Embree's, of the tessellated (and displaced)
  // surface - not the cage's hull, which is larger than the limit surface
  // and would frame an auto camera differently from the OpenSubdiv backend.
  hasSubdivision_ = true;
  if (topLevel_.size() <= id) topLevel_.resize(id + 1);
  topLevel_[id].primitive = int(worldPrimitives_.size());
  topLevel_[id].object = currentObject_;
  worldPrimitives_.push_back(std::move(p));
  return int(worldPrimitives_.size()) - 1;
}

int Scene::addInstancedMesh(std::string name) {
  InstancedMesh m;
  m.name = std::move(name);
  m.rtcScene = rtcNewScene(device_);
  meshes_.push_back(std::move(m));
  return int(meshes_.size()) - 1;
}

void Scene::addPrimitiveToMesh(int mesh, const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices,
                               std::vector<Vec3> normals, std::vector<float> uvs, int material,
                               std::vector<float> tangents) {
  InstancedMesh& m = meshes_.at(size_t(mesh));
  unsigned id = 0;
  Primitive p = makePrimitive(m.rtcScene, positions, indices, std::move(normals), std::move(uvs), material,
                              std::move(tangents), &id);
  for (const Vec3& v : positions) m.objectBounds.extend(v);
  if (m.primitives.size() != id) throw Error("internal: unexpected Embree geometry id");
  m.primitives.push_back(std::move(p));
}

void Scene::addInstance(int mesh, const Affine& toWorld, std::string node) {
  addMovingInstance(mesh, std::span<const Affine>(&toWorld, 1), std::move(node));
}

void Scene::addMovingInstance(int mesh, std::span<const Affine> steps, std::string node) {
  const InstancedMesh& m = meshes_.at(size_t(mesh));
  if (steps.empty() || steps.size() > 129) throw Error("internal: an instance needs 1 to 129 transform steps");
  RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
  rtcSetGeometryInstancedScene(g, m.rtcScene);
  // Embree interpolates the steps' matrices linearly at the ray's time
  // (time range [0, 1] = the shutter): Instance::toWorldAt does the same.
  rtcSetGeometryTimeStepCount(g, unsigned(steps.size()));
  for (size_t k = 0; k < steps.size(); ++k)
    rtcSetGeometryTransform(g, unsigned(k), RTC_FORMAT_FLOAT3X4_ROW_MAJOR, &steps[k].m[0][0]);
  rtcCommitGeometry(g);
  const unsigned id = rtcAttachGeometry(top_, g);
  rtcReleaseGeometry(g);
  if (topLevel_.size() <= id) topLevel_.resize(id + 1);
  topLevel_[id].instance = int(instances_.size());
  topLevel_[id].object = currentObject_;
  Instance inst{mesh, steps[0], std::move(node), {}};
  if (steps.size() > 1) inst.motion.assign(steps.begin(), steps.end()), ++moving_;
  instances_.push_back(std::move(inst));
  // The bounds hold the object over the whole shutter: the steps' boxes
  // (a linear blend of two transforms stays inside their corners' hull).
  if (!m.objectBounds.empty())
    for (const Affine& toWorld : steps)
      for (int c = 0; c < 8; ++c) {
        const Vec3 corner(c & 1 ? m.objectBounds.hi.x : m.objectBounds.lo.x,
                          c & 2 ? m.objectBounds.hi.y : m.objectBounds.lo.y,
                          c & 4 ? m.objectBounds.hi.z : m.objectBounds.lo.z);
        bounds_.extend(toWorld.point(corner));
      }
}

void Scene::setUvsRunDown() {
  for (auto& p : worldPrimitives_) p.uvsRunDown = true;
  for (auto& m : meshes_)
    for (auto& p : m.primitives) p.uvsRunDown = true;
}

void Scene::commit() {
  if (committed_) return;
  // Embree silently leaves out primitives beyond its range, and rays from a
  // camera framing them would be invalid (kMaxCoordinate, core/scene/camera.h).
  Bounds3 all = bounds_;
  all.extend(cageBounds_);
  if (!all.empty())
    for (const float x : {all.lo.x, all.lo.y, all.lo.z, all.hi.x, all.hi.y, all.hi.z})
      if (!inTraceableRange(x)) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "%g", double(x));
        throw Error((sourcePath.empty() ? "" : sourcePath + ": ") + "the scene's bounds reach " + buf +
                    " (after node transforms), outside the range Embree traces (|x| <= 1e+16)");
      }
  // And below: Embree's triangle tests are single precision and form
  // products of three lengths (an edge, an edge and the distance along the
  // ray: T = Ng . C); once those leave float's normal range (2^-126) hits
  // are lost at corners, then everywhere (a cornell box scaled by 1e-16 came
  // out blank, exit status 0). The pass is scale-invariant above the limit
  // (tests/test_scene_scale.cpp): 2^-40 keeps size^3 at 2^-120, a margin of
  // 2^6 for the smaller triangles and distances of a scene. Embree's robust
  // (watertight) test loses occlusion much earlier - measured on the cornell
  // box, wrong at 1.7e-9 across and right at 5.6e-9 - so it needs 2^-28
  // (docs/scenes.md "Scene scale").
  if (!all.empty()) {
    const Vec3 d = all.diagonal();
    const double size = std::max({double(d.x), double(d.y), double(d.z)});
    const double limit = robust_ ? 0x1p-28 : 0x1p-40;
    if (!(size >= limit)) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "the scene is %g across (its largest extent), below %g", size, limit);
      throw Error((sourcePath.empty() ? "" : sourcePath + ": ") + buf + (robust_ ? " (robust traversal)" : "") +
                  ", the smallest scale single-precision ray tracing renders correctly; scale it up (e.g. a node scale)");
    }
  }
  for (const SceneObject& o : objects)
    if (o.roles.occlusion != OcclusionScope::All) {
      scopes_.objectCount = uint32_t(objects.size());
      break;
    }
  applyObjectRoles();
  attachAlphaFilters();
  const auto t0 = std::chrono::steady_clock::now();
  RTCSceneFlags flags = robust_ ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE;
  // The context filter runs only in scenes that ask for it (and is then
  // called for every candidate hit): only when some object is scoped.
  if (scopes_.objectCount) flags = RTCSceneFlags(flags | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
  rtcSetSceneFlags(top_, flags);
  for (auto& m : meshes_) {
    rtcSetSceneFlags(m.rtcScene, flags);
    rtcCommitScene(m.rtcScene);
  }
  rtcCommitScene(top_);
  buildSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const RTCError err = rtcGetDeviceError(device_);
  if (err == RTC_ERROR_OUT_OF_MEMORY) throw Error("out of memory building the BVH");
  if (err != RTC_ERROR_NONE) throw Error("Embree failed to build the BVH (error " + std::to_string(int(err)) + ")");
  if (hasSubdivision_) {
    RTCBounds b;
    rtcGetSceneBounds(top_, &b);
    bounds_.extend(Vec3(b.lower_x, b.lower_y, b.lower_z));
    bounds_.extend(Vec3(b.upper_x, b.upper_y, b.upper_z));
  }
  committed_ = true;
}

void Scene::applyObjectRoles() {
  for (size_t o = 0; o < objects.size(); ++o)
    if (objects[o].roles.matte) {
      matte_.resize(objects.size(), 0);
      matte_[o] = 1;
    }
  for (size_t id = 0; id < topLevel_.size(); ++id) {
    const uint32_t o = topLevel_[id].object;
    if (o == kNoObject) continue;
    if (o >= objects.size()) throw Error("internal: geometry of an object that does not exist");
    const ObjectRoles& r = objects[o].roles;
    // Default roles keep Embree's default mask (all bits): the geometry is
    // left exactly as a scene without roles has it.
    if (r.camera && r.occluder) continue;
    RTCGeometry g = rtcGetGeometry(top_, unsigned(id));
    rtcSetGeometryMask(g, r.mask());
    rtcCommitGeometry(g);
  }
  if (!scopes_.objectCount) return;
  objectOfTop_.resize(topLevel_.size());
  for (size_t id = 0; id < topLevel_.size(); ++id) objectOfTop_[id] = topLevel_[id].object;
  scopeOfObject_.resize(objects.size());
  for (size_t o = 0; o < objects.size(); ++o) scopeOfObject_[o] = uint8_t(objects[o].roles.occlusion);
  scopes_.objectOfTop = objectOfTop_.data();
  scopes_.scope = scopeOfObject_.data();
}

void Scene::attachAlphaFilters() {
  const auto attach = [&](const Primitive& p) {
    const Material* m = materialOf(p);
    if (!m || m->alphaMode == AlphaMode::Opaque) return;
    const Texture* tex = m->texture >= 0 && !p.uvs.empty() ? textures[size_t(m->texture)].get() : nullptr;
    if (tex) tex->decode();  // up front: the filter never throws
    if (!m->cutsOut(tex && tex->hasAlpha())) return;
    if (p.subdivision) {
      Log::warn((sourcePath.empty() ? "" : sourcePath + ": ") + (p.name.empty() ? "a subdivision surface" : p.name) +
                ": alpha (alphaMode " + (m->alphaMode == AlphaMode::Mask ? "MASK" : "BLEND") +
                ") is not applied to Embree subdivision surfaces (rendered opaque; the osd backend applies it)");
      return;
    }
    auto s = std::make_unique<AlphaSurface>();
    s->indices = p.indices;
    s->uvs = tex ? p.uvs.data() : nullptr;
    s->texture = tex && tex->hasAlpha() ? tex : nullptr;
    s->wrapS = m->wrapS, s->wrapT = m->wrapT;
    s->transform = m->transform;
    s->mode = m->alphaMode;
    s->alpha = m->alpha;
    s->cutoff = m->alphaCutoff;
    attachAlphaFilter(p, *s);
    rtcCommitGeometry(p.geometry);
    alphaSurfaces_.push_back(std::move(s));
  };
  for (const Primitive& p : worldPrimitives_) attach(p);
  for (const InstancedMesh& m : meshes_)
    for (const Primitive& p : m.primitives) attach(p);
}

void Scene::decodeNormalMaps() const {
  if (!hasNormalMaps()) return;
  for (const Material& m : materials)
    if (m.normalTexture >= 0) dataTextures.at(size_t(m.normalTexture))->decode();
}

size_t Scene::attributeBytes() const {
  size_t b = 0;
  const auto add = [&](const Primitive& p) {
    b += p.normals.size() * sizeof(Vec3) + (p.uvs.size() + p.tangents.size()) * sizeof(float);
    if (p.subdivision) b += p.subdivision->uvs.bytes() + p.subdivision->faceRate.size() * sizeof(float);
  };
  for (const auto& p : worldPrimitives_) add(p);
  for (const auto& m : meshes_)
    for (const auto& p : m.primitives) add(p);
  return b;
}

SceneStats Scene::stats() const {
  SceneStats s;
  s.meshes = sourceMeshes;
  s.flattenedMeshes = flattenedMeshes;
  s.instances = instances_.size();
  s.movingInstances = moving_;
  s.primitives = worldPrimitives_.size();
  for (const auto& p : worldPrimitives_) {
    s.subdivisionFaces += p.faceCount;
    s.uniqueTriangles += p.triangleCount;
    s.renderedTriangles += p.triangleCount;
  }
  std::vector<size_t> meshTris(meshes_.size(), 0);
  for (size_t i = 0; i < meshes_.size(); ++i) {
    s.primitives += meshes_[i].primitives.size();
    for (const auto& p : meshes_[i].primitives) meshTris[i] += p.triangleCount;
    s.uniqueTriangles += meshTris[i];
  }
  for (const auto& inst : instances_) s.renderedTriangles += meshTris[size_t(inst.mesh)];
  return s;
}

}  // namespace obscura
