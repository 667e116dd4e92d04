#include "tests/support.h"

#include <filesystem>

namespace obscura::test {

std::string tempDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("obscura_test_" + std::to_string(::getpid())) / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

void addSphereCavity(Scene& scene, float rs, double alpha, int rings, int segments) {
  std::vector<Vec3> pos, nrm;
  std::vector<uint32_t> idx;
  // Ring r at polar angle theta_r from +Z: theta_0 = alpha (hole edge) to
  // theta_rings = pi (the -Z pole, one vertex).
  for (int r = 0; r <= rings; ++r) {
    const double theta = alpha + (M_PI - alpha) * double(r) / rings;
    const int n = r == rings ? 1 : segments;
    for (int s = 0; s < n; ++s) {
      const double phi = 2.0 * M_PI * double(s) / segments;
      const Vec3 p(float(rs * std::sin(theta) * std::cos(phi)), float(rs * std::sin(theta) * std::sin(phi)),
                   float(rs * std::cos(theta)));
      pos.push_back(r == rings ? Vec3(0, 0, -rs) : p);
      nrm.push_back(r == rings ? Vec3(0, 0, 1) : normalize(-p));
    }
  }
  const auto at = [&](int r, int s) { return uint32_t(r * segments + (s % segments)); };
  for (int r = 0; r + 1 < rings; ++r)
    for (int s = 0; s < segments; ++s) {
      idx.insert(idx.end(), {at(r, s), at(r + 1, s), at(r + 1, s + 1)});
      idx.insert(idx.end(), {at(r, s), at(r + 1, s + 1), at(r, s + 1)});
    }
  const uint32_t pole = uint32_t(rings * segments);
  for (int s = 0; s < segments; ++s) idx.insert(idx.end(), {at(rings - 1, s), pole, at(rings - 1, s + 1)});
  scene.addWorldPrimitive(pos, idx, nrm, {}, -1);
}

void addPlane(Scene& scene, float h, float z) {
  scene.addWorldPrimitive({{-h, -h, z}, {h, -h, z}, {h, h, z}, {-h, h, z}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
}

Film renderWith(const Scene& scene, const Camera& camera, const std::string& integrator,
                const std::vector<std::string>& params, const RenderSettings& settings, RenderStats* stats) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find(integrator);
  ParamSet p(d.params, d.name);
  for (const auto& a : params) p.setAssignment(a);
  auto integ = d.create(p);
  RenderStats local;
  return render(scene, camera, *integ, d.needs(p), settings, stats ? *stats : local);
}

double meanCovered(const Film& film, int channel, size_t* count) {
  double sum = 0;
  size_t n = 0;
  for (int y = 0; y < film.height(); ++y)
    for (int x = 0; x < film.width(); ++x)
      if (film.at(kA, x, y) == 1.0f) {
        sum += film.at(channel, x, y);
        ++n;
      }
  if (count) *count = n;
  return n ? sum / double(n) : NAN;
}

}  // namespace obscura::test
