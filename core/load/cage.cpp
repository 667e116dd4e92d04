#include "core/load/cage.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <obscura/error.h>
#include "core/util/option_names.h"

namespace obscura {

std::vector<float> edgePixelLengths(const SubdivisionCage& cage, const Camera& camera, int width, int height) {
  // A pixel at distance z spans z * 2 tan(yfov / 2) / height scene units.
  const double pixelPerUnitDistance = 2.0 * std::tan(0.5 * double(camera.yfov)) / double(height);
  (void)width;  // square pixels: the vertical field of view sets the scale
  const Vec3 eye = camera.position();
  std::vector<float> out(cage.faceIndices.size());
  size_t k = 0;
  for (const int n : cage.faceSizes) {
    for (int j = 0; j < n; ++j) {
      const Vec3 a = cage.positions[size_t(cage.faceIndices[k + size_t(j)])];
      const Vec3 b = cage.positions[size_t(cage.faceIndices[k + size_t((j + 1) % n)])];
      // min/max of the two ends make the value symmetric in (a, b).
      const double da = length(a - eye), db = length(b - eye);
      const double near = std::max(std::min(da, db), 1e-30);
      const double len = std::max(double(length(b - a)), 0.0);
      out[k + size_t(j)] = float(std::min(len / (near * pixelPerUnitDistance), 1e30));
    }
    k += size_t(n);
  }
  return out;
}

int levelForEdgeLength(const std::vector<float>& edgePixels, double maxPixels) {
  double longest = 0;
  for (const float e : edgePixels) longest = std::max(longest, double(e));
  if (!(longest > maxPixels)) return 0;
  return int(std::min(10.0, std::ceil(std::log2(longest / maxPixels))));
}

size_t embreeSubdivisionBytes(const SubdivisionCage& cage, const std::vector<float>& rates) {
  // Measured on the Spot cage, levels 5-7 (obscura_bench_subdiv: Embree's
  // memory monitor at the build's peak; `obscura render` peak RSS agrees):
  // 33-35 bytes per tessellation point, grid and BVH together; 40 with a
  // margin.
  constexpr double kBytesPerPoint = 40.0;
  double points = 0;
  size_t k = 0;
  for (const int n : cage.faceSizes) {
    double r = 1;
    for (int j = 0; j < n; ++j) r = std::max(r, double(rates.size() == 1 ? rates[0] : rates[k + size_t(j)]));
    r = std::min(r, 4096.0);
    points += n == 4 ? (r + 1) * (r + 1) : double(n) * (0.5 * r + 1) * (0.5 * r + 1);
    k += size_t(n);
  }
  return size_t(std::min(points * kBytesPerPoint, 1e18));
}

void addCage(Scene& scene, const SubdivisionCage& cage, const LoadOptions& o, const CageDisplacement& disp, int material,
             const std::string& what) {
  const bool adaptive = o.maxEdgePixels > 0;
  if (!adaptive && (o.subdivisionLevel < 0 || o.subdivisionLevel > 10))
    throw Error(what + ": subdivision level " + std::to_string(o.subdivisionLevel) + " is outside [0, 10]");
  if (adaptive && (!o.camera || o.imageWidth < 1 || o.imageHeight < 1))
    throw Error("internal: adaptive subdivision without a camera");
  if (disp.map && cage.uvIndices.empty()) throw Error(what + ": displacement needs texture coordinates on every face corner");
  if (disp.map) {
    // Embree's ray-primitive arithmetic is float and forms products of three
    // coordinate differences (the Pluecker/Moeller tests: a determinant of
    // edge and origin vectors), which overflow past cbrt(FLT_MAX) = 7e12
    // scene units: on subdivision grids the intersection then returns NaN
    // distances, the next ray starts at NaN and Embree aborts on its
    // ray.valid() assertion (measured, Spot cage on the embree backend:
    // largest displaced coordinate 6.3e12 renders, 8.4e12 aborts - the
    // cube root of FLT_MAX, 6.98e12, lies between); on triangles hits are
    // silently lost instead.
    // Embree documents a range only for rays (|org|, |dir| <= FLT_LARGE =
    // 1.8e18), which is looser. So displacement may take no point beyond
    // kMaxDisplacedCoordinate = 1e12 (a factor 7 under the overflow, for the
    // sum of three products and origins anywhere in the scene): the cage's
    // largest coordinate plus |scale| times the height map's largest
    // |h - midlevel| (the limit surface lies in the cage's hull and moves
    // along unit normals).
    double cageMax = 0;
    for (const Vec3& p : cage.positions) cageMax = std::max({cageMax, double(std::abs(p.x)), double(std::abs(p.y)), double(std::abs(p.z))});
    const double dev = std::max(std::abs(double(disp.map->maxTexel()) - disp.midlevel),
                                std::abs(double(disp.map->minTexel()) - disp.midlevel));
    const double reach = cageMax + std::abs(disp.scale) * dev;
    if (!(reach <= kMaxDisplacedCoordinate)) {
      char buf[160];
      std::snprintf(buf, sizeof buf, ": %g moves %s up to %.3g scene units from the origin; at most %g is traced reliably",
                    disp.scale, "the surface", reach, kMaxDisplacedCoordinate);
      throw Error((disp.scaleField.empty() ? settingName(Setting::DisplacementScale) : disp.scaleField) + buf + " (" + what + ")");
    }
  }
  const std::string budget = ", over the " + settingName(Setting::MaxMemory) + " budget of " + std::to_string(o.maxMemoryBytes >> 20) + " MiB";

  if (o.backend == SubdivisionBackend::Embree) {
    if (o.scheme != SubdivisionScheme::CatmullClark)
      throw Error(what + ": Embree's subdivision surfaces are Catmull-Clark only (use " + settingName(Setting::SubdivisionBackendOsd) + " for loop)");
    validateCage(cage, SubdivisionScheme::CatmullClark, what);
    for (const int n : cage.faceSizes)
      if (n > 15) throw Error(what + ": a face has " + std::to_string(n) + " vertices; Embree's subdivision takes 3 to 15");
    std::vector<float> rates;
    if (adaptive) {
      rates = edgePixelLengths(cage, *o.camera, o.imageWidth, o.imageHeight);
      for (float& r : rates) r = float(std::clamp(std::ceil(double(r) / o.maxEdgePixels), 1.0, 4096.0));
    } else {
      rates = {float(1 << o.subdivisionLevel)};  // level L: 2^L segments per cage edge, as OpenSubdiv
    }
    const size_t bytes = embreeSubdivisionBytes(cage, rates);
    if (bytes > o.maxMemoryBytes)
      throw Error(what + ": Embree's tessellation needs about " + std::to_string(bytes >> 20) + " MiB" + budget);
    scene.setPrimitiveName(
        scene.addSubdivisionSurface(cage, rates, disp.map, float(disp.scale), float(disp.midlevel), disp.flipV, material),
        what);
    return;
  }
  const int level = adaptive ? levelForEdgeLength(edgePixelLengths(cage, *o.camera, o.imageWidth, o.imageHeight),
                                                  o.maxEdgePixels)
                             : o.subdivisionLevel;
  SubdividedMesh m = subdivide(cage, o.scheme, level, o.maxMemoryBytes, what);
  if (disp.map) displace(m, *disp.map, disp.scale, disp.midlevel, disp.flipV);
  scene.setPrimitiveName(scene.addWorldPrimitive(m.positions, m.triangles, std::move(m.normals), std::move(m.uvs), material),
                         what);
}

}  // namespace obscura
