// Fuzzy membership (falloff) functions mu(d) of docs/math.md §2, shared by
// every integrator that weighs an occluder by its distance: obscurance,
// transfer and gi. One place defines mu, the sampling of mu', the edge cases
// and the parameters, so the integrators agree bit for bit where their math
// coincides (transfer with black occluders is obscurance, gi in vacuum is
// the step membership at R = inf).
//
// Memberships (R = `distance`, sigma = `sigma`):
//   step         mu = [d > R]                      r = R
//   linear       mu = min(d/R, 1)                  r = R xi
//   sqrt         mu = min(sqrt(d/R), 1)            r = R xi^2
//   exponential  mu = 1 - e^(-sigma d) for d <= R, 1 beyond R (cut-off)
//                                                  r = min(-log1p(-xi)/sigma, R)
// The exponential's cut-off turns mu' into the density sigma e^(-sigma r) on
// [0, R) plus an atom of mass e^(-sigma R) at R, which is exactly what
// clamping the unbounded sample to R draws. R = inf means no cut-off.
//
// Edge cases (each one documented where the integrators use it):
// - Embree accepts a hit at t == tfar, so an occluder exactly at R counts
//   (step: mu(R) = 0, like `ao`; the other memberships are continuous).
// - R = inf with linear or sqrt gives mu = 0 for every finite d: the step
//   membership at R = inf, and it is traced as such (R xi would be
//   inf * 0 = NaN for xi = 0).
// - R = 0 (or below float range, 2^-150): mu = 1 for every occluder at
//   d > 0 (the limit R -> 0+); only the surface itself occludes.
// - mu is evaluated in double, 1 - e^(-sigma d) as -expm1(-sigma d) (no
//   cancellation for tiny sigma d), r with log1p; values are clamped to
//   [0, 1], so sigma in [1e-30, 1e30] and every R and scale stay finite.
// - Distances beyond float range become +inf for Embree (converting an
//   out-of-range double to float is undefined behaviour).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <obscura/params.h>
#include <obscura/ray_batch.h>
#include <obscura/warp.h>

namespace obscura {

enum class Falloff { Step, Linear, Sqrt, Exponential };
// The value of the `falloff` parameter.
inline const char* falloffName(Falloff f) {
  switch (f) {
    case Falloff::Step: return "step";
    case Falloff::Linear: return "linear";
    case Falloff::Sqrt: return "sqrt";
    case Falloff::Exponential: return "exponential";
  }
  return "?";
}
// distance: trace the closest hit and weigh it by mu(d).
// occlusion: draw r ~ mu'(r) and test the segment [0, r] (docs/math.md §3).
enum class Estimator { Distance, Occlusion };

// (toRayDistance, a distance as a ray's tfar: obscura/ray_batch.h.)

class Membership {
 public:
  Membership(Falloff falloff, double R, double sigma) : falloff_(falloff), R_(R), sigma_(sigma), tfar_(toRayDistance(R)) {
    if (std::isinf(R_) && (falloff_ == Falloff::Linear || falloff_ == Falloff::Sqrt)) falloff_ = Falloff::Step;
  }
  // From the parameters `falloff`, `distance` and `sigma` (membershipParams).
  static Membership fromParams(const ParamSet& p);

  Falloff falloff() const { return falloff_; }
  // R as an Embree tfar: the distance estimator's ray length.
  float tfar() const { return tfar_; }
  // R = 0 (or below float range): nothing but the surface itself occludes.
  bool zeroRadius() const { return tfar_ == 0.0f; }

  // mu(d) for an occluder found at distance d <= R, in [0, 1].
  double operator()(double d) const {
    double m = 0.0;  // step: found within R (a hit at t == R included)
    switch (falloff_) {
      case Falloff::Step: break;
      case Falloff::Linear: m = d / R_; break;
      case Falloff::Sqrt: m = std::sqrt(d / R_); break;
      case Falloff::Exponential: m = -std::expm1(-sigma_ * d); break;
    }
    return std::clamp(m, 0.0, 1.0);
  }

  // The occlusion estimator's segment length r ~ mu'(r), xi in [0, 1), as an
  // Embree tfar. r = 0 (xi = 0, or r below float range) is an empty segment.
  float segment(double xi) const {
    switch (falloff_) {
      case Falloff::Step: return tfar_;
      case Falloff::Linear: return toRayDistance(R_ * xi);
      case Falloff::Sqrt: return toRayDistance(R_ * xi * xi);
      case Falloff::Exponential: return toRayDistance(std::min(-std::log1p(-xi) / sigma_, R_));
    }
    return tfar_;
  }

 private:
  Falloff falloff_;
  double R_, sigma_;
  float tfar_;
};

// The parameters every membership-based integrator declares, with the same
// names, ranges and defaults: falloff, distance, sigma, estimator, rays.
std::vector<ParamSpec> membershipParams(const std::string& raysDoc);
Estimator estimatorFromParams(const ParamSet& p);

}  // namespace obscura
