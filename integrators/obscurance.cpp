// Obscurance with a fuzzy membership (falloff) function (docs/math.md sections 2
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
//              r_i ~ mu'(r) (table of docs/math.md §2), one any-hit ray
//              with tfar = r_i. Unbiased because
//              mu(d) = Int_0^inf mu'(r) [d > r] dr = P(r < d).
//
// Memberships, their sampling and their edge cases: integrators/falloff.h.
// inside, spread and near shape the lobe (include/obscura/lobe.h, docs/math.md §11);
// with near, d is the distance to the first occluder beyond near (the
// distance estimator's tnear; the occlusion estimator tests [near, r], an
// r below near being an empty segment), and the two estimators still agree:
// P(r < d) = mu(d) for that d.
//
// Conventions at the edges of the parameter space:
// - Embree accepts a hit at t == tfar, so an occluder exactly at R counts
//   (step: mu(R) = 0, like the `ao` integrator; all other memberships are
//   continuous there). The boundary has measure zero; the convention only
//   makes `falloff=step` bit-identical to `ao` with either estimator.
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
#include <cmath>
#include <limits>
#include <string>

#include <obscura/plugin.h>
#include <obscura/warp.h>
#include "integrators/falloff.h"

namespace obscura {
namespace {

class Obscurance final : public Integrator {
 public:
  Obscurance(Membership mu, Estimator estimator, int rays, LobeControls lobe)
      : mu_(mu), estimator_(estimator), rays_(uint32_t(rays)), lobe_(lobe) {}

  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* W) const override {
    if (mu_.zeroRadius())  // only the surface itself occludes
      estimateZeroRadius(hits, W);
    else if (estimator_ == Estimator::Distance)
      estimateDistance(hits, ctx, W);
    else
      estimateOcclusion(hits, ctx, W);
  }

 private:
  // Directions come from cosineDirection (include/obscura/integrator.h), the sequence
  // `ao` uses, dimension for dimension. sampleMean is the arithmetic `ao`
  // and `transfer` use.
  static void setGrey(SampleEstimate& out, double sum, uint32_t n) {
    const float o = std::min(sampleMean(sum, n), 1.0f);
    out.num = Vec3(o, o, o);
  }

  void estimateZeroRadius(std::span<const SurfaceHit> hits, SampleEstimate* W) const {
    for (size_t i = 0; i < hits.size(); ++i) {
      const SurfaceHit& h = hits[i];
      const Lobe lobe = lobe_.at(h);
      double open = 0.0;
      Vec3 bent(0, 0, 0);
      for (uint32_t k = 0; k < rays_; ++k) {
        const Vec3 w = cosineDirection(h, lobe, rays_, k);
        if (lobe.blocked(w)) continue;
        open += 1.0;
        bent += w;
      }
      setGrey(W[i], open, rays_);
      W[i].bent = bent;
    }
  }

  void estimateDistance(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* W) const {
    IntersectBatch& batch = ctx.intersectBatch(hits.size() * rays_);
    for (const SurfaceHit& h : hits) {
      const Lobe lobe = lobe_.at(h);
      for (uint32_t k = 0; k < rays_; ++k) {
        const Vec3 w = cosineDirection(h, lobe, rays_, k);
        if (lobe.blocked(w))
          batch.push(spawnOrigin(h, w), w, kInfinity, 0.0f, h);
        else
          batch.push(spawnOrigin(h, w), w, lobe_.tnear, mu_.tfar(), h);
      }
    }
    ctx.trace(batch);
    size_t r = 0;
    for (size_t i = 0; i < hits.size(); ++i) {
      double sum = 0.0;
      Vec3 bent(0, 0, 0);  // each direction weighted by its mu, as in the sum
      for (uint32_t k = 0; k < rays_; ++k, ++r) {
        if (lobe_.blocked(hits[i], batch.dir(r))) continue;  // mu = 0
        const double m = batch.hit(r) ? mu_(double(batch.t(r))) : 1.0;
        sum += m;
        bent += batch.dir(r) * float(m);
      }
      setGrey(W[i], sum, rays_);
      W[i].bent = bent;
    }
  }

  void estimateOcclusion(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* W) const {
    OcclusionBatch& batch = ctx.occlusionBatch(hits.size() * rays_);
    for (const SurfaceHit& h : hits) {
      const Lobe lobe = lobe_.at(h);
      for (uint32_t k = 0; k < rays_; ++k) {
        const Vec3 w = cosineDirection(h, lobe, rays_, k);
        // xi from its own dimension, same index as the direction.
        const double xi = Sampler::get1D(h.pixelKey, h.sampleIndex * rays_ + k, kFirstIntegratorDim + 1);
        const float r = mu_.segment(xi);
        // A segment shorter than near (tnear > r) is inactive too: open.
        if (r > 0.0f && !lobe.blocked(w))
          batch.push(spawnOrigin(h, w), w, lobe_.tnear, r, h);
        else  // inactive (tnear > tfar): Embree skips it and leaves tfar = 0
          batch.push(spawnOrigin(h, w), w, kInfinity, 0.0f, h);
      }
    }
    ctx.trace(batch);
    // An empty segment (r = 0) is unoccluded: its inactive ray reads so.
    writeMeanVisibility(hits, batch, rays_, lobe_, W);
  }

  Membership mu_;
  Estimator estimator_;
  uint32_t rays_;
  LobeControls lobe_;
};

IntegratorDescriptor obscuranceDescriptor() {
  IntegratorDescriptor d;
  d.name = "obscurance";
  d.doc = "Obscurance: cosine-weighted mean of a falloff mu(d) of the distance to the first occluder (AO with fuzzy membership).";
  d.params = membershipParams("obscurance rays per camera sample");
  addLobeParams(d.params);
  d.bentNormal = true;  // SampleEstimate::bent: the open directions (e0=bent)
  d.needs = [](const ParamSet&) { return IntegratorNeeds{}; };
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    return std::make_unique<Obscurance>(Membership::fromParams(p), estimatorFromParams(p), p.getInt("rays"),
                                        lobeFromParams(p, p.getFloat("distance")));
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(obscuranceDescriptor)
}  // namespace obscura
