// Full global illumination under the uniform sky or an environment map: the
// reference every other integrator approximates (docs/math.md §1, §2, §5
// and §14.3).
//
//   W(x) = (1/pi) Int L_in(x, w) / La cos+(theta) dw,
//   L_in = e^(-sigma d) a(y) La W(y) + La (1 - e^(-sigma d))  (hit at d)
//   L_in = La                                                   (escape)
//
// A diffuse path tracer with cosine-distributed directions and Russian
// roulette. It is the path estimator of the recursive transfer
// (integrators/ambient_paths.h) with the membership that makes the
// recursion exact: in vacuum (sigma = 0) the step membership at R = inf
// (mu = 0 for every hit, 1 for escape); in the ambient medium of section 2
// (sigma > 0) the exponential mu = 1 - e^(-sigma d), whose 1 - mu is the
// medium's transmittance and whose mu is its in-scattered sky light.
// Nothing is closed: paths end by escaping, at max-depth bounces, or by
// roulette (unbiased), so the estimate is a plain mean with error ~ 1/sqrt(spp).
// Under an environment map, L_in of an escape is L(w) and W is normalised by
// the map's mean radiance Lbar; light directions drawn from the map join
// the cosine ones by MIS (integrators/ambient_paths.h).
#include <cmath>

#include <obscura/plugin.h>
#include "integrators/ambient_paths.h"

namespace obscura {
namespace {

IntegratorDescriptor giDescriptor() {
  IntegratorDescriptor d;
  d.name = "gi";
  d.doc = "Full global illumination: diffuse path tracing under the sky or environment map, optionally in an ambient medium (the reference).";
  // W is the irradiance over pi relative to the environment's mean
  // radiance: shaded.* = albedo x W x Lbar is the reflected radiance.
  d.shading = Shading::MeanRadiance;
  d.params = {
      {.name = "sigma", .type = ParamType::Float, .defaultValue = "0", .min = 0.0, .max = 1e30,
       .doc = "extinction of the ambient medium (1/scene units); 0 = vacuum"},
      {.name = "max-depth", .type = ParamType::Int, .defaultValue = "-1", .min = -1, .max = 1 << 30,
       .doc = "bounces after the first segment; -1 = unlimited (roulette ends paths), 0 = AO"},
      {.name = "rays", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 65536,
       .doc = "paths per camera sample"},
      {.name = "sampling", .type = ParamType::Enum, .defaultValue = "mis", .choices = {"mis", "cosine"},
       .doc = "under an environment map: cosine and light directions combined by MIS, or cosine directions "
              "alone (a constant sky needs no light directions: both are cosine alone)"},
  };
  d.needs = [](const ParamSet&) { return IntegratorNeeds{.albedo = true}; };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    const double sigma = p.getFloat("sigma");
    const Membership mu = sigma > 0.0 ? Membership(Falloff::Exponential, INFINITY, sigma)
                                      : Membership(Falloff::Step, INFINITY, 1.0);
    AmbientPaths paths{.mu = mu};
    paths.estimator = Estimator::Distance;
    paths.rays = uint32_t(p.getInt("rays"));
    const int maxDepth = p.getInt("max-depth");
    paths.depth = maxDepth < 0 ? AmbientPaths::kUnlimited : uint32_t(maxDepth);
    paths.closedTail = false;
    paths.roulette = true;
    paths.environment = true;
    paths.lightSamples = p.getEnum("sampling") == "mis";
    return std::make_unique<AmbientPathIntegrator>(paths);
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(giDescriptor)
}  // namespace obscura
