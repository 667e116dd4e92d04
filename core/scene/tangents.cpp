#include "core/scene/tangents.h"

#include <cmath>

namespace obscura {

namespace {
struct D3 {
  double x = 0, y = 0, z = 0;
};
D3 d3(Vec3 a) { return {a.x, a.y, a.z}; }
D3 operator-(D3 a, D3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
D3 operator+(D3 a, D3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
D3 operator*(D3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(D3 a, D3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
D3 cross(D3 a, D3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double len(D3 a) { return std::sqrt(dot(a, a)); }
// a / |a|, or zero when a has no usable length.
D3 unit(D3 a) {
  const double l = len(a);
  return l > 0 && std::isfinite(l) ? a * (1.0 / l) : D3{};
}
// The corner angle between edges a and b.
double angle(D3 a, D3 b) {
  const double la = len(a), lb = len(b);
  if (!(la > 0) || !(lb > 0)) return 0;
  return std::acos(std::fmax(-1.0, std::fmin(1.0, dot(a, b) / (la * lb))));
}
}  // namespace

std::vector<float> generateTangents(const std::vector<Vec3>& positions, const std::vector<Vec3>& normals,
                                    const std::vector<float>& uvs, const std::vector<uint32_t>& indices,
                                    bool vRunsDown) {
  const size_t n = positions.size();
  std::vector<D3> tSum(n), bSum(n), nSum(n);
  const double vSign = vRunsDown ? -1.0 : 1.0;
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    const uint32_t i[3] = {indices[t], indices[t + 1], indices[t + 2]};
    const D3 p[3] = {d3(positions[i[0]]), d3(positions[i[1]]), d3(positions[i[2]])};
    const D3 e1 = p[1] - p[0], e2 = p[2] - p[0];
    // Solve [e1 e2] = [dP/du dP/dv] [duv1 duv2] (v up the image).
    const double du1 = double(uvs[2 * i[1]]) - uvs[2 * i[0]], dv1 = vSign * (double(uvs[2 * i[1] + 1]) - uvs[2 * i[0] + 1]);
    const double du2 = double(uvs[2 * i[2]]) - uvs[2 * i[0]], dv2 = vSign * (double(uvs[2 * i[2] + 1]) - uvs[2 * i[0] + 1]);
    const double det = du1 * dv2 - dv1 * du2;
    const D3 faceN = unit(cross(e1, e2));
    D3 tu, tv;
    if (std::abs(det) > 1e-20 && std::isfinite(det)) {
      tu = unit((e1 * dv2 - e2 * dv1) * (1.0 / det));
      tv = unit((e2 * du1 - e1 * du2) * (1.0 / det));
    }
    for (int k = 0; k < 3; ++k) {
      const D3 a = p[(k + 1) % 3] - p[k], b = p[(k + 2) % 3] - p[k];
      const double w = angle(a, b);
      tSum[i[k]] = tSum[i[k]] + tu * w;
      bSum[i[k]] = bSum[i[k]] + tv * w;
      nSum[i[k]] = nSum[i[k]] + faceN * w;
    }
  }
  std::vector<float> out(4 * n);
  for (size_t v = 0; v < n; ++v) {
    D3 N = unit(normals.empty() ? nSum[v] : d3(normals[v]));
    if (len(N) == 0) N = {0, 0, 1};
    D3 T = unit(tSum[v] - N * dot(N, tSum[v]));
    if (len(T) == 0) {
      // No usable uv gradient: any direction in the tangent plane.
      const D3 axis = std::abs(N.x) < 0.9 ? D3{1, 0, 0} : D3{0, 1, 0};
      T = unit(axis - N * dot(N, axis));
    }
    const double w = dot(cross(N, T), bSum[v]) < 0 ? -1.0 : 1.0;
    out[4 * v] = float(T.x), out[4 * v + 1] = float(T.y), out[4 * v + 2] = float(T.z), out[4 * v + 3] = float(w);
  }
  return out;
}

}  // namespace obscura
