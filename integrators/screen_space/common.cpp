#include "integrators/screen_space/common.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace obscura::screen_space {

std::vector<ParamSpec> sharedParams(const std::string& countDoc, int countDefault, const std::string& interleaveDefault) {
  return {
      {.name = "count", .type = ParamType::Int, .defaultValue = std::to_string(countDefault), .min = 1, .max = 256,
       .doc = countDoc},
      {.name = "interleave", .type = ParamType::Enum, .defaultValue = interleaveDefault, .choices = {"on", "off"},
       .doc = "on: 16 rotations of the set in a 4x4 pixel pattern, then the depth-aware 4x4 box filter (AT 4.2); "
              "off: a random rotation per pixel, no filter"},
      {.name = "filter-depth", .type = ParamType::Float, .defaultValue = "0.02", .min = 0.0, .max = 1e30,
       .doc = "the filter averages neighbours whose depth differs by at most this fraction of the pixel's"},
      {.name = "depth", .type = ParamType::Enum, .defaultValue = "gbuffer", .choices = {"gbuffer", "traced"},
       .doc = "gbuffer: z* read from the depth buffer; traced: the camera ray through each sample point traced "
              "(the same estimator without the depth buffer's discretization)"},
      {.name = "guard-band", .type = ParamType::Int, .defaultValue = "-1", .min = -1, .max = 4096,
       .doc = "pixels of G-buffer rendered around the frame (or region), and how far from its pixel a sample reads "
              "the depth buffer; -1: R's projected size from the scene's nearest point, at most 1/8 of the larger "
              "image side (min 16); 0: none (reads anywhere in the frame, nothing beyond; no --region)"},
  };
}


// Compiled twice (AVX2, baseline): 8 points per instruction where the CPU
// has AVX2, without requiring it of the build.
__attribute__((target_clones("avx2", "default"))) void projectOffsets(const PointProjection& pr, Vec3 P,
                                                                      const Frame& f, Vec3 c,
                                                                      const float* __restrict ox,
                                                                      const float* __restrict oy,
                                                                      const float* __restrict oz, int count,
                                                                      float* __restrict depth,
                                                                      uint32_t* __restrict pixel) {
  // Everything in locals, the conditions as selects: the loop vectorizes.
  const float sx = f.s.x, sy = f.s.y, sz = f.s.z, tx = f.t.x, ty = f.t.y, tz = f.t.z;
  const float nx = f.n.x, ny = f.n.y, nz = f.n.z;
  const float cx = pr.cx, cy = pr.cy, scaleX = pr.sx, scaleY = pr.sy;
  const float x0 = pr.window.x0, y0 = pr.window.y0, x1 = pr.window.x1, y1 = pr.window.y1;
  const float wMax = x1 - 1.0f, hMax = y1 - 1.0f;
  const uint32_t width = pr.width;
  for (int k = 0; k < count; ++k) {
    float x = sx * ox[k] + tx * oy[k] + nx * oz[k];
    float y = sy * ox[k] + ty * oy[k] + ny * oz[k];
    float z = sz * ox[k] + tz * oy[k] + nz * oz[k];
    // o - 2 min(c.o, 0) c: the reflection when below, nothing otherwise
    // (2 min(a, 0) = a - |a|: arithmetic, where a select kept GCC from
    // vectorizing the loop).
    const float cd = c.x * x + c.y * y + c.z * z;
    const float r = cd - std::fabs(cd);
    x -= r * c.x, y -= r * c.y, z -= r * c.z;
    const float d = -(P.z + z);
    const float inv = 1.0f / d;
    const float fx = cx + (P.x + x) * inv * scaleX, fy = cy - (P.y + y) * inv * scaleY;
    const bool inside = (d > 0.0f) & (fx >= x0) & (fy >= y0) & (fx < x1) & (fy < y1);
    // Clamped before the conversion so that no lane converts an
    // out-of-range float (undefined; NaN compares false and clamps to the
    // window's x0, y0); the clamp changes no valid pixel.
    const float cxl = std::min(std::max(x0, fx), wMax);  // max(x0, NaN) = x0
    const float cyl = std::min(std::max(y0, fy), hMax);
    pixel[k] = uint32_t(int32_t(cyl)) * width + uint32_t(int32_t(cxl));
    depth[k] = inside ? d : -1.0f;
  }
}

DepthSource depthSourceFromParams(const ParamSet& p) {
  return p.getEnum("depth") == "traced" ? DepthSource::Traced : DepthSource::GBuffer;
}

}  // namespace obscura::screen_space
