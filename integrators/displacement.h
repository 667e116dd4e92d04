// The displacement field of a height map, as the height-field containment
// passes read it (`containment`; `ssat map=`, the combination of AT §6:
// docs/math.md §9, §10, docs/containment.md).
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>

#include <obscura/math.h>
#include <obscura/surface_hit.h>
#include "core/subd/subdivision.h"

namespace obscura {

// The displacement field d(uv) = scale (h(uv) - midlevel) of a height map,
// read and sampled as `--displace` does (core/subd/subdivision.h HeightMap:
// bilinear between texel centres, repeat, v = 0 at the bottom row; the uv
// frame reports glTF's downward v flipped, so glTF meshes read the map as
// their extras displacement does).
class Displacement {
 public:
  Displacement(const std::string& path, double scale, double midlevel)
      : map_(std::make_shared<const HeightMap>(path)), scale_(scale), midlevel_(midlevel) {
    du_ = 1.0 / map_->width(), dv_ = 1.0 / map_->height();
  }
  // d at (u, v), any finite u, v (the map repeats).
  double operator()(double u, double v) const { return scale_ * (map_->sample(u, v) - midlevel_); }
  // dd/du, dd/dv by central differences one texel apart.
  void gradient(double u, double v, double& ddu, double& ddv) const {
    ddu = ((*this)(u + du_, v) - (*this)(u - du_, v)) / (2 * du_);
    ddv = ((*this)(u, v + dv_) - (*this)(u, v - dv_)) / (2 * dv_);
  }

 private:
  std::shared_ptr<const HeightMap> map_;
  double scale_, midlevel_, du_ = 0, dv_ = 0;
};

// The local height-field frame at a point p of the macro surface with unit
// normal N (facing the viewer) and texture frame f (uv, dP/du, dP/dv, in
// the same space as N): a test point q has tangent coordinates
// q - p = a dP/du + b dP/dv + z N, a = dot(q - p, ea), b = dot(q - p, eb),
// z = dot(q - p, ez) (the dual basis), lies above uv' = uv + (a, b) at
// height z, and is inside iff z < d(uv') [AT 4, figure 3]; the shaded point
// is p + N d0. nd: the displaced normal normalize((dP/du + N dd/du) x
// (dP/dv + N dd/dv)) on N's side (dN/du, dN/dv dropped: curvature ignored).
// false for a degenerate frame.
struct FieldFrame {
  double u, v, d0, ddu, ddv;
  Vec3 ea, eb, ez, nd;
};
inline bool fieldFrame(const Displacement& field, const UvFrame& f, Vec3 N, FieldFrame& L) {
  const Vec3 cv = cross(f.dpdv, N), cn = cross(N, f.dpdu), cu = cross(f.dpdu, f.dpdv);
  const float det = dot(f.dpdu, cv);
  if (!(std::abs(det) > 0.0f) || !std::isfinite(det)) return false;
  const float inv = 1.0f / det;
  L.ea = cv * inv, L.eb = cn * inv, L.ez = cu * inv;
  if (!isFinite(L.ea) || !isFinite(L.eb) || !isFinite(L.ez)) return false;
  L.u = f.u, L.v = f.v;
  L.d0 = field(L.u, L.v);
  field.gradient(L.u, L.v, L.ddu, L.ddv);
  Vec3 nd = cross(f.dpdu + N * float(L.ddu), f.dpdv + N * float(L.ddv));
  const float len = length(nd);
  nd = len > 0.0f && std::isfinite(len) ? nd * (1.0f / len) : N;
  if (dot(nd, N) < 0.0f) nd = -nd;  // a mirrored uv layout flips the cross product
  L.nd = nd;
  return true;
}

// Is p + N d0 + w t outside the field for every t = r i/m, i = 1..m,
// t >= tnear? If not, (*su, *sv) = the uv of the first point inside (where
// the segment meets the field: "the projection of the point first tested
// positively for occlusion onto the surface", whose albedo [AT 9] takes).
inline bool outsideField(const Displacement& field, const FieldFrame& L, Vec3 w, float r, uint32_t steps,
                         float tnear, double* su = nullptr, double* sv = nullptr) {
  // q - p = N d0 + w t, and (N; ea, eb, ez) = (0, 0, 1).
  const double wa = dot(w, L.ea), wb = dot(w, L.eb), wz = dot(w, L.ez);
  for (uint32_t i = 1; i <= steps; ++i) {
    const double t = double(r) * double(i) / double(steps);
    if (t < double(tnear)) continue;  // nearer than `near`: ignored
    if (L.d0 + t * wz < field(L.u + t * wa, L.v + t * wb)) {  // inside (I0 = 0)
      if (su) *su = L.u + t * wa, *sv = L.v + t * wb;
      return false;
    }
  }
  return true;
}

}  // namespace obscura
