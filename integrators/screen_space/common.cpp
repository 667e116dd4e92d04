#include "integrators/screen_space/common.h"

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
  };
}

// Compiled twice (AVX2, baseline): 8 points per instruction where the CPU
// has AVX2, without requiring it of the build.
__attribute__((target_clones("avx2", "default"))) void projectOffsets(const PointProjection& pr, Vec3 P,
                                                                      const Frame& f, Vec3 c, const float* ox,
                                                                      const float* oy, const float* oz, int count,
                                                                      float* depth, uint32_t* pixel) {
  for (int k = 0; k < count; ++k) {
    float x = f.s.x * ox[k] + f.t.x * oy[k] + f.n.x * oz[k];
    float y = f.s.y * ox[k] + f.t.y * oy[k] + f.n.y * oz[k];
    float z = f.s.z * ox[k] + f.t.z * oy[k] + f.n.z * oz[k];
    // o - 2 min(c.o, 0) c: the reflection when below, nothing otherwise.
    const float cd = c.x * x + c.y * y + c.z * z;
    const float r = 2.0f * (cd < 0.0f ? cd : 0.0f);
    x -= r * c.x, y -= r * c.y, z -= r * c.z;
    const float qx = P.x + x, qy = P.y + y, d = -(P.z + z);
    const float inv = 1.0f / d;
    const float fx = pr.cx + qx * inv * pr.sx, fy = pr.cy - qy * inv * pr.sy;
    const bool inside = d > 0.0f && fx >= 0.0f && fy >= 0.0f && fx < pr.w && fy < pr.h;
    // Clamped before the conversion so that no lane converts an
    // out-of-range float (undefined); the clamp changes no valid pixel.
    const float cxl = fx > 0.0f ? (fx < pr.w - 1.0f ? fx : pr.w - 1.0f) : 0.0f;
    const float cyl = fy > 0.0f ? (fy < pr.h - 1.0f ? fy : pr.h - 1.0f) : 0.0f;
    pixel[k] = uint32_t(cyl) * pr.width + uint32_t(cxl);
    depth[k] = inside ? d : -1.0f;
  }
}

DepthSource depthSourceFromParams(const ParamSet& p) {
  return p.getEnum("depth") == "traced" ? DepthSource::Traced : DepthSource::GBuffer;
}

}  // namespace obscura::screen_space
