// Reflection occlusion (docs/math.md §12): the fraction of a glossy lobe
// about the mirror direction of the view ray that is unoccluded within R -
// what a compositor multiplies environment reflections by (V-Ray Dirt's
// reflection mode, RenderMan's reflection occlusion).
//
//   W(x) = Int_A V_R(x, w) D(w) dw / Int_A D(w) dw,   A = {w : w . ng > 0}
//
// D is the normalised Phong lobe (m + 1)/(2 pi) cos^m(angle to r) over the
// hemisphere about the mirror direction r = d - 2 (d . ns) ns of the view
// direction d, m = (1 - a^2) / (2 a^2) with a = roughness^2 (glTF's alpha):
// roughness 0 is the mirror direction alone, 1 the uniform hemisphere about
// r. Directions are drawn from D itself, so every sample weighs D/p = 1 and
// both integrals are counts: num = open directions, den = directions above
// the geometric surface; a pixel's W = Sum num / Sum den (the ratio
// estimator of include/obscura/integrator.h). An open surface is exactly 1 at every
// roughness and view angle. A pixel none of whose directions is above its
// surface (0/0: a mirror direction below it at roughness 0, from a shading
// normal tilted against the view) resolves to 1, the core's convention -
// the value an open surface has as the view turns grazing.
//
// Of the lobe controls only `near` applies (the rays' tnear); `inside` and
// `spread` shape a lobe about the normal, which this is not.
#include <cmath>
#include <limits>

#include <obscura/error.h>
#include <obscura/plugin.h>
#include <obscura/warp.h>

namespace obscura {
namespace {

// e = 1/(m + 1) of the lobe for a roughness in [0, 1] (docs/math.md §12):
// with a = roughness^2 and m = (1 - a^2)/(2 a^2), e = 2 a^2 / (1 + a^2) -
// 0 at roughness 0 (the mirror limit, m = inf, never formed), 1 at
// roughness 1 (m = 0). Evaluated in double so that roughness^4 does not
// underflow before the float result would.
float lobeExponent(float roughness) {
  const double r2 = double(roughness) * double(roughness), a2 = r2 * r2;
  return float(2.0 * a2 / (1.0 + a2));
}

// The mirror image of the view direction d about the shading normal n.
inline Vec3 mirror(Vec3 d, Vec3 n) { return d - n * (2.0f * dot(d, n)); }

class ReflectionOcclusion final : public Integrator {
 public:
  // roughness < 0: each hit's material roughness.
  ReflectionOcclusion(float distance, int rays, float roughness, float tnear)
      : distance_(distance), rays_(uint32_t(rays)), material_(roughness < 0.0f),
        exponent_(roughness < 0.0f ? 0.0f : lobeExponent(roughness)), tnear_(tnear) {}

  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const override {
    OcclusionBatch& batch = ctx.occlusionBatch(hits.size() * rays_);
    // Only directions above the surface are traced (the others are blocked
    // by it, core/scene/surface.h). Until the batch is traced, out[i].den holds
    // how many of hit i's directions are above it and out[i].num how many
    // rays represent them, so the second pass knows which rays are its.
    for (size_t i = 0; i < hits.size(); ++i) {
      const SurfaceHit& h = hits[i];
      const float e = material_ ? lobeExponent(ctx.roughnessAt(h)) : exponent_;
      const Vec3 r = mirror(h.dir, h.ns);
      uint32_t above = 0, traced = 0;
      if (e == 0.0f) {
        // The mirror limit exactly: every direction is r (no lobe to
        // sample, no rounding through a frame), one ray stands for all.
        if (!intoSurface(h, r)) {
          batch.push(spawnOrigin(h, r), r, tnear_, distance_, h);
          above = rays_, traced = 1;
        }
      } else {
        const Frame frame = Frame::fromNormal(r);
        for (uint32_t k = 0; k < rays_; ++k) {
          // Keyed like cosineDirection (include/obscura/integrator.h): a pixel's
          // (sample, ray) pairs index one sequence, jointly stratified.
          const Sample2 s = Sampler::get2D(h.pixelKey, h.sampleIndex * rays_ + k, kFirstIntegratorDim);
          const Vec3 w = frame.toWorld(squareToPowerCosine(s.u, s.v, e));
          if (intoSurface(h, w)) continue;
          batch.push(spawnOrigin(h, w), w, tnear_, distance_, h);
          ++above, ++traced;
        }
      }
      out[i].num = Vec3(float(traced), 0, 0);
      out[i].den = Vec3(float(above), float(above), float(above));
    }
    ctx.trace(batch);
    size_t ray = 0;
    for (size_t i = 0; i < hits.size(); ++i) {
      const uint32_t traced = uint32_t(out[i].num.x), above = uint32_t(out[i].den.x);
      uint32_t open = 0;
      for (uint32_t k = 0; k < traced; ++k, ++ray) open += batch.occluded(ray) ? 0U : 1U;
      if (traced == 1 && above > 1) open *= above;  // the mirror ray, for all of them
      out[i].num = Vec3(float(open), float(open), float(open));
    }
  }

 private:
  float distance_;
  uint32_t rays_;
  bool material_;
  float exponent_;
  float tnear_;
};

IntegratorDescriptor reflectionOcclusionDescriptor() {
  IntegratorDescriptor d;
  d.name = "reflocc";
  d.doc = "Reflection occlusion: fraction of a glossy lobe about the view ray's mirror direction unoccluded "
          "within distance R (docs/math.md §12).";
  d.params = {
      {.name = "distance", .type = ParamType::Float, .defaultValue = "inf", .min = 0.0, .max = 1e308,
       .allowInfinity = true, .doc = "R: occluders farther than this (scene units) do not count; inf = any hit occludes"},
      {.name = "rays", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 65536,
       .doc = "rays per camera sample, jointly stratified over a pixel's samples"},
      {.name = "roughness", .type = ParamType::Float, .defaultValue = "-1", .min = -1.0, .max = 1.0,
       .doc = "the lobe's roughness in [0, 1] (glTF's: alpha = roughness^2; 0 = the mirror direction, 1 = the "
              "hemisphere about it); -1 = each surface's material, roughnessFactor x the G channel of its "
              "metallicRoughnessTexture"},
  };
  addLobeParams(d.params, LobeSet::Near);
  d.needs = [](const ParamSet& p) {
    IntegratorNeeds n;
    n.roughness = p.getFloat("roughness") < 0.0;
    return n;
  };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    const double roughness = p.getFloat("roughness");
    // The range check allows [-1, 1] for the sentinel; below 0 only -1 means anything.
    if (roughness < 0.0 && roughness != -1.0)
      throw Error("integrator '" + p.owner() + "': parameter 'roughness': expected -1 (the material's) or a value in [0, 1], got '" +
                  formatFloat(roughness) + "'");
    const double R = p.getFloat("distance");
    const float r = toRayDistance(R);
    const LobeControls near = lobeFromParams(p, R);
    return std::make_unique<ReflectionOcclusion>(r, p.getInt("rays"), float(roughness), near.tnear);
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(reflectionOcclusionDescriptor)
}  // namespace obscura
