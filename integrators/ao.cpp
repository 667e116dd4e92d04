// Classical ambient occlusion (docs/math.md §1 and §3, step membership).
//
//   AO(x) = (1/pi) Int_Omega V_R(x, w) cos+(theta) dw
//
// with V_R = 1 when nothing is hit within distance R. Directions are drawn
// with density cos(theta)/pi about the shading normal, so the estimator is
// the plain mean of the visibility: AO ~ (1/n) Sum_i V_R(x, w_i). Only
// any-hit rays are traced: AO never needs the occluder itself.
//
// inside, spread and near shape the lobe (include/obscura/lobe.h, docs/math.md §11):
// AO(x) = (1/(pi sin^2 thetaMax)) Int_cone V_R,near cos dw about +-n.
//
// weighting=uniform: the uniform (solid-angle) AO of the improved-AO paper
// [IAO 4], the AO the `improved` and `fitted` multi-bounce mappings are fed
// (docs/math.md §6):
//   alpha(x) = (1/(2 pi)) Int_Omega V_R(x, w) dw,
// directions uniform in solid angle (density 1/(2 pi)), so again the plain
// mean of the visibility. Within the lobe's cone it is the fraction of the
// cone's solid angle 2 pi (1 - cos thetaMax) that is open. alpha and AO
// agree wherever V is symmetric enough (1 on an open plane, 1/2 beside an
// infinite wall); they differ where the occluders sit at a preferred
// elevation: beside a wall seen only within R, AO weighs the low directions
// that reach the wall less than alpha does (docs/math.md §7 gives both).
//
// Surfaces are opaque: a direction below the geometric surface (possible
// when the shading normal tilts away from the geometric one) is blocked by
// the surface itself, whatever the ray finds (LobeControls::open, include/obscura/lobe.h).
#include <cmath>
#include <limits>

#include <obscura/plugin.h>
#include "integrators/uniform_rays.h"
#include <obscura/warp.h>

namespace obscura {
namespace {

class AmbientOcclusion final : public Integrator {
 public:
  AmbientOcclusion(float distance, int rays, bool uniform, LobeControls lobe)
      : distance_(distance), rays_(uint32_t(rays)), uniform_(uniform), lobe_(lobe) {}

  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const override {
    OcclusionBatch& batch = ctx.occlusionBatch(hits.size() * rays_);
    if (uniform_)
      pushUniformRays(hits, rays_, distance_, lobe_, batch);
    else
      pushCosineRays(hits, rays_, distance_, lobe_, batch);
    ctx.trace(batch);
    writeMeanVisibility(hits, batch, rays_, lobe_, out);
  }

 private:
  float distance_;
  uint32_t rays_;
  bool uniform_;  // weighting=uniform
  LobeControls lobe_;
};

IntegratorDescriptor aoDescriptor() {
  IntegratorDescriptor d;
  d.name = "ao";
  d.doc = "Classical ambient occlusion: fraction of cosine-weighted (or uniform) rays unoccluded within distance R.";
  d.params = {
      {.name = "distance", .type = ParamType::Float, .defaultValue = "inf", .min = 0.0, .max = 1e308,
       .allowInfinity = true, .doc = "R: occluders farther than this (scene units) do not count; inf = any hit occludes"},
      {.name = "rays", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 65536,
       .doc = "AO rays per camera sample"},
      {.name = "weighting", .type = ParamType::Enum, .defaultValue = "cosine", .choices = {"cosine", "uniform"},
       .doc = "cosine: (1/pi) Int V cos dw; uniform: the solid-angle fraction Int V dw / 2 pi (improved AO's alpha)"},
  };
  addLobeParams(d.params);
  d.bentNormal = true;  // SampleEstimate::bent: the open directions (e0=bent)
  d.needs = [](const ParamSet&) { return IntegratorNeeds{}; };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    const double R = p.getFloat("distance");
    const float r = toRayDistance(R);
    return std::make_unique<AmbientOcclusion>(r, p.getInt("rays"), p.getEnum("weighting") == "uniform",
                                              lobeFromParams(p, R));
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(aoDescriptor)
}  // namespace obscura
