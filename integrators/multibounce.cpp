// Multi-bounce AO: ambient occlusion followed by a mapping that predicts the
// light of further bounces from the AO value and the pixel's albedo
// (docs/math.md §6; integrators/multibounce_mapping.h), per RGB channel.
//
// Each mapping gets the AO flavour it was fitted to:
// - gtao: the cosine-weighted visibility v = (1/pi) Int V cos+ dw, estimated
//   with directions ~ cos(theta)/pi (the `ao` integrator's sequence);
// - improved: the uniform solid-angle visibility alpha = Int V dw / 2 pi,
//   estimated with directions uniform over the hemisphere.
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
#include "integrators/falloff.h"
#include "integrators/multibounce_mapping.h"

namespace obscura {
namespace {

enum class Mapping { Gtao, Improved };

class MultiBounce final : public Integrator {
 public:
  MultiBounce(Mapping mapping, float R, uint32_t rays, LobeControls lobe)
      : mapping_(mapping), R_(R), rays_(rays), lobe_(lobe) {}

  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const override {
    OcclusionBatch& batch = ctx.occlusionBatch(hits.size() * rays_);
    if (mapping_ == Mapping::Gtao) {
      pushCosineRays(hits, rays_, R_, lobe_, batch);
    } else {
      for (const SurfaceHit& h : hits) {
        const Frame frame = lobe_.at(h).frame;
        for (uint32_t k = 0; k < rays_; ++k) {
          const Sample2 s = Sampler::get2D(h.pixelKey, h.sampleIndex * rays_ + k, kFirstIntegratorDim);
          const Vec3 w = frame.toWorld(squareToUniformCone(s.u, s.v, lobe_.cosThetaMax));
          batch.push(spawnOrigin(h, w), w, lobe_.tnear, R_, h);
        }
      }
    }
    ctx.trace(batch);
    writeMeanVisibility(hits, batch, rays_, lobe_, out);
  }

  Vec3 resolvePixel(Vec3 W, Vec3 albedo) const override {
    const auto map = [&](float v, float rho) {
      return float(mapping_ == Mapping::Gtao ? gtaoMultiBounce(v, rho) : improvedMultiBounce(v, rho));
    };
    return Vec3(map(W.x, albedo.x), map(W.y, albedo.y), map(W.z, albedo.z));
  }

 private:
  Mapping mapping_;
  float R_;
  uint32_t rays_;
  LobeControls lobe_;
};

IntegratorDescriptor multibounceDescriptor() {
  IntegratorDescriptor d;
  d.name = "multibounce";
  d.doc = "Multi-bounce AO: AO mapped per pixel with its albedo to predict further bounces (GTAO or improved-AO fit).";
  d.params = {
      {.name = "mapping", .type = ParamType::Enum, .defaultValue = "gtao", .choices = {"gtao", "improved"},
       .doc = "gtao: Jimenez et al. 2016 on cosine-weighted AO; improved: improved-AO fit on uniform AO"},
      {.name = "distance", .type = ParamType::Float, .defaultValue = "inf", .min = 0.0, .max = 1e308,
       .allowInfinity = true, .doc = "R of the AO: occluders farther than this do not count; inf = any hit occludes"},
      {.name = "rays", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 65536,
       .doc = "AO rays per camera sample"},
  };
  addLobeParams(d.params);
  d.bentNormal = true;  // SampleEstimate::bent: the open directions (e0=bent)
  d.needs = [](const ParamSet&) { return IntegratorNeeds{.albedo = true, .pixelAlbedo = true}; };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    const Mapping m = p.getEnum("mapping") == "gtao" ? Mapping::Gtao : Mapping::Improved;
    return std::make_unique<MultiBounce>(m, toRayDistance(p.getFloat("distance")), uint32_t(p.getInt("rays")),
                                         lobeFromParams(p, p.getFloat("distance")));
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(multibounceDescriptor)
}  // namespace obscura
