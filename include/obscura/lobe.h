// The lobe controls of the AO family (docs/math.md §11): which hemisphere,
// how wide a cone and from what distance on the visibility rays of `ao`,
// `obscurance`, `transfer` (its first bounce), `containment` (spread and
// near), `multibounce` and the bent-normal plugin look for occluders.
//
//   inside  the lobe faces -ng, -ns: the hemisphere behind the surface
//           (a hit's normals face the incoming ray, obscura/surface_hit.h), for
//           interior occlusion and thickness passes;
//   spread  the lobe is the cone of half-angle thetaMax = spread * pi/2
//           about the (possibly inverted) shading normal, cosine-distributed
//           and normalised over the cone, so W = 1 on an open surface;
//   near    occluders closer than `near` along a ray are ignored: the ray's
//           tnear.
// The defaults (inside=false, spread=1, near=0) give sign 1, sinThetaMax 1,
// cosThetaMax 0 and tnear 0 exactly, values that leave every product and
// comparison they enter unchanged bit for bit, so the defaults reproduce the
// renders from before these controls existed with no branch per ray.
#pragma once

#include <string>
#include <vector>

#include <obscura/math.h>
#include <obscura/params.h>
#include <obscura/sampler.h>
#include <obscura/surface_hit.h>
#include <obscura/warp.h>

namespace obscura {

// One hit's lobe: what its directions and its below-surface test use.
// spawnOrigin (obscura/surface_hit.h) needs no sign: it offsets the origin to the
// side the direction points to, whichever way ng faces.
struct Lobe {
  Frame frame;        // about sign * ns
  Vec3 ng;            // sign * ng: the plane that bounds the lobe
  float sinThetaMax;  // of the cone (1: the hemisphere)

  // The cosine-weighted direction of sample s (docs/math.md §11).
  Vec3 direction(Sample2 s) const { return frame.toWorld(squareToCosineCone(s.u, s.v, sinThetaMax)); }
  // Is w blocked by the surface itself (intoSurface, for the lobe's side)?
  bool blocked(Vec3 w) const { return intoSurface(ng, w); }
};

// The controls as an integrator was configured, shared by all its hits.
struct LobeControls {
  float sign = 1.0f;         // -1: inside
  float sinThetaMax = 1.0f;  // sin(spread pi/2), exactly 1 at spread = 1
  float cosThetaMax = 0.0f;  // cos(spread pi/2), exactly 0 at spread = 1
  float tnear = 0.0f;        // near as an Embree tnear (capped to float range)

  // The lobe at h (per hit, not per ray: one Frame).
  Lobe at(const SurfaceHit& h) const { return {Frame::fromNormal(h.ns * sign), h.ng * sign, sinThetaMax}; }
  // h with its normals turned to the lobe's side: for code that continues a
  // path from h (the side it leaves from is then the lobe's).
  SurfaceHit oriented(const SurfaceHit& h) const {
    SurfaceHit o = h;
    o.ng = h.ng * sign;
    o.ns = h.ns * sign;
    return o;
  }
  // Is w blocked by h's surface itself, on the lobe's side?
  bool blocked(const SurfaceHit& h, Vec3 w) const { return intoSurface(h.ng * sign, w); }
  // An any-hit ray i of `batch` spawned from h along the lobe: is it open?
  template <class Batch>
  bool open(const SurfaceHit& h, const Batch& batch, size_t i) const {
    return !blocked(h, batch.dir(i)) && !batch.occluded(i);
  }
};

// Which controls an integrator declares: containment has no `inside` (the
// hemisphere behind a height field is inside the field); reflocc only
// `near` (its lobe is about the mirror direction, not the normal).
enum class LobeSet { All, SpreadNear, Near };

// Appends the ParamSpecs `inside`, `spread`, `near` to `params` (names,
// ranges, defaults and documentation in one place for every integrator).
void addLobeParams(std::vector<ParamSpec>& params, LobeSet set = LobeSet::All);

// The controls from the parameters addLobeParams declared (an undeclared one
// keeps its default). `distance` is the integrator's R (inf when it has
// none): near > 0 must be below it, or every occluder would be ignored.
// Throws obscura::Error naming the integrator and the parameter for spread = 0
// (the range check of ParamSet already refuses < 0, > 1 and NaN) and for
// near >= distance.
LobeControls lobeFromParams(const ParamSet& p, double distance);

}  // namespace obscura
