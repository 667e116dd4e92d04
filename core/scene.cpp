#include "core/scene.h"

#include <chrono>
#include <cstring>

#include "core/error.h"

namespace obscura {
namespace {
void embreeErrorCallback(void*, RTCError code, const char* str) {
  if (code == RTC_ERROR_NONE) return;
  // Embree reports out-of-memory and invalid use here; turn the first into a
  // user-facing error at the next check, the rest into warnings.
  Log::warn(std::string("Embree: ") + (str ? str : "unknown error"));
}
}  // namespace

Scene::Scene() {
  device_ = rtcNewDevice(nullptr);
  if (!device_) throw Error("cannot create the Embree device (error " + std::to_string(rtcGetDeviceError(nullptr)) + ")");
  rtcSetDeviceErrorFunction(device_, embreeErrorCallback, nullptr);
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
                               std::vector<float> uvs, int material, unsigned* geomID) {
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
  p.material = material;
  return p;
}

int Scene::addWorldPrimitive(const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices,
                             std::vector<Vec3> normals, std::vector<float> uvs, int material) {
  unsigned id = 0;
  Primitive p = makePrimitive(top_, positions, indices, std::move(normals), std::move(uvs), material, &id);
  for (const Vec3& v : positions) bounds_.extend(v);
  if (topLevel_.size() <= id) topLevel_.resize(id + 1);
  topLevel_[id].primitive = int(worldPrimitives_.size());
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
                               std::vector<Vec3> normals, std::vector<float> uvs, int material) {
  InstancedMesh& m = meshes_.at(size_t(mesh));
  unsigned id = 0;
  Primitive p = makePrimitive(m.rtcScene, positions, indices, std::move(normals), std::move(uvs), material, &id);
  for (const Vec3& v : positions) m.objectBounds.extend(v);
  if (m.primitives.size() != id) throw Error("internal: unexpected Embree geometry id");
  m.primitives.push_back(std::move(p));
}

void Scene::addInstance(int mesh, const Affine& toWorld, std::string node) {
  const InstancedMesh& m = meshes_.at(size_t(mesh));
  RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
  rtcSetGeometryInstancedScene(g, m.rtcScene);
  rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, &toWorld.m[0][0]);
  rtcCommitGeometry(g);
  const unsigned id = rtcAttachGeometry(top_, g);
  rtcReleaseGeometry(g);
  if (topLevel_.size() <= id) topLevel_.resize(id + 1);
  topLevel_[id].instance = int(instances_.size());
  instances_.push_back({mesh, toWorld, std::move(node)});
  if (!m.objectBounds.empty()) {
    for (int c = 0; c < 8; ++c) {
      const Vec3 corner(c & 1 ? m.objectBounds.hi.x : m.objectBounds.lo.x,
                        c & 2 ? m.objectBounds.hi.y : m.objectBounds.lo.y,
                        c & 4 ? m.objectBounds.hi.z : m.objectBounds.lo.z);
      bounds_.extend(toWorld.point(corner));
    }
  }
}

void Scene::commit() {
  if (committed_) return;
  const auto t0 = std::chrono::steady_clock::now();
  const RTCSceneFlags flags = robust_ ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE;
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
  committed_ = true;
}

SceneStats Scene::stats() const {
  SceneStats s;
  s.meshes = sourceMeshes;
  s.flattenedMeshes = flattenedMeshes;
  s.instances = instances_.size();
  s.primitives = worldPrimitives_.size();
  for (const auto& p : worldPrimitives_) {
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
