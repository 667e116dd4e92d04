#include "bench/generated_scene.h"

#include <cmath>
#include <cstdint>
#include <vector>

#include <obscura/sampler.h>

namespace obscura::bench {
namespace {

constexpr int kGrid = 720;          // terrain cells per side: 2 * 720^2 = 1,036,800 triangles
constexpr float kHalfExtent = 80;   // terrain covers [-80, 80]^2 in x, z
constexpr int kSpheres = 40, kSphereSegments = 48, kSphereRings = 24;
constexpr int kBoxes = 60;

// Height h(x, z) = sum of a * sin(kx x + px) * cos(kz z + pz), and its
// gradient for the exact normal (-dh/dx, 1, -dh/dz).
struct Wave {
  float a, kx, kz, px, pz;
};
constexpr Wave kWaves[] = {
    {4.0f, 0.070f, 0.060f, 0.0f, 0.3f},
    {1.5f, 0.230f, 0.190f, 1.1f, 0.7f},
    {0.6f, 0.610f, 0.530f, 2.3f, 1.9f},
    {0.2f, 1.700f, 1.450f, 0.4f, 2.8f},
};

float height(float x, float z, Vec3* normal = nullptr) {
  float h = 0, dx = 0, dz = 0;
  for (const Wave& w : kWaves) {
    const float sx = std::sin(w.kx * x + w.px), cx = std::cos(w.kx * x + w.px);
    const float sz = std::sin(w.kz * z + w.pz), cz = std::cos(w.kz * z + w.pz);
    h += w.a * sx * cz;
    dx += w.a * w.kx * cx * cz;
    dz -= w.a * w.kz * sx * sz;
  }
  if (normal) *normal = normalize(Vec3(-dx, 1.0f, -dz));
  return h;
}

// Deterministic uniform [0,1) from (object, field).
float rand01(uint32_t object, uint32_t field) {
  return bitsToUnitFloat(hashCombine(mixBits32(object * 0x9e3779b1U + 0x1234567U), field));
}

// A material of albedo `c` (no texture), its index in scene.materials.
int addMaterial(Scene& scene, const char* name, Vec3 c) {
  Material m;
  m.name = name;
  m.baseColorFactor = c;
  scene.materials.push_back(m);
  return int(scene.materials.size()) - 1;
}

void addTerrain(Scene& scene) {
  const int n = kGrid + 1;
  std::vector<Vec3> pos, nrm;
  pos.reserve(size_t(n) * n);
  nrm.reserve(size_t(n) * n);
  for (int j = 0; j < n; ++j) {
    const float z = -kHalfExtent + 2.0f * kHalfExtent * float(j) / float(kGrid);
    for (int i = 0; i < n; ++i) {
      const float x = -kHalfExtent + 2.0f * kHalfExtent * float(i) / float(kGrid);
      Vec3 nn;
      const float y = height(x, z, &nn);
      pos.emplace_back(x, y, z);
      nrm.push_back(nn);
    }
  }
  std::vector<uint32_t> idx;
  idx.reserve(size_t(kGrid) * kGrid * 6);
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i) {
      const uint32_t a = uint32_t(j * n + i), b = a + 1, c = a + uint32_t(n), d = c + 1;
      // Counter-clockwise seen from +y.
      idx.insert(idx.end(), {a, c, b, b, c, d});
    }
  scene.addWorldPrimitive(pos, idx, std::move(nrm), {}, addMaterial(scene, "terrain", Vec3(0.5f, 0.45f, 0.35f)));
}

void addSpheres(Scene& scene) {
  std::vector<Vec3> pos, nrm;
  std::vector<uint32_t> idx;
  const int cols = kSphereSegments + 1;
  for (int s = 0; s < kSpheres; ++s) {
    const float x = -60.0f + 120.0f * rand01(uint32_t(s), 0);
    const float z = -60.0f + 120.0f * rand01(uint32_t(s), 1);
    const float r = 1.5f + 3.5f * rand01(uint32_t(s), 2);
    const Vec3 c(x, height(x, z) + 0.5f * r, z);
    const uint32_t base = uint32_t(pos.size());
    for (int ring = 0; ring <= kSphereRings; ++ring) {
      const float theta = kPi * float(ring) / float(kSphereRings);
      for (int seg = 0; seg <= kSphereSegments; ++seg) {
        const float phi = 2.0f * kPi * float(seg) / float(kSphereSegments);
        const Vec3 d(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
        pos.push_back(c + d * r);
        nrm.push_back(d);
      }
    }
    for (int ring = 0; ring < kSphereRings; ++ring)
      for (int seg = 0; seg < kSphereSegments; ++seg) {
        const uint32_t a = base + uint32_t(ring * cols + seg), b = a + 1, cc = a + uint32_t(cols), d = cc + 1;
        if (ring != 0) idx.insert(idx.end(), {a, b, cc});                  // skip the degenerate pole triangles
        if (ring != kSphereRings - 1) idx.insert(idx.end(), {b, d, cc});
      }
  }
  scene.addWorldPrimitive(pos, idx, std::move(nrm), {}, addMaterial(scene, "spheres", Vec3(0.8f, 0.8f, 0.8f)));
}

void addBoxes(Scene& scene) {
  std::vector<Vec3> pos;
  std::vector<uint32_t> idx;
  // Corner c of the unit cube: bit 0 = x, bit 1 = y, bit 2 = z. Faces as quads.
  static const int kFaces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (int b = 0; b < kBoxes; ++b) {
    const float x = -70.0f + 140.0f * rand01(uint32_t(1000 + b), 0);
    const float z = -70.0f + 140.0f * rand01(uint32_t(1000 + b), 1);
    const Vec3 half(0.5f + 2.0f * rand01(uint32_t(1000 + b), 2), 0.5f + 3.0f * rand01(uint32_t(1000 + b), 3),
                    0.5f + 2.0f * rand01(uint32_t(1000 + b), 4));
    const float angle = 2.0f * kPi * rand01(uint32_t(1000 + b), 5);
    const float ca = std::cos(angle), sa = std::sin(angle);
    const Vec3 c(x, height(x, z) + 0.6f * half.y, z);
    const uint32_t base = uint32_t(pos.size());
    for (int k = 0; k < 8; ++k) {
      const Vec3 l(k & 1 ? half.x : -half.x, k & 2 ? half.y : -half.y, k & 4 ? half.z : -half.z);
      pos.push_back(c + Vec3(ca * l.x + sa * l.z, l.y, -sa * l.x + ca * l.z));
    }
    for (const auto& f : kFaces) {
      idx.insert(idx.end(), {base + uint32_t(f[0]), base + uint32_t(f[1]), base + uint32_t(f[2])});
      idx.insert(idx.end(), {base + uint32_t(f[0]), base + uint32_t(f[2]), base + uint32_t(f[3])});
    }
  }
  scene.addWorldPrimitive(pos, idx, {}, {}, addMaterial(scene, "boxes", Vec3(0.3f, 0.4f, 0.6f)));  // no normals: shading uses Ng
}

}  // namespace

void buildGeneratedScene(Scene& scene) {
  addTerrain(scene);
  addSpheres(scene);
  addBoxes(scene);
}

Camera generatedSceneCamera() {
  // Pitched down ~45 degrees over the terrain's +z edge: with the default
  // 0.7 rad vertical field of view even the top corners land on the terrain.
  return makeLookAtCamera(Vec3(0.0f, 55.0f, 62.0f), Vec3(0.0f, 0.0f, 5.0f), Vec3(0, 1, 0), 0.7f, "bench");
}

}  // namespace obscura::bench
