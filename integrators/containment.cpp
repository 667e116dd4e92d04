// Height-field containment obscurance (Umenhoffer, Toth, Szirmay-Kalos,
// "Efficient Methods for Ambient Lighting", sections 4 and 6; docs/math.md
// sections 2 and 3; docs/containment.md).
//
// The camera sees the UNDISPLACED macro surface; the displacement detail a
// height map would add (displacement d(uv) = scale (h(uv) - midlevel) along
// the macro normal, what `--displace` builds as geometry) is not traced but
// tested for containment, and only the macro geometry is traced - the
// paper's section 6 combination: "the z-buffer [here: rays] for occlusions
// of other objects, the height field for self-shadowing".
//
// Obscurance as a 3D integral over direction and distance [AT 7, numerator]:
//
//   O(x) = Int_0^R Int_Omega mu'(r) eps(d(w) - r) cos+(theta)/pi dw dr
//
// sampled with density p(w, r) = mu'(r) cos+(theta)/pi [AT 4.1], so the
// estimator is the mean of eps(d(w_k) - r_k) = [segment x -> x + w r open].
// The containment approximation of that indicator [AT 4]:
//
//   eps(d(w) - r) ~ I(x + w r) = Prod_{i=1..m} I0(x + w r i/m)
//
// with I0(q) = 1 iff q is outside the height field (the surface itself
// belongs to the inside). Here each sample is open iff all m test points are
// outside AND the macro geometry does not block the segment: one any-hit ray
// from spawnOrigin(h, w) along w to r, traced in the context's batch.
//
// The local height-field frame at a hit (p = h.p on the macro surface,
// N = h.ns its unit shading normal, uv and dP/du, dP/dv from ctx.uvFrameAt):
// - the shaded point is x = p + N d(uv) (the displaced surface point);
// - a test point q has tangent coordinates (a, b, z) from
//   q - p = a dP/du + b dP/dv + z N, i.e. uv' = uv + (a, b) and height z,
//   and is inside (I0 = 0) iff z < d(uv') [AT 4, figure 3, "height field"];
// - the cosine lobe is about the displaced normal
//   n_d = normalize(cross(dP/du + N dd/du, dP/dv + N dd/dv)), dd/du and
//   dd/dv by central differences of the height map one texel apart.
// Curvature is ignored: the terms d dN/du, d dN/dv of the displaced
// surface's derivatives are dropped, and the frame (dP/du, dP/dv, N) is
// taken as constant over the neighbourhood R (exact on a plane; on a curved
// macro surface test points are placed in the tangent space of the hit).
//
// Conventions and limits (docs/containment.md):
// - Directions below the macro geometric plane (dot(w, ng) <= 0, reachable
//   because n_d tilts away from N) skip the macro ray: the macro surface is
//   not an occluder there (the displaced surface is, through containment),
//   and other macro geometry below the plane is not looked for.
// - The macro ray starts on the macro surface (spawnOrigin at p), not at x:
//   starting at x would put points with d < 0 under their own macro surface.
//   The two differ by |d| <= |scale| max|h - midlevel|.
// - Test points are at distances r i/m, i = 1..m, not jittered (as the
//   paper); an excursion of the ray into the field between two test points
//   is missed (the paper's "at most one intersection within R" assumption).
// - No section 4.3 distance threshold: a height field is one connected
//   surface, so a test point deep under it is occluded by it (the threshold
//   is for z-buffers, where a deep point can be behind a far foreground
//   object); other objects are found exactly by the macro ray.
// - The displacement direction is the shading normal facing the viewer: a
//   back face (a closed mesh seen from inside) sees its field mirrored.
// - A hit without a uv frame (no texture coordinates, or degenerate ones)
//   falls back to plain obscurance of the macro geometry with the
//   occlusion estimator: the same samples as `obscurance estimator=occlusion`,
//   bit for bit.
// - R must be finite (except for the exponential falloff, whose sampled r is
//   always finite): the test points must be at finite distances.
//
// Lobe controls (include/obscura/lobe.h, docs/math.md §11): `spread` narrows the cosine
// lobe about n_d to its cone; `near` ignores occluders closer than near - the
// macro ray's tnear, and test points at r i/m < near are skipped (a segment
// shorter than near is open). No `inside`: the hemisphere behind the
// displaced surface starts inside the height field, every sample closed.
//
// e0=bent: the bent normal is the sum of the open samples' directions (the
// cosine lobe about n_d), as obscurance's (docs/math.md §14.6).
//
// Sampling: the direction of sample k of a camera sample is the Sobol' pair
// kFirstIntegratorDim and r the 1D dimension kFirstIntegratorDim + 1, both
// indexed by sampleIndex * rays + k - the very numbers `obscurance` draws,
// so the two integrators share their noise (and the fallback is exact).
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <obscura/error.h>
#include <obscura/plugin.h>
#include "core/subd/subdivision.h"
#include <obscura/warp.h>
#include "integrators/displacement.h"
#include "integrators/falloff.h"

namespace obscura {
namespace {

class Containment final : public Integrator {
 public:
  Containment(Displacement field, Membership mu, int rays, int steps, bool transfer, LobeControls lobe)
      : field_(std::move(field)), mu_(mu), rays_(uint32_t(rays)), steps_(uint32_t(steps)), transfer_(transfer),
        lobe_(lobe) {}

  void estimate(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* W) const override {
    if (transfer_) return estimateTransfer(hits, ctx, W);
    OcclusionBatch& batch = ctx.occlusionBatch(hits.size() * rays_);
    for (const SurfaceHit& h : hits) {
      Local L;
      if (localFrame(h, ctx, L)) {
        pushContained(h, L, batch);
      } else {
        noFrame(h, ctx);
        pushPlain(h, batch);
      }
    }
    ctx.trace(batch);
    // A sample closed by containment was pushed inactive with tfar = -inf,
    // which Embree leaves as it is and occluded() reads as blocked; the
    // other inactive rays (tfar = 0) read as open.
    size_t r = 0;
    for (size_t i = 0; i < hits.size(); ++i) {
      uint32_t open = 0;
      Vec3 bent(0, 0, 0);
      for (uint32_t k = 0; k < rays_; ++k, ++r)
        if (!batch.occluded(r)) ++open, bent += batch.dir(r);
      const float v = sampleMean(double(open), rays_);
      W[i].num = Vec3(v, v, v);
      W[i].bent = bent;
    }
  }

 private:
  // A hit without a uv frame gets plain obscurance - silently wrong if the
  // user expected displacement detail there, so the first one of a render
  // is reported, naming its mesh (one relaxed load per such hit after that).
  void noFrame(const SurfaceHit& h, const IntegratorContext& ctx) const {
    if (warnedNoFrame_.load(std::memory_order_relaxed) || warnedNoFrame_.exchange(true)) return;
    Log::warn("containment: " + ctx.surfaceName(h) +
              " has no usable texture coordinates; it gets plain obscurance, without the height map's detail "
              "(so may other meshes without them)");
  }

  // What a hit's samples share: the height-field frame (docs/containment.md).
  struct Local {
    FieldFrame field;
    Frame lobe;  // about n_d
  };

  bool localFrame(const SurfaceHit& h, const IntegratorContext& ctx, Local& L) const {
    UvFrame f;
    if (!ctx.uvFrameAt(h, f) || !fieldFrame(field_, f, h.ns, L.field)) return false;
    L.lobe = Frame::fromNormal(L.field.nd);
    return true;
  }

  // Is x + w t outside the height field for every t = r i/m, i = 1..m? [AT 4]
  bool outside(const Local& L, Vec3 w, float r, double* su = nullptr, double* sv = nullptr) const {
    return outsideField(field_, L.field, w, r, steps_, lobe_.tnear, su, sv);
  }

  // The ambient transfer of eq. 9 [AT 4.1]: the same samples, each open one
  // adding 1 to the numerator and the denominator, each closed one adding
  // 1 - a~ to the denominator, a~ the albedo where it closed - the shaded
  // surface's at the first test point inside the field, or the macro
  // occluder's at the closest hit (so the macro rays find their hit here).
  // A direction below the macro plane without a uv frame is closed by the
  // surface itself, a~ its own albedo.
  void estimateTransfer(std::span<const SurfaceHit> hits, IntegratorContext& ctx, SampleEstimate* W) const {
    const size_t n = hits.size() * rays_;
    IntersectBatch& batch = ctx.intersectBatch(n);
    thread_local std::vector<Vec3> closedBy;  // a~ of samples the field (or the surface) closed; -1: none
    if (closedBy.size() < n) closedBy.resize(n);
    const Vec3 none(-1, -1, -1);
    size_t j = 0;
    for (const SurfaceHit& h : hits) {
      Local L;
      const bool frame = localFrame(h, ctx, L);
      if (!frame) noFrame(h, ctx);
      // Without a frame, obscurance's lobe about the shading normal.
      const Frame lobe = frame ? L.lobe : lobe_.at(h).frame;
      for (uint32_t k = 0; k < rays_; ++k, ++j) {
        const uint32_t index = h.sampleIndex * rays_ + k;
        const Sample2 s2 = Sampler::get2D(h.pixelKey, index, kFirstIntegratorDim);
        const Vec3 w = lobe.toWorld(squareToCosineCone(s2.u, s2.v, lobe_.sinThetaMax));
        const float r = mu_.segment(Sampler::get1D(h.pixelKey, index, kFirstIntegratorDim + 1));
        const Vec3 o = spawnOrigin(h, w);
        double su, sv;
        closedBy[j] = none;
        if (frame && !outside(L, w, r, &su, &sv)) {
          closedBy[j] = ctx.albedoAtUv(h, float(su), float(sv));
          batch.push(o, w, kInfinity, 0.0f, h);  // inactive
        } else if (!frame && intoSurface(h, w)) {
          closedBy[j] = h.albedo;
          batch.push(o, w, kInfinity, 0.0f, h);
        } else if (r > 0.0f && !intoSurface(h, w)) {
          batch.push(o, w, lobe_.tnear, r, h);
        } else {
          batch.push(o, w, kInfinity, 0.0f, h);  // empty segment, or below the macro plane: open
        }
      }
    }
    ctx.trace(batch);
    j = 0;
    for (size_t i = 0; i < hits.size(); ++i) {
      double num = 0, den[3] = {0, 0, 0};
      Vec3 bent(0, 0, 0);
      for (uint32_t k = 0; k < rays_; ++k, ++j) {
        const bool byField = closedBy[j].x >= 0.0f;
        if (!byField && !batch.hit(j)) {
          num += 1;
          for (double& d : den) d += 1;
          bent += batch.dir(j);
          continue;
        }
        const Vec3 a = byField ? closedBy[j] : ctx.albedoAt(batch, j);
        den[0] += 1.0 - double(a.x), den[1] += 1.0 - double(a.y), den[2] += 1.0 - double(a.z);
      }
      const float o = sampleMean(num, rays_);
      W[i].num = Vec3(o, o, o);
      W[i].den = Vec3(sampleMean(den[0], rays_), sampleMean(den[1], rays_), sampleMean(den[2], rays_));
      W[i].bent = bent;
    }
  }

  void pushContained(const SurfaceHit& h, const Local& L, OcclusionBatch& batch) const {
    for (uint32_t k = 0; k < rays_; ++k) {
      const uint32_t index = h.sampleIndex * rays_ + k;
      const Sample2 s = Sampler::get2D(h.pixelKey, index, kFirstIntegratorDim);
      const Vec3 w = L.lobe.toWorld(squareToCosineCone(s.u, s.v, lobe_.sinThetaMax));
      const float r = mu_.segment(Sampler::get1D(h.pixelKey, index, kFirstIntegratorDim + 1));
      const Vec3 o = spawnOrigin(h, w);
      if (!outside(L, w, r))
        batch.push(o, w, kInfinity, -kInfinity, h);  // closed by the height field
      else if (r > 0.0f && !intoSurface(h, w))
        batch.push(o, w, lobe_.tnear, r, h);  // the macro geometry decides (r < near: inactive, open)
      else  // empty segment, or below the macro plane: open
        batch.push(o, w, kInfinity, 0.0f, h);
    }
  }

  // No uv frame: obscurance's occlusion estimator on the macro geometry.
  void pushPlain(const SurfaceHit& h, OcclusionBatch& batch) const {
    const Lobe lobe = lobe_.at(h);
    for (uint32_t k = 0; k < rays_; ++k) {
      const Vec3 w = cosineDirection(h, lobe, rays_, k);
      const float r = mu_.segment(Sampler::get1D(h.pixelKey, h.sampleIndex * rays_ + k, kFirstIntegratorDim + 1));
      if (lobe.blocked(w))
        batch.push(spawnOrigin(h, w), w, kInfinity, -kInfinity, h);  // the surface itself, d = 0
      else if (r > 0.0f)
        batch.push(spawnOrigin(h, w), w, lobe_.tnear, r, h);
      else
        batch.push(spawnOrigin(h, w), w, kInfinity, 0.0f, h);
    }
  }

  Displacement field_;
  mutable std::atomic<bool> warnedNoFrame_{false};
  Membership mu_;
  uint32_t rays_, steps_;
  bool transfer_;
  LobeControls lobe_;  // spread and near; never inside
};

IntegratorDescriptor containmentDescriptor() {
  IntegratorDescriptor d;
  d.name = "containment";
  d.doc = "Obscurance of height-map displacement detail by containment tests on the undisplaced surface "
          "(height field for self-shadowing, any-hit rays for the macro geometry).";
  d.params = {
      {.name = "map", .type = ParamType::String, .defaultValue = "",
       .doc = "height map (PNG/EXR/TIFF..., first channel, bilinear, repeat, v = 0 at the bottom; glTF uvs read at (u, 1 - v)); required"},
      {.name = "scale", .type = ParamType::Float, .defaultValue = "0.1", .min = -1e30, .max = 1e30,
       .doc = "displacement: scene units per unit of height (as --displace-scale)"},
      {.name = "midlevel", .type = ParamType::Float, .defaultValue = "0.5", .min = -1e30, .max = 1e30,
       .doc = "displacement: the height that leaves the surface in place (as --displace-midlevel)"},
      {.name = "steps", .type = ParamType::Int, .defaultValue = "2", .min = 1, .max = 4096,
       .doc = "m: containment test points per sample, at r i/m (the paper uses 1 or 2)"},
      {.name = "albedo", .type = ParamType::Bool, .defaultValue = "false",
       .doc = "false: obscurance; true: the ambient transfer of eq. 9, W = Sum I / (n - Sum (1 - I) a~), a~ the "
              "albedo where a sample closed (the surface's at the field, the macro occluder's)"},
  };
  for (ParamSpec& s : membershipParams("samples (direction, distance) per camera sample")) {
    if (s.name == "estimator") continue;  // always the occlusion estimator: r ~ mu'(r)
    if (s.name == "distance")
      s.doc = "R (scene units): step/linear/sqrt radius, must be finite; exponential cut-off (inf: none); "
              "0: nothing occludes";
    d.params.push_back(std::move(s));
  }
  addLobeParams(d.params, LobeSet::SpreadNear);
  // What the controls mean here (no `inside`: behind the displaced surface
  // is inside its own height field).
  for (ParamSpec& s : d.params) {
    if (s.name == "spread") s.doc += "; the cone is about the displaced normal (containment has no `inside`)";
    if (s.name == "near") s.doc += "; containment test points nearer than it are skipped too";
  }
  d.needs = [](const ParamSet& p) { return IntegratorNeeds{.albedo = p.getBool("albedo")}; };
  d.bentNormal = true;  // SampleEstimate::bent: the open directions (e0=bent)
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    const std::string& map = p.getString("map");
    if (map.empty()) throw Error("integrator 'containment': parameter 'map' (a height map file) is required");
    const Membership mu = Membership::fromParams(p);
    if (mu.falloff() != Falloff::Exponential && std::isinf(mu.tfar()))
      throw Error("integrator 'containment': parameter 'distance' must be finite (and within float range) for "
                  "falloff " + p.getEnum("falloff") + ": the containment test needs a bounded neighbourhood R");
    return std::make_unique<Containment>(Displacement(map, p.getFloat("scale"), p.getFloat("midlevel")), mu,
                                         p.getInt("rays"), p.getInt("steps"), p.getBool("albedo"),
                                         lobeFromParams(p, p.getFloat("distance")));
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(containmentDescriptor)
}  // namespace obscura
