// Perspective pinhole camera with glTF conventions: looks down its local -Z,
// +Y up, +X right; the vertical field of view is fixed and the horizontal one
// follows the image's aspect ratio.
#pragma once

#include <cmath>
#include <string>

#include "core/math.h"

namespace obscura {

class Scene;

// The largest |coordinate| of a vertex, a scene's bounds or a camera that
// Obscura accepts. Embree traces values up to FLT_LARGE = 1.844e18 only: it
// silently ignores primitives with larger coordinates when it builds the
// BVH, and a ray whose origin exceeds it is invalid (Embree 3,
// rtcCommitScene and common/math/constants.h). 1e16 leaves a factor of more
// than 100 for the automatic camera (about three bounding radii from the
// centre) and for the products of two coordinates in intersection and
// shading arithmetic (1e32, far below float's 3.4e38).
constexpr float kMaxCoordinate = 1e16f;
inline bool inTraceableRange(float x) { return std::abs(x) <= kMaxCoordinate; }  // false for NaN


struct Camera {
  std::string name;
  int fileIndex = -1;    // index in the file's cameras[], -1 if made up
  Affine toWorld;       // camera-to-world, rigid (scale is removed on load)
  float yfov = 0.8f;    // radians
  float znear = 0.0f;   // rays start here (along the ray, not depth)
  float zfar = kInfinity;
  bool animated = false;  // placed by a node that an animation moves (at the time loaded)

  // Primary ray through film position (fx, fy) in pixels, y down, for an
  // image of w x h pixels. Direction is unit length.
  void generateRay(float fx, float fy, int w, int h, Vec3& org, Vec3& dir) const {
    const float tanHalf = std::tan(0.5f * yfov);
    const float aspect = float(w) / float(h);
    const float sx = (2.0f * fx / float(w) - 1.0f) * tanHalf * aspect;
    const float sy = (1.0f - 2.0f * fy / float(h)) * tanHalf;
    org = Vec3(toWorld.m[0][3], toWorld.m[1][3], toWorld.m[2][3]);
    dir = normalize(toWorld.vector(Vec3(sx, sy, -1.0f)));
  }
  Vec3 position() const { return {toWorld.m[0][3], toWorld.m[1][3], toWorld.m[2][3]}; }
};

// A camera prepared for one image size: the per-ray work is a few FMAs.
struct RasterCamera {
  Vec3 org, dx, dy, d0;  // dir(fx, fy) = normalize(d0 + fx*dx + fy*dy)
  RasterCamera(const Camera& c, int w, int h) {
    const float tanHalf = std::tan(0.5f * c.yfov);
    const float aspect = float(w) / float(h);
    org = c.position();
    const Vec3 right = c.toWorld.vector(Vec3(1, 0, 0)) * (2.0f * tanHalf * aspect / float(w));
    const Vec3 down = c.toWorld.vector(Vec3(0, -1, 0)) * (2.0f * tanHalf / float(h));
    dx = right;
    dy = down;
    d0 = c.toWorld.vector(Vec3(-tanHalf * aspect, tanHalf, -1.0f));
  }
  Vec3 direction(float fx, float fy) const { return normalize(d0 + dx * fx + dy * fy); }
};

// A camera framing the whole scene from above and to the side, used when the
// file has none: glTF's +Y up, looking at the bounding box centre from the
// (+X, +Y, +Z) octant, far enough that the bounding sphere fits the view.
Camera makeAutoCamera(const Bounds3& bounds, float aspect);

// Throws obscura::Error "`what`: camera position ... outside the range Embree
// traces" unless the camera's position and znear are finite and within
// kMaxCoordinate (a zfar beyond it is as good as infinity).
void checkCameraRange(const Camera& camera, const std::string& what);

// Camera from the look-at form (rigid, orthonormal).
Camera makeLookAtCamera(Vec3 eye, Vec3 target, Vec3 up, float yfov, std::string name);

}  // namespace obscura
