// Directional occlusion: the environment-weighted visibility
// (docs/math.md §14.6),
//
//   D(x) = Int L(w) V(x, w) cos+(theta) dw / Int L(w) cos+(theta) dw
//        = (1/pi) Int L V cos+ dw / (E0(n) / pi),
//
// so that albedo/pi x E0(n) x D is exactly the direct light of the
// environment at x: shaded.* of this pass is the first bounce of `gi`
// (max-depth=0) with the visibility V of an unbounded any-hit ray. Under a
// uniform sky L cancels and D is ambient occlusion at R = inf; under a sun
// it is the sun's shadow blended with the sky's occlusion - the quantity AO
// is a stand-in for, and so the measure of how far AO is from the light.
//
// Estimator: a ratio per camera sample (include/obscura/integrator.h),
// num = the MIS estimate of (1/pi) Int L V cos+ dw, den = E0(n)/pi from the
// environment's table at the same normal the core shades with, so the
// pixel's shaded.* = albedo x (Sum num / Sum den) x (Sum den / hits) is the
// plain mean of the direct-light estimates whatever the table's error.
// num combines (power heuristic, Veach 1997 eq. 9.13) a cosine direction
// w_b, contributing L(w_b) p_b^2 / (p_b^2 + p_l^2) when open, and a
// direction w_l from the map's density p_l, contributing
// L(w_l) (cos theta_l / pi) / p_l x p_l^2 / (p_b^2 + p_l^2) when open,
// p_b = cos theta / pi. Under a constant sky there are no light directions
// and the estimate is exactly `ao`'s at R = inf (the same rays, the same
// arithmetic: writeMeanVisibility).
//
// Sample dimensions: the cosine directions are ao's (kFirstIntegratorDim),
// the light directions kFirstIntegratorDim + 3, as gi's first bounce
// (integrators/ambient_paths.h).
#include <cmath>
#include <vector>

#include <obscura/plugin.h>
#include <obscura/warp.h>

namespace obscura {
namespace {

class DirectionalOcclusion final : public Integrator {
 public:
  DirectionalOcclusion(uint32_t rays, bool lightSamples) : rays_(rays), lightSamples_(lightSamples) {}

  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const override {
    const EnvironmentView& env = ctx.environment();
    const size_t n = hits.size() * rays_;
    const bool mis = !env.constant && lightSamples_ && env.samplable;
    OcclusionBatch& batch = ctx.occlusionBatch(mis ? 2 * n : n);
    const LobeControls hemisphere;
    pushCosineRays(hits, rays_, kInfinity, hemisphere, batch);
    if (env.constant) {
      ctx.trace(batch);
      writeMeanVisibility(hits, batch, rays_, hemisphere, out);
      return;
    }
    // The light directions after the cosine ones: ray n + i * rays + k.
    std::vector<float>& factor = factor_;
    std::vector<Vec3>& radiance = radiance_;
    factor.assign(mis ? n : 0, 0.0f);
    radiance.assign(mis ? n : 0, Vec3(0, 0, 0));
    if (mis)
      for (size_t i = 0; i < hits.size(); ++i)
        for (uint32_t k = 0; k < rays_; ++k) {
          const SurfaceHit& h = hits[i];
          const size_t r = i * rays_ + k;
          float pl = 0.0f;
          Vec3 L;
          const Vec3 w = env.sample(Sampler::get2D(h.pixelKey, h.sampleIndex * rays_ + k, kFirstIntegratorDim + 3), pl, L);
          const float cosTheta = dot(w, h.ns);
          if (!(pl > 0.0f) || !(cosTheta > 0.0f) || intoSurface(h, w)) {
            batch.push(spawnOrigin(h, w), w, kInfinity, 0.0f, h);
            continue;
          }
          const double pb = double(cosTheta) * double(kInvPi), pld = pl;
          factor[r] = float(pb / pld * powerHeuristic(pld, pb));
          radiance[r] = L;
          batch.push(spawnOrigin(h, w), w, 0.0f, kInfinity, h);
        }
    ctx.trace(batch);
    for (size_t i = 0; i < hits.size(); ++i) {
      const SurfaceHit& h = hits[i];
      double num[3] = {0, 0, 0};
      Vec3 bent(0, 0, 0);
      for (uint32_t k = 0; k < rays_; ++k) {
        const size_t r = i * rays_ + k;
        if (hemisphere.open(h, batch, r)) {
          const Vec3 w = batch.dir(r);
          float pl = 0.0f;
          const Vec3 L = env.radianceAndPdf(w, pl);
          const double wb = mis ? powerHeuristic(double(dot(w, h.ns)) * double(kInvPi), pl) : 1.0;
          num[0] += wb * L.x, num[1] += wb * L.y, num[2] += wb * L.z;
          bent += w;
        }
        if (mis && factor[r] > 0.0f && !batch.occluded(n + r)) {
          const Vec3& L = radiance[r];
          num[0] += double(factor[r]) * L.x, num[1] += double(factor[r]) * L.y, num[2] += double(factor[r]) * L.z;
        }
      }
      out[i].num = Vec3(sampleMean(num[0], rays_), sampleMean(num[1], rays_), sampleMean(num[2], rays_));
      out[i].den = env.irradianceOverPi(h.ns);
      out[i].bent = bent;
    }
  }

 private:
  uint32_t rays_;
  bool lightSamples_;
  // Per thread (threads share the integrator), keeping their memory
  // between batches: the loop allocates nothing once warm.
  static thread_local std::vector<float> factor_;
  static thread_local std::vector<Vec3> radiance_;
};

thread_local std::vector<float> DirectionalOcclusion::factor_;
thread_local std::vector<Vec3> DirectionalOcclusion::radiance_;

IntegratorDescriptor diroccDescriptor() {
  IntegratorDescriptor d;
  d.name = "dirocc";
  d.doc = "Directional occlusion: environment-weighted visibility, Int L V cos / Int L cos (the direct light over E0).";
  d.params = {
      {.name = "rays", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 65536,
       .doc = "cosine directions (and as many light directions) per camera sample"},
      {.name = "sampling", .type = ParamType::Enum, .defaultValue = "mis", .choices = {"mis", "cosine"},
       .doc = "under an environment map: cosine and light directions combined by MIS, or cosine directions alone"},
  };
  d.bentNormal = true;
  d.needs = [](const ParamSet&) { return IntegratorNeeds{}; };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    return std::make_unique<DirectionalOcclusion>(uint32_t(p.getInt("rays")), p.getEnum("sampling") == "mis");
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(diroccDescriptor)
}  // namespace obscura
