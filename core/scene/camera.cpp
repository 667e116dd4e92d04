#include "core/scene/camera.h"

#include <cmath>
#include <cstdio>

#include <obscura/error.h>

namespace obscura {

Camera makeLookAtCamera(Vec3 eye, Vec3 target, Vec3 up, float yfov, std::string name) {
  Camera c;
  c.name = std::move(name);
  c.yfov = yfov;
  const Vec3 back = normalize(eye - target);  // camera +Z points away from the view
  Vec3 right = cross(up, back);
  if (length(right) < 1e-6f) right = cross(Vec3(1, 0, 0), back);  // looking along up
  if (length(right) < 1e-6f) right = cross(Vec3(0, 0, 1), back);
  right = normalize(right);
  const Vec3 trueUp = cross(back, right);
  for (int r = 0; r < 3; ++r) {
    c.toWorld.m[r][0] = right[r];
    c.toWorld.m[r][1] = trueUp[r];
    c.toWorld.m[r][2] = back[r];
    c.toWorld.m[r][3] = eye[r];
  }
  return c;
}

Camera makeAutoCamera(const Bounds3& bounds, float aspect) {
  const float yfov = 0.7f;
  if (bounds.empty()) return makeLookAtCamera(Vec3(0, 0, 1), Vec3(0, 0, 0), Vec3(0, 1, 0), yfov, "auto");
  const Vec3 c = bounds.center();
  const float radius = std::max(0.5f * length(bounds.diagonal()), 1e-30f);
  // The sphere must fit the narrower of the two fields of view.
  const float halfFov = std::min(0.5f * yfov, std::atan(std::tan(0.5f * yfov) * aspect));
  const float dist = 1.05f * radius / std::sin(halfFov);
  const Vec3 dir = normalize(Vec3(0.8f, 0.55f, 1.0f));
  Camera cam = makeLookAtCamera(c + dir * dist, c, Vec3(0, 1, 0), yfov, "auto");
  return cam;
}

void checkCameraRange(const Camera& c, const std::string& what) {
  const auto g = [](float v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", double(v));
    return std::string(buf);
  };
  const Vec3 p = c.position();
  for (int i = 0; i < 3; ++i)
    if (!inTraceableRange(p[i]))
      throw Error(what + ": camera position (" + g(p.x) + ", " + g(p.y) + ", " + g(p.z) +
                  ") is outside the range Embree traces (|x| <= 1e+16)");
  if (!(c.znear >= 0.0f) || !inTraceableRange(c.znear))
    throw Error(what + ": znear " + g(c.znear) + " is outside [0, 1e+16]");
  // Every primary ray's origin and direction must be finite or Embree
  // aborts (ray.valid()): the frame (at rest and at each motion step) must
  // be a rotation and the field of view in (0, pi).
  if (!cameraFrameValid(c.toWorld)) throw Error(what + ": the camera's orientation is not finite and orthonormal");
  for (const Affine& m : c.motion)
    if (!cameraFrameValid(m) || !inTraceableRange(m.m[0][3]) || !inTraceableRange(m.m[1][3]) ||
        !inTraceableRange(m.m[2][3]))
      throw Error(what + ": the camera's motion has a position or orientation that is not finite");
  if (!(c.yfov > 0.0f && c.yfov < kPi)) throw Error(what + ": yfov " + g(c.yfov) + " is outside (0, pi)");
}

bool cameraFrameValid(const Affine& m) {
  Vec3 col[3];
  for (int k = 0; k < 3; ++k) {
    col[k] = Vec3(m.m[0][k], m.m[1][k], m.m[2][k]);
    for (int r = 0; r < 3; ++r)
      if (!std::isfinite(col[k][r])) return false;
    if (!(std::abs(length(col[k]) - 1.0f) < 1e-3f)) return false;
  }
  return std::abs(dot(col[0], col[1])) < 1e-3f && std::abs(dot(col[0], col[2])) < 1e-3f &&
         std::abs(dot(col[1], col[2])) < 1e-3f;
}

}  // namespace obscura
