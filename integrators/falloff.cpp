#include "integrators/falloff.h"

namespace obscura {

Membership Membership::fromParams(const ParamSet& p) {
  const std::string& f = p.getEnum("falloff");
  const Falloff falloff = f == "step"     ? Falloff::Step
                          : f == "linear" ? Falloff::Linear
                          : f == "sqrt"   ? Falloff::Sqrt
                                          : Falloff::Exponential;
  return Membership(falloff, p.getFloat("distance"), p.getFloat("sigma"));
}

Estimator estimatorFromParams(const ParamSet& p) {
  return p.getEnum("estimator") == "distance" ? Estimator::Distance : Estimator::Occlusion;
}

std::vector<ParamSpec> membershipParams(const std::string& raysDoc) {
  return {
      {.name = "falloff", .type = ParamType::Enum, .defaultValue = "step",
       .choices = {"step", "linear", "sqrt", "exponential"},
       .doc = "mu(d): step [d>R] (AO), linear min(d/R,1), sqrt min(sqrt(d/R),1), exponential 1-exp(-sigma d)"},
      {.name = "distance", .type = ParamType::Float, .defaultValue = "inf", .min = 0.0, .max = 1e308,
       .allowInfinity = true,
       .doc = "R (scene units): step/linear/sqrt radius (inf: any hit occludes, all three = step); "
              "exponential cut-off (mu = 1 beyond R; inf: none); 0: only the surface itself occludes"},
      {.name = "sigma", .type = ParamType::Float, .defaultValue = "1", .min = 1e-30, .max = 1e30,
       .doc = "exponential only: extinction sigma of the ambient medium (1/scene units)"},
      {.name = "estimator", .type = ParamType::Enum, .defaultValue = "distance", .choices = {"distance", "occlusion"},
       .doc = "distance: closest hit, weight mu(d); occlusion: ray to r ~ mu'(r), weight [segment open]"},
      {.name = "rays", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 65536, .doc = raysDoc},
  };
}

}  // namespace obscura
