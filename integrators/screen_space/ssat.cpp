// `ssat`: obscurance and the ambient transfer by containment tests against
// the z-buffer (Umenhoffer, Toth, Szirmay-Kalos §4-5, eqs. 7 and 9;
// docs/math.md §9).
//
// The obscurance of docs/math.md §3 written as an integral over direction
// and distance, O = Int Int mu'(r) [no surface before r along w] cos/pi dw dr
// [AT 7], sampled at n fixed points: (xi_x, xi_y, xi_z) from a Poisson-disk
// set improved by Lloyd relaxation (AT §4.1, sample_sets.h), w cosine
// distributed from (xi_x, xi_y), r = the membership's sample of mu' from xi_z
// (integrators/falloff.h, the draw of `obscurance`'s occlusion
// estimator), as offsets (X, Y, Z) = w r [AT 8] placed in each pixel's
// tangent frame, rotated about the normal per pixel (AT §5); (xi_y, xi_z)
// are shifted per layer (layerOffsets), so the mean over layers is unbiased.
// "No surface before r" is the characteristic function of the z-buffer: the
// test point is outside (I0 = 1) unless it lies behind the depth buffer;
// with `steps` m, the points at r i/m, i = 1..m, must all be outside [AT 7].
// The silhouette rule (AT §4.3): a point counts as inside only when
// R > z - z* > 0, so a foreground object farther than R in front of the
// shaded point casts no false shadow around its silhouette.
//
//   albedo=false  W ~ (1/n) Sum I_i                          (obscurance)
//   albedo=true   W ~ Sum I_i / (n - Sum (1 - I_i) a~_i)     [AT 9]
// with a~ the albedo of the pixel where the first inside test point
// projects; a ratio estimator, pooled over the pixel's layers before the
// division as `transfer` does (include/obscura/integrator.h).
//
// occluder=radiance (with albedo=true; end of AT §4.1, docs/math.md §9,
// the pixel's radiance): the pixel where a closed sample's first inside
// point projects stands in with the radiance it reflects under the
// ambient light, L~/La = a~ O~ [AT 2 with W(y) = its obscurance O], and
// the transfer is [AT 4]'s two integrals estimated directly, not [AT 6]'s
// ratio:
//   W ~ (1/n) (Sum I_i + Sum (1 - I_i) a~_i O~_i)
// - the obscurance plus one bounce of the occluders' light (colour
// bleeding). Putting a radiance into [AT 9]'s denominator instead would
// count the bounces twice: that denominator is the geometric series of
// W(y) ~ W(x), which a radiance already contains. O~_i is the pass's own
// containment estimate at that pixel (its G-buffer point, normal and
// rotation; count x steps more tests), with a set shift and a rotation of
// its own (independent dimensions), so that E[O~_i | the outer sample] is
// the pixel's obscurance and the product's mean is unbiased. Its reads
// stay in the shaded pixel's read window (regions stay exact); the reach
// doubles (2R) for the guard band.
//
// Converges to `obscurance` with the same mu when the depth buffer holds
// every occluder and each segment crosses at most one surface.
//
// map= (AT §6, docs/math.md §9, the height field with the z-buffer): the
// camera sees the undisplaced macro surface; a height field (as
// `containment`'s, integrators/displacement.h) decides the visible
// surface's own displaced detail and the depth buffer every other
// occluder. Test point j of sample k is outer iff outer for both,
//   I0 = I0_field(x + w t) I0_zbuffer(P + w t),   t = r j/m,
// P the G-buffer point, x = P + N d(uv) the shaded point, w about the
// displaced normal (estimateWithField).
//
// e0=bent: the bent normal is obscurance's, the sum of the open samples'
// directions w (cosine distributed, so the sum estimates the
// cosine-weighted mean open direction; docs/math.md §14.6), rotated from
// the pixel's frame to world space once per pixel.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <obscura/error.h>
#include "core/render/gbuffer.h"
#include <obscura/plugin.h>
#include "integrators/displacement.h"
#include "integrators/falloff.h"
#include "integrators/screen_space/common.h"
#include "integrators/screen_space/sample_sets.h"

namespace obscura {
namespace {

using namespace screen_space;

struct SsatConfig {
  int count = 16;
  int steps = 1;
  bool albedo = false;
  bool radiance = false;  // occluder=radiance: a~ O~ added, not a~ in the denominator
  bool silhouette = true;
  bool bent = false;  // e0=bent: write SampleEstimate::bent
  bool interleave = true;
  float filterDepth = 0.02f;
  DepthSource depth = DepthSource::GBuffer;
  int guardBand = -1;  // guard-band: pixels, -1 auto
};

class ZBufferTransfer final : public ScreenSpaceIntegrator {
 public:
  ZBufferTransfer(const Membership& mu, const SsatConfig& c, std::shared_ptr<const Displacement> field)
      : c_(c), field_(std::move(field)), mu_(mu), zero_(mu.zeroRadius()) {
    xi_ = cubeSet(c_.count);
    // The rule's R: the membership's radius, or for an uncut exponential
    // the farthest distance a sample can reach (xi_z < 1).
    ruleR_ = std::isinf(mu.tfar()) ? mu.segment(1.0 - 0x1p-24) : mu.tfar();
  }

  // The offsets (X, Y, Z) = w r of the layer [AT 8]: the set's (xi_y, xi_z)
  // shifted per layer modulo 1 (Cranley-Patterson; xi_x, the azimuth, is
  // randomized by the per-pixel rotation), which keeps the set's
  // stratification within a layer and makes the mean over layers unbiased
  // for the integral of AT 7. Computed once per call, n values.
  // (dx, dy, dz): the unit directions w of the offsets, for the bent normal.
  // `dim`: the shift's dimension (kOuterShiftDim; occluder=radiance's
  // estimates at the occluders draw theirs from kOccluderShiftDim).
  // radius, if not null: each sample's r.
  void layerOffsets(uint32_t imageKey, uint32_t sampleIndex, uint32_t dim, float* ox, float* oy, float* oz,
                    Vec3* dir, float* radius = nullptr) const {
    const Sample2 sh = Sampler::get2D(imageKey, sampleIndex, dim);
    for (int k = 0; k < c_.count; ++k) {
      float uy = xi_[k].y + sh.u, uz = xi_[k].z + sh.v;
      uy -= uy >= 1.0f ? 1.0f : 0.0f;
      uz -= uz >= 1.0f ? 1.0f : 0.0f;
      // Cosine-distributed direction about +z from (xi_x, xi_y) [AT 4.1].
      const float phi = 2.0f * kPi * xi_[k].x, sr = std::sqrt(uy);
      const float r = mu_.segment(double(uz));
      if (radius) radius[k] = r;
      dir[k] = Vec3(std::cos(phi) * sr, std::sin(phi) * sr, std::sqrt(std::max(0.0f, 1.0f - uy)));
      ox[k] = dir[k].x * r;
      oy[k] = dir[k].y * r;
      oz[k] = dir[k].z * r;
    }
  }

  float interleaveFilterTolerance() const override { return c_.interleave ? c_.filterDepth : 0.0f; }
  // Test points reach the membership's radius (the rule's R).
  // occluder=radiance: the occluder's own test points lie within R of a
  // point within R of the shaded one (2R).
  GuardBand guardBand() const override {
    return {.reach = zero_ ? 0.0 : double(ruleR_) * (c_.radiance ? 2.0 : 1.0), .pixels = c_.guardBand};
  }

  void estimateTile(const GBufferLayer& g, const PixelRect& tile, IntegratorContext& ctx, SampleEstimate* out) const override {
    if (zero_) {  // R = 0: nothing but the surface occludes (the limit R -> 0+): W = 1
      for (int y = tile.y0; y < tile.y1; ++y)
        for (int x = tile.x0; x < tile.x1; ++x) out[tile.offset(x, y)].num = Vec3(1, 1, 1);
      return;
    }
    if (field_) return estimateWithField(g, tile, ctx, out);
    const size_t perPixel = size_t(c_.count) * size_t(c_.steps);
    float ox[kMaxCount], oy[kMaxCount], oz[kMaxCount];
    Vec3 dir[kMaxCount];
    layerOffsets(g.imageKey, g.sampleIndex, kOuterShiftDim, ox, oy, oz, dir);
    // The set rotated about the normal per pixel (AT §4.2, §5).
    const NormalRotations rotations(g, c_.interleave);
    const auto frameOf = [&](size_t i, int x, int y) {
      return rotations.rotate(g, i, x, y, Frame::fromNormal(g.normal[i]));
    };
    // occluder=radiance: the test points of an occluder pixel's obscurance,
    // m = k steps + j (as sx, sy, sz below), from a set shifted by a draw
    // of its own and turned by a further angle psi of the layer's own, on
    // top of that pixel's rotation: independent of the shaded pixel's
    // samples, uniform in azimuth.
    OccluderSet occ;
    if (c_.radiance) {
      float qx[kMaxCount], qy[kMaxCount], qz[kMaxCount];
      Vec3 qdir[kMaxCount];
      layerOffsets(g.imageKey, g.sampleIndex, kOccluderShiftDim, qx, qy, qz, qdir);
      for (int k = 0, m = 0; k < c_.count; ++k)
        for (int j = 1; j <= c_.steps; ++j, ++m) {
          const float t = float(j) / float(c_.steps);
          occ.x[m] = qx[k] * t, occ.y[m] = qy[k] * t, occ.z[m] = qz[k] * t;
        }
      const float psi = 2.0f * kPi * Sampler::get1D(g.imageKey, g.sampleIndex, kOccluderAngleDim);
      occ.cosPsi = std::cos(psi), occ.sinPsi = std::sin(psi);
    }
    // The occluder's frame at layer pixel (qx, qy), index j.
    const auto occluderFrame = [&](size_t j, int qx, int qy) {
      return rotateAboutNormal(frameOf(j, qx, qy), occ.cosPsi, occ.sinPsi);
    };
    if (c_.depth == DepthSource::GBuffer) {
      // The offsets of every test point, m = k steps + j: the k-th sample's
      // at (j + 1) / m of its length [AT 7].
      alignas(32) float sx[kMaxPoints], sy[kMaxPoints], sz[kMaxPoints];
      for (int k = 0, m = 0; k < c_.count; ++k)
        for (int j = 1; j <= c_.steps; ++j, ++m) {
          const float t = float(j) / float(c_.steps);
          sx[m] = ox[k] * t, sy[m] = oy[k] * t, sz[m] = oz[k] * t;
        }
      PixelPoints pts(g, perPixel);
      forEachPixelPipelined(
          g, tile, c_.interleave,
          [&](size_t i, int x, int y, int b) {
            pts.project(b, x, y, g.position[i], frameOf(i, x, y), Vec3(0, 0, 0), sx, sy, sz);
            prefetchAt(g.depthSlack, pts.pixels(b), perPixel);
          },
          [&](size_t, int x, int y, int b) {
            const Vec3 P = pts.P[b];
            const Frame& f = pts.f[b];
            const float* depth = pts.depth(b);
            const uint32_t* pixel = pts.pixels(b);
            const auto point = [&](size_t m) { return P + f.s * sx[m] + f.t * sy[m] + f.n * sz[m]; };
            const ReadWindow window = readWindow(g, x, y);
            // occluder=radiance: the occluder pixel's test points read
            // from the z-buffer, within the shaded pixel's window.
            const auto occluderOpen = [&](size_t j, int qx, int qy) {
              const Frame fq = occluderFrame(j, qx, qy);
              const Vec3 Pq = g.position[j];
              const auto pointQ = [&](size_t m) { return Pq + fq.s * occ.x[m] + fq.t * occ.y[m] + fq.n * occ.z[m]; };
              return openSamples([&](size_t m) { return zBufferDepth(g, pointQ(m), false, window); },
                                 [&](size_t m) { return -pointQ(m).z; });
            };
            tally(
                g,
                [&](size_t m) {
                  // Outside the read window or behind the camera (depth -1): no occluder known.
                  return depth[m] > 0.0f ? zStarAt(g, pixel[m], depth[m], false, [&] { return point(m); }) : kInfinity;
                },
                [&](size_t m) { return depth[m]; }, point, dir, f, window, occluderOpen, out[tile.offset(x, y)]);
          });
      return;
    }
    DepthLookup look(c_.depth, size_t(kPixelRun) * perPixel, false);
    // occluder=radiance: one occluder's test points at a time, traced as a
    // stream of their own after the run's (the run's depths are copied
    // out of the context's batch by then).
    DepthLookup lookQ(c_.depth, c_.radiance ? perPixel : 0, false);
    const auto push = [&](size_t i, int x, int y) {
      const Vec3 P = g.position[i];
      const Frame f = frameOf(i, x, y);
      for (int k = 0; k < c_.count; ++k) {
        const Vec3 off = f.s * ox[k] + f.t * oy[k] + f.n * oz[k];
        for (int j = 1; j <= c_.steps; ++j) look.push(g, P + off * (float(j) / float(c_.steps)));
      }
    };
    const auto evaluate = [&](size_t i, int x, int y, size_t at, SampleEstimate& o) {
      // The frame again only for the bent normal (a rotation per pixel).
      const Frame f = c_.bent ? frameOf(i, x, y) : Frame{};
      const auto occluderOpen = [&](size_t j, int qx, int qy) {
        const Frame fq = occluderFrame(j, qx, qy);
        const Vec3 Pq = g.position[j];
        lookQ.clear();
        for (size_t m = 0; m < perPixel; ++m) lookQ.push(g, Pq + fq.s * occ.x[m] + fq.t * occ.y[m] + fq.n * occ.z[m]);
        lookQ.run(g, ctx);
        return openSamples([&](size_t m) { return lookQ.z(m); }, [&](size_t m) { return -lookQ.q(m).z; });
      };
      tally(
          g, [&](size_t m) { return look.z(at + m); }, [&](size_t m) { return -look.q(at + m).z; },
          [&](size_t m) { return look.q(at + m); }, dir, f, readWindow(g, x, y), occluderOpen, o);
    };
    forEachPixelRun(g, tile, perPixel, ctx, look, out, push, evaluate);
  }

  // map=: the combination of AT §6 - the height field decides the shaded
  // surface's own displaced detail, the z-buffer every other occluder.
  // Per pixel, the G-buffer point P on the undisplaced macro surface, its
  // texture frame (the pixel's camera ray traced again to its point, once
  // per pixel and layer: the G-buffer keeps no uv) and the field's frame
  // (integrators/displacement.h, as `containment`'s): shaded point
  // x = P + N d0, the set rotated about the displaced normal n_d. Sample k
  // (direction w, length r) has m test points at t = r j/m and
  //   I0(t) = I0_field(x + w t) I0_zbuffer(P + w t)               [AT 7]
  // - a point is outer iff it is outer for both: the product of the two
  // characteristic functions, so the inner parts are the union of the
  // field's and the depth buffer's. The z-buffer's points start on the
  // macro surface, as `containment`'s macro ray does (from x, a point with
  // d0 < 0 would start behind its own macro surface), and directions below
  // the macro plane (n_d tilts away from N) skip them: the macro surface is
  // no occluder there. ã: the shaded surface's albedo at the uv of the
  // field's first inside point, or the depth buffer's where it projects. A
  // pixel without a uv frame is plain ssat (its frame about N, no field).
  // With a flat field (zero gradient) n_d = N: the plain pass's frame.
  void estimateWithField(const GBufferLayer& g, const PixelRect& tile, IntegratorContext& ctx,
                         SampleEstimate* out) const {
    const size_t perPixel = size_t(c_.count) * size_t(c_.steps);
    float ox[kMaxCount], oy[kMaxCount], oz[kMaxCount], radius[kMaxCount];
    Vec3 dir[kMaxCount];
    layerOffsets(g.imageKey, g.sampleIndex, kOuterShiftDim, ox, oy, oz, dir, radius);
    const NormalRotations rotations(g, c_.interleave);
    // The tile's texture frames: its covered pixels' camera rays to their
    // G-buffer points, in one stream (on the heap, once per tile).
    struct FieldPixel {
      bool field = false;
      FieldFrame L;
      Frame f;       // the sample frame (rotated about n_d, or N)
      Vec3 ng;       // the macro plane's normal on N's side (view space)
      SurfaceHit h;  // for the albedo at uv'
    };
    const size_t tw = size_t(tile.x1 - tile.x0);
    std::vector<FieldPixel> px(tw * size_t(tile.y1 - tile.y0));
    IntersectBatch& camera = ctx.intersectBatch(px.size());
    std::vector<size_t> traced;  // px index of each ray
    traced.reserve(px.size());
    for (int y = tile.y0; y < tile.y1; ++y)
      for (int x = tile.x0; x < tile.x1; ++x) {
        const size_t i = g.index(x, y);
        if (!g.covered(i)) continue;
        const Vec3 d = g.view.vectorToWorld(g.position[i]);
        const float len = length(d);
        if (!(len > 0.0f)) continue;
        camera.pushCamera(g.view.origin, d * (1.0f / len), 0.0f, kInfinity);
        traced.push_back(size_t(y - tile.y0) * tw + size_t(x - tile.x0));
      }
    ctx.trace(camera);
    for (size_t r = 0; r < traced.size(); ++r) {
      if (!camera.hit(r)) continue;
      FieldPixel& p = px[traced[r]];
      const int x = tile.x0 + int(traced[r] % tw), y = tile.y0 + int(traced[r] / tw);
      const size_t i = g.index(x, y);
      ctx.surfaceAt(camera, r, false, g.pixelKey[i], g.sampleIndex, p.h);
      UvFrame uv;
      bool framed = ctx.uvFrameAt(p.h, uv);
      const Vec3 N = g.normal[i];
      if (framed) {
        uv.dpdu = g.view.vectorToView(uv.dpdu), uv.dpdv = g.view.vectorToView(uv.dpdv);
        framed = fieldFrame(*field_, uv, N, p.L);
      }
      if (!framed) {
        noFrame(p.h, ctx);
        continue;
      }
      if (p.L.ddu == 0.0 && p.L.ddv == 0.0) p.L.nd = N;
      // The shaded point x = P + N d0 enters only through the field's
      // frame: x + w t - P = N d0 + w t, whose height is d0 + t (w . ez).
      p.field = true;
      const std::array<float, 4>& pl = g.plane[i];
      p.ng = Vec3(pl[0], pl[1], pl[2]);
      if (dot(p.ng, N) < 0.0f) p.ng = -p.ng;
    }
    const auto pixelOfTile = [&](int x, int y) -> FieldPixel& {
      return px[size_t(y - tile.y0) * tw + size_t(x - tile.x0)];
    };
    DepthLookup look(c_.depth, size_t(kPixelRun) * perPixel, false);
    const auto push = [&](size_t i, int x, int y) {
      FieldPixel& p = pixelOfTile(x, y);
      p.f = rotations.rotate(g, i, x, y, Frame::fromNormal(p.field ? p.L.nd : g.normal[i]));
      const Vec3 P = g.position[i];
      for (int k = 0; k < c_.count; ++k) {
        const Vec3 off = p.f.s * ox[k] + p.f.t * oy[k] + p.f.n * oz[k];
        for (int j = 1; j <= c_.steps; ++j) look.push(g, P + off * (float(j) / float(c_.steps)));
      }
    };
    const auto evaluate = [&](size_t, int x, int y, size_t at, SampleEstimate& o) {
      const FieldPixel& p = pixelOfTile(x, y);
      const ReadWindow window = readWindow(g, x, y);
      Vec3 closedAlbedo(0, 0, 0), bent(0, 0, 0);
      int openCount = 0;
      for (int k = 0; k < c_.count; ++k) {
        const Vec3 w = p.f.toWorld(dir[k]);  // view space
        const bool macro = !p.field || dot(w, p.ng) > 0.0f;
        const double wa = dot(w, p.L.ea), wb = dot(w, p.L.eb), wz = dot(w, p.L.ez);
        bool closed = false;
        for (int j = 1; j <= c_.steps && !closed; ++j) {
          if (p.field) {
            const double t = double(radius[k]) * double(j) / double(c_.steps);
            const double u = p.L.u + t * wa, v = p.L.v + t * wb;
            if (p.L.d0 + t * wz < (*field_)(u, v)) {  // inside the height field
              closed = true;
              if (c_.albedo) closedAlbedo += ctx.albedoAtUv(p.h, float(u), float(v));
              break;
            }
          }
          if (!macro) continue;
          const size_t m = at + size_t(k) * size_t(c_.steps) + size_t(j - 1);
          const float z = look.z(m);
          const float behind = -look.q(m).z - z;
          if (behind > kDepthBias * z && (!c_.silhouette || behind < ruleR_)) {  // behind the depth buffer
            closed = true;
            if (c_.albedo) closedAlbedo += albedoAt(g, look.q(m), window);
          }
        }
        openCount += !closed;
        if (c_.bent && !closed) bent += dir[k];
      }
      if (c_.bent) o.bent = g.view.vectorToWorld(p.f.toWorld(bent));
      const float n = float(c_.count);
      const float opened = float(openCount);
      const Vec3 open{opened, opened, opened};
      if (c_.albedo) {
        o.num = open;
        o.den = Vec3(n, n, n) - closedAlbedo;
      } else {
        o.num = open * (1.0f / n);
      }
    };
    forEachPixelRun(g, tile, perPixel, ctx, look, out, push, evaluate);
  }

 private:
  // A pixel without a uv frame gets plain ssat - silently wrong if the user
  // expected the field's detail there, so the first one of a render is
  // reported, naming its mesh, as `containment` does.
  void noFrame(const SurfaceHit& h, const IntegratorContext& ctx) const {
    if (warnedNoFrame_.load(std::memory_order_relaxed) || warnedNoFrame_.exchange(true)) return;
    Log::warn("ssat: " + ctx.surfaceName(h) +
              " has no usable texture coordinates; it gets plain ssat, without the height map's detail (so may other "
              "meshes without them)");
  }

  // One pixel's estimate from its test points m = k steps + j: zStar(m) the
  // depth the lookup found on the camera ray through point m, depthOf(m)
  // the point's own view depth, point(m) the point (view space); dir[k]
  // sample k's direction in the pixel's frame f (view space);
  // occluderOpen(j, qx, qy) the open samples of the obscurance estimate at
  // layer pixel (qx, qy), index j (occluder=radiance).
  template <class ZStar, class DepthOf, class Point, class OccluderOpen>
  void tally(const GBufferLayer& g, ZStar&& zStar, DepthOf&& depthOf, Point&& point, const Vec3* dir, const Frame& f,
             const ReadWindow& window, OccluderOpen&& occluderOpen, SampleEstimate& o) const {
    // What a closed sample's occluder gives: its albedo a~ (for [AT 9]'s
    // denominator) or its radiance a~ O~ (added, [AT 4]).
    const auto occluder = [&](Vec3 q) {
      return c_.radiance ? radianceAt(g, q, window, occluderOpen) : albedoAt(g, q, window);
    };
    Vec3 open(0, 0, 0), closedAlbedo(0, 0, 0), bent(0, 0, 0);
    if (c_.steps == 1) {
      // One test point per sample (the default): inside or not as a
      // bitwise expression, not a branch - the outcome is as good as random
      // from sample to sample, and mispredicted branches were a large part
      // of the pass.
      int openCount = 0;
      for (int k = 0; k < c_.count; ++k) {
        const float z = zStar(size_t(k));
        const float behind = depthOf(size_t(k)) - z;
        const bool inside = (behind > kDepthBias * z) & (!c_.silhouette | (behind < ruleR_));
        openCount += !inside;
        if (c_.albedo && inside) closedAlbedo += occluder(point(size_t(k)));
        if (c_.bent && !inside) bent += dir[k];
      }
      open = Vec3(float(openCount), float(openCount), float(openCount));
    }
    for (int k = 0; c_.steps > 1 && k < c_.count; ++k) {
      int inside = -1;  // the first test point found inside
      for (int j = 0; j < c_.steps; ++j) {
        const size_t m = size_t(k) * size_t(c_.steps) + size_t(j);
        const float z = zStar(m);
        const float behind = depthOf(m) - z;
        if (behind > kDepthBias * z && (!c_.silhouette || behind < ruleR_)) {
          inside = int(m);
          break;
        }
      }
      if (inside < 0) {
        open += Vec3(1, 1, 1);
        if (c_.bent) bent += dir[k];
      } else if (c_.albedo)
        closedAlbedo += occluder(point(size_t(inside)));
    }
    if (c_.bent) o.bent = g.view.vectorToWorld(f.toWorld(bent));
    const float n = float(c_.count);
    if (c_.radiance) {
      // [AT 4]: the open samples plus the occluders' radiance, a mean.
      o.num = (open + closedAlbedo) * (1.0f / n);
    } else if (c_.albedo) {
      o.num = open;
      o.den = Vec3(n, n, n) - closedAlbedo;
    } else {
      o.num = open * (1.0f / n);
    }
  }

  // The albedo of the pixel a test point projects to (the occluder's, as the
  // paper approximates it). From the z-buffer a point outside the read
  // window is never inside; the traced twin can find one inside there,
  // where no pixel's albedo may be read: black (0), the obscurance's
  // occluder.
  static Vec3 albedoAt(const GBufferLayer& g, Vec3 q, const ReadWindow& window) {
    int x, y;
    if (g.albedo.empty() || !pixelOf(g, q, window, x, y)) return Vec3(0, 0, 0);
    return g.albedo[g.index(x, y)];
  }

  // The open samples among count, each with `steps` test points m = k steps
  // + j: zStar(m) the depth found on the camera ray through point m,
  // depthOf(m) the point's own (the inside rule of tally).
  template <class ZStar, class DepthOf>
  int openSamples(ZStar&& zStar, DepthOf&& depthOf) const {
    int openCount = 0;
    for (int k = 0; k < c_.count; ++k) {
      bool closed = false;
      for (int j = 0; j < c_.steps && !closed; ++j) {
        const size_t m = size_t(k) * size_t(c_.steps) + size_t(j);
        const float z = zStar(m);
        const float behind = depthOf(m) - z;
        closed = behind > kDepthBias * z && (!c_.silhouette || behind < ruleR_);
      }
      openCount += !closed;
    }
    return openCount;
  }

  // The radiance (over La) of the pixel a test point projects to, as its
  // pixel reflects the ambient light: a~ O~ [AT 2], O~ the pass's
  // obscurance estimate there (occluderOpen). Black where no albedo may be
  // read (albedoAt); a black pixel needs no estimate.
  template <class OccluderOpen>
  Vec3 radianceAt(const GBufferLayer& g, Vec3 q, const ReadWindow& window, OccluderOpen&& occluderOpen) const {
    int x, y;
    if (g.albedo.empty() || !pixelOf(g, q, window, x, y)) return Vec3(0, 0, 0);
    const size_t j = g.index(x, y);
    const Vec3 a = g.albedo[j];
    if (!g.covered(j) || (a.x <= 0.0f && a.y <= 0.0f && a.z <= 0.0f)) return Vec3(0, 0, 0);
    return a * (float(occluderOpen(j, x, y)) / float(c_.count));
  }

  // The sample dimensions (with g.imageKey) of the set's per-layer shift,
  // and of occluder=radiance's own shift and angle.
  static constexpr uint32_t kOuterShiftDim = kFirstIntegratorDim + 3;
  static constexpr uint32_t kOccluderShiftDim = kFirstIntegratorDim + 4;
  static constexpr uint32_t kOccluderAngleDim = kFirstIntegratorDim + 5;

  static constexpr int kMaxCount = 256;               // the `count` parameter's maximum
  static constexpr int kMaxPoints = kMaxCount * 16;   // ... times `steps`' maximum
  // occluder=radiance's test points (offsets in the occluder's frame) and
  // its extra rotation; on the stack per tile call.
  struct OccluderSet {
    float x[kMaxPoints], y[kMaxPoints], z[kMaxPoints];
    float cosPsi = 1.0f, sinPsi = 0.0f;
  };
  SsatConfig c_;
  std::shared_ptr<const Displacement> field_;  // map=: the height field (AT §6), else null
  mutable std::atomic<bool> warnedNoFrame_{false};
  Membership mu_;
  bool zero_;
  float ruleR_ = 0.0f;
  std::vector<Vec3> xi_;
};

IntegratorDescriptor ssatDescriptor() {
  IntegratorDescriptor d;
  d.name = "ssat";
  d.kind = IntegratorKind::ScreenSpace;
  d.doc = "Z-buffer obscurance and ambient transfer (screen-space): containment tests of sample points of the "
          "falloff mu against the depth buffer, Poisson/Lloyd sets, 4x4 interleaving (docs/math.md §9).";
  for (ParamSpec& s : membershipParams("")) {
    if (s.name == "estimator" || s.name == "rays") continue;  // containment is the occlusion estimator
    if (s.name == "distance") {
      // A screen-space neighbourhood must be bounded: default 1, not inf.
      s.defaultValue = std::to_string(1);  // (a literal here trips GCC 12's -Wrestrict false positive)
      s.doc = "R (scene units): step/linear/sqrt radius, must be finite (default 1, unlike obscurance's inf); "
              "exponential cut-off (inf: none); 0: nothing occludes";
    }
    d.params.push_back(std::move(s));
  }
  d.params.push_back({.name = "albedo", .type = ParamType::Bool, .defaultValue = "false",
                      .doc = "false: obscurance; true: ambient transfer W = Sum I / (n - Sum (1 - I) a~) [AT 9], a "
                             "ratio pooled over the pixel's samples"});
  d.params.push_back({.name = "occluder", .type = ParamType::Enum, .defaultValue = "albedo",
                      .choices = {"albedo", "radiance"},
                      .doc = "with albedo=true, what a closed sample's occluder gives: albedo: a~ in [AT 9]'s "
                             "denominator; radiance: the light the pixel reflects, a~ O~ with O~ its own obscurance "
                             "estimate, added: W = (Sum I + Sum (1 - I) a~ O~) / n [AT 4], one bounce (end of AT 4.1)"});
  d.params.push_back({.name = "silhouette", .type = ParamType::Bool, .defaultValue = "true",
                      .doc = "AT 4.3: a point is inside only when R > z - z* > 0 (no false halo around "
                             "foreground silhouettes)"});
  d.params.push_back({.name = "steps", .type = ParamType::Int, .defaultValue = "1", .min = 1, .max = 16,
                      .doc = "m: test points per sample at r i/m (the paper uses 1 or 2)"});
  for (ParamSpec& p : sharedParams("n: sample points per pixel and layer", 16, "on")) d.params.push_back(p);
  // AT §6: the height field for the surface's own detail (as containment's).
  d.params.push_back({.name = "map", .type = ParamType::String, .defaultValue = "",
                      .doc = "height map of the visible surfaces' displacement (as containment's): the field decides "
                             "their own detail, the depth buffer every other occluder (AT 6); empty: none"});
  d.params.push_back({.name = "scale", .type = ParamType::Float, .defaultValue = "0.1", .min = -1e30, .max = 1e30,
                      .doc = "with map: scene units per unit of height (as --displace-scale)"});
  d.params.push_back({.name = "midlevel", .type = ParamType::Float, .defaultValue = "0.5", .min = -1e30, .max = 1e30,
                      .doc = "with map: the height that leaves the surface in place (as --displace-midlevel)"});
  d.needs = [](const ParamSet& p) { return IntegratorNeeds{.albedo = p.getBool("albedo")}; };
  d.bentNormal = true;  // SampleEstimate::bent: the open directions (e0=bent)
  d.create = [](const ParamSet& p) -> std::unique_ptr<Integrator> {
    const Membership mu = Membership::fromParams(p);
    if (mu.falloff() != Falloff::Exponential && std::isinf(mu.tfar()))
      throw Error("integrator 'ssat': parameter 'distance' must be finite (and within float range) for falloff " +
                  p.getEnum("falloff") + ": the test points need a bounded neighbourhood R");
    SsatConfig c;
    c.count = p.getInt("count");
    c.steps = p.getInt("steps");
    c.albedo = p.getBool("albedo");
    c.radiance = p.getEnum("occluder") == "radiance";
    if (c.radiance && !c.albedo)
      throw Error("integrator 'ssat': occluder=radiance needs albedo=true (the occluders' light is the transfer's)");
    c.silhouette = p.getBool("silhouette");
    c.bent = bentE0Requested(p);
    c.interleave = p.getEnum("interleave") == "on";
    c.filterDepth = float(p.getFloat("filter-depth"));
    c.depth = depthSourceFromParams(p);
    c.guardBand = p.getInt("guard-band");
    std::shared_ptr<const Displacement> field;
    if (!p.getString("map").empty()) {
      if (c.radiance)
        throw Error("integrator 'ssat': occluder=radiance is not combined with map (the occluders' estimates would "
                    "need their own fields)");
      field = std::make_shared<const Displacement>(p.getString("map"), p.getFloat("scale"), p.getFloat("midlevel"));
    }
    return std::make_unique<ZBufferTransfer>(mu, c, std::move(field));
  };
  return d;
}

}  // namespace
OBSCURA_REGISTER_INTEGRATOR(ssatDescriptor)
}  // namespace obscura
