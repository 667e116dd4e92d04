// The ambient transfer function (docs/math.md §4 and §5): obscurance that
// gives back the light bounced by nearby occluders, read with their albedo.
//
// depth = 0, the closed form [AT 6, 9]:
//
//   W(x) ~ Int mu cos+ dw / (pi - Int (1 - mu(d)) a(y(w)) cos+ dw)
//        ~ Sum_i mu_i / Sum_i (mu_i + (1 - mu_i)(1 - a_i))       per RGB channel
//
// numerator and denominator from the same cosine-distributed samples, summed
// over all of a pixel's camera samples and divided once (ratio estimator,
// include/obscura/integrator.h). With the occlusion estimator mu_i is the 0/1 segment
// test [AT 9] and a_i the albedo of the closest occluder on the segment.
// depth = N >= 1: the recursive transfer, N bounces of the path estimator
// closed by the closed form (tail=closed) or by 0 (tail=zero).
// Both live in integrators/ambient_paths.h, shared with `gi`. inside,
// spread and near shape the first bounce's lobe in both (include/obscura/lobe.h,
// docs/math.md §11); later bounces are light transport, not the pass's lobe.
//
// Properties (tested): W <= 1 for albedo <= 1; W == 1 exactly when every
// albedo is 1 (white furnace); W == obscurance bit for bit when every
// albedo is 0, same parameters and seed. The ratio is biased by O(1/n) for
// n = spp x rays samples per pixel (docs/math.md §4 gives figures), so
// spp x rays of a few hundred or more is advisable.
//
// 0/0 (no open sample and every occluder white, so num = den = 0): the pixel
// resolves to 1, the white-furnace limit of f / (1 - a(1 - f)) as a -> 1.
#include <obscura/plugin.h>
#include "integrators/ambient_paths.h"

namespace obscura {
namespace {

IntegratorDescriptor transferDescriptor() {
  IntegratorDescriptor d;
  d.name = "transfer";
  d.doc = "Ambient transfer: obscurance plus the light nearby occluders reflect (closed form, or recursive with depth=N).";
  d.params = membershipParams("transfer paths per camera sample");
  d.params.push_back({.name = "depth", .type = ParamType::Int, .defaultValue = "0", .min = 0, .max = 1000,
                      .doc = "bounces traced before the tail; 0 = the closed form"});
  d.params.push_back({.name = "tail", .type = ParamType::Enum, .defaultValue = "closed", .choices = {"closed", "zero"},
                      .doc = "after depth bounces: closed = the closed form (local approximation), zero = truncate"});
  addLobeParams(d.params);
  d.bentNormal = true;  // SampleEstimate::bent: the open directions (e0=bent)
  d.needs = [](const ParamSet&) { return IntegratorNeeds{.albedo = true}; };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    AmbientPaths paths{.mu = Membership::fromParams(p)};
    paths.estimator = estimatorFromParams(p);
    paths.rays = uint32_t(p.getInt("rays"));
    paths.depth = uint32_t(p.getInt("depth"));
    paths.closedTail = p.getEnum("tail") == "closed";
    paths.roulette = false;
    paths.lobe = lobeFromParams(p, p.getFloat("distance"));
    return std::make_unique<AmbientPathIntegrator>(paths);
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(transferDescriptor)
}  // namespace obscura
