// `gtao`: ground-truth-based ambient occlusion from the depth buffer
// (Jimenez, Wu, Pesce, Jarabo 2016, "Practical Realtime Strategies for
// Accurate Indirect Occlusion" [GTAO]; docs/math.md §15).
//
// What it estimates: the cosine-weighted visibility within R,
//   v = (1/pi) Int_H V_R(w) cos+(theta_n) dw,
// the quantity `ao distance=R` estimates, under GTAO's height-field
// assumption (everything below a slice's horizon is occluded).
//
// Slices [GTAO §4]: v = -P/|P| is the direction to the camera. Directions
// are parametrized by slice planes through P containing v - rotated about v
// by phi in [0, pi) - and the signed angle theta from v within each slice,
// w = cos(theta) v + sin(theta) d_phi, dw = |sin theta| dtheta dphi. With
// n_p the normal projected into the slice, |n_p| its length and gamma its
// angle from v (towards d_phi), cos+(theta_n) = |n_p| cos+(theta - gamma),
// and the hemisphere about n is theta in [gamma - pi/2, gamma + pi/2] in
// every slice, so
//   v = (1/pi) Int_0^pi |n_p| Int_{h1}^{h2} cos(theta - gamma) |sin theta| dtheta dphi
// with h1 <= 0 <= h2 the horizons of the slice's two sides. The inner
// integral is the paper's, per side
//   A(h) = 1/4 (-cos(2h - gamma) + cos(gamma) + 2 h sin(gamma)),
// (Int_0^h for h >= 0, Int_h^0 with |sin| for h <= 0 - the same function).
//
// The estimator: phi_k = pi (k + u) / slices, u per pixel and layer (the
// interleave pattern or the pixel's stream), stratified and unbiased for the
// outer integral. Written as 1 minus the occluded part,
//   W = 1 - (1/slices) Sum_k |n_p| [A(gamma + pi/2) - A(h2) + A(gamma - pi/2) - A(h1)],
// which has the paper's expectation (the open slice's |n_p| (A(gamma +
// pi/2) + A(gamma - pi/2)) = |n_p| (cos gamma + gamma sin gamma) integrates
// to exactly 1 over phi: a control variate) and is exactly 1 where nothing
// occludes, in every slice, not only in the mean. Clamped to [0, 1].
//
// The horizons [GTAO Algorithm 1]: each side is searched along the camera
// rays in the slice plane (they are the slice's line on the screen),
// `steps` rays at angles alpha_j = alpha_max (j + xi) / steps from P's own
// ray, alpha_max = asin(min(1, R / |P|)) - exactly the rays that pass
// within R of P. Each ray's first surface S (depth buffer: the stored plane
// of the pixel it crosses; traced: the camera ray traced) counts when
// |S - P| <= R: cos h = max over them of (S - P).v / |S - P|, and the
// horizon is clamped to the tangent plane (h2 <= gamma + pi/2, h1 >=
// gamma - pi/2). Beyond R everything is open, as for `ao distance=R`.
// Where two consecutive samples lie on one plane (same normal, each on the
// other's plane) and the sphere |X - P| = R separates them, the point where
// the segment between them crosses the sphere is a candidate too: the
// surface between them is that plane, so the horizon of a planar occluder
// cut by R is exact instead of short by up to a step (the paper's march
// takes the last sample inside R). Different planes are not joined: the
// chord across a concave corner lies in the open.
//
// e0=bent: the cosine-weighted mean open direction (1/pi) Int V w cos+ dw,
// per slice |n_p| Int_{h1}^{h2} w cos(theta - gamma) |sin theta| dtheta in
// closed form (the paper's bent normal from the same horizons), per side
//   Iv(h) = (4 cos(gamma) - cos(3h - gamma) - 3 cos(h + gamma)) / 12      along v,
//   Id(h) = (6 sin(h - gamma) - sin(3h - gamma) - 3 sin(h + gamma) + 8 sin(gamma)) / 12   along d,
// written like W as the open hemisphere's (2/3) n minus the occluded arcs'.
//
// multibounce=on: GTAO's cubic fit (docs/math.md §6) applied per pixel to
// the converged W and the pixel's mean albedo (resolvePixel).
#include <algorithm>
#include <cmath>
#include <string>

#include <obscura/error.h>
#include "core/render/gbuffer.h"
#include <obscura/plugin.h>
#include "integrators/multibounce_mapping.h"
#include "integrators/screen_space/common.h"

namespace obscura {
namespace {

using namespace screen_space;

struct GtaoConfig {
  float R = 1.0f;
  int slices = 4;
  int steps = 8;
  bool multibounce = false;
  bool bent = false;  // e0=bent: write SampleEstimate::bent
  bool interleave = true;
  float filterDepth = 0.02f;
  DepthSource depth = DepthSource::GBuffer;
  int guardBand = -1;  // guard-band: pixels, -1 auto
};

// One slice of a pixel: its direction d (unit, perpendicular to v), and the
// projected normal's length and angle gamma from v (towards d).
struct Slice {
  Vec3 d;
  float npLength, gamma;
};

// The inner integral of one side up to horizon h [GTAO §4].
inline float arcIntegral(float h, float gamma, float cosG, float sinG) {
  return 0.25f * (-std::cos(2.0f * h - gamma) + cosG + 2.0f * h * sinG);
}

// The first moments of one side up to h, along v and along d (the file's head).
inline float momentV(float h, float gamma, float cosG) {
  return (4.0f * cosG - std::cos(3.0f * h - gamma) - 3.0f * std::cos(h + gamma)) * (1.0f / 12.0f);
}
inline float momentD(float h, float gamma, float sinG) {
  return (6.0f * std::sin(h - gamma) - std::sin(3.0f * h - gamma) - 3.0f * std::sin(h + gamma) + 8.0f * sinG) *
         (1.0f / 12.0f);
}

// Samples nearer P than this fraction of its distance from the camera are
// no horizon candidates: their direction from P is the float rounding of
// two points ~2^-24 |P| apart (a 1e-4 separation leaves ~1e-3 rad, and an
// error at the tangent plane costs its square: the integrand's cos(theta -
// gamma) vanishes there).
constexpr float kMinSeparation = 1e-4f;

class Gtao final : public ScreenSpaceIntegrator {
 public:
  explicit Gtao(const GtaoConfig& c) : c_(c) {}

  float interleaveFilterTolerance() const override { return c_.interleave ? c_.filterDepth : 0.0f; }
  // The horizon search reads within R of the pixel's point.
  GuardBand guardBand() const override { return {.reach = c_.R, .pixels = c_.guardBand}; }

  Vec3 resolvePixel(Vec3 W, Vec3 albedo) const override {
    if (!c_.multibounce) return W;
    return Vec3(float(gtaoMultiBounce(W.x, albedo.x)), float(gtaoMultiBounce(W.y, albedo.y)),
                float(gtaoMultiBounce(W.z, albedo.z)));
  }

  void estimateTile(const GBufferLayer& g, const PixelRect& tile, IntegratorContext& ctx,
                    SampleEstimate* out) const override {
    if (!(c_.R > 0.0f)) {  // R = 0: nothing occludes (the limit R -> 0+): W = 1
      for (int y = tile.y0; y < tile.y1; ++y)
        for (int x = tile.x0; x < tile.x1; ++x) {
          const size_t i = g.index(x, y);
          if (!g.covered(i)) continue;
          SampleEstimate& o = out[tile.offset(x, y)];
          o.num = Vec3(1, 1, 1);
          if (c_.bent) o.bent = g.view.vectorToWorld(g.normal[i] * (2.0f / 3.0f));
        }
      return;
    }
    const size_t perPixel = size_t(c_.slices) * 2U * size_t(c_.steps);
    DepthLookup look(c_.depth, size_t(kPixelRun) * perPixel, true, true);
    forEachPixelRun(
        g, tile, perPixel, ctx, look, out,
        [&](size_t i, int x, int y) { forEachRay(g, i, x, y, [&](Vec3 q) { look.push(g, q); }); },
        [&](size_t i, int x, int y, size_t at, SampleEstimate& o) { evaluate(g, i, x, y, look, at, o); });
  }

 private:
  // The slice k of pixel i (u: the pixel's rotation in this layer).
  Slice sliceOf(const Frame& about, Vec3 v, Vec3 n, int k, float u) const {
    const float phi = kPi * (float(k) + u) / float(c_.slices);
    Slice s;
    s.d = about.s * std::cos(phi) + about.t * std::sin(phi);
    // n's components in the slice: along d and along v (n.a drops out).
    const float nd = dot(n, s.d), nv = std::max(0.0f, dot(n, v));  // a normal facing away: edge-on
    s.npLength = std::sqrt(nd * nd + nv * nv);
    s.gamma = std::atan2(nd, nv);
    return s;
  }

  // The sample rays' jitter xi for slice k, side `side` (0, 1): the pixel's
  // second random number moved along the golden-ratio sequence.
  static float jitter(float u, int k, int side) {
    const float x = u + float(2 * k + side) * 0.6180339887f;
    return x - std::floor(x);
  }

  // Calls f(q) for the pixel's sample points in order (slice, side, step):
  // q on the camera ray at angle alpha_j from P's own, in the slice plane,
  // at P's distance from the camera.
  template <class F>
  void forEachRay(const GBufferLayer& g, size_t i, int x, int y, F&& f) const {
    const Vec3 P = g.position[i];
    const float dist = length(P);
    const Vec3 v = P * (-1.0f / dist);
    const Frame about = Frame::fromNormal(v);
    const Vec3 u = rotationSample(g, i, x, y, c_.interleave);
    const float alphaMax = std::asin(std::min(1.0f, c_.R / dist));
    for (int k = 0; k < c_.slices; ++k) {
      const Slice s = sliceOf(about, v, g.normal[i], k, u.x);
      for (int side = 0; side < 2; ++side) {
        const Vec3 across = s.d * (side == 0 ? dist : -dist);
        const float xi = jitter(u.y, k, side);
        for (int j = 0; j < c_.steps; ++j) {
          const float alpha = alphaMax * (float(j) + xi) / float(c_.steps);
          f(P * std::cos(alpha) + across * std::sin(alpha));
        }
      }
    }
  }

  // Whether the surfaces found at a and b (points, unit normals; zero: none)
  // are one plane: the same normal, and each point on the other's plane.
  static bool samePlane(Vec3 a, Vec3 na, Vec3 b, Vec3 nb) {
    if (!(dot(na, nb) > 1.0f - 1e-6f)) return false;
    const Vec3 e = b - a;
    const float tol = 1e-5f * length(e);
    return std::abs(dot(na, e)) <= tol && std::abs(dot(nb, e)) <= tol;
  }

  // The cosine (relative to v) of the point where the segment a -> b (a
  // and b relative to P) crosses the sphere of radius R about P, one of
  // them inside, the other outside. Double: R^2 overflows float from R ~ 1e19.
  static float crossingCos(Vec3 a, Vec3 b, Vec3 v, float R) {
    const double ax = a.x, ay = a.y, az = a.z;
    const double ex = double(b.x) - ax, ey = double(b.y) - ay, ez = double(b.z) - az;
    const double A = ex * ex + ey * ey + ez * ez;
    if (!(A > 0.0)) return -1.0f;
    const double B = ax * ex + ay * ey + az * ez, C = ax * ax + ay * ay + az * az - double(R) * double(R);
    const double root = std::sqrt(std::max(0.0, B * B - A * C));
    // a inside (C <= 0): the larger root; a outside: the smaller.
    const double t = std::clamp((C <= 0.0 ? -B + root : -B - root) / A, 0.0, 1.0);
    const double dv = (ax + t * ex) * v.x + (ay + t * ey) * v.y + (az + t * ez) * v.z;
    return float(std::clamp(dv / double(R), -1.0, 1.0));
  }

  // Pixel i's estimate from its looked-up rays (from index `at`, in
  // forEachRay's order).
  void evaluate(const GBufferLayer& g, size_t i, int x, int y, const DepthLookup& look, size_t at,
                SampleEstimate& o) const {
    const Vec3 P = g.position[i], n = g.normal[i];
    const float dist = length(P);
    const Vec3 v = P * (-1.0f / dist);
    const Frame about = Frame::fromNormal(v);
    const float u = rotationSample(g, i, x, y, c_.interleave).x;
    const float R = c_.R, minSep = kMinSeparation * dist;
    const bool crossings = R > minSep;  // else the crossing's direction is rounding
    float occluded = 0.0f;
    Vec3 bentOccluded(0, 0, 0);
    size_t m = at;
    for (int k = 0; k < c_.slices; ++k) {
      const Slice s = sliceOf(about, v, n, k, u);
      const float cosG = std::cos(s.gamma), sinG = std::sin(s.gamma);
      float occ = 0.0f, occV = 0.0f, occD = 0.0f;
      for (int side = 0; side < 2; ++side) {
        // The tangent plane's horizon on this side, gamma +- pi/2, as the
        // cosine from v: cos(gamma + pi/2) = -sin(gamma), cos(gamma - pi/2) = sin(gamma).
        float best = side == 0 ? -sinG : sinG;
        Vec3 prev(0, 0, 0), prevN(0, 0, 0);
        bool prevValid = false, prevInside = false;
        for (int j = 0; j < c_.steps; ++j, ++m) {
          const float z = look.z(m);
          if (!(z < kInfinity)) {
            prevValid = false;
            continue;
          }
          const Vec3 q = look.q(m);
          const Vec3 rel = q * (z / -q.z) - P;  // S - P
          const float r = length(rel);
          const bool inside = r <= R;
          if (inside && r > minSep) best = std::max(best, dot(rel, v) / r);
          const Vec3 nS = look.normal(m);
          if (crossings && prevValid && inside != prevInside && samePlane(prev, prevN, rel, nS))
            best = std::max(best, crossingCos(prev, rel, v, R));
          prev = rel, prevN = nS, prevValid = true, prevInside = inside;
        }
        // The horizon angle, signed (side 1 is theta < 0), and its limit.
        const float sign = side == 0 ? 1.0f : -1.0f;
        const float h = sign * std::acos(std::clamp(best, -1.0f, 1.0f));
        const float limit = s.gamma + sign * (0.5f * kPi);
        occ += std::max(0.0f, arcIntegral(limit, s.gamma, cosG, sinG) - arcIntegral(h, s.gamma, cosG, sinG));
        if (c_.bent) {
          occV += momentV(limit, s.gamma, cosG) - momentV(h, s.gamma, cosG);
          occD += momentD(limit, s.gamma, sinG) - momentD(h, s.gamma, sinG);
        }
      }
      occluded += s.npLength * occ;
      if (c_.bent) bentOccluded += (v * occV + s.d * occD) * s.npLength;
    }
    const float inv = 1.0f / float(c_.slices);
    const float w = std::clamp(1.0f - occluded * inv, 0.0f, 1.0f);
    o.num = Vec3(w, w, w);
    if (c_.bent) o.bent = g.view.vectorToWorld(n * (2.0f / 3.0f) - bentOccluded * inv);
  }

  GtaoConfig c_;
};

IntegratorDescriptor gtaoDescriptor() {
  IntegratorDescriptor d;
  d.name = "gtao";
  d.kind = IntegratorKind::ScreenSpace;
  d.doc = "Ground-truth-based AO from the depth buffer (screen-space): horizons within R searched along slices, "
          "the cosine-weighted visibility integrated over each slice in closed form (docs/math.md §15).";
  d.params = {
      {.name = "radius", .type = ParamType::Float, .defaultValue = "1", .min = 0.0, .max = 1e30,
       .doc = "R (scene units): surfaces farther than R from the point do not occlude; 0: nothing occludes (W = 1)"},
      {.name = "steps", .type = ParamType::Int, .defaultValue = "8", .min = 1, .max = 64,
       .doc = "horizon search: camera rays per side of a slice, spread over those passing within R of the point"},
      {.name = "multibounce", .type = ParamType::Enum, .defaultValue = "off", .choices = {"off", "on"},
       .doc = "on: GTAO's multi-bounce cubic applied per pixel to W and the pixel's albedo (docs/math.md §6)"},
  };
  for (ParamSpec p : sharedParams("slices per pixel and layer", 4, "on")) {
    if (p.name == "count") p.name = "slices", p.max = 32;
    d.params.push_back(std::move(p));
  }
  d.needs = [](const ParamSet& p) {
    const bool mb = p.getEnum("multibounce") == "on";
    return IntegratorNeeds{.albedo = mb, .pixelAlbedo = mb};
  };
  d.bentNormal = true;  // SampleEstimate::bent: the cosine-weighted open directions (e0=bent)
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    GtaoConfig c;
    c.R = float(p.getFloat("radius"));
    c.slices = p.getInt("slices");
    c.steps = p.getInt("steps");
    c.multibounce = p.getEnum("multibounce") == "on";
    c.bent = bentE0Requested(p);
    c.interleave = p.getEnum("interleave") == "on";
    c.filterDepth = float(p.getFloat("filter-depth"));
    c.depth = depthSourceFromParams(p);
    c.guardBand = p.getInt("guard-band");
    return std::make_unique<Gtao>(c);
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(gtaoDescriptor)
}  // namespace obscura
