// `vo`: volumetric obscurance from the depth buffer (Loos & Sloan; docs/math.md §8).
//
//   V(P) = (1/|X|) Int_X Occ(x) dx
//
// the fraction of the ball X of radius R about P (the half-ball above P's
// tangent plane with the normal clamp, VO §4.4) that is empty, read from the
// depth buffer: a point is occupied when it lies behind the surface the
// camera sees through it (depth(x) > z*), or, with the thickness model (VO
// §4.3), only within `thickness` behind it.
//
// - samples=point: x_k = P + R p_k, p_k the weighted ball set (VO §4.5,
//   sample_sets.h) under a uniformly random rotation per pixel, its radii
//   shifted per layer in the ball's volume measure (so the estimator is
//   unbiased); with the normal clamp points below the tangent plane are
//   reflected into it. V ~ Sum w_k [x_k empty].
// - samples=line: the ball's chords through the disk set, one per disk point,
//   each along the camera ray through the point P + R (x e1 + y e2) (e1, e2
//   span the plane perpendicular to the view direction of P). The depth
//   buffer gives, along that ray, where the surface lies, so the empty length
//   of the chord is exact for one surface (VO §4.1; the paper's lines run
//   parallel to the view axis, ours along the camera rays, which makes a
//   plane exact under perspective too). With the normal clamp the chord is
//   cut at the tangent plane. V ~ Sum a_k free_k / Sum a_k chord_k with a_k
//   = w_k / (2 sqrt(1 - x_k^2 - y_k^2)) cos(theta_k): each disk cell's share
//   of the ball per unit of chord length, times the cosine of its ray with
//   the disk's normal; free and chord lengths are weighed by the camera
//   rays' spread, ((dQ + s) / dQ)^2 at s along a chord whose disk point is
//   dQ from the camera, so that the chords measure the ball's volume under
//   perspective (dV = ((dQ + s) / dQ)^2 cos(theta) dA ds). The ratio makes
//   the plane exactly 1 (clamp), and 1/2 without the clamp to the disk set's
//   quadrature (plain lengths gave 1/2 + (3/8) R / d, d the camera's
//   distance).
// - samples=area (VO §4.2; docs/math.md §8 "Area samples"): the chords of
//   line samples against a depth distribution over each disk cell's
//   footprint instead of one depth: the moments (coverage, mean, variance
//   of the depths at the pixel centres, level 0 pre-blurred by a Gaussian
//   of sigma 1 pixel with prefilter=on; core/render/gbuffer.cpp) read
//   trilinearly at level log2(footprint span), modelled as a box of the
//   same mean and variance, mu +- sqrt(3) sigma (a uniform distribution on
//   [a, b] has sigma = (b - a) / sqrt(12)), the empty probability falling
//   linearly across it. With the normal clamp the distribution is that of
//   delta = z - p, the surface's depth relative to the tangent plane p over
//   the footprint (where the plane ends the chord): each ray of the
//   footprint ends at its own clamp, free = (p - s0) + min(delta, 0), so the
//   plane's own ramp across the footprint is no spread. Per texel j: delta_j
//   = mu_j - p(c_j), sd_j = |sigma_j - sigma_p,j| (the surface varying with
//   the plane within a texel; sigma_p,j the plane's spread over the texel's
//   pixel centres, to 4th order in |grad p / p| x their offsets), mixed
//   between texels with the plane's curvature over each texel (kappa_j, the
//   same order) taken out of the spread. An open plane at any angle:
//   delta_j = kappa_j >= 0 (a plane's depth is convex along image lines),
//   the box behind the clamp, W = 1 (the box about the absolute depth gave
//   0.91 on a grazing floor).
// - radius2 > 0: V computed at both radii with the same samples, combined by
//   product or min (VO §6).
//
// e0=bent (docs/math.md §14.6): the bent normal is the first moment of the
// empty part of the ball about P, Int_{X empty} (x - P) dx, estimated with
// the same samples - points: Sum w_k [x_k empty] (x_k - P); lines and areas:
// Sum a_k cos(theta_k) Int_{free part of chord k} (Q0 + s u - P) ds, the
// free part the chord before the surface (and, with the thickness model,
// after surface + T), an area sample's surface at its filtered mean depth
// and its uncovered fraction free; lengths not weighed by the camera rays'
// spread (the direction is what E0 reads). From the first radius only. An
// open plane gives the normal (the half-ball's centroid), a crease the
// bisector of the open quarter ball.
//
// VO equals obscurance with mu(d) = min(d/R, 1)^3 under *uniform* direction
// weighting when every line crosses one surface: the empty length of a chord
// through P in direction w is min(d(w), R) (VO §3).
//
// kernel=quadratic (VO §4; docs/math.md §8): V = Int rho Occ dx / Int rho dx
// with rho = 1 - |x - P|^2 / R^2, quadratic in x, so along a chord Q0 + s u
// it is a quadratic in s and the chord's weight rho (1 + s/dQ)^2 a quartic
// (times the area samples' ramp, a quintic): 3-point Gauss-Legendre is
// exact for both (ChordWeight). Points on the (half-)ball draw their radii
// from the kernel-weighted volume, M(r) = (5 r^3 - 3 r^5) / 2 = mu_V, in
// place of r^3 (radialSampled); membership mu_V(d) = (5 e^3 - 3 e^5) / 2,
// e = min(d/R, 1).
//
// normal=tangent-sphere (VO §4.4's cited variant): the ball of radius R/2
// about C = P + n R/2, tangent at P; the same sets scaled by R/2 about C
// (the lines' disk through C, perpendicular to P's view direction). Its
// extent from P along w is R cos(theta): a cos^3-weighted obscurance whose
// reach shrinks as R cos(theta). The kernel stays about P; points weigh
// by it as a ratio there (rho is not radial about C).
//
// blur=r (VO §2, §5): the core's depth-aware bilateral blur of each layer's
// estimates (ScreenSpaceIntegrator::blur, core/render/gbuffer.h
// bilateralBlur), its range test's tolerance filter-depth.
#include <algorithm>
#include <cmath>
#include <string>

#include <obscura/error.h>
#include "core/render/gbuffer.h"
#include <obscura/plugin.h>
#include "integrators/screen_space/common.h"
#include "integrators/screen_space/sample_sets.h"

namespace obscura {
namespace {

using namespace screen_space;

// The pre-blur's 4th moment per axis, Sum w_i i^4 / Sum w_i (pixels^4; its
// variance: momentBlurVariance).
constexpr float momentBlurFourthMoment() {
  float w = 0.0f, m = 0.0f;
  for (int i = -kMomentBlurRadius; i <= kMomentBlurRadius; ++i) {
    w += kMomentBlurWeights[i + kMomentBlurRadius];
    m += kMomentBlurWeights[i + kMomentBlurRadius] * float(i * i * i * i);
  }
  return m / w;
}

enum class VoSamples { Point, Line, Area };
enum class Combine { Product, Min };
// The kernel rho of VO §4 (docs/math.md §8): constant, or 1 - (r/R)^2.
enum class Kernel { Constant, Quadratic };
// The region integrated over: the whole ball, the half-ball above the
// tangent plane (the normal clamp, VO §4.4), or the ball of radius R/2
// tangent to the surface at P (the variant VO §4.4 cites).
enum class Domain { Ball, HalfBall, TangentSphere };

struct VoConfig {
  VoSamples samples = VoSamples::Line;
  float R = 1.0f, R2 = 0.0f;
  Combine combine = Combine::Product;
  int count = 16;
  bool centre = true;
  bool optimisedSets = false;  // sets=optimised: VO §4.5's optimiser (sample_sets.h)
  Domain domain = Domain::HalfBall;
  Kernel kernel = Kernel::Constant;
  bool bent = false;  // e0=bent: write SampleEstimate::bent
  float thickness = 0.0f;  // 0 = off (every point behind the surface is occupied)
  bool interleave = false;
  float filterDepth = 0.02f;
  DepthSource depth = DepthSource::GBuffer;
  int guardBand = -1;  // guard-band: pixels, -1 auto
  int blur = 0;        // the bilateral blur's radius (pixels), 0 = off
  bool prefilter = true;  // area samples: the moments' Gaussian pre-blur (VO §4.2)
};

class VolumetricObscurance final : public ScreenSpaceIntegrator {
 public:
  explicit VolumetricObscurance(const VoConfig& c) : c_(c) {
    if (c_.samples == VoSamples::Point) {
      const BallSet b = c_.optimisedSets ? optimisedBallSet(c_.count) : ballSet(c_.count);
      for (int k = 0; k < c_.count; ++k) px_.push_back(b.p[k].x), py_.push_back(b.p[k].y), pz_.push_back(b.p[k].z);
      w_ = b.w;
      for (int k = 0; k < c_.count; ++k) {
        rad_.push_back(length(b.p[k]));
        cube_.push_back(radialSampled() ? kernelVolume(rad_[k]) : rad_[k] * rad_[k] * rad_[k]);
      }
    } else {
      const DiskSet d = c_.optimisedSets ? optimisedDiskSet(c_.count, c_.centre) : diskSet(c_.count, c_.centre);
      px_ = d.x, py_ = d.y;
      for (int k = 0; k < c_.count; ++k) {
        const float zs = std::sqrt(std::max(0.0f, 1.0f - d.x[k] * d.x[k] - d.y[k] * d.y[k]));
        w_.push_back(zs > 0.0f ? d.w[k] / (2.0f * zs) : 0.0f);  // a disk point on the rim has no chord
      }
    }
  }

  float interleaveFilterTolerance() const override { return c_.interleave ? c_.filterDepth : 0.0f; }
  // VO §2, §5: an edge-aware blur after the estimate (the core's bilateralBlur).
  Blur blur() const override { return {.radius = c_.blur, .tolerance = c_.filterDepth}; }
  bool needsDepthMoments() const override { return c_.samples == VoSamples::Area; }
  bool prefilterDepthMoments() const override { return c_.samples == VoSamples::Area && c_.prefilter; }
  // Reads reach R (or R2) from the pixel's point.
  GuardBand guardBand() const override { return {.reach = std::max(c_.R, c_.R2), .pixels = c_.guardBand}; }

  void estimateTile(const GBufferLayer& g, const PixelRect& tile, IntegratorContext& ctx, SampleEstimate* out) const override {
    const int radii = c_.R2 > 0.0f ? 2 : 1;
    const size_t perPixel = size_t(c_.count) * size_t(radii);
    // Points: the radii shifted per layer in the ball's volume measure
    // (u = |p|^3 -> frac(u + shift), Cranley-Patterson), so each point's
    // radius, like its direction, is distributed as the ball's: the mean
    // over layers is the ball integral for any set whose weights sum to 1.
    // As a factor on p_k, once per call.
    float radial[kMaxCount];
    if (c_.samples == VoSamples::Point) {
      const float shift = Sampler::get1D(g.imageKey, g.sampleIndex, kFirstIntegratorDim + 2);
      for (int k = 0; k < c_.count; ++k) {
        float u = cube_[k] + shift;
        u -= u >= 1.0f ? 1.0f : 0.0f;
        radial[k] = rad_[k] > 0.0f ? (radialSampled() ? kernelRadius(u) : std::cbrt(u)) / rad_[k] : 0.0f;
      }
    }
    const NormalRotations rotations(g, c_.interleave && c_.samples != VoSamples::Point);
    // The radii's values combined (VO §6), clamped to [0, 1].
    const auto combine = [&](float v, float v2) {
      if (radii == 2) v = c_.combine == Combine::Product ? v * v2 : std::min(v, v2);
      v = std::clamp(v, 0.0f, 1.0f);
      return Vec3(v, v, v);
    };
    // The tangent sphere's centre depends on the pixel's normal and the
    // radius, which the pipelined paths' shared offsets cannot carry: it
    // takes the general path below.
    const bool pipelined = c_.depth == DepthSource::GBuffer && c_.domain != Domain::TangentSphere;
    if (c_.samples == VoSamples::Point && pipelined) {
      // Points read from the z-buffer: each pixel's points projected in one
      // vectorized pass, then one depth read per point.
      alignas(32) float ox[2 * kMaxCount], oy[2 * kMaxCount], oz[2 * kMaxCount];
      for (int r = 0, m = 0; r < radii; ++r)
        for (int k = 0; k < c_.count; ++k, ++m) {
          const float scale = radial[k] * (r == 0 ? c_.R : c_.R2);
          ox[m] = px_[k] * scale, oy[m] = py_[k] * scale, oz[m] = pz_[k] * scale;
        }
      PixelPoints pts(g, perPixel);
      forEachPixelPipelined(
          g, tile, c_.interleave,
          [&](size_t i, int x, int y, int b) {
            pts.project(b, x, y, g.position[i], pixelFrame(g, i, x, y, rotations),
                        c_.domain == Domain::HalfBall ? g.normal[i] : Vec3(0, 0, 0), ox, oy, oz);
            prefetchAt(g.depthSlack, pts.pixels(b), perPixel);
          },
          [&](size_t, int x, int y, int b) {
            const Vec3 P = pts.P[b], clamp = pts.c[b];
            const Frame& f = pts.f[b];
            const float* depth = pts.depth(b);
            const uint32_t* pixel = pts.pixels(b);
            float v[2] = {0.0f, 0.0f};
            Vec3 bent(0, 0, 0);
            for (int r = 0, m = 0; r < radii; ++r)
              for (int k = 0; k < c_.count; ++k, ++m) {
                const auto offset = [&] {  // the point again, for the exact read near a surface
                  Vec3 o = f.s * ox[m] + f.t * oy[m] + f.n * oz[m];
                  const float on = dot(o, clamp);
                  if (on < 0.0f) o = o - clamp * (2.0f * on);
                  return o;
                };
                const float w = w_[k];  // the quadratic kernel is in the radii (radialSampled)
                // Behind the camera or outside the read window (depth -1): no occluder known.
                if (!(depth[m] > 0.0f) ||
                    !occupied(depth[m], zStarAt(g, pixel[m], depth[m], false, [&] { return P + offset(); }),
                              c_.thickness)) {
                  v[r] += w;
                  if (c_.bent && r == 0) bent += offset() * w;
                }
              }
            SampleEstimate& o = out[tile.offset(x, y)];
            o.num = combine(v[0], v[1]);
            if (c_.bent) o.bent = g.view.vectorToWorld(bent);
          });
      return;
    }
    if (c_.samples == VoSamples::Line && pipelined) {
      // Lines read from the z-buffer: each pixel's disk points projected in
      // one vectorized pass, their (depth, slack) and planes prefetched
      // pixels ahead, then the exact read (the plane) per chord.
      alignas(32) float ox[2 * kMaxCount], oy[2 * kMaxCount], oz[2 * kMaxCount];
      for (int r = 0, m = 0; r < radii; ++r)
        for (int k = 0; k < c_.count; ++k, ++m) {
          const float R = r == 0 ? c_.R : c_.R2;
          ox[m] = px_[k] * R, oy[m] = py_[k] * R, oz[m] = 0.0f;
        }
      PixelPoints pts(g, perPixel);
      forEachPixelPipelined(
          g, tile, c_.interleave,
          [&](size_t i, int x, int y, int b) {
            pts.project(b, x, y, g.position[i], pixelFrame(g, i, x, y, rotations), Vec3(0, 0, 0), ox, oy, oz);
            prefetchAt(g.plane, pts.pixels(b), perPixel);  // the exact read: the plane only
          },
          [&](size_t i, int x, int y, int b) {
            const Vec3 P = pts.P[b];
            const Frame& f = pts.f[b];
            const float* depth = pts.depth(b);
            const uint32_t* pixel = pts.pixels(b);
            const auto radius = [&](int first, float R, Vec3* bent) {
              const auto q = [&](int k) { return P + f.s * ox[first + k] + f.t * oy[first + k]; };
              return evaluate(
                  g, i, q,
                  [&](int k) {
                    // Outside the read window or behind the camera (depth -1): no occluder known.
                    const float d = depth[first + k];
                    if (!(d > 0.0f)) return kInfinity;
                    return zStarAt(g, pixel[first + k], d, true, [&] { return q(k); });
                  },
                  R, bent);
            };
            SampleEstimate& o = out[tile.offset(x, y)];
            Vec3 bent(0, 0, 0);
            const float v = radius(0, c_.R, c_.bent ? &bent : nullptr);
            o.num = combine(v, radii == 2 ? radius(c_.count, c_.R2, nullptr) : 1.0f);
            if (c_.bent) o.bent = g.view.vectorToWorld(bent);
          });
      return;
    }
    DepthLookup look(c_.samples == VoSamples::Area ? DepthSource::None : c_.depth, size_t(kPixelRun) * perPixel,
                     c_.samples == VoSamples::Line);
    forEachPixelRun(
        g, tile, perPixel, ctx, look, out,
        [&](size_t i, int x, int y) { pushPoints(g, i, x, y, radii, radial, rotations, look); },
        [&](size_t i, int, int, size_t at, SampleEstimate& o) {
          const auto radius = [&](size_t first, float R, Vec3* bent) {
            return evaluate(
                g, i, [&](int k) { return look.q(first + size_t(k)); }, [&](int k) { return look.z(first + size_t(k)); },
                R, bent);
          };
          Vec3 bent(0, 0, 0);
          const float v = radius(at, c_.R, c_.bent ? &bent : nullptr);
          o.num = combine(v, radii == 2 ? radius(at + size_t(c_.count), c_.R2, nullptr) : 1.0f);
          if (c_.bent) o.bent = g.view.vectorToWorld(bent);
        });
  }

 private:
  // Points: a uniformly random rotation of the ball set (every point's
  // direction uniform; with the radial shift, the estimator is unbiased).
  // Lines: the disk
  // perpendicular to the view direction of P, rotated about it (VO §4.5).
  Frame pixelFrame(const GBufferLayer& g, size_t i, int x, int y, const NormalRotations& rotations) const {
    if (c_.samples == VoSamples::Point) return uniformRotation(rotationSample(g, i, x, y, c_.interleave));
    return rotations.rotate(g, i, x, y, Frame::fromNormal(normalize(-g.position[i])));
  }

  // Points: x_k. Lines: the point where the chord's camera ray crosses the
  // disk plane, Q0 = P + R (x e1 + y e2).
  void pushPoints(const GBufferLayer& g, size_t i, int x, int y, int radii, const float* radial,
                  const NormalRotations& rotations, DepthLookup& look) const {
    const Vec3 P = g.position[i], n = g.normal[i];
    const Frame f = pixelFrame(g, i, x, y, rotations);
    for (int r = 0; r < radii; ++r) {
      // The set's ball: about P with radius R, or the tangent sphere's, about P + n R/2 with radius R/2.
      const float R = r == 0 ? c_.R : c_.R2;
      const float Rs = c_.domain == Domain::TangentSphere ? 0.5f * R : R;
      const Vec3 C = c_.domain == Domain::TangentSphere ? P + n * Rs : P;
      for (int k = 0; k < c_.count; ++k) {
        if (c_.samples == VoSamples::Point) {
          Vec3 p = (f.s * px_[k] + f.t * py_[k] + f.n * pz_[k]) * radial[k];
          const float pn = dot(p, n);
          if (c_.domain == Domain::HalfBall && pn < 0.0f) p = p - n * (2.0f * pn);  // reflected into the half-ball (VO §4.4)
          look.push(g, C + p * Rs);
        } else {
          look.push(g, C + (f.s * px_[k] + f.t * py_[k]) * Rs);
        }
      }
    }
  }

  // The quadratic kernel rho at distance r R from P (docs/math.md §8).
  static float kernelAt(float r) { return std::max(0.0f, 1.0f - r * r); }

  // Points on the (half-)ball with the quadratic kernel: the radii are
  // drawn from the kernel-weighted volume, density ~ rho(r) r^2, instead of
  // weighing the points - the per-layer shift moves u = M(|p_k|) to
  // frac(u + shift) and the radius is M^-1(u), M(r) = (5 r^3 - 3 r^5) / 2
  // the kernel's share of the ball within r (mu_V, docs/math.md §8; r^3 for
  // the constant kernel). Each point is then distributed as rho dx / Int rho
  // and Sum w_k Occ_k is unbiased for V with weights summing to 1: an open
  // plane stays exactly 1 and no ratio bias enters.
  bool radialSampled() const { return c_.kernel == Kernel::Quadratic && c_.domain != Domain::TangentSphere; }
  static float kernelVolume(float r) { return 0.5f * r * r * r * (5.0f - 3.0f * r * r); }
  // M^-1(u) by bisection in double (M increases on [0, 1]; 40 halvings,
  // below float's resolution), once per point and call.
  static float kernelRadius(float u) {
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < 40; ++it) {
      const double r = 0.5 * (lo + hi);
      (0.5 * r * r * r * (5.0 - 3.0 * r * r) < double(u) ? lo : hi) = r;
    }
    return float(0.5 * (lo + hi));
  }

  bool occupied(float depthQ, float zStar, float thick) const {
    const float behind = depthQ - zStar;
    return behind > kDepthBias * zStar && (thick <= 0.0f || behind < thick);
  }

  // V at pixel i for radius R from its points k = 0..count-1: q(k) the
  // point (points) or the chord's disk point Q0 (lines, areas), zStar(k)
  // the depth the lookup found on the camera ray through it. bent: if not
  // null, the empty volume's first moment about P is added to it (view
  // space; see the head of the file).
  template <class Point, class ZStar>
  float evaluate(const GBufferLayer& g, size_t i, Point&& q, ZStar&& zStar, float R, Vec3* bent) const {
    const Vec3 P = g.position[i];
    if (c_.samples == VoSamples::Point) {
      // The quadratic kernel about P over the tangent sphere, which is not
      // radial about the sphere's centre: a weight rho(|x_k - P| / R) per
      // point, normalised by the sample's own sum (a ratio: a plane stays
      // exactly 1; biased by O(1/count) elsewhere, docs/math.md §8). On the
      // (half-)ball the kernel is in the radii instead (radialSampled).
      const bool weighed = c_.kernel == Kernel::Quadratic && !radialSampled();
      float v = 0.0f, sum = 0.0f;
      for (int k = 0; k < c_.count; ++k) {
        const float w = weighed ? w_[k] * kernelAt(length(q(k) - P) / R) : w_[k];
        sum += w;
        if (!occupied(-q(k).z, zStar(k), c_.thickness)) {
          v += w;
          if (bent) *bent += (q(k) - P) * w;
        }
      }
      if (weighed) v = sum > 0.0f ? v / sum : 1.0f;
      return v;
    }
    // Area samples: the continuous mip level whose texel matches a disk
    // cell's footprint - a cell of the n-point set covers ~1/n of the disk,
    // radius R / sqrt(n), which spans 2 R / sqrt(n) / (pixel size at P's
    // depth) pixels: level log2(span) (VO §4.2: one log per pixel, the
    // cells' share precomputed), read trilinearly (depthModel); from -1
    // (half a pixel or less: the pixel's own texel) to the coarsest.
    float level = 0.0f;
    if (c_.samples == VoSamples::Area) {
      const float pixelSize = 2.0f * g.view.tanHalfY * g.depth[i] / g.view.height;
      const float span = 2.0f * (c_.domain == Domain::TangentSphere ? 0.5f * R : R) / std::sqrt(float(c_.count)) / pixelSize;
      level = std::clamp(std::log2(span), -1.0f, float(int(g.moments.size()) - 1));
      if (std::isnan(level)) level = -1.0f;  // a degenerate span: the pixel's own texel
    }
    // The chords in float where that is safe, in double where it is not:
    // with R up to 1e30 the chord's lengths, |Q0|^2 and the spread's weight
    // ((dQ + s) / dQ)^2 - large where the ball holds the camera, dQ << R -
    // overflow float (NaN from inf / inf in every covered pixel for R in
    // 1e14 .. 1e19, issue 36). With R < |P| / 2 the camera is outside the
    // ball, dQ > |P| / 2, the weight < 4 and every length < 2R: float holds
    // for R < 1e18. Float keeps the common case fast (double cost the line
    // samples 18 % of the pass on scenes/default.gltf).
    if (R < 0.5f * length(P) && R < 1e18f) return chords<float>(g, i, q, zStar, R, level, bent);
    return chords<double>(g, i, q, zStar, R, level, bent);
  }

  // evaluate's chords (lines, areas) with scalar T.
  template <class T, class Point, class ZStar>
  float chords(const GBufferLayer& g, size_t i, Point&& q, ZStar&& zStar, float R, float level, Vec3* bent) const {
    using V = V3<T>;
    const Vec3 P = g.position[i], n = g.normal[i];
    const ReadWindow window = readWindow(g, int(i % size_t(g.width)), int(i / size_t(g.width)));
    double freeSum = 0.0, chordSum = 0.0;  // over the chords: double for either T
    const V Pd(P), nd(n);
    // The sphere the chords cross: about P with radius R, or the tangent
    // sphere about C = P + n R/2 with radius R/2 (its disk points Q0 lie in
    // the plane through C perpendicular to P's view direction).
    const bool tangent = c_.domain == Domain::TangentSphere;
    const T Rs = tangent ? T(0.5) * T(R) : T(R);
    const V C = tangent ? Pd + nd * Rs : Pd;
    // The disk plane's distance from the camera along its normal P/|P|.
    const T lengthP = tangent ? Pd.dot(C) / Pd.length() : Pd.length();
    // bent: the moments relative to R^2 (only their direction is read), so
    // that they stay finite in float at every R.
    const T invR = T(1) / T(R);
    for (int k = 0; k < c_.count; ++k) {
      const V Q0(q(k));
      const T dQ = Q0.length();
      if (!(dQ > T(0)) || w_[k] == 0.0f) continue;
      const T invDQ = T(1) / dQ;
      const V u = Q0 * invDQ;
      // Chord of the sphere |Q0 + s u - C| = Rs along the ray: s^2 + 2 b s + c = 0.
      const V o = Q0 - Pd;
      const V oC = tangent ? Q0 - C : o;
      const T b = u.dot(oC), c = oC.dot(oC) - Rs * Rs;
      const T disc = b * b - c;
      if (!(disc > T(0))) continue;
      const T root = std::sqrt(disc);
      T s0 = -b - root, s1 = -b + root;
      if (c_.domain == Domain::HalfBall) {  // keep the side of the tangent plane n.(X - P) >= 0
        const T nu = nd.dot(u), no = nd.dot(o);
        if (nu < T(0))
          s1 = std::min(s1, -no / nu);
        else if (nu > T(0))
          s0 = std::max(s0, -no / nu);
        else if (no < T(0))
          s1 = s0;  // parallel to the plane, below it
      }
      if (!(s1 > s0)) continue;
      // The volume the chord stands for: the rays through a disk cell fan
      // out from the camera, so at s along the chord the cross-section is
      // the cell's area x cos(theta) x ((dQ + s) / dQ)^2, theta the angle
      // between the ray and the disk's normal (the view direction of P):
      // cos = |P| / dQ. Lengths are weighed by that (weightedLength); with
      // plain lengths a plane without the clamp reads 1/2 + (3/8) R / d.
      const T cosTheta = lengthP * invDQ;
      // With the quadratic kernel the element is weighed by rho(|X - P| / R) too (docs/math.md §8).
      const ChordWeight<T> density{invDQ, o * invR, u * invR};
      const bool quadratic = c_.kernel == Kernel::Quadratic;
      const T chord = quadratic ? density.integral(s0, s1) : weightedLength(s0, s1, invDQ);
      // Depth along a camera ray is proportional to distance along it: a
      // depth z sits at s = z |Q0| / depth(Q0) - |Q0| on the chord's line.
      const T perDepth = dQ / -Q0.z;
      float covered = 1.0f, zMean = c_.samples == VoSamples::Area ? kInfinity : zStar(k), zSigma = 0.0f;
      if (c_.samples == VoSamples::Area) {
        // Where the tangent plane ends the chord (the ray meets it going
        // in, n.u < 0) the spread is taken relative to that plane
        // (depthModel): the footprint's rays each end at their own clamp.
        const bool relative = c_.domain == Domain::HalfBall && nd.dot(u) < T(0);
        depthModel(g, level, q(k), window, relative ? &n : nullptr, dot(n, P), c_.prefilter, covered, zMean, zSigma);
      }
      T freeLen = chord;
      // The first moment of the segment [a, b] of the chord about P (bent), / R^2.
      const auto moment = [&](T a, T b) {
        return b > a ? (o * invR + u * (T(0.5) * (a + b) * invR)) * ((b - a) * invR) : V();
      };
      V freeMoment = bent ? moment(s0, s1) : V();
      if (covered > 0.0f && zMean < kInfinity) {
        const T bias = T(kDepthBias) * zMean * perDepth;
        const T surface = zMean * perDepth - dQ + bias;
        // The box of the depth model: a uniform distribution with the
        // moments' standard deviation sigma spans mu +- sqrt(3) sigma
        // (docs/math.md §8; VO §4.2's mu +- sigma has a third less spread).
        const T halfWidth = T(kSqrt3) * zSigma * perDepth;
        const T lo = surface - halfWidth, hi = surface + halfWidth;
        const auto freeFrom = [&](T l, T h) {
          return quadratic ? density.freeAlong(s0, s1, l, h) : freeAlong(s0, s1, l, h, invDQ);
        };
        T f = freeFrom(lo, hi);
        const T t = c_.thickness * perDepth;
        if (c_.thickness > 0.0f)  // VO §4.3: the occupancy shifted back by the thickness, complemented, added
          f += chord - freeFrom(lo + t, hi + t);
        freeLen = (T(1) - covered) * chord + covered * std::clamp(f, T(0), chord);
        if (bent) {
          V m = moment(s0, std::min(s1, surface));
          if (c_.thickness > 0.0f) m = m + moment(std::max(s0, surface + t), s1);
          freeMoment = freeMoment * (T(1) - covered) + m * T(covered);
        }
      }
      const T weight = T(w_[k]) * cosTheta;
      freeSum += double(weight) * double(freeLen);
      chordSum += double(weight) * double(chord);
      if (bent) *bent += (freeMoment * weight).toFloat();
    }
    return chordSum > 0.0 ? float(freeSum / chordSum) : 1.0f;
  }

  // A 3-vector of T for the chord geometry (chords).
  template <class T>
  struct V3 {
    T x = 0, y = 0, z = 0;
    V3() = default;
    V3(T a, T b, T c) : x(a), y(b), z(c) {}
    explicit V3(Vec3 v) : x(v.x), y(v.y), z(v.z) {}
    V3 operator+(const V3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    V3 operator-(const V3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    V3 operator*(T s) const { return {x * s, y * s, z * s}; }
    T dot(const V3& o) const { return x * o.x + y * o.y + z * o.z; }
    T length() const { return std::sqrt(dot(*this)); }
    Vec3 toFloat() const { return Vec3(float(x), float(y), float(z)); }
  };

  // The weight of the volume element at s along a chord whose disk point
  // is dQ = 1 / invDQ from the camera, (1 + s / dQ)^2, integrated over [a, b]: exact
  // for the quadratic as (b - a)(A^2 + AB + B^2)/3, A and B its square
  // roots at the ends - no difference of cubes, which would cancel when
  // the chord is short against dQ.
  template <class T>
  static T weightedLength(T a, T b, T invDQ) {
    const T A = T(1) + a * invDQ, B = T(1) + b * invDQ;
    return (b - a) * (A * A + A * B + B * B) * (T(1) / T(3));
  }

  // The weighted empty length of the chord [s0, s1] when the surface's
  // depth along it is distributed uniformly on [lo, hi] (VO §4.2's box
  // model: empty with probability 1 before lo, 0 after hi, linear
  // between); lo = hi is one surface at lo (line samples). The ramp's
  // integrand (hi - s)/(hi - lo) (1 + s/dQ)^2 is a cubic: Simpson's rule is
  // exact for it.
  template <class T>
  static T freeAlong(T s0, T s1, T lo, T hi, T invDQ) {
    T f = 0;
    const T e = std::min(s1, lo);
    if (e > s0) f += weightedLength(s0, e, invDQ);
    const T a = std::max(s0, lo), b = std::min(s1, hi);
    if (b > a && hi > lo) {
      const auto g = [&](T s) {
        const T w = T(1) + s * invDQ;
        return (hi - s) / (hi - lo) * w * w;
      };
      f += (b - a) * (T(1) / T(6)) * (g(a) + T(4) * g(T(0.5) * (a + b)) + g(b));
    }
    return f;
  }

  // The quadratic kernel's chord weight (docs/math.md §8): at s along a
  // chord, the fan's (1 + s/dQ)^2 times rho = 1 - |X - P|^2 / R^2, X - P =
  // o + s u (oR, uR: o / R, u / R). Both factors are quadratics in s, so
  // the weight is a quartic and, with the box model's linear ramp, a
  // quintic: 3-point Gauss-Legendre integrates both exactly, with positive
  // weights on positive values (no cancellation).
  template <class T>
  struct ChordWeight {
    T invDQ;
    V3<T> oR, uR;
    T operator()(T s) const {
      const T w = T(1) + s * invDQ;
      const V3<T> x = oR + uR * s;
      return w * w * std::max(T(0), T(1) - x.dot(x));  // rho >= 0 in the ball; max() for rounding at its rim
    }
    // Int_a^b f(s) ds by 3-point Gauss-Legendre (exact to degree 5).
    template <class F>
    static T gauss3(T a, T b, F&& f) {
      const T m = T(0.5) * (a + b), h = T(0.5) * (b - a), d = h * T(0.7745966692414834);  // sqrt(3/5)
      return h * (T(5.0 / 9.0) * (f(m - d) + f(m + d)) + T(8.0 / 9.0) * f(m));
    }
    T integral(T a, T b) const { return b > a ? gauss3(a, b, *this) : T(0); }
    // freeAlong's box model under this weight.
    T freeAlong(T s0, T s1, T lo, T hi) const {
      T f = integral(s0, std::min(s1, lo));
      const T a = std::max(s0, lo), b = std::min(s1, hi);
      if (b > a && hi > lo) f += gauss3(a, b, [&](T s) { return (hi - s) / (hi - lo) * (*this)(s); });
      return f;
    }
  };

  // Area samples: the depth moments at Q0, filtered trilinearly (VO §4.2):
  // bilinearly within each of the two levels bracketing the continuous
  // `level`, linearly between them; below level 0, between level 0 and
  // the texel of the pixel Q0 lies in. The texels read are a mixture of
  // depth distributions, each weighing its filter weight times its
  // coverage: coverage = Sum w_j c_j / Sum w_j, mean = Sum w_j c_j mu_j /
  // Sum w_j c_j, variance = Sum w_j c_j (var_j + (mu_j - mean)^2) / Sum w_j
  // c_j (the linear filtering of the moments M1, M2; buildDepthMoments'
  // 2x2 reduction). Q0 outside the read window: nothing known (no
  // occluder). A texel is read only if it lies in its level and, with a
  // band, its block's centre lies in the window (its block may reach half
  // a block beyond the window: the layer's margin holds it); the weights
  // are renormalised over the texels read (a texel not read is unknown,
  // not empty).
  //
  // clamp (the normal clamp's plane n.X = nP, when it ends the chord): the
  // distribution returned is that of the surface's depth relative to the
  // plane's over the same footprint, delta = z - p, moved to the plane's
  // depth on Q0's ray: mean = p(Q0) + mean(delta), sigma = sd(delta)
  // (docs/math.md §8 "The plane-relative spread"). Per texel j: delta_j =
  // mu_j - p(c_j), the plane's depth at the texel's centre c_j; within the
  // texel the surface's depth is taken to vary with the plane's (their
  // correlation 1), sd_j(delta) = |sigma_j - sigma_p,j|, sigma_p,j the
  // plane's own spread over the texel's pixel centres (relativeToPlane),
  // whose positions have per axis the variance V and 4th moment m4 of a
  // block of 2^l pixels, pre-blurred (blurred) or not; between texels the
  // mixture, the plane's curvature over each texel taken out. On an open
  // plane delta_j is that curvature, >= 0: the chord is free to its clamp,
  // W = 1. A texel whose centre sees the plane edge-on or behind the
  // camera: the absolute model (no plane).
  static void depthModel(const GBufferLayer& g, float level, Vec3 Q0, const ReadWindow& window, const Vec3* clamp,
                         float nP, bool blurred, float& covered, float& mean, float& sigma) {
    covered = 0.0f, mean = kInfinity, sigma = 0.0f;
    if (!(Q0.z < 0.0f)) return;
    float fx, fy;
    g.view.project(Q0, fx, fy);
    if (!window.contains(fx, fy)) return;
    // The filter's position in image coordinates: the layer's origin moves
    // with the region, and the weights must not (regions equal the full
    // render bit for bit); the texel grid is aligned to image coordinates
    // (the origin is a multiple of the coarsest block; 0 without a band).
    const float inv = 1.0f / -Q0.z;
    const float ix = 0.5f * g.view.width + Q0.x * inv * g.view.filmScaleX;
    const float iy = 0.5f * g.view.height - Q0.y * inv * g.view.filmScaleY;
    const int top = int(g.moments.size()) - 1;
    // xj, yj: the texel's centre (image); pv, pm: its pixel centres' position variance and 4th moment per axis
    float wj[9], cj[9], mj[9], vj[9], xj[9], yj[9], pv[9], pm[9];
    int n = 0;
    if (level < 0.0f) {
      // A footprint under a pixel: the pixel Q0 lies in, read as a line
      // sample reads it - its surface's plane on Q0's ray, one depth at
      // Q0's own film position (the "level -1" of the filter, weight
      // -level) - and level 0 bilinearly (weight 1 + level), so that a tiny
      // ball reads its own pixel exactly: a bilinear read, or the pixel's
      // pre-blurred texel, would spread the neighbours' depths over it.
      const size_t j = g.index(int(fx), int(fy));
      const float z = planeDepth(g, j, Q0.x * inv, Q0.y * inv);  // +inf: background or no occluder
      wj[n] = -level, cj[n] = z < kInfinity ? 1.0f : 0.0f, mj[n] = z < kInfinity ? z : 0.0f, vj[n] = 0.0f;
      xj[n] = ix, yj[n] = iy, pv[n] = 0.0f, pm[n] = 0.0f;
      ++n;
    }
    const int l0 = std::clamp(int(level), 0, top), l1 = level < 0.0f ? 0 : std::min(l0 + 1, top);
    const float t = l1 > l0 ? level - float(l0) : 0.0f;
    const float wBase = level < 0.0f ? 1.0f + level : 1.0f;
    for (int l = l0; l <= l1; ++l) {
      const float wl = wBase * (l == l0 ? 1.0f - t : t);
      if (!(wl > 0.0f)) continue;
      const DepthMoments& m = g.moments[size_t(l)];
      const float size = float(1 << l), scale = 1.0f / size;
      // A block of 2^l pixel centres, each pre-blurred: per axis the discrete
      // uniform's variance and 4th moment, (N^2 - 1) / 12 and (N^2 - 1)
      // (3 N^2 - 7) / 240, convolved with the blur's (moments of a sum).
      const float N2 = size * size, Vbox = (N2 - 1.0f) * (1.0f / 12.0f);
      const float m4box = (N2 - 1.0f) * (3.0f * N2 - 7.0f) * (1.0f / 240.0f);
      const float Vl = Vbox + (blurred ? kBlurV : 0.0f);
      const float m4l = m4box + (blurred ? 6.0f * Vbox * kBlurV + kBlurM4 : 0.0f);
      // Texel centres at (b + 1/2) 2^l: the four around the point.
      const int step = 1 << l;
      const bool aligned = g.originX % step == 0 && g.originY % step == 0;
      const float u = (aligned ? ix : fx) * scale - 0.5f, v = (aligned ? iy : fy) * scale - 0.5f;
      const float fu = std::floor(u), fv = std::floor(v);
      const float ax = u - fu, ay = v - fv;
      const int bx0 = int(fu) - (aligned ? g.originX / step : 0), by0 = int(fv) - (aligned ? g.originY / step : 0);
      for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
          const int bx = bx0 + dx, by = by0 + dy;
          const float w = wl * (dx ? ax : 1.0f - ax) * (dy ? ay : 1.0f - ay);
          if (!(w > 0.0f) || bx < 0 || by < 0 || bx >= m.width || by >= m.height) continue;
          if (g.band > 0 && !window.contains((float(bx) + 0.5f) * size, (float(by) + 0.5f) * size)) continue;
          const size_t j = size_t(by) * size_t(m.width) + size_t(bx);
          wj[n] = w, cj[n] = m.coverage[j], mj[n] = m.mean[j], vj[n] = m.variance[j];
          xj[n] = (float(bx) + 0.5f) * size + float(g.originX), yj[n] = (float(by) + 0.5f) * size + float(g.originY);
          pv[n] = Vl, pm[n] = m4l;
          ++n;
        }
    }
    float W = 0.0f, Wc = 0.0f, M = 0.0f;
    for (int k = 0; k < n; ++k) {
      W += wj[k];
      Wc += wj[k] * cj[k];
      M += wj[k] * cj[k] * mj[k];
    }
    if (!(W > 0.0f)) return;
    covered = Wc / W;
    if (!(Wc > 0.0f)) return;
    mean = M / Wc;
    if (clamp && relativeToPlane(g, Q0, *clamp, nP, n, wj, cj, mj, vj, xj, yj, pv, pm, Wc, mean, sigma)) return;
    float var = 0.0f;
    for (int k = 0; k < n; ++k) {
      const float d = mj[k] - mean;
      var += wj[k] * cj[k] * (vj[k] + d * d);
    }
    sigma = std::sqrt(std::max(0.0f, var / Wc));
  }

  // depthModel's plane-relative distribution of the n texels read (see
  // there): false where the plane is seen edge-on or behind the camera at
  // Q0 or at a texel's centre (then mean and sigma are left as they are).
  // The plane's depth on the camera ray depth x (a, b, -1) is p = nP / (n .
  // (a, b, -1)), its gradient in image pixels |grad p| = p |(n.x / filmScaleX,
  // n.y / filmScaleY)| / |n . (a, b, -1)|.
  static bool relativeToPlane(const GBufferLayer& g, Vec3 Q0, Vec3 c, float nP, int n, const float* wj,
                              const float* cj, const float* mj, const float* vj, const float* xj, const float* yj,
                              const float* pv, const float* pm, float Wc, float& mean, float& sigma) {
    const float gx = c.x / g.view.filmScaleX, gy = c.y / g.view.filmScaleY, gradScale = std::sqrt(gx * gx + gy * gy);
    // The positions' 4th moment along the gradient's direction (ux, uy):
    // (ux^4 + uy^4) m4 + 6 ux^2 uy^2 V^2 for independent axes alike.
    const float ux2 = gradScale > 0.0f ? gx * gx / (gradScale * gradScale) : 1.0f, uy2 = 1.0f - ux2;
    const float along4 = ux2 * ux2 + uy2 * uy2, cross4 = 6.0f * ux2 * uy2;
    // The plane on the ray depth x (a, b, -1): 1 / (n . (a, b, -1)) into
    // invDen, false where it is seen edge-on (|cos| below 1e-3, compared
    // squared) or behind the camera.
    const auto planeAt = [&](float a, float b, float& p, float& invDen) {
      const float den = c.x * a + c.y * b - c.z;
      invDen = 1.0f / den;
      p = nP * invDen;
      return den * den > 1e-6f * (a * a + b * b + 1.0f) && p > 0.0f && p < kInfinity;
    };
    float pQ, invDenQ;
    if (!planeAt(Q0.x / -Q0.z, Q0.y / -Q0.z, pQ, invDenQ)) return false;
    float dj[9], cv[9], sj2[9];
    float D = 0.0f, C = 0.0f;
    const float invFx = 1.0f / g.view.filmScaleX, invFy = 1.0f / g.view.filmScaleY;
    // Branch-free over the texels (the loop vectorizes), validity summed.
    bool ok = true;
    for (int k = 0; k < n; ++k) {
      const float a = (xj[k] - 0.5f * g.view.width) * invFx, b = (0.5f * g.view.height - yj[k]) * invFy;
      float p, invDen;
      ok &= planeAt(a, b, p, invDen);
      const float slope = gradScale * std::abs(invDen);  // |grad p| / p
      // Along the gradient the plane's depth is p / (1 + s t), s = slope, t
      // the position's offset (variance V, 4th moment m4): to 4th order its
      // mean over the texel is p (1 + s^2 V + s^4 m4) (the curvature
      // offset) and its variance p^2 s^2 (V + s^2 (3 m4 - V^2)).
      const float s2 = slope * slope, V = pv[k], m4 = along4 * pm[k] + cross4 * V * V;
      cv[k] = p * (s2 * V + s2 * s2 * m4);
      const float planeVar = p * p * s2 * std::max(0.0f, V + s2 * (3.0f * m4 - V * V));
      // (sigma_j - sigma_p,j)^2 with one root: var_j + var_p - 2 sqrt(var_j var_p).
      sj2[k] = std::max(0.0f, vj[k] + planeVar - 2.0f * std::sqrt(vj[k] * planeVar));
      dj[k] = mj[k] - p;
      D += wj[k] * cj[k] * dj[k], C += wj[k] * cj[k] * cv[k];
    }
    if (!ok) return false;
    D /= Wc, C /= Wc;
    float var = 0.0f;
    for (int k = 0; k < n; ++k) {
      const float d = (dj[k] - cv[k]) - (D - C);
      var += wj[k] * cj[k] * (sj2[k] + d * d);
    }
    mean = pQ + D;
    sigma = std::sqrt(std::max(0.0f, var / Wc));
    return true;
  }

  static constexpr int kMaxCount = 256;  // the `count` parameter's maximum
  static constexpr float kSqrt3 = 1.7320508f;
  // The pre-blur's variance and 4th moment per axis (pixels^2, ^4).
  static constexpr float kBlurV = momentBlurVariance(), kBlurM4 = momentBlurFourthMoment();
  VoConfig c_;
  std::vector<float> px_, py_, pz_, w_;
  std::vector<float> rad_, cube_;  // points: |p_k| and |p_k|^3
};

IntegratorDescriptor voDescriptor() {
  IntegratorDescriptor d;
  d.name = "vo";
  d.kind = IntegratorKind::ScreenSpace;
  d.doc = "Volumetric obscurance from the depth buffer (screen-space): the empty fraction of a ball of radius R "
          "about each pixel's point (half-ball with the normal), point, line or area samples (docs/math.md §8).";
  d.params = {
      {.name = "samples", .type = ParamType::Enum, .defaultValue = "line", .choices = {"point", "line", "area"},
       .doc = "point: points in the ball; line: chords of the ball along camera rays through disk points; "
              "area: those chords against the depth's mean and variance over each disk cell's footprint (mip-mapped, "
              "read trilinearly)"},
      {.name = "radius", .type = ParamType::Float, .defaultValue = "1", .min = 0.0, .max = 1e30,
       .doc = "R, the ball's radius (scene units); 0: nothing occludes (W = 1)"},
      {.name = "radius2", .type = ParamType::Float, .defaultValue = "0", .min = 0.0, .max = 1e30,
       .doc = "second radius (VO dual radii); 0: off"},
      {.name = "combine", .type = ParamType::Enum, .defaultValue = "product", .choices = {"product", "min"},
       .doc = "how the two radii's values combine"},
      {.name = "centre", .type = ParamType::Bool, .defaultValue = "true",
       .doc = "line and area samples: the disk set includes the centre"},
      {.name = "sets", .type = ParamType::Enum, .defaultValue = "relaxed", .choices = {"relaxed", "optimised"},
       .doc = "sample sets: relaxed (one Poisson start, repulsion and Lloyd steps; ~10 ms) or optimised "
              "(VO §4.5: 32 starts, boundary charge, 128^3/512^2 Voronoi grids; ~1 s at count 16, memoised "
              "per process; docs/vo_sample_sets.md)"},
      {.name = "normal", .type = ParamType::Enum, .defaultValue = "true",
       .choices = {"true", "clamp", "tangent-sphere", "false", "on", "off", "yes", "no", "1", "0"},
       .doc = "true or clamp: only the half-ball above the tangent plane (a plane gives 1); tangent-sphere: the ball "
              "of radius R/2 tangent at the point (VO §4.4's cited variant); false: the whole ball (a plane: 1/2). "
              "(on/yes/1 and off/no/0, its values as a boolean, still read as true and false.)"},
      {.name = "kernel", .type = ParamType::Enum, .defaultValue = "constant", .choices = {"constant", "quadratic"},
       .doc = "the kernel rho weighing the ball (VO §4): constant, or quadratic 1 - (r/R)^2, 1 at the point and 0 at R"},
      {.name = "blur", .type = ParamType::Int, .defaultValue = "0", .min = 0.0, .max = 64.0,
       .doc = "radius (pixels) of the depth-aware bilateral blur after the estimate (VO §2, §5): Gaussian in image "
              "distance (sigma = radius/2), only neighbours on the pixel's surface (normals within ~25 degrees, "
              "within filter-depth x depth of its tangent plane); 0: off"},
      {.name = "thickness", .type = ParamType::Float, .defaultValue = "0", .min = 0.0, .max = 1e30,
       .doc = "thickness model: occupied only this far behind the depth buffer (scene units); 0: off (solid)"},
      {.name = "prefilter", .type = ParamType::Enum, .defaultValue = "on", .choices = {"on", "off"},
       .doc = "area samples: blur the depth moments' finest level with a Gaussian (sigma 1 pixel) before the mip "
              "chain is built (VO §4.2)"},
  };
  for (ParamSpec& p : sharedParams("samples per pixel and layer (the set's size)", 16, "off")) d.params.push_back(p);
  d.needs = [](const ParamSet&) { return IntegratorNeeds{}; };
  d.bentNormal = true;  // SampleEstimate::bent: the empty volume's first moment (e0=bent)
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    VoConfig c;
    const std::string& kind = p.getEnum("samples");
    c.samples = kind == "point" ? VoSamples::Point : kind == "line" ? VoSamples::Line : VoSamples::Area;
    c.R = float(p.getFloat("radius"));
    c.R2 = float(p.getFloat("radius2"));
    c.combine = p.getEnum("combine") == "min" ? Combine::Min : Combine::Product;
    c.count = p.getInt("count");
    c.centre = p.getBool("centre");
    c.optimisedSets = p.getEnum("sets") == "optimised";
    const std::string& normal = p.getEnum("normal");
    c.domain = normal == "tangent-sphere"                                          ? Domain::TangentSphere
               : normal == "false" || normal == "off" || normal == "no" || normal == "0" ? Domain::Ball
                                                                                   : Domain::HalfBall;
    c.kernel = p.getEnum("kernel") == "quadratic" ? Kernel::Quadratic : Kernel::Constant;
    c.bent = bentE0Requested(p);
    c.thickness = float(p.getFloat("thickness"));
    c.interleave = p.getEnum("interleave") == "on";
    c.filterDepth = float(p.getFloat("filter-depth"));
    c.depth = depthSourceFromParams(p);
    c.guardBand = p.getInt("guard-band");
    c.blur = p.getInt("blur");
    c.prefilter = p.getEnum("prefilter") == "on";
    if (c.samples == VoSamples::Area && c.depth == DepthSource::Traced)
      throw Error("integrator 'vo': samples=area reads the depth buffer's mip-mapped moments; depth=traced applies "
                  "to point and line samples");
    return std::make_unique<VolumetricObscurance>(c);
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(voDescriptor)
}  // namespace obscura
