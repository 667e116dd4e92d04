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

DepthSource depthSourceFromParams(const ParamSet& p) {
  return p.getEnum("depth") == "traced" ? DepthSource::Traced : DepthSource::GBuffer;
}

}  // namespace obscura::screen_space
