// bent-normal: the mean unoccluded direction, a standard film AOV (for
// relighting with environment maps and for directional ambient).
//
//   B(x) = (1/pi) Int_Omega V_R(x, w) w cos+(theta) dw
//
// With w drawn from cos(theta)/pi about the shading normal, the estimator is
// the plain mean of V_R(x, w_i) w_i (linear, so pixel filtering and sample
// accumulation are exact). R,G,B of the pass hold B's world-space x, y, z.
// It is NOT normalized: its length is the cosine-weighted "openness"
// (2/3 on an unoccluded plane, where E[cos theta] = 2/3); the unit bent
// normal a shader wants is normalize(RGB). Components lie in [-1, 1].
// inside, spread and near shape the lobe (include/obscura/lobe.h, docs/math.md §11):
// inside=true gives the mean open direction behind the surface; with spread
// s = sin(thetaMax) < 1 an open plane's length is
// E[cos theta] = 2 (1 - (1 - s^2)^(3/2)) / (3 s^2) (-> 1 as s -> 0).
#include <cmath>
#include <limits>

#include <obscura/plugin.h>
#include <obscura/warp.h>

namespace {

using namespace obscura;

class BentNormal final : public Integrator {
 public:
  BentNormal(float distance, uint32_t rays, LobeControls lobe) : distance_(distance), rays_(rays), lobe_(lobe) {}

  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const override {
    OcclusionBatch& batch = ctx.occlusionBatch(hits.size() * rays_);
    pushCosineRays(hits, rays_, distance_, lobe_, batch);
    ctx.trace(batch);
    const float inv = 1.0f / float(rays_);
    size_t r = 0;
    for (size_t i = 0; i < hits.size(); ++i) {
      Vec3 sum(0, 0, 0);
      for (uint32_t k = 0; k < rays_; ++k, ++r)
        if (lobe_.open(hits[i], batch, r)) sum += batch.dir(r);
      out[i].num = sum * inv;
      out[i].bent = sum;  // e0=bent: E0 at the pass's own direction
    }
  }

 private:
  float distance_;
  uint32_t rays_;
  LobeControls lobe_;
};

IntegratorDescriptor bentNormalDescriptor() {
  IntegratorDescriptor d;
  d.name = "bent-normal";
  d.doc = "Bent normal: mean unoccluded cosine-weighted direction (world xyz in RGB, unnormalized).";
  ParamSpec distance;
  distance.name = "distance";
  distance.type = ParamType::Float;
  distance.defaultValue = "inf";
  distance.min = 0.0;
  distance.allowInfinity = true;
  distance.doc = "R: occluders farther than this (scene units) do not count; inf = any hit occludes";
  ParamSpec rays;
  rays.name = "rays";
  rays.type = ParamType::Int;
  rays.defaultValue = "1";
  rays.min = 1;
  rays.max = 65536;
  rays.doc = "rays per camera sample";
  d.params = {distance, rays};
  addLobeParams(d.params);
  d.needs = [](const ParamSet&) { return IntegratorNeeds{}; };
  d.bentNormal = true;
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    const double R = p.getFloat("distance");
    const float r = toRayDistance(R);
    return std::make_unique<BentNormal>(r, uint32_t(p.getInt("rays")), lobeFromParams(p, R));
  };
  return d;
}

}  // namespace

OBSCURA_REGISTER_INTEGRATOR(bentNormalDescriptor)
OBSCURA_PLUGIN_ENTRY("bent-normal")
