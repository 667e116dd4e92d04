// Perspective pinhole camera with glTF conventions: looks down its local -Z,
// +Y up, +X right; the vertical field of view is fixed and the horizontal one
// follows the image's aspect ratio.
#pragma once

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <obscura/math.h>

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
  // Motion blur: camera-to-world at steps k = 0..n-1, at times k / (n - 1)
  // across the shutter (rigid each, interpolated linearly in between as a
  // moving instance is: core/scene/scene.h Instance); empty when still.
  std::vector<Affine> motion;

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
    axis = c.toWorld.vector(Vec3(0, 0, -1));
  }
  Vec3 direction(float fx, float fy) const { return normalize(d0 + dx * fx + dy * fy); }
  // out[i] = direction(fx[i], fy[i]) for i < n, bit for bit, four lanes at a
  // time: the same operations in the same order (IEEE sqrt and division are
  // correctly rounded in SSE lanes as in scalar code). One ray at a time,
  // the square root and division of each normalization stalled the render
  // loop's camera stage (a quarter of its time, perf); across lanes they
  // overlap.
  void directions(const float* fx, const float* fy, size_t n, Vec3* out) const {
    size_t i = 0;
#if defined(__SSE2__)
    const auto axisLanes = [&](float o, float a, float b, __m128 x, __m128 y) {
      return _mm_add_ps(_mm_add_ps(_mm_set1_ps(o), _mm_mul_ps(_mm_set1_ps(a), x)), _mm_mul_ps(_mm_set1_ps(b), y));
    };
    for (; i + 4 <= n; i += 4) {
      const __m128 x = _mm_loadu_ps(fx + i), y = _mm_loadu_ps(fy + i);
      const __m128 vx = axisLanes(d0.x, dx.x, dy.x, x, y), vy = axisLanes(d0.y, dx.y, dy.y, x, y),
                   vz = axisLanes(d0.z, dx.z, dy.z, x, y);
      const __m128 len2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(vx, vx), _mm_mul_ps(vy, vy)), _mm_mul_ps(vz, vz));
      const __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), _mm_sqrt_ps(len2));
      alignas(16) float ox[4], oy[4], oz[4];
      _mm_store_ps(ox, _mm_mul_ps(vx, inv));
      _mm_store_ps(oy, _mm_mul_ps(vy, inv));
      _mm_store_ps(oz, _mm_mul_ps(vz, inv));
      for (int k = 0; k < 4; ++k) out[i + size_t(k)] = Vec3(ox[k], oy[k], oz[k]);
    }
#endif
    for (; i < n; ++i) out[i] = direction(fx[i], fy[i]);
  }
  Vec3 axis;  // the view axis, camera-to-world of (0, 0, -1)
};

// A RasterCamera over the shutter: a moving camera's at each motion step,
// blended linearly at a sample's time (every field is linear in the
// camera-to-world matrix, so this is the raster of the blended matrix).
class ShutterCamera {
 public:
  ShutterCamera(const Camera& c, int w, int h) {
    if (c.motion.size() < 2) {
      steps_.emplace_back(c, w, h);
      return;
    }
    for (const Affine& m : c.motion) {
      Camera at = c;
      at.toWorld = m;
      steps_.emplace_back(at, w, h);
    }
  }
  bool moves() const { return steps_.size() > 1; }
  const RasterCamera& still() const { return steps_[0]; }
  RasterCamera at(float time) const {
    if (steps_.size() == 1) return steps_[0];
    const float x = std::clamp(time, 0.0f, 1.0f) * float(steps_.size() - 1);
    const size_t k = std::min(size_t(x), steps_.size() - 2);
    const float f = x - float(k), g = 1.0f - f;
    RasterCamera r = steps_[k];
    const RasterCamera& b = steps_[k + 1];
    r.org = r.org * g + b.org * f, r.dx = r.dx * g + b.dx * f;
    r.dy = r.dy * g + b.dy * f, r.d0 = r.d0 * g + b.d0 * f;
    r.axis = r.axis * g + b.axis * f;
    return r;
  }

 private:
  std::vector<RasterCamera> steps_;
};

// A camera framing the whole scene from above and to the side, used when the
// file has none: glTF's +Y up, looking at the bounding box centre from the
// (+X, +Y, +Z) octant, far enough that the bounding sphere fits the view.
Camera makeAutoCamera(const Bounds3& bounds, float aspect);

// Throws obscura::Error "`what`: camera position ... outside the range Embree
// traces" unless the camera's position and znear are finite and within
// kMaxCoordinate (a zfar beyond it is as good as infinity).
// It also throws unless the frame (and every motion step's) is a finite
// rotation and yfov is in (0, pi), so no primary ray has a NaN or infinite
// origin or direction (Embree aborts on one: ray.valid()).
void checkCameraRange(const Camera& camera, const std::string& what);

// True if m's 3x3 part is finite and orthonormal (within 1e-3).
bool cameraFrameValid(const Affine& m);

// Camera from the look-at form (rigid, orthonormal).
Camera makeLookAtCamera(Vec3 eye, Vec3 target, Vec3 up, float yfov, std::string name);

}  // namespace obscura
