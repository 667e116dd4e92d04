#include "core/render/gbuffer.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <optional>

#include "core/render/adaptive.h"
#include <obscura/error.h>
#include "core/render/pixel_sums.h"
#include "core/scene/surface.h"
#include "core/util/progress.h"
#include "core/render/render.h"

namespace obscura {

ViewTransform viewTransform(const Camera& c, int w, int h, int originX, int originY) {
  ViewTransform v;
  v.toWorld = c.toWorld;
  v.origin = c.position();
  v.row0 = c.toWorld.vector(Vec3(1, 0, 0));
  v.row1 = c.toWorld.vector(Vec3(0, 1, 0));
  v.row2 = c.toWorld.vector(Vec3(0, 0, 1));
  v.tanHalfY = std::tan(0.5f * c.yfov);
  v.tanHalfX = v.tanHalfY * float(w) / float(h);
  v.width = float(w), v.height = float(h);
  v.filmScaleX = 0.5f * v.width / v.tanHalfX;
  v.filmScaleY = 0.5f * v.height / v.tanHalfY;
  v.centreX = 0.5f * v.width - float(originX);
  v.centreY = 0.5f * v.height - float(originY);
  return v;
}

int guardBandCap(int w, int h) { return std::max(16, (std::max(w, h) + 7) / 8); }

namespace {
// floor(a / b) for b > 0.
int floorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
}  // namespace

LayerGeometry layerGeometry(const ScreenSpaceIntegrator& integrator, const Scene& scene, const Camera& camera,
                            int w, int h, const PixelRect& window) {
  const ScreenSpaceIntegrator::GuardBand gb = integrator.guardBand();
  LayerGeometry L;
  if (gb.pixels >= 0) {
    L.band = gb.pixels;
  } else if (gb.reach > 0.0) {
    // R projected at the smallest depth a point of the scene's bounds can
    // have in view: the bounds' distance from the camera times the cosine
    // of the view's half diagonal (depth = distance x cos(angle off axis)).
    const Bounds3& b = scene.bounds();
    const Vec3 p = camera.position();
    double d2 = 0.0;
    for (int a = 0; a < 3; ++a) {
      const double e = std::max({double(b.lo[a]) - p[a], 0.0, double(p[a]) - b.hi[a]});
      d2 += e * e;
    }
    const double tanHalfY = std::tan(0.5 * double(camera.yfov)), aspect = double(w) / double(h);
    const double cosDiag = 1.0 / std::sqrt(1.0 + tanHalfY * tanHalfY * (1.0 + aspect * aspect));
    const double depth = std::sqrt(d2) * cosDiag, filmScale = 0.5 * double(h) / tanHalfY;
    const double px = depth > 0.0 ? gb.reach * filmScale / depth : kInfinity;
    const int cap = guardBandCap(w, h);
    // (An empty scene's bounds are infinitely far: px = 0, one pixel.)
    L.band = px < double(cap) ? int(std::ceil(px)) + 1 : cap;
  }
  // The moments' levels: with a band, blocks no larger than it; without,
  // the whole image's pyramid, as before there was a band.
  int align = 4, extra = 0;
  if (integrator.needsDepthMoments()) {
    if (L.band > 0) {
      int top = 0;
      while ((2 << top) <= L.band) ++top;  // 2^top <= band
      L.momentLevels = top + 1;
      align = std::max(align, 1 << top);
      extra = top > 0 ? 1 << (top - 1) : 0;
    } else {
      L.momentLevels = 1 + int(std::ceil(std::log2(double(std::max(w, h)))));
    }
  }
  // No band: the window is the frame (no --region), the layer the image.
  // The pre-blur reads kMomentBlurRadius pixels beyond a block.
  const int blur = integrator.needsDepthMoments() && integrator.prefilterDepthMoments() ? kMomentBlurRadius : 0;
  const int margin =
      L.band > 0 ? L.band + extra + blur + (integrator.interleaveFilterTolerance() > 0.0f ? 2 : 0) : 0;
  L.originX = L.band > 0 ? floorDiv(window.x0 - margin, align) * align : window.x0;
  L.originY = L.band > 0 ? floorDiv(window.y0 - margin, align) * align : window.y0;
  L.width = window.x1 + margin - L.originX;
  L.height = window.y1 + margin - L.originY;
  L.shaded = {window.x0 - L.originX, window.y0 - L.originY, window.x1 - L.originX, window.y1 - L.originY};
  L.image = {-L.originX, -L.originY, w - L.originX, h - L.originY};
  return L;
}
namespace {

// Camera rays per traced stream, as in the ray-traced loop.
constexpr size_t kChunk = 256;
// Rows per parallel task of the per-layer passes.
constexpr int kRowBand = 4;

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// v[i] = value for every i, from all threads (the pages of a fresh
// LargeVector are first touched here, in parallel).
template <class T>
void parallelFill(LargeVector<T>& v, const T& value) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, v.size(), size_t(1) << 16), [&](const tbb::blocked_range<size_t>& r) {
    std::fill(v.begin() + std::ptrdiff_t(r.begin()), v.begin() + std::ptrdiff_t(r.end()), value);
  });
}

template <class F>
void parallelRows(int height, F&& f) {
  tbb::parallel_for(tbb::blocked_range<int>(0, (height + kRowBand - 1) / kRowBand, 1),
                    [&](const tbb::blocked_range<int>& r) {
                      for (int b = r.begin(); b != r.end(); ++b) f(b * kRowBand, std::min(height, (b + 1) * kRowBand));
                    });
}

}  // namespace

uint64_t screenSpaceWorkingBytes(const PixelRect& window, int band) {
  // The layer: the window and on each side the band, half a block (<= half
  // the band), the filter's 2 pixels, the moments' pre-blur and the
  // alignment (< the band, or 4).
  const uint64_t margin = 2 * (uint64_t(band) + uint64_t(band) / 2 + 2 + uint64_t(kMomentBlurRadius) +
                               std::max<uint64_t>(4, uint64_t(band)));
  const uint64_t n = (uint64_t(window.width()) + margin) * (uint64_t(window.height()) + margin);
  const uint64_t layer = n * (sizeof(float) + 3 * sizeof(Vec3) + sizeof(std::array<float, 4>) +
                              sizeof(std::array<float, 2>) + 2 * sizeof(uint32_t));
  // The mip chain (4/3 of level 0) and the pre-blur's one-level scratch.
  const uint64_t moments = n * 3 * sizeof(float) * 4 / 3 + n * 3 * sizeof(float);
  // Sums: num, den, hits (twice: the whole pixel's and the even layers'),
  // the AOVs' albedo, normal and depth, E0 and the bent normal.
  const uint64_t layerSums = 2 * sizeof(Vec3) + sizeof(uint32_t);
  return layer + moments +
         n * (2 * layerSums + 4 * sizeof(Vec3) + sizeof(float) + sizeof(SampleEstimate));
}

void renderGBufferLayer(const Scene& scene, const Tracer& tracer, const Camera& camera, const RenderSettings& s,
                        uint32_t sampleIndex, bool albedo, GBufferLayer& g, uint64_t& cameraRays) {
  const size_t n = size_t(g.width) * size_t(g.height);
  // The layer's replicate and index within it (include/obscura/sampler.h sampleStream):
  // the ray-traced loop's for the same sample.
  g.sampleIndex = sampleStream(0, sampleIndex).index;
  g.view = viewTransform(camera, s.width, s.height, g.originX, g.originY);
  g.depth.resize(n);
  g.position.resize(n);
  g.normal.resize(n);
  g.plane.resize(n);
  g.depthSlack.resize(n);
  g.object.resize(n);
  g.pixelKey.resize(n);
  g.albedo.resize(albedo ? n : 0);
  const RasterCamera raster(camera, s.width, s.height);
  const Sampler sampler(s.seed);
  const bool mattes = scene.hasMattes(), nonOccluders = scene.hasNonOccluders();
  // No pixel has coordinates (2^32 - 1, 2^32 - 1): a key of its own.
  g.imageKey = sampleStream(sampler.pixelKey(~0U, ~0U), sampleIndex).key;
  tbb::enumerable_thread_specific<IntersectBatch> batches;
  tbb::enumerable_thread_specific<uint64_t> rays(0);
  parallelRows(g.height, [&](int y0, int y1) {
    IntersectBatch& cam = batches.local();
    cam.reserve(kChunk);
    // Chunks of kRowBand x 64 pixels, pushed in 4 x 4 blocks: the stream's
    // packets of 16 rays are then squares of neighbouring pixels, more
    // coherent than 16 along a row (the layer does not depend on the order).
    size_t order[kChunk];
    for (int xb = 0; xb < g.width; xb += kChunk / kRowBand) {
      const int xe = std::min(g.width, xb + int(kChunk) / kRowBand);
      size_t n = 0;
      for (int bx = xb; bx < xe; bx += 4)
        for (int y = y0; y < y1; ++y)
          for (int x = bx; x < std::min(xe, bx + 4); ++x) order[n++] = g.index(x, y);
      cam.clear();
      for (size_t l = 0; l < n; ++l) {
        const size_t i = order[l];
        // Image coordinates: negative or beyond the image in the band, where
        // the film extends (the key of pixel (-1, -1) is the image key's, at
        // other dimensions: harmless).
        const int px = int(i % size_t(g.width)) + g.originX, py = int(i / size_t(g.width)) + g.originY;
        // The ray-traced loop's camera ray of (pixel, sample index):
        // the same key, filter dimension and film position.
        const uint32_t key = sampleStream(sampler.pixelKey(uint32_t(px), uint32_t(py)), sampleIndex).key;
        float fx, fy;
        cameraSampleFilm(s.filter, Sampler::seeds2D(key, kDimPixelFilter), g.sampleIndex, px, py, fx, fy);
        cam.pushCamera(raster.org, raster.direction(fx, fy), camera.znear, camera.zfar);
        g.pixelKey[i] = key;
      }
      tracer.intersect(cam, RayCoherence::Coherent);
      rays.local() += n;
      for (size_t l = 0; l < n; ++l) {
        const size_t i = order[l];
        // A matte object holds out: its pixels are background (docs/production.md "Objects and roles").
        if (!cam.hit(l) || (mattes && scene.isMatte(scene.objectOf(cam.geomID(l), cam.instID(l))))) {
          g.depth[i] = kInfinity;
          g.position[i] = Vec3(0, 0, 0);
          g.normal[i] = Vec3(0, 0, 0);
          g.plane[i] = {0, 0, 0, 0};
          g.depthSlack[i] = {kInfinity, 0.0f};
          g.object[i] = ~0U;
          if (albedo) g.albedo[i] = Vec3(0, 0, 0);
          continue;
        }
        SurfaceHit h;
        computeSurfaceHit(scene, cam.data()[l], albedo, h);
        const Vec3 v = g.view.pointToView(h.p);
        g.position[i] = v;
        // A hit in front of the camera has -z > 0; clamp a degenerate 0
        // (a hit at the eye) to the smallest depth so it never reads as
        // background.
        g.depth[i] = std::max(-v.z, std::numeric_limits<float>::min());
        g.normal[i] = g.view.vectorToView(h.ns);
        const Vec3 ng = g.view.vectorToView(h.ng);
        g.plane[i] = {ng.x, ng.y, ng.z, dot(ng, v)};
        // The plane's depth at the pixel's four corners: its range over the
        // pixel (depth along a ray is monotone between corners of a plane
        // not crossing the eye, so the corners bound it).
        float slack = 0.0f;
        const int px = int(i % size_t(g.width)), py = int(i / size_t(g.width));
        for (int c = 0; c < 4; ++c) {
          const float cx = float(px + (c & 1)), cy = float(py + (c >> 1));
          const float a = (cx - g.view.centreX) / g.view.filmScaleX;
          const float b = (g.view.centreY - cy) / g.view.filmScaleY;
          const float den = ng.x * a + ng.y * b - ng.z;
          const float z = den != 0.0f ? dot(ng, v) / den : -1.0f;
          slack = z > 0.0f ? std::max(slack, std::abs(z - g.depth[i])) : kInfinity;
        }
        g.depthSlack[i] = {g.depth[i], slack};
        // An object that occludes nothing (docs/production.md "Objects and roles") is
        // shaded where the camera sees it but is no occluder in the depth
        // buffer its neighbours read: there it reads as background.
        if (nonOccluders && !scene.objectOccludes(h.object)) g.depthSlack[i] = {kInfinity, 0.0f}, g.plane[i] = {0, 0, 0, 0};
        g.object[i] = h.geomID ^ (h.instID << 20);
        if (albedo) g.albedo[i] = h.albedo;
      }
    }
  });
  for (uint64_t r : rays) cameraRays += r;
}

namespace {

// The depth of pixel i's surface at the pixel's centre: its stored plane
// met by the centre's camera ray (as planeDepth in the screen-space
// integrators), the stored depth where the plane is seen edge-on. So the
// moments' depths sit at the pixel centres (texel centres (b + 1/2) 2^l),
// which vo's plane-relative spread relies on; the camera sample's own depth
// lies somewhere in the pixel (a plane's slope across a pixel as noise).
// The offsets from the centre are image coordinates (centreX carries the
// origin), so a region's layer gets the full frame's values bit for bit.
float centreDepth(const GBufferLayer& g, size_t i) {
  const float a = (float(i % size_t(g.width)) + 0.5f - g.view.centreX) / g.view.filmScaleX;
  const float b = (g.view.centreY - (float(i / size_t(g.width)) + 0.5f)) / g.view.filmScaleY;
  const std::array<float, 4>& p = g.plane[i];
  const float den = p[0] * a + p[1] * b - p[2];
  if (!(std::abs(den) > 1e-3f * std::sqrt(a * a + b * b + 1.0f))) return g.depthSlack[i][0];
  const float z = p[3] / den;
  return z > 0.0f ? z : g.depthSlack[i][0];
}

// Texels merged as a mixture of depth distributions (the parallel-variance
// formula, docs/math.md §8): each part weighs its weight w times its
// coverage c; coverage = Sum w c / Sum w, mean = Sum w c mu / Sum w c,
// variance = Sum w c (var + (mu - mean)^2) / Sum w c. Two passes over the
// parts, in double: never E[z^2] - E[z]^2.
struct MomentMerge {
  double w = 0.0, wc = 0.0, wcMu = 0.0, wcSpread = 0.0;
  template <class ForParts>  // ForParts(f) calls f(weight, coverage, mean, variance) per part
  void run(ForParts&& parts, float& coverage, float& mean, float& variance) {
    parts([&](double wt, float c, float mu, float) {
      w += wt, wc += wt * c, wcMu += wt * c * mu;
    });
    coverage = w > 0.0 ? float(wc / w) : 0.0f;
    if (!(wc > 0.0)) {
      mean = 0.0f, variance = 0.0f;
      return;
    }
    const double m = wcMu / wc;
    parts([&](double wt, float c, float mu, float var) {
      const double d = double(mu) - m;
      wcSpread += wt * c * (double(var) + d * d);
    });
    mean = float(m), variance = float(wcSpread / wc);
  }
};

// One separable pass of the pre-blur over level 0: from `a` into `b`
// (same size), along x (dx = 1) or y; taps off the layer are not read and
// the rest renormalised (layerGeometry's margin keeps every texel a pass
// reads at least kMomentBlurRadius pixels from the layer's edge).
void blurPass(const DepthMoments& a, DepthMoments& b, bool alongX) {
  parallelRows(a.height, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < a.width; ++x) {
        const auto parts = [&](auto&& f) {
          for (int t = -kMomentBlurRadius; t <= kMomentBlurRadius; ++t) {
            const int xx = alongX ? x + t : x, yy = alongX ? y : y + t;
            if (xx < 0 || yy < 0 || xx >= a.width || yy >= a.height) continue;
            const size_t j = size_t(yy) * size_t(a.width) + size_t(xx);
            f(double(kMomentBlurWeights[t + kMomentBlurRadius]), a.coverage[j], a.mean[j], a.variance[j]);
          }
        };
        const size_t i = size_t(y) * size_t(a.width) + size_t(x);
        MomentMerge().run(parts, b.coverage[i], b.mean[i], b.variance[i]);
      }
  });
}

}  // namespace

void buildDepthMoments(GBufferLayer& g, int levels, bool prefilter) {
  g.moments.resize(size_t(std::max(levels, 1)));
  DepthMoments& base = g.moments[0];
  base.width = g.width, base.height = g.height;
  const size_t n = size_t(g.width) * size_t(g.height);
  base.mean.resize(n), base.variance.assign(n, 0.0f), base.coverage.resize(n);
  parallelRows(g.height, [&](int y0, int y1) {
    for (size_t i = size_t(y0) * size_t(g.width); i < size_t(y1) * size_t(g.width); ++i) {
      // Occluders only: a non-occluding object's pixels are no depth here.
      const bool c = g.covered(i) && g.depthSlack[i][0] < kInfinity;
      base.mean[i] = c ? centreDepth(g, i) : 0.0f;
      base.coverage[i] = c ? 1.0f : 0.0f;
    }
  });
  if (prefilter) {
    // VO §4.2's Gaussian blur of the top level: separable, x then y. Each
    // pass is a mixture merge, and so is the pair: a tap's weight in the
    // y pass is the x pass's normaliser times its own, the same for every
    // row a y pass reads (the layer's edges are straight), so the result is
    // the mixture of the 5x5 neighbourhood under the product weights.
    DepthMoments tmp;
    tmp.width = base.width, tmp.height = base.height;
    tmp.mean.resize(n), tmp.variance.resize(n), tmp.coverage.resize(n);
    blurPass(base, tmp, true);
    blurPass(tmp, base, false);
  }
  for (size_t l = 1; l < g.moments.size(); ++l) {
    const DepthMoments& a = g.moments[l - 1];
    DepthMoments& b = g.moments[l];
    b.width = (a.width + 1) / 2, b.height = (a.height + 1) / 2;
    const size_t m = size_t(b.width) * size_t(b.height);
    b.mean.resize(m), b.variance.resize(m), b.coverage.resize(m);
    parallelRows(b.height, [&](int y0, int y1) {
      for (int y = y0; y < y1; ++y)
        for (int x = 0; x < b.width; ++x) {
          // The block's children: 2x2, fewer at an odd edge; each weighs
          // its coverage (children at an odd edge span fewer pixels than
          // their siblings - a small error on the last texel of a row or
          // column, accepted).
          const auto forChildren = [&](auto&& f) {
            for (int dy = 0; dy < 2; ++dy)
              for (int dx = 0; dx < 2; ++dx) {
                const int cx = 2 * x + dx, cy = 2 * y + dy;
                if (cx < a.width && cy < a.height) f(size_t(cy) * size_t(a.width) + size_t(cx));
              }
          };
          const auto parts = [&](auto&& f) {
            forChildren([&](size_t j) { f(1.0, a.coverage[j], a.mean[j], a.variance[j]); });
          };
          const size_t i = size_t(y) * size_t(b.width) + size_t(x);
          MomentMerge().run(parts, b.coverage[i], b.mean[i], b.variance[i]);
        }
    });
  }
}

void depthAwareBoxFilter(const GBufferLayer& g, const SampleEstimate* in, float tolerance, int y0, int y1,
                         SampleEstimate* out) {
  // Neighbours within the image (a region's layer holds the estimates of
  // those around it: layerGeometry's margin), never beyond it.
  const int nx0 = std::max(0, g.image.x0), ny0 = std::max(0, g.image.y0);
  const int nx1 = std::min(g.width, g.image.x1) - 1, ny1 = std::min(g.height, g.image.y1) - 1;
  const int w = g.shaded.width();
  for (int y = y0; y < y1; ++y) {
    for (int x = g.shaded.x0; x < g.shaded.x1; ++x) {
      const size_t c = g.index(x, y);
      SampleEstimate& o = out[size_t(y - y0) * size_t(w) + size_t(x - g.shaded.x0)];
      if (!g.covered(c)) {
        o = in[c];
        continue;
      }
      const float z = g.depth[c], limit = tolerance * z;
      Vec3 num(0, 0, 0), den(0, 0, 0), bent(0, 0, 0);
      int count = 0;
      for (int yy = std::max(ny0, y - 1); yy <= std::min(ny1, y + 2); ++yy)
        for (int xx = std::max(nx0, x - 1); xx <= std::min(nx1, x + 2); ++xx) {
          const size_t j = g.index(xx, yy);
          // Uncovered neighbours have depth inf and fail the test.
          if (!(std::abs(g.depth[j] - z) <= limit)) continue;
          num += in[j].num;
          den += in[j].den;
          bent += in[j].bent;
          ++count;
        }
      // count >= 1: the pixel itself passes.
      const float inv = 1.0f / float(count);
      o.num = num * inv;
      o.den = den * inv;
      o.bent = bent * inv;
    }
  }
}

Film renderScreenSpace(const Scene& scene, const Camera& camera, const ScreenSpaceIntegrator& integrator,
                       const IntegratorNeeds& needs, const RenderSettings& settings, RenderStats& stats,
                       const std::atomic<bool>* cancel) {
  const RenderSettings s = withEnvironment(settings);
  // render() has checked the settings (it is the one entry point).
  const bool wantAlbedo = needs.albedo || (s.aovs && s.albedoAov);
  if (wantAlbedo)  // decode once, up front: the loops never throw or block
    for (const auto& t : scene.textures) t->decode();

  // The window (the frame or the --region) and the layers around it, with
  // their guard band (layerGeometry).
  const PixelRect window = renderWindow(s);
  const LayerGeometry geometry = layerGeometry(integrator, scene, camera, s.width, s.height, window);
  if (hasRegion(s) && geometry.band == 0 && integrator.guardBand().reach != 0.0)
    throw Error("--region: this screen-space pass has no guard band (guard-band=0, or a plugin that states no "
                "reach), so its pixels near the region's edges would read what the full frame's do not; give it a "
                "band or render the full frame");
  Film film(window, s.width, s.height, s.aovs, s.albedoAov);
  const int errorPlane = s.aovs ? film.addPlane(kErrorPlane) : -1;
  const int sppPlane = s.aovs ? film.addPlane(kSppPlane) : -1;
  addLightingPlanes(film, s);
  const PixelLighting light{.env = &s.environment->view(), .shading = integrator.shading(), .bent = needs.bentE0,
                            .plane = film.find(kLightingPlane)};
  const bool wantE0 = light.wantsE0() && film.hasAlbedo();
  const Tracer tracer(scene.rtcScene(), s.recorder, scene.occlusionScopes());
  std::optional<CryptomatteFilm> crypto;  // its own pass, after the layers
  if (s.cryptomatte.any()) crypto.emplace(scene, s.cryptomatte, s.spp, film);
  // The window's pixels: sums[k], k = (y - window.y0) w + (x - window.x0)
  // for image pixel (x, y), layer pixel (x - originX, y - originY).
  const size_t n = window.size();
  const int ww = window.width();
  // Whole-window state: the pixel sums, one layer (and its estimates when
  // the integrator interleaves). The sums are float and
  // the AOVs' only kept when written: each sums at most spp values in
  // [0, 1] (relative rounding below spp 2^-24), and at 1920x1080 every byte
  // per pixel is 2 MB to fault in and clear.
  struct LayerSums {
    Vec3 num{0, 0, 0}, den{0, 0, 0};
    uint32_t hits = 0;
  };
  // Allocated here, zeroed in parallel in the arena below.
  LargeVector<LayerSums> sums(n), evenSums(n);  // evenSums: the even layers' (docs/math.md §13)
  LargeVector<Vec3> albedoSums(wantAlbedo ? n : 0), normalSums(s.aovs ? n : 0), e0Sums(wantE0 ? n : 0),
      bentSums(light.bent ? n : 0);  // e0=bent: SampleEstimate::bent (world space)
  LargeVector<float> depthSums(s.aovs ? n : 0);
  GBufferLayer g;
  g.width = geometry.width, g.height = geometry.height;
  g.originX = geometry.originX, g.originY = geometry.originY;
  g.band = geometry.band;
  g.shaded = geometry.shaded, g.image = geometry.image;
  const auto layerIndex = [&](size_t k) {
    return g.index(g.shaded.x0 + int(k % size_t(ww)), g.shaded.y0 + int(k / size_t(ww)));
  };
  // The layer's estimates as a whole layer only for the depth-aware filter
  // (estimated over the window and its neighbours in the image: `estimated`);
  // otherwise each tile's go from a per-thread buffer into the sums.
  const float tolerance = integrator.interleaveFilterTolerance();
  LargeVector<SampleEstimate> est(tolerance > 0.0f ? size_t(g.width) * size_t(g.height) : 0);
  PixelRect estimated = g.shaded;
  if (tolerance > 0.0f) {
    estimated = {std::max({g.shaded.x0 - 1, g.image.x0, 0}), std::max({g.shaded.y0 - 1, g.image.y0, 0}),
                 std::min({g.shaded.x1 + 2, g.image.x1, g.width}), std::min({g.shaded.y1 + 2, g.image.y1, g.height})};
  }
  tbb::enumerable_thread_specific<std::vector<SampleEstimate>> tileBuffers, rowBuffers;
  tbb::enumerable_thread_specific<std::unique_ptr<IntegratorContext>> contexts;

  Progress progress("render", uint64_t(s.spp), s.progress);
  // Adaptive sampling (core/render/adaptive.h): after each round of layers, the
  // pixels whose error is small enough stop accumulating; the loop ends when
  // none is left. Each layer is traced for the whole image, so a round is
  // the same layers for every running pixel.
  std::optional<SampleSchedule> schedule;
  if (adaptiveSampling(s)) schedule.emplace(window, s, true);
  std::vector<float> error(schedule ? n : 0);
  // The pass's standard error at pixel i from the layer sums
  // (core/render/pixel_sums.h), and with `n` samples taken its composited error,
  // what the schedule decides on.
  const auto pixelError = [&](size_t i, uint32_t n = 0) {
    const LayerSums& p = sums[i];
    const LayerSums& h = evenSums[i];
    Sum3 num, den;
    num.add(p.num), den.add(p.den);
    HalfSums even;
    even.num.add(h.num), even.den.add(h.den), even.hits = h.hits;
    const Vec3 albedo = wantAlbedo && p.hits ? albedoSums[i] * (1.0f / float(p.hits)) : Vec3(1, 1, 1);
    return n ? compositedError(num, den, p.hits, even, integrator, albedo, n)
             : standardError(num, den, p.hits, even, integrator, albedo);
  };
  stats = {};
  uint64_t cameraRays = 0;
  const auto t0 = std::chrono::steady_clock::now();
  const int threads = s.threads > 0 ? s.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] {
    parallelFill(sums, LayerSums{});
    parallelFill(evenSums, LayerSums{});
    parallelFill(albedoSums, Vec3(0, 0, 0));
    parallelFill(normalSums, Vec3(0, 0, 0));
    parallelFill(e0Sums, Vec3(0, 0, 0));
    parallelFill(bentSums, Vec3(0, 0, 0));
    parallelFill(depthSums, 0.0f);
    for (int si = 0; si < s.spp; ++si) {
      if (cancel && cancel->load(std::memory_order_relaxed)) break;
      auto t = std::chrono::steady_clock::now();
      renderGBufferLayer(scene, tracer, camera, s, uint32_t(si), wantAlbedo, g, cameraRays);
      if (integrator.needsDepthMoments())
        buildDepthMoments(g, geometry.momentLevels, integrator.prefilterDepthMoments());
      stats.gbufferSeconds += secondsSince(t);

      // Window pixel k's (layer pixel i's) estimate of this layer into its
      // sums (and the AOVs').
      const auto accumulate = [&](size_t k, size_t i, const SampleEstimate& e) {
        if (schedule && uint32_t(si) >= schedule->target(k)) return;  // stopped
        if ((si & 1) == 0) {
          LayerSums& h = evenSums[k];
          h.num += e.num, h.den += e.den, h.hits += 1;
        }
        LayerSums& p = sums[k];
        p.num += e.num;
        p.den += e.den;
        p.hits += 1;
        if (wantAlbedo) albedoSums[k] += g.albedo[i];
        if (light.bent) bentSums[k] += e.bent;
        if (wantE0) e0Sums[k] += light.env->irradianceOverPi(normalize(g.view.vectorToWorld(g.normal[i])));
        if (s.aovs) {
          // The ray-traced loop's AOVs: world normal, camera-plane depth.
          normalSums[k] += g.view.vectorToWorld(g.normal[i]);
          depthSums[k] += g.depth[i];
        }
      };
      t = std::chrono::steady_clock::now();
      // Tiles of the estimated pixels, in layer coordinates.
      const int tiles = PixelRect::tileCount(kScreenSpaceTile, estimated.width(), estimated.height());
      tbb::parallel_for(tbb::blocked_range<int>(0, tiles, 1), [&](const tbb::blocked_range<int>& r) {
        std::unique_ptr<IntegratorContext>& ctx = contexts.local();
        if (!ctx) ctx = std::make_unique<IntegratorContext>(scene, tracer, s.environment->view());
        std::vector<SampleEstimate>& out = tileBuffers.local();
        out.resize(size_t(kScreenSpaceTile) * size_t(kScreenSpaceTile));
        for (int t = r.begin(); t != r.end(); ++t) {
          PixelRect tile = PixelRect::tile(t, kScreenSpaceTile, estimated.width(), estimated.height());
          tile.x0 += estimated.x0, tile.x1 += estimated.x0, tile.y0 += estimated.y0, tile.y1 += estimated.y0;
          std::fill_n(out.begin(), tile.size(), SampleEstimate{Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(0, 0, 0)});
          integrator.estimateTile(g, tile, *ctx, out.data());
          // Filtered layers go to the whole-layer estimates (the filter
          // reads neighbours across tiles); the others straight to the sums.
          for (int y = tile.y0; y < tile.y1; ++y)
            for (int x = tile.x0; x < tile.x1; ++x) {
              const size_t i = g.index(x, y);
              if (tolerance > 0.0f)
                est[i] = out[tile.offset(x, y)];
              else if (g.covered(i))
                accumulate(size_t(y - g.shaded.y0) * size_t(ww) + size_t(x - g.shaded.x0), i, out[tile.offset(x, y)]);
            }
        }
      });
      stats.screenSpaceSeconds += secondsSince(t);

      if (tolerance > 0.0f) {
        t = std::chrono::steady_clock::now();
        parallelRows(window.height(), [&](int r0, int r1) {
          std::vector<SampleEstimate>& out = rowBuffers.local();
          out.resize(size_t(r1 - r0) * size_t(ww));
          depthAwareBoxFilter(g, est.data(), tolerance, g.shaded.y0 + r0, g.shaded.y0 + r1, out.data());
          for (size_t k = size_t(r0) * size_t(ww), e = size_t(r1) * size_t(ww); k < e; ++k) {
            const size_t i = layerIndex(k);
            if (g.covered(i)) accumulate(k, i, out[k - size_t(r0) * size_t(ww)]);
          }
        });
        stats.filterSeconds += secondsSince(t);
      }
      progress.advance(1);
      if (schedule && uint32_t(si + 1) == schedule->maxTarget()) {  // a round ends
        parallelRows(window.height(), [&](int r0, int r1) {
          for (size_t k = size_t(r0) * size_t(ww), e = size_t(r1) * size_t(ww); k < e; ++k)
            error[k] = pixelError(k, schedule->target(k));
        });
        const uint64_t planned = schedule->next(error.data());
        const double seconds = secondsSince(t0);
        if (planned && s.timeLimit > 0.0 &&
            seconds + seconds / double(schedule->total()) * double(planned) > s.timeLimit)
          schedule->dropPlan();
        // The bar counts layers: those taken and those the forecast says
        // are still to come (the bar ends full when the rounds end early).
        progress.setTotal(schedule->planned() ? schedule->expectedMaxTarget() : progress.done());
        if (!schedule->planned()) break;
      }
    }
    // The shared resolution (core/render/pixel_sums.h) from these sums.
    const auto pixelSums = [&](size_t i) {
      PixelSums p{};
      p.num.add(sums[i].num);
      p.den.add(sums[i].den);
      p.hits = sums[i].hits;
      if (wantAlbedo) p.albedo.add(albedoSums[i]);
      if (s.aovs) p.N.add(normalSums[i]), p.Z = double(depthSums[i]);
      if (wantE0) p.e0.add(e0Sums[i]);
      if (light.bent) p.bent.add(bentSums[i]);
      return p;
    };
    parallelRows(window.height(), [&](int r0, int r1) {
      for (int y = window.y0 + r0; y < window.y0 + r1; ++y)
        for (int x = window.x0; x < window.x1; ++x) {
          const size_t i = size_t(y - window.y0) * size_t(ww) + size_t(x - window.x0);
          const int spp = schedule ? int(schedule->taken(i)) : s.spp;
          resolvePixelSums(pixelSums(i), spp, integrator, wantAlbedo, light, film, x, y);
          if (errorPlane >= 0) film.at(errorPlane, x, y) = writtenError(pixelError(i), film, x, y);
          if (sppPlane >= 0) film.at(sppPlane, x, y) = float(spp);
        }
    });
    if (crypto && !(cancel && cancel->load(std::memory_order_relaxed)))
      renderCryptomatteSamples(scene, tracer, camera, s, *crypto, cameraRays);
  });
  stats.seconds = secondsSince(t0);
  progress.finish();
  stats.meanSpp = schedule ? schedule->meanSpp() : double(s.spp);
  stats.rounds = schedule ? schedule->rounds() : 1;
  stats.rays.camera = cameraRays;
  for (const auto& ctx : contexts) {
    if (!ctx) continue;
    stats.rays.occlusion += ctx->counters.occlusion;
    stats.rays.closest += ctx->counters.closest;
  }
  if (cancel && cancel->load()) stats.seconds = -1;
  return film;
}

}  // namespace obscura
