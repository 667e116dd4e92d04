// Multi-bounce AO: ambient occlusion followed by a mapping that predicts the
// light of further bounces from the AO value and the pixel's albedo
// (docs/math.md §6; integrators/multibounce_mapping.h), per RGB channel.
//
// Each mapping gets the AO flavour it was fitted to:
// - gtao: the cosine-weighted visibility v = (1/pi) Int V cos+ dw, estimated
//   with directions ~ cos(theta)/pi (the `ao` integrator's sequence);
// - improved: the uniform solid-angle visibility alpha = Int V dw / 2 pi,
//   estimated with directions uniform over the hemisphere (pushUniformRays);
// - fitted: the same function with the coefficients of a file `fit=FILE`
//   that `obscura fit` wrote (integrators/iao_fit.h, docs/math.md §6
//   "Fitting F0 and F1"), read once when the integrator is created; with the
//   published coefficients it is `improved` bit for bit (one evaluation,
//   fittedMultiBounce, serves both).
// The mappings are nonlinear, so they are applied once per pixel to the
// converged AO value and the pixel's mean albedo (Integrator::resolvePixel),
// not per camera sample: mapping a noisy one-ray estimate would be biased.
// Directions below the geometric plane are blocked by the surface itself.
// inside, spread and near shape the AO's lobe (include/obscura/lobe.h, docs/math.md
// §11): gtao's cosine lobe within the cone, improved's uniform one within it
// (the fraction of the cone's solid angle that is open). The mappings were
// fitted to full-hemisphere AO; fed a narrowed lobe they are extrapolated.
#include <limits>

#include <obscura/plugin.h>
#include "integrators/uniform_rays.h"
#include "integrators/falloff.h"
#include <obscura/error.h>
#include "integrators/iao_fit.h"
#include "integrators/multibounce_mapping.h"

namespace obscura {
namespace {

enum class Mapping { Gtao, Improved, Fitted };

class MultiBounce final : public Integrator {
 public:
  MultiBounce(Mapping mapping, ImprovedFit fit, float R, uint32_t rays, LobeControls lobe)
      : mapping_(mapping), fit_(fit), R_(R), rays_(rays), lobe_(lobe) {}

  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const override {
    OcclusionBatch& batch = ctx.occlusionBatch(hits.size() * rays_);
    if (mapping_ == Mapping::Gtao)
      pushCosineRays(hits, rays_, R_, lobe_, batch);
    else
      pushUniformRays(hits, rays_, R_, lobe_, batch);
    ctx.trace(batch);
    writeMeanVisibility(hits, batch, rays_, lobe_, out);
  }

  Vec3 resolvePixel(Vec3 W, Vec3 albedo) const override {
    const auto map = [&](float v, float rho) {
      return float(mapping_ == Mapping::Gtao ? gtaoMultiBounce(v, rho) : fittedMultiBounce(v, rho, fit_));
    };
    return Vec3(map(W.x, albedo.x), map(W.y, albedo.y), map(W.z, albedo.z));
  }

 private:
  Mapping mapping_;
  ImprovedFit fit_;  // improved: the published coefficients
  float R_;
  uint32_t rays_;
  LobeControls lobe_;
};

IntegratorDescriptor multibounceDescriptor() {
  IntegratorDescriptor d;
  d.name = "multibounce";
  d.doc = "Multi-bounce AO: AO mapped per pixel with its albedo to predict further bounces (GTAO, or the improved-AO "
          "fit: published or made by 'obscura fit').";
  d.params = {
      {.name = "mapping", .type = ParamType::Enum, .defaultValue = "gtao", .choices = {"gtao", "improved", "fitted"},
       .doc = "gtao: Jimenez et al. 2016 on cosine-weighted AO; improved: improved-AO fit on uniform AO; fitted: the "
              "improved-AO form with the coefficients of fit=FILE"},
      {.name = "fit", .type = ParamType::String, .defaultValue = "",
       .doc = "mapping=fitted: the coefficients file 'obscura fit' writes (JSON: F0.scale, F0.exponent, F1.A, F1.B)"},
      {.name = "distance", .type = ParamType::Float, .defaultValue = "inf", .min = 0.0, .max = 1e308,
       .allowInfinity = true, .doc = "R of the AO: occluders farther than this do not count; inf = any hit occludes"},
      {.name = "rays", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 65536,
       .doc = "AO rays per camera sample"},
  };
  addLobeParams(d.params);
  d.bentNormal = true;  // SampleEstimate::bent: the open directions (e0=bent)
  d.needs = [](const ParamSet&) { return IntegratorNeeds{.albedo = true, .pixelAlbedo = true}; };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    const std::string& name = p.getEnum("mapping");
    const Mapping m = name == "gtao" ? Mapping::Gtao : name == "improved" ? Mapping::Improved : Mapping::Fitted;
    const std::string& file = p.getString("fit");
    if (m == Mapping::Fitted && file.empty())
      throw Error("integrator 'multibounce': parameter 'fit' (a coefficients file from 'obscura fit') is required with "
                  "mapping=fitted");
    if (m != Mapping::Fitted && !file.empty())
      throw Error("integrator 'multibounce': parameter 'fit' is read only with mapping=fitted, not mapping=" + name);
    ImprovedFit fit;  // the published coefficients
    if (m == Mapping::Fitted) {
      try {
        fit = readImprovedFit(file);
      } catch (const Error& e) {
        throw Error(std::string("integrator 'multibounce': parameter 'fit': ") + e.what());
      }
    }
    return std::make_unique<MultiBounce>(m, fit, toRayDistance(p.getFloat("distance")), uint32_t(p.getInt("rays")),
                                         lobeFromParams(p, p.getFloat("distance")));
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(multibounceDescriptor)
}  // namespace obscura
