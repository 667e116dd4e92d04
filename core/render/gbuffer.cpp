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
    // R projects wider than the cap (a camera close to the scene, or
    // inside its bounds): limiting reads to the band about each pixel would
    // call open what the image shows beyond it (measured: docs/temporal.md),
    // so reads go anywhere within the band of the image, and every region's
    // layer holds the whole image to keep regions exact.
    L.readsImage = !(px < double(cap));
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
  // (The interleave filter reads 2 pixels further and the blur its radius:
  // their neighbours are estimated too, from their own reads; the moments'
  // pre-blur reads kMomentBlurRadius pixels beyond a block.)
  const int preBlur = integrator.needsDepthMoments() && integrator.prefilterDepthMoments() ? kMomentBlurRadius : 0;
  const int margin = L.band > 0 ? L.band + extra + preBlur + (integrator.interleaveFilterTolerance() > 0.0f ? 2 : 0) +
                                      std::max(0, integrator.blur().radius)
                                : 0;
  const PixelRect covered = L.readsImage ? PixelRect{0, 0, w, h} : window;
  L.originX = L.band > 0 ? floorDiv(covered.x0 - margin, align) * align : covered.x0;
  L.originY = L.band > 0 ? floorDiv(covered.y0 - margin, align) * align : covered.y0;
  L.width = covered.x1 + margin - L.originX;
  L.height = covered.y1 + margin - L.originY;
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

uint64_t screenSpaceWorkingBytes(const PixelRect& window, int band, int passes) {
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
  // Each pass of the shared layer loop keeps its own, and a film of its
  // own beside the output's (at most 16 planes with its AOVs).
  const uint64_t layerSums = 2 * sizeof(Vec3) + sizeof(uint32_t);
  const uint64_t perPass = n * (2 * layerSums + 4 * sizeof(Vec3) + sizeof(float) + sizeof(SampleEstimate)) +
                           uint64_t(window.size()) * 16 * sizeof(float);
  return layer + moments + uint64_t(std::max(1, passes)) * perPass;
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

namespace {
// The neighbourhood filters' loop (depthAwareBoxFilter, bilateralBlur):
// each covered pixel (x, y) of layer rows [y0, y1) x columns [x0, x1)
// gets the weighted mean of (num, den, bent) over the pixels of its window
// x+lo..x+hi, y+lo..y+hi within the image (a region's layer holds the
// estimates of those around it: layerGeometry's margin), never beyond it;
// weight(c, j, dx, dy) >= 0, 0 where j is not mixed in, > 0 for the pixel
// itself. Uncovered pixels pass through. store(x, y, estimate).
template <class Weight, class Store>
void filterPixels(const GBufferLayer& g, const SampleEstimate* in, int x0, int x1, int y0, int y1, int lo, int hi,
                  Weight&& weight, Store&& store) {
  const int nx0 = std::max(0, g.image.x0), ny0 = std::max(0, g.image.y0);
  const int nx1 = std::min(g.width, g.image.x1) - 1, ny1 = std::min(g.height, g.image.y1) - 1;
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      const size_t c = g.index(x, y);
      if (!g.covered(c)) {
        store(x, y, in[c]);
        continue;
      }
      Vec3 num(0, 0, 0), den(0, 0, 0), bent(0, 0, 0);
      float sum = 0.0f;
      for (int yy = std::max(ny0, y + lo); yy <= std::min(ny1, y + hi); ++yy)
        for (int xx = std::max(nx0, x + lo); xx <= std::min(nx1, x + hi); ++xx) {
          const size_t j = g.index(xx, yy);
          const float w = weight(c, j, xx - x, yy - y);
          if (!(w > 0.0f)) continue;
          num += in[j].num * w;
          den += in[j].den * w;
          bent += in[j].bent * w;
          sum += w;
        }
      // sum > 0: the pixel itself passes.
      const float inv = 1.0f / sum;
      SampleEstimate o = in[c];
      o.num = num * inv;
      o.den = den * inv;
      o.bent = bent * inv;
      store(x, y, o);
    }
  }
}

// The box filter's weight: 1 within the relative depth tolerance of the
// pixel's depth, else 0 (uncovered neighbours have depth inf and fail).
// (Weights of 1 sum the estimates exactly as a count would.)
auto boxWeight(const GBufferLayer& g, float tolerance) {
  return [&g, tolerance](size_t c, size_t j, int, int) {
    const float z = g.depth[c];
    return std::abs(g.depth[j] - z) <= tolerance * z ? 1.0f : 0.0f;
  };
}

auto blurWeight(const GBufferLayer& g, const BlurKernel& k) {
  const int side = 2 * k.radius + 1;
  return [&g, &k, side](size_t c, size_t j, int dx, int dy) {
    if (!g.covered(j)) return 0.0f;
    const Vec3 n = g.normal[c];
    if (!(dot(n, g.normal[j]) >= kBlurNormalCos)) return 0.0f;
    if (!(std::abs(dot(n, g.position[j] - g.position[c])) <= k.tolerance * g.depth[c])) return 0.0f;
    return k.weights[size_t(dy + k.radius) * size_t(side) + size_t(dx + k.radius)];
  };
}

// Rows [y0, y1) of g.shaded into out (g.shaded's width per row).
auto shadedRows(const GBufferLayer& g, int y0, SampleEstimate* out) {
  return [&g, y0, out](int x, int y, const SampleEstimate& e) {
    out[size_t(y - y0) * size_t(g.shaded.width()) + size_t(x - g.shaded.x0)] = e;
  };
}
}  // namespace

void depthAwareBoxFilter(const GBufferLayer& g, const SampleEstimate* in, float tolerance, int y0, int y1,
                         SampleEstimate* out) {
  filterPixels(g, in, g.shaded.x0, g.shaded.x1, y0, y1, -1, 2, boxWeight(g, tolerance), shadedRows(g, y0, out));
}

BlurKernel::BlurKernel(int r, float tol) : radius(r), tolerance(tol) {
  const int side = 2 * r + 1;
  const double inv2s2 = r > 0 ? 2.0 / (double(r) * double(r)) : 0.0;  // 1 / (2 sigma^2), sigma = r / 2
  weights.resize(size_t(side) * size_t(side));
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx)
      weights[size_t(dy + r) * size_t(side) + size_t(dx + r)] = float(std::exp(-double(dx * dx + dy * dy) * inv2s2));
}

void bilateralBlur(const GBufferLayer& g, const SampleEstimate* in, const BlurKernel& k, int y0, int y1,
                   SampleEstimate* out) {
  filterPixels(g, in, g.shaded.x0, g.shaded.x1, y0, y1, -k.radius, k.radius, blurWeight(g, k), shadedRows(g, y0, out));
}

namespace {

// One screen-space pass of a shared layer loop: its integrator, settings,
// film and sums, and where its reads may go in the shared layer (its own
// guard band and moment levels: layerGeometry for it alone).
struct ScreenSpacePass {
  const ScreenSpaceIntegrator* integrator = nullptr;
  IntegratorNeeds needs;
  RenderSettings s;
  int band = 0, momentLevels = 0;
  bool readsImage = false;
  bool wantAlbedo = false, wantE0 = false;
  PixelLighting light;
  Film film;
  int errorPlane = -1, sppPlane = -1;
  std::optional<CryptomatteFilm> crypto;
  struct LayerSums {
    Vec3 num{0, 0, 0}, den{0, 0, 0};
    uint32_t hits = 0;
  };
  // The window's pixels: sums[k], k = (y - window.y0) w + (x - window.x0)
  // for image pixel (x, y). Allocated here, zeroed in parallel in the arena.
  // The sums are float and the AOVs' only kept when written: each sums at
  // most spp values in [0, 1] (relative rounding below spp 2^-24), and at
  // 1920x1080 every byte per pixel is 2 MB to fault in and clear.
  LargeVector<LayerSums> sums, evenSums;  // evenSums: the even layers' (docs/math.md §13)
  LargeVector<Vec3> albedoSums, normalSums, e0Sums, bentSums;  // bent: SampleEstimate::bent (world space)
  LargeVector<float> depthSums;
  // The layer's estimates as a whole layer only for the depth-aware filter
  // (estimated over the window and its neighbours in the image: `estimated`);
  // otherwise each tile's go from a per-thread buffer into the sums.
  // With the blur (after the interleave filter, if any), the filter's
  // output over the window and the blur's reach (`blurred`) in `filtered`.
  float tolerance = 0.0f;
  BlurKernel blur{0, 0.02f};
  bool wholeLayer = false;
  LargeVector<SampleEstimate> est, filtered;
  PixelRect estimated, blurred;
  // Adaptive sampling (core/render/adaptive.h): after each round of layers,
  // the pixels whose error is small enough stop accumulating; the pass is
  // done when none is left.
  std::optional<SampleSchedule> schedule;
  std::vector<float> error;
  bool done = false;
  RenderStats stats;

  ScreenSpacePass(const Scene& scene, const Camera& camera, const ScreenSpaceIntegrator& ssi, const IntegratorNeeds& nd,
                  const RenderSettings& settings, const PixelRect& window)
      : integrator(&ssi), needs(nd), s(withEnvironment(settings)), film(window, s.width, s.height, s.aovs, s.albedoAov) {
    wantAlbedo = needs.albedo || (s.aovs && s.albedoAov);
    errorPlane = s.aovs ? film.addPlane(kErrorPlane) : -1;
    sppPlane = s.aovs ? film.addPlane(kSppPlane) : -1;
    addLightingPlanes(film, s);
    light = PixelLighting{.env = &s.environment->view(), .shading = ssi.shading(), .bent = needs.bentE0,
                          .plane = film.find(kLightingPlane)};
    wantE0 = light.wantsE0() && film.hasAlbedo();
    if (s.cryptomatte.any()) crypto.emplace(scene, s.cryptomatte, s.spp, film);
    const size_t n = window.size();
    sums.resize(n), evenSums.resize(n);
    albedoSums.resize(wantAlbedo ? n : 0), normalSums.resize(s.aovs ? n : 0), e0Sums.resize(wantE0 ? n : 0);
    bentSums.resize(light.bent ? n : 0), depthSums.resize(s.aovs ? n : 0);
    tolerance = ssi.interleaveFilterTolerance();
    blur = BlurKernel(std::max(0, ssi.blur().radius), ssi.blur().tolerance);
    wholeLayer = tolerance > 0.0f || blur.radius > 0;
    if (adaptiveSampling(s)) schedule.emplace(window, s, true), error.resize(n);
    const LayerGeometry own = layerGeometry(ssi, scene, camera, s.width, s.height, window);
    band = own.band, momentLevels = own.momentLevels, readsImage = own.readsImage;
  }

  // The pass's standard error at window pixel i from the layer sums
  // (core/render/pixel_sums.h), and with `n` samples taken its composited
  // error, what the schedule decides on.
  float pixelError(size_t i, uint32_t n = 0) const {
    const LayerSums& p = sums[i];
    const LayerSums& h = evenSums[i];
    Sum3 num, den;
    num.add(p.num), den.add(p.den);
    HalfSums even;
    even.num.add(h.num), even.den.add(h.den), even.hits = h.hits;
    const Vec3 albedo = wantAlbedo && p.hits ? albedoSums[i] * (1.0f / float(p.hits)) : Vec3(1, 1, 1);
    return n ? compositedError(num, den, p.hits, even, *integrator, albedo, n)
             : standardError(num, den, p.hits, even, *integrator, albedo);
  }

  // The shared resolution (core/render/pixel_sums.h) from these sums.
  PixelSums pixelSums(size_t i) const {
    PixelSums p{};
    p.num.add(sums[i].num);
    p.den.add(sums[i].den);
    p.hits = sums[i].hits;
    if (wantAlbedo) p.albedo.add(albedoSums[i]);
    if (s.aovs) p.N.add(normalSums[i]), p.Z = double(depthSums[i]);
    if (wantE0) p.e0.add(e0Sums[i]);
    if (light.bent) p.bent.add(bentSums[i]);
    return p;
  }
};

// The layer's moments cut to `levels` while a pass reads them (a pass
// whose band is narrower than another's reads the levels a solo render
// builds, no coarser), given back after.
class MomentLevels {
 public:
  MomentLevels(GBufferLayer& g, int levels) : g_(g) {
    for (size_t l = size_t(levels); l < g.moments.size(); ++l) kept_.push_back(std::move(g.moments[l]));
    g.moments.resize(std::min(g.moments.size(), size_t(levels)));
  }
  ~MomentLevels() {
    for (auto& m : kept_) g_.moments.push_back(std::move(m));
  }

 private:
  GBufferLayer& g_;
  std::vector<DepthMoments> kept_;
};

// The layer loop of a group of screen-space passes that share one layer
// per camera sample (renderScreenSpace).
void renderSharedLayers(const Scene& scene, const Camera& camera, std::span<ScreenSpacePass*> passes,
                        const PixelRect& window, RenderStats& stats, const std::atomic<bool>* cancel) {
  const RenderSettings& s = passes[0]->s;
  for (const ScreenSpacePass* p : passes)
    if (p->wantAlbedo)  // decode once, up front: the loops never throw or block
      for (const auto& t : scene.textures) t->decode();
  // The shared layer covers every pass's: the widest margin, the coarsest
  // alignment, the most moment levels (layerGeometry of the union).
  LayerGeometry geometry;
  for (const ScreenSpacePass* p : passes) {
    const LayerGeometry own = layerGeometry(*p->integrator, scene, camera, s.width, s.height, window);
    if (p == passes[0]) {
      geometry = own;
      continue;
    }
    const int x0 = std::min(geometry.originX, own.originX), y0 = std::min(geometry.originY, own.originY);
    geometry.width = std::max(geometry.originX + geometry.width, own.originX + own.width) - x0;
    geometry.height = std::max(geometry.originY + geometry.height, own.originY + own.height) - y0;
    geometry.originX = x0, geometry.originY = y0;
    geometry.band = std::max(geometry.band, own.band);
    geometry.momentLevels = std::max(geometry.momentLevels, own.momentLevels);
  }
  const Tracer tracer(scene.rtcScene(), s.recorder, scene.occlusionScopes());
  const int ww = window.width();
  GBufferLayer g;
  g.width = geometry.width, g.height = geometry.height;
  g.originX = geometry.originX, g.originY = geometry.originY;
  g.band = geometry.band;
  g.shaded = {window.x0 - g.originX, window.y0 - g.originY, window.x1 - g.originX, window.y1 - g.originY};
  g.image = {-g.originX, -g.originY, s.width - g.originX, s.height - g.originY};
  const auto layerIndex = [&](size_t k) {
    return g.index(g.shaded.x0 + int(k % size_t(ww)), g.shaded.y0 + int(k / size_t(ww)));
  };
  // Each pass estimates its window's pixels and, for its filters, their
  // neighbours in the image: the blur's radius, then the interleave
  // filter's 4x4 window about those.
  const auto around = [&](const PixelRect& r, int lo, int hi) {
    return PixelRect{std::max({r.x0 - lo, g.image.x0, 0}), std::max({r.y0 - lo, g.image.y0, 0}),
                     std::min({r.x1 + hi, g.image.x1, g.width}), std::min({r.y1 + hi, g.image.y1, g.height})};
  };
  for (ScreenSpacePass* p : passes) {
    p->blurred = around(g.shaded, p->blur.radius, p->blur.radius);
    p->estimated = g.shaded;
    if (p->wholeLayer) {
      p->est.resize(size_t(g.width) * size_t(g.height));
      p->estimated = p->tolerance > 0.0f ? around(p->blurred, 1, 2) : p->blurred;
    }
    if (p->tolerance > 0.0f && p->blur.radius > 0) p->filtered.resize(p->est.size());
  }
  tbb::enumerable_thread_specific<std::vector<SampleEstimate>> tileBuffers, rowBuffers;
  tbb::enumerable_thread_specific<std::unique_ptr<IntegratorContext>> contexts;

  // One bar for the group: it counts layers (with adaptive sampling, those
  // taken and those the passes' forecasts say are still to come).
  Progress progress("render", uint64_t(s.spp), s.progress);
  uint64_t cameraRays = 0;
  const auto t0 = std::chrono::steady_clock::now();
  const int threads = s.threads > 0 ? s.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] {
    for (ScreenSpacePass* p : passes) {
      parallelFill(p->sums, ScreenSpacePass::LayerSums{});
      parallelFill(p->evenSums, ScreenSpacePass::LayerSums{});
      parallelFill(p->albedoSums, Vec3(0, 0, 0));
      parallelFill(p->normalSums, Vec3(0, 0, 0));
      parallelFill(p->e0Sums, Vec3(0, 0, 0));
      parallelFill(p->bentSums, Vec3(0, 0, 0));
      parallelFill(p->depthSums, 0.0f);
    }
    for (int si = 0; si < s.spp; ++si) {
      if (cancel && cancel->load(std::memory_order_relaxed)) break;
      // The layer holds what the passes still running read (a layer's
      // pixels do not depend on which arrays it fills).
      bool running = false, wantAlbedo = false;
      for (const ScreenSpacePass* p : passes) {
        if (p->done) continue;
        running = true;
        wantAlbedo = wantAlbedo || p->wantAlbedo;
      }
      if (!running) break;
      auto t = std::chrono::steady_clock::now();
      renderGBufferLayer(scene, tracer, camera, s, uint32_t(si), wantAlbedo, g, cameraRays);
      // The moments are built for the first pass that reads them, again for
      // a pass that wants the other pre-blur (prefilterDepthMoments).
      int momentsBuilt = -1;  // -1: none; else the pre-blur they have
      stats.gbufferSeconds += secondsSince(t);

      for (ScreenSpacePass* pass : passes) {
        if (pass->done) continue;
        ScreenSpacePass& p = *pass;
        const ScreenSpaceIntegrator& integrator = *p.integrator;
        // The pass reads as a solo render's layer lets it: its own band
        // and moment levels.
        g.band = p.band;
        g.readsImage = p.readsImage;
        if (integrator.needsDepthMoments() && momentsBuilt != int(integrator.prefilterDepthMoments())) {
          t = std::chrono::steady_clock::now();
          buildDepthMoments(g, geometry.momentLevels, integrator.prefilterDepthMoments());
          momentsBuilt = int(integrator.prefilterDepthMoments());
          stats.gbufferSeconds += secondsSince(t);
        }
        const MomentLevels levels(g, p.momentLevels);
        // Window pixel k's (layer pixel i's) estimate of this layer into its
        // sums (and the AOVs').
        const auto accumulate = [&](size_t k, size_t i, const SampleEstimate& e) {
          if (p.schedule && uint32_t(si) >= p.schedule->target(k)) return;  // stopped
          if ((si & 1) == 0) {
            ScreenSpacePass::LayerSums& h = p.evenSums[k];
            h.num += e.num, h.den += e.den, h.hits += 1;
          }
          ScreenSpacePass::LayerSums& q = p.sums[k];
          q.num += e.num;
          q.den += e.den;
          q.hits += 1;
          if (p.wantAlbedo) p.albedoSums[k] += g.albedo[i];
          if (p.light.bent) p.bentSums[k] += e.bent;
          if (p.wantE0) p.e0Sums[k] += p.light.env->irradianceOverPi(normalize(g.view.vectorToWorld(g.normal[i])));
          if (p.s.aovs) {
            // The ray-traced loop's AOVs: world normal, camera-plane depth.
            p.normalSums[k] += g.view.vectorToWorld(g.normal[i]);
            p.depthSums[k] += g.depth[i];
          }
        };
        t = std::chrono::steady_clock::now();
        // Tiles of the estimated pixels, in layer coordinates.
        const PixelRect& estimated = p.estimated;
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
                if (p.wholeLayer)
                  p.est[i] = out[tile.offset(x, y)];
                else if (g.covered(i))
                  accumulate(size_t(y - g.shaded.y0) * size_t(ww) + size_t(x - g.shaded.x0), i, out[tile.offset(x, y)]);
              }
          }
        });
        stats.screenSpaceSeconds += secondsSince(t);

        if (p.wholeLayer) {
          t = std::chrono::steady_clock::now();
          const PixelRect& blurred = p.blurred;
          if (p.tolerance > 0.0f && p.blur.radius > 0)  // the interleave filter over what the blur reads
            parallelRows(blurred.height(), [&](int r0, int r1) {
              filterPixels(g, p.est.data(), blurred.x0, blurred.x1, blurred.y0 + r0, blurred.y0 + r1, -1, 2,
                           boxWeight(g, p.tolerance),
                           [&](int x, int y, const SampleEstimate& e) { p.filtered[g.index(x, y)] = e; });
            });
          parallelRows(window.height(), [&](int r0, int r1) {
            std::vector<SampleEstimate>& out = rowBuffers.local();
            out.resize(size_t(r1 - r0) * size_t(ww));
            if (p.blur.radius > 0)
              bilateralBlur(g, p.tolerance > 0.0f ? p.filtered.data() : p.est.data(), p.blur, g.shaded.y0 + r0,
                            g.shaded.y0 + r1, out.data());
            else
              depthAwareBoxFilter(g, p.est.data(), p.tolerance, g.shaded.y0 + r0, g.shaded.y0 + r1, out.data());
            for (size_t k = size_t(r0) * size_t(ww), e = size_t(r1) * size_t(ww); k < e; ++k) {
              const size_t i = layerIndex(k);
              if (g.covered(i)) accumulate(k, i, out[k - size_t(r0) * size_t(ww)]);
            }
          });
          stats.filterSeconds += secondsSince(t);
        }
        if (p.schedule && uint32_t(si + 1) == p.schedule->maxTarget()) {  // a round ends
          parallelRows(window.height(), [&](int r0, int r1) {
            for (size_t k = size_t(r0) * size_t(ww), e = size_t(r1) * size_t(ww); k < e; ++k)
              p.error[k] = p.pixelError(k, p.schedule->target(k));
          });
          const uint64_t planned = p.schedule->next(p.error.data());
          const double seconds = secondsSince(t0);
          if (planned && s.timeLimit > 0.0 &&
              seconds + seconds / double(p.schedule->total()) * double(planned) > s.timeLimit)
            p.schedule->dropPlan();
          p.done = !p.schedule->planned();
        }
      }
      g.band = geometry.band;
      progress.advance(1);
      if (passes[0]->schedule) {
        // The bar's total: the layers taken and the most any pass's
        // forecast says are still to come (it ends full when the rounds
        // end early).
        uint64_t total = progress.done();
        for (const ScreenSpacePass* p : passes)
          if (!p->done) total = std::max<uint64_t>(total, p->schedule->expectedMaxTarget());
        progress.setTotal(total);
      }
    }
    for (ScreenSpacePass* pass : passes) {
      ScreenSpacePass& p = *pass;
      parallelRows(window.height(), [&](int r0, int r1) {
        for (int y = window.y0 + r0; y < window.y0 + r1; ++y)
          for (int x = window.x0; x < window.x1; ++x) {
            const size_t i = size_t(y - window.y0) * size_t(ww) + size_t(x - window.x0);
            const int spp = p.schedule ? int(p.schedule->taken(i)) : s.spp;
            resolvePixelSums(p.pixelSums(i), spp, *p.integrator, p.wantAlbedo, p.light, p.film, x, y);
            if (p.errorPlane >= 0) p.film.at(p.errorPlane, x, y) = writtenError(p.pixelError(i), p.film, x, y);
            if (p.sppPlane >= 0) p.film.at(p.sppPlane, x, y) = float(spp);
          }
      });
      if (p.crypto && !(cancel && cancel->load(std::memory_order_relaxed)))
        renderCryptomatteSamples(scene, tracer, camera, p.s, *p.crypto, cameraRays);
    }
  });
  stats.seconds = secondsSince(t0);
  progress.finish();
  stats.rays.camera = cameraRays;
  for (const auto& ctx : contexts) {
    if (!ctx) continue;
    stats.rays.occlusion += ctx->counters.occlusion;
    stats.rays.closest += ctx->counters.closest;
  }
  for (ScreenSpacePass* p : passes) {
    p->stats.meanSpp = p->schedule ? p->schedule->meanSpp() : double(s.spp);
    p->stats.rounds = p->schedule ? p->schedule->rounds() : 1;
  }
}

}  // namespace

std::vector<Film> renderScreenSpace(const Scene& scene, const Camera& camera, std::span<const ScreenSpaceJob> jobs,
                                    RenderStats& stats, const std::atomic<bool>* cancel) {
  stats = {};
  if (jobs.empty()) return {};
  // render() has checked the settings (it is the one entry point). The
  // window (the frame or the --region) is the same for every job.
  const PixelRect window = renderWindow(jobs[0].settings);
  std::vector<std::unique_ptr<ScreenSpacePass>> passes;
  for (const ScreenSpaceJob& j : jobs) {
    passes.push_back(std::make_unique<ScreenSpacePass>(scene, camera, *j.integrator, j.needs, j.settings, window));
    if (hasRegion(passes.back()->s) && passes.back()->band == 0 && j.integrator->guardBand().reach != 0.0)
      throw Error("--region: this screen-space pass has no guard band (guard-band=0, or a plugin that states no "
                  "reach), so its pixels near the region's edges would read what the full frame's do not; give it a "
                  "band or render the full frame");
  }
  // Two groups at most: the passes with a guard band share a layer that
  // covers every one's band; those without one read the whole layer, which
  // must then be the image alone (a band's margin would give them depths
  // beyond it that a solo render's layer does not have).
  for (const bool banded : {true, false}) {
    std::vector<ScreenSpacePass*> group;
    for (const auto& p : passes)
      if ((p->band > 0) == banded) group.push_back(p.get());
    if (group.empty() || (cancel && cancel->load())) continue;
    RenderStats part;
    renderSharedLayers(scene, camera, group, window, part, cancel);
    addStats(stats, part);
  }
  // The first job's samples per pixel are the films'.
  stats.meanSpp = passes[0]->stats.meanSpp, stats.rounds = passes[0]->stats.rounds;
  if (cancel && cancel->load()) stats.seconds = -1;
  std::vector<Film> films;
  for (auto& p : passes) films.push_back(std::move(p->film));
  return films;
}

}  // namespace obscura
