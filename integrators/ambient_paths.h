// The path estimator of the ambient transfer equation (docs/math.md §5),
// shared by `transfer` (closed form and recursive) and `gi` (full global
// illumination), because their math is the same:
//
//   W(x) = O(x) + (1/pi) Int (1 - mu(d)) a(y) W(y) cos+(theta) dw
//
// At each vertex a direction w ~ cos(theta)/pi is drawn; the path adds
// throughput * mu(d) and continues from the occluder y with
// throughput *= (1 - mu(d)) * a(y). With the step membership at R = inf
// (mu = 0 for every hit, 1 for escape) and no depth limit this is the
// diffuse path tracer under a uniform sky; with the exponential membership
// it is the exact solution of the ambient-medium model of section 2.
//
// After `depth` bounces the recursion is closed:
// - tail=zero: the rest is dropped (truncation, biased low); each path's
//   estimate is its sum, den = 1.
// - tail=closed: the closed form of section 4 closes it. With the local
//   approximation W(beyond the last occluder) ~ W(x), the equation for the
//   unknown tail gives W(x) ~ E[S] / E[1 - T], S = the path's sum and
//   T = its throughput after the last occluder. Both expectations are
//   estimated from the same samples and divided once per pixel (the ratio
//   estimator of section 4; a ratio per path with one direction would
//   degenerate to AO). 1 - T is computed as S + A, A = the energy the path's
//   occluders absorbed, Sum throughput * (1 - mu) * (1 - a) - equal in exact
//   arithmetic, and exact in floating point at both ends: A = 0 for white
//   occluders (num == den, W = 1 exactly: the white furnace) and
//   mu + (1 - mu) rounds to exactly 1 for black ones (W = obscurance,
//   bit for bit). depth = 0 is the closed form itself [AT 6, 9]:
//   W ~ Sum mu_i / Sum (mu_i + (1 - mu_i)(1 - a_i)) = Sum mu_i / (n - Sum (1 - mu_i) a_i).
//   For depth >= 1 the approximation is the paper's closure moved one
//   occluder further each time; in a uniform configuration (the spherical
//   cavity) every depth is exact.
//
// Occluder albedo: the distance estimator reads it at the closest hit
// (mu < 1 there). The occlusion estimator traces the segment [0, r] for its
// closest hit, so the occluder is the model's one - the first surface along
// w - not an arbitrary any-hit one; its rays are closest-hit rays, shorter
// on average than the distance estimator's.
//
// Opaque surfaces: a direction below the geometric plane meets the surface
// itself at d = 0 (mu = 0); that occluder is x, with x's albedo, and a path
// continues from x. No ray is traced for it.
//
// Russian roulette (gi): from bounce kRouletteStart on, a path survives with
// q = min(1, max channel of its throughput), and its throughput is divided by
// q. Unbiased, and it keeps every path's weight at most 1: a fixed cap on q
// (0.95, say) would instead let a path in a near-white, nearly closed room
// grow its weight by a/0.95 a bounce - infinite variance once the escape
// probability drops below 5% (fireflies of 3x in the Cornell boxes).
// Paths end by escaping, by losing energy to albedo < 1, by roulette, or at
// kMaxBounces: only a lossless enclosure with no way out reaches that bound
// (its true W is what the first kMaxBounces bounces carried).
// Roulette needs tail=zero (a divided throughput breaks the S + A = 1 - T
// identity the closed tail relies on).
//
// Lobe controls (docs/math.md §11): the path starts from the camera hit
// turned to the lobe's side (LobeControls::oriented), so with inside=true
// its first vertex - and a continuation from it after a direction blocked
// by the surface itself - lies on the inside; bounce 0 draws from the cone
// of `spread` and ignores occluders closer than `near`.
//
// Environment lighting (gi, docs/math.md §14.3): what escapes along w
// carries L(w) / Lbar (Lbar the environment's mean radiance, per channel),
// and in the ambient medium the in-scattered light along w is mu(d) L(w) /
// Lbar: the uniform sky's model with the sky's radiance taken from the
// direction. So W = (1/pi) Int L_in cos / Lbar, and under a constant sky
// (L = Lbar exactly) every factor is exactly 1 and the estimator is the
// one above bit for bit. With `lightSamples` (a non-constant map), each
// vertex also draws a direction from the map's density (light sampling)
// and the two techniques are combined by the power heuristic (Veach 1997,
// eq. 9.13): the cosine direction's escape weighs w_b = p_b^2 / (p_b^2 +
// p_l^2), the light direction's unoccluded contribution
//   T L(w_l) (cos theta_l / pi) / p_l x p_l^2 / (p_b^2 + p_l^2),
// p_b = cos theta / pi about the shading normal, p_l the map's density.
// The light direction's ray is an any-hit ray over [0, r]: r = R (inf) in
// vacuum, r ~ mu' in the medium, whose probability of being open is mu(d)
// (the occlusion estimator of §3), so the medium stays unbiased too.
//
// Sample dimensions: bounce b draws its direction from the 2D pair
// kFirstIntegratorDim + 4b, the occlusion estimator's r (and the light
// ray's, which the distance estimator leaves free) from the 1D dimension
// kFirstIntegratorDim + 4b + 1, roulette from + 4b + 2 and the light
// direction from the 2D pair + 4b + 3, all at
// index sampleIndex * rays + k (path k of the camera sample). Bounce 0 is
// exactly the obscurance integrator's sequence, which is what makes
// transfer with black occluders equal obscurance bit for bit.
#pragma once

#include <cstdint>
#include <limits>
#include <span>

#include <obscura/integrator.h>
#include "integrators/falloff.h"

namespace obscura {

struct AmbientPaths {
  static constexpr uint32_t kUnlimited = std::numeric_limits<uint32_t>::max();
  static constexpr uint32_t kRouletteStart = 3;
  static constexpr uint32_t kMaxBounces = 1u << 16;  // depth = kUnlimited stops here

  Membership mu;
  Estimator estimator = Estimator::Distance;
  uint32_t rays = 1;           // paths per camera sample
  uint32_t depth = 0;          // bounces after the first segment; kUnlimited with roulette
  bool closedTail = true;      // tail=closed (ratio) or tail=zero (plain mean)
  bool roulette = false;
  // The first bounce's lobe (inside, spread, near; include/obscura/lobe.h): the camera
  // hit's side, cone and near clip. Later bounces sample the full cosine
  // hemisphere from tnear 0 (they are light transport, not the pass's lobe).
  LobeControls lobe;
  // Environment lighting (gi; see above): escapes carry L(w) / Lbar.
  bool environment = false;
  // With environment: MIS with light sampling where the map is not constant.
  bool lightSamples = true;

  // Writes out[i] for every camera hit (num and den, see above).
  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const;

 private:
  static constexpr size_t kMaxPaths = 4096;
  void estimateGroup(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const;
};

// An integrator that is nothing but a configured path estimator (transfer, gi).
class AmbientPathIntegrator final : public Integrator {
 public:
  explicit AmbientPathIntegrator(const AmbientPaths& paths) : paths_(paths) {}
  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* out) const override {
    paths_.estimate(hits, ctx, out);
  }
  Shading shading() const override { return paths_.environment ? Shading::MeanRadiance : Shading::Irradiance; }

 private:
  AmbientPaths paths_;
};

}  // namespace obscura
