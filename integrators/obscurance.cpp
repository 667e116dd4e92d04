// Obscurance with a fuzzy membership (falloff) function (MATH.md sections 2
// and 3).
//
//   O(x) = (1/pi) Int_Omega mu(d(x, w)) cos+(theta) dw
//
// d = distance to the first occluder along w (d = inf when the ray escapes,
// mu(inf) = 1). Directions are drawn with density cos(theta)/pi about the
// shading normal, so both estimators are plain means:
//
// - distance:  O ~ (1/n) Sum_i mu(d_i), one closest-hit ray per direction
//              with tfar = R (occluders beyond R have mu = 1 for every
//              falloff, so they need not be found).
// - occlusion: O ~ (1/n) Sum_i [segment x -> x + w_i r_i is unoccluded],
//              r_i ~ mu'(r) (table of MATH.md section 2), one any-hit ray
//              with tfar = r_i. Unbiased because
//              mu(d) = Int_0^inf mu'(r) [d > r] dr = P(r < d).
//
// Memberships (R = `distance`, sigma = `sigma`):
//   step         mu = [d > R]                      r = R
//   linear       mu = min(d/R, 1)                  r = R xi
//   sqrt         mu = min(sqrt(d/R), 1)            r = R xi^2
//   exponential  mu = 1 - e^(-sigma d) for d <= R, 1 beyond R (cut-off)
//                                                  r = min(-log1p(-xi)/sigma, R)
// The exponential's cut-off turns mu' into the density sigma e^(-sigma r) on
// [0, R) plus an atom of mass e^(-sigma R) at R, which is exactly what
// clamping the unbounded sample to R draws. R = inf (the default) means no
// cut-off.
//
// Conventions at the edges of the parameter space:
// - Embree accepts a hit at t == tfar, so an occluder exactly at R counts
//   (step: mu(R) = 0, like the `ao` integrator; all other memberships are
//   continuous there). The boundary has measure zero; the convention only
//   makes `falloff=step` bit-identical to `ao` with either estimator.
// - R = inf with linear or sqrt gives mu = 0 for every finite d: the same
//   membership as step with R = inf ("any hit occludes"), and it is traced
//   as such (R xi would be inf * 0 = NaN for xi = 0).
// - Surfaces are opaque: a direction below the geometric plane (reachable
//   when the shading normal tilts away from ng) meets the surface itself at
//   d = 0, so mu(0) = 0 for every falloff and R > 0; it is not traced.
// - R = 0: mu = 1 for every occluder at d > 0 and every falloff (the limit
//   R -> 0+), so only the surface itself occludes: O is the fraction of
//   directions above the geometric plane (1 wherever ns = ng), and no rays
//   are traced. This is what `ao` gives with distance=0. An R that rounds to
//   0 as a float (below 2^-150 ~ 7e-46) is treated the same way: it is
//   below every distance a float ray can resolve.
// - d is measured from the ray origin, which spawnOrigin pushes h.eps
//   (2^-16 of the hit's coordinate magnitude) off the surface along +-ng;
//   the distance from the surface point itself differs by at most that,
//   far below any meaningful R or 1/sigma, and both estimators measure the
//   same way, so they estimate the same quantity.
// - A sampled r of 0 (xi = 0, or r below float range for huge sigma) is an
//   empty segment: unoccluded, which is right since mu' has no mass at 0
//   when R > 0. The ray is made inactive (tnear > tfar: Embree skips it and
//   leaves tfar = 0, which reads as unoccluded).
// - Distances beyond float range become +inf for Embree (a C++ conversion
//   of an out-of-range double to float is undefined).
// - mu is evaluated in double; 1 - e^(-sigma d) as -expm1(-sigma d), which
//   has no cancellation for tiny sigma d, and r with log1p. Every value is
//   clamped to [0, 1], so the output is finite and in [0, 1] for every
//   sigma in [1e-30, 1e30], every R and every scene scale.
#include <cmath>
#include <limits>
#include <string>

#include "core/plugin.h"
#include "core/warp.h"

namespace obscura {
namespace {

enum class Falloff { Step, Linear, Sqrt, Exponential };
enum class Estimator { Distance, Occlusion };

// Distance for an Embree ray: +inf when beyond float range.
inline float toRayDistance(double t) {
  return t > double(std::numeric_limits<float>::max()) ? kInfinity : float(t);
}

class Obscurance final : public Integrator {
 public:
  Obscurance(Falloff falloff, double R, double sigma, Estimator estimator, int rays)
      : falloff_(falloff), R_(R), sigma_(sigma), estimator_(estimator), rays_(uint32_t(rays)),
        tfar_(toRayDistance(R)) {
    // linear/sqrt with R = inf: mu = 0 for every finite d, i.e. step, R = inf.
    if (std::isinf(R_) && (falloff_ == Falloff::Linear || falloff_ == Falloff::Sqrt)) falloff_ = Falloff::Step;
  }

  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, Vec3* W) const override {
    if (tfar_ == 0.0f)  // R = 0 (or below float range): only the surface itself occludes
      estimateZeroRadius(hits, W);
    else if (estimator_ == Estimator::Distance)
      estimateDistance(hits, ctx, W);
    else
      estimateOcclusion(hits, ctx, W);
  }

 private:
  // Directions come from cosineDirection (core/integrator.h), the sequence
  // `ao` uses, dimension for dimension.
  static void setGrey(Vec3& out, double sum, float inv) {
    const float o = std::min(float(sum) * inv, 1.0f);
    out = Vec3(o, o, o);
  }

  // mu(d) for an occluder found at distance d <= R (MATH.md section 2).
  double membership(double d) const {
    switch (falloff_) {
      case Falloff::Step: return 0.0;  // found within R (hit at t == R included)
      case Falloff::Linear: return d / R_;
      case Falloff::Sqrt: return std::sqrt(d / R_);
      case Falloff::Exponential: return -std::expm1(-sigma_ * d);
    }
    return 0.0;
  }

  // r ~ mu'(r), xi in [0,1) (MATH.md section 2, table).
  double sampleDistance(double xi) const {
    switch (falloff_) {
      case Falloff::Step: return R_;
      case Falloff::Linear: return R_ * xi;
      case Falloff::Sqrt: return R_ * xi * xi;
      case Falloff::Exponential: return std::min(-std::log1p(-xi) / sigma_, R_);
    }
    return R_;
  }

  void estimateZeroRadius(std::span<const SurfaceHit> hits, Vec3* W) const {
    const float inv = 1.0f / float(rays_);
    for (size_t i = 0; i < hits.size(); ++i) {
      const SurfaceHit& h = hits[i];
      const Frame frame = Frame::fromNormal(h.ns);
      double open = 0.0;
      for (uint32_t k = 0; k < rays_; ++k)
        open += intoSurface(h, cosineDirection(h, frame, rays_, k)) ? 0.0 : 1.0;
      setGrey(W[i], open, inv);
    }
  }

  void estimateDistance(std::span<const SurfaceHit> hits, IntegratorContext& ctx, Vec3* W) const {
    IntersectBatch& batch = ctx.intersectBatch(hits.size() * rays_);
    for (const SurfaceHit& h : hits) {
      const Frame frame = Frame::fromNormal(h.ns);
      for (uint32_t k = 0; k < rays_; ++k) {
        const Vec3 w = cosineDirection(h, frame, rays_, k);
        if (intoSurface(h, w))
          batch.push(spawnOrigin(h, w), w, kInfinity, 0.0f);
        else
          batch.push(spawnOrigin(h, w), w, 0.0f, tfar_);
      }
    }
    ctx.trace(batch);
    const float inv = 1.0f / float(rays_);
    size_t r = 0;
    for (size_t i = 0; i < hits.size(); ++i) {
      double sum = 0.0;
      for (uint32_t k = 0; k < rays_; ++k, ++r) {
        if (intoSurface(hits[i], batch.dir(r))) continue;  // mu = 0
        sum += batch.hit(r) ? std::clamp(membership(double(batch.t(r))), 0.0, 1.0) : 1.0;
      }
      setGrey(W[i], sum, inv);
    }
  }

  void estimateOcclusion(std::span<const SurfaceHit> hits, IntegratorContext& ctx, Vec3* W) const {
    OcclusionBatch& batch = ctx.occlusionBatch(hits.size() * rays_);
    for (const SurfaceHit& h : hits) {
      const Frame frame = Frame::fromNormal(h.ns);
      for (uint32_t k = 0; k < rays_; ++k) {
        const Vec3 w = cosineDirection(h, frame, rays_, k);
        // xi from its own dimension, same index as the direction.
        const double xi = Sampler::get1D(h.pixelKey, h.sampleIndex * rays_ + k, kFirstIntegratorDim + 1);
        const float r = falloff_ == Falloff::Step ? tfar_ : toRayDistance(sampleDistance(xi));
        if (r > 0.0f && !intoSurface(h, w))
          batch.push(spawnOrigin(h, w), w, 0.0f, r);
        else  // inactive (tnear > tfar): Embree skips it and leaves tfar = 0
          batch.push(spawnOrigin(h, w), w, kInfinity, 0.0f);
      }
    }
    ctx.trace(batch);
    const float inv = 1.0f / float(rays_);
    size_t r = 0;
    for (size_t i = 0; i < hits.size(); ++i) {
      uint32_t open = 0;
      for (uint32_t k = 0; k < rays_; ++k, ++r)
        // An empty segment (r = 0) is unoccluded: its inactive ray reads so.
        open += openDirection(hits[i], batch, r) ? 1U : 0U;
      setGrey(W[i], double(open), inv);
    }
  }

  Falloff falloff_;
  double R_, sigma_;
  Estimator estimator_;
  uint32_t rays_;
  float tfar_;  // R for Embree
};

IntegratorDescriptor obscuranceDescriptor() {
  IntegratorDescriptor d;
  d.name = "obscurance";
  d.doc = "Obscurance: cosine-weighted mean of a falloff mu(d) of the distance to the first occluder (AO with fuzzy membership).";
  d.params = {
      {.name = "falloff", .type = ParamType::Enum, .defaultValue = "step",
       .choices = {"step", "linear", "sqrt", "exponential"},
       .doc = "mu(d): step [d>R] (AO), linear min(d/R,1), sqrt min(sqrt(d/R),1), exponential 1-exp(-sigma d)"},
      {.name = "distance", .type = ParamType::Float, .defaultValue = "inf", .min = 0.0, .max = 1e308,
       .allowInfinity = true,
       .doc = "R (scene units): step/linear/sqrt radius (inf: any hit occludes, all three = step); "
              "exponential cut-off (mu = 1 beyond R; inf: none); 0: O = 1"},
      {.name = "sigma", .type = ParamType::Float, .defaultValue = "1", .min = 1e-30, .max = 1e30,
       .doc = "exponential only: extinction sigma of the ambient medium (1/scene units)"},
      {.name = "estimator", .type = ParamType::Enum, .defaultValue = "distance", .choices = {"distance", "occlusion"},
       .doc = "distance: closest hit, mean mu(d); occlusion: any-hit ray to r ~ mu'(r), mean unoccluded"},
      {.name = "rays", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 65536,
       .doc = "obscurance rays per camera sample"},
  };
  d.needs = [](const ParamSet&) { return IntegratorNeeds{}; };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    const std::string& f = p.getEnum("falloff");
    const Falloff falloff = f == "step"     ? Falloff::Step
                            : f == "linear" ? Falloff::Linear
                            : f == "sqrt"   ? Falloff::Sqrt
                                            : Falloff::Exponential;
    const Estimator estimator = p.getEnum("estimator") == "distance" ? Estimator::Distance : Estimator::Occlusion;
    return std::make_unique<Obscurance>(falloff, p.getFloat("distance"), p.getFloat("sigma"), estimator,
                                        p.getInt("rays"));
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(obscuranceDescriptor)
}  // namespace obscura
