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

ViewTransform viewTransform(const Camera& c, int w, int h) {
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
  return v;
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

uint64_t screenSpaceWorkingBytes(int w, int h) {
  const uint64_t n = uint64_t(w) * uint64_t(h);
  const uint64_t layer = n * (sizeof(float) + 3 * sizeof(Vec3) + sizeof(std::array<float, 4>) +
                              sizeof(std::array<float, 2>) + 2 * sizeof(uint32_t));
  const uint64_t moments = n * 3 * sizeof(float) * 4 / 3;  // the mip chain: 4/3 of level 0
  // Sums: num, den, hits (twice: the whole pixel's and the even layers'),
  // the AOVs' albedo, normal and depth, E0 and the bent normal.
  const uint64_t layerSums = 2 * sizeof(Vec3) + sizeof(uint32_t);
  return layer + moments +
         n * (2 * layerSums + 4 * sizeof(Vec3) + sizeof(float) + sizeof(SampleEstimate));
}

void renderGBufferLayer(const Scene& scene, const Tracer& tracer, const Camera& camera, const RenderSettings& s,
                        uint32_t sampleIndex, bool albedo, GBufferLayer& g, uint64_t& cameraRays) {
  const size_t n = size_t(s.width) * size_t(s.height);
  g.width = s.width;
  g.height = s.height;
  // The layer's replicate and index within it (include/obscura/sampler.h sampleStream):
  // the ray-traced loop's for the same sample.
  g.sampleIndex = sampleStream(0, sampleIndex).index;
  g.view = viewTransform(camera, s.width, s.height);
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
  parallelRows(s.height, [&](int y0, int y1) {
    IntersectBatch& cam = batches.local();
    cam.reserve(kChunk);
    // Chunks of kRowBand x 64 pixels, pushed in 4 x 4 blocks: the stream's
    // packets of 16 rays are then squares of neighbouring pixels, more
    // coherent than 16 along a row (the layer does not depend on the order).
    size_t order[kChunk];
    for (int xb = 0; xb < s.width; xb += kChunk / kRowBand) {
      const int xe = std::min(s.width, xb + int(kChunk) / kRowBand);
      size_t n = 0;
      for (int bx = xb; bx < xe; bx += 4)
        for (int y = y0; y < y1; ++y)
          for (int x = bx; x < std::min(xe, bx + 4); ++x) order[n++] = g.index(x, y);
      cam.clear();
      for (size_t l = 0; l < n; ++l) {
        const size_t i = order[l];
        const int px = int(i % size_t(s.width)), py = int(i / size_t(s.width));
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
        const int px = int(i % size_t(s.width)), py = int(i / size_t(s.width));
        for (int c = 0; c < 4; ++c) {
          const float cx = float(px + (c & 1)), cy = float(py + (c >> 1));
          const float a = (cx - 0.5f * g.view.width) / g.view.filmScaleX;
          const float b = (0.5f * g.view.height - cy) / g.view.filmScaleY;
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

void buildDepthMoments(GBufferLayer& g) {
  const int levels = 1 + int(std::ceil(std::log2(double(std::max(g.width, g.height)))));
  g.moments.resize(size_t(std::max(levels, 1)));
  DepthMoments& base = g.moments[0];
  base.width = g.width, base.height = g.height;
  const size_t n = size_t(g.width) * size_t(g.height);
  base.mean.resize(n), base.variance.assign(n, 0.0f), base.coverage.resize(n);
  for (size_t i = 0; i < n; ++i) {
    // Occluders only: a non-occluding object's pixels are no depth here.
    const bool c = g.covered(i) && g.depthSlack[i][0] < kInfinity;
    base.mean[i] = c ? g.depth[i] : 0.0f;
    base.coverage[i] = c ? 1.0f : 0.0f;
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
          double w = 0.0, mean = 0.0, cov = 0.0;
          int children = 0;
          forChildren([&](size_t j) {
            ++children;
            cov += a.coverage[j];
            w += a.coverage[j];
            mean += double(a.coverage[j]) * a.mean[j];
          });
          const size_t i = size_t(y) * size_t(b.width) + size_t(x);
          b.coverage[i] = float(cov / children);
          if (!(w > 0.0)) {
            b.mean[i] = 0.0f, b.variance[i] = 0.0f;
            continue;
          }
          mean /= w;
          double var = 0.0;
          forChildren([&](size_t j) {
            const double d = double(a.mean[j]) - mean;
            var += double(a.coverage[j]) * (double(a.variance[j]) + d * d);
          });
          b.mean[i] = float(mean);
          b.variance[i] = float(var / w);
        }
    });
  }
}

void depthAwareBoxFilter(const GBufferLayer& g, const SampleEstimate* in, float tolerance, int y0, int y1,
                         SampleEstimate* out) {
  const int w = g.width, h = g.height;
  for (int y = y0; y < y1; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t c = g.index(x, y);
      SampleEstimate& o = out[size_t(y - y0) * size_t(w) + size_t(x)];
      if (!g.covered(c)) {
        o = in[c];
        continue;
      }
      const float z = g.depth[c], limit = tolerance * z;
      Vec3 num(0, 0, 0), den(0, 0, 0), bent(0, 0, 0);
      int count = 0;
      for (int yy = std::max(0, y - 1); yy <= std::min(h - 1, y + 2); ++yy)
        for (int xx = std::max(0, x - 1); xx <= std::min(w - 1, x + 2); ++xx) {
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

  Film film(s.width, s.height, s.aovs, s.albedoAov);
  const int errorPlane = s.aovs ? film.addPlane(kErrorPlane) : -1;
  const int sppPlane = s.aovs ? film.addPlane(kSppPlane) : -1;
  addLightingPlanes(film, s);
  const PixelLighting light{.env = &s.environment->view(), .shading = integrator.shading(), .bent = needs.bentE0,
                            .plane = film.find(kLightingPlane)};
  const bool wantE0 = light.wantsE0() && film.hasAlbedo();
  const Tracer tracer(scene.rtcScene(), s.recorder, scene.occlusionScopes());
  std::optional<CryptomatteFilm> crypto;  // its own pass, after the layers
  if (s.cryptomatte.any()) crypto.emplace(scene, s.cryptomatte, s.spp, film);
  const size_t n = size_t(s.width) * size_t(s.height);
  // Whole-image state: the pixel sums, one layer (and its estimates when
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
  // The layer's estimates as a whole image only for the depth-aware filter;
  // otherwise each tile's go from a per-thread buffer into the sums.
  const float tolerance = integrator.interleaveFilterTolerance();
  LargeVector<SampleEstimate> est(tolerance > 0.0f ? n : 0);
  tbb::enumerable_thread_specific<std::vector<SampleEstimate>> tileBuffers, rowBuffers;
  tbb::enumerable_thread_specific<std::unique_ptr<IntegratorContext>> contexts;

  Progress progress("render", uint64_t(s.spp), s.progress);
  // Adaptive sampling (core/render/adaptive.h): after each round of layers, the
  // pixels whose error is small enough stop accumulating; the loop ends when
  // none is left. Each layer is traced for the whole image, so a round is
  // the same layers for every running pixel.
  std::optional<SampleSchedule> schedule;
  if (adaptiveSampling(s)) schedule.emplace(PixelRect{0, 0, s.width, s.height}, s, true);
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
      if (integrator.needsDepthMoments()) buildDepthMoments(g);
      stats.gbufferSeconds += secondsSince(t);

      // A pixel's estimate of this layer into its sums (and the AOVs').
      const auto accumulate = [&](size_t i, const SampleEstimate& e) {
        if (schedule && uint32_t(si) >= schedule->target(i)) return;  // stopped
        if ((si & 1) == 0) {
          LayerSums& h = evenSums[i];
          h.num += e.num, h.den += e.den, h.hits += 1;
        }
        LayerSums& p = sums[i];
        p.num += e.num;
        p.den += e.den;
        p.hits += 1;
        if (wantAlbedo) albedoSums[i] += g.albedo[i];
        if (light.bent) bentSums[i] += e.bent;
        if (wantE0) e0Sums[i] += light.env->irradianceOverPi(normalize(g.view.vectorToWorld(g.normal[i])));
        if (s.aovs) {
          // The ray-traced loop's AOVs: world normal, camera-plane depth.
          normalSums[i] += g.view.vectorToWorld(g.normal[i]);
          depthSums[i] += g.depth[i];
        }
      };
      t = std::chrono::steady_clock::now();
      const int tiles = PixelRect::tileCount(kScreenSpaceTile, s.width, s.height);
      tbb::parallel_for(tbb::blocked_range<int>(0, tiles, 1), [&](const tbb::blocked_range<int>& r) {
        std::unique_ptr<IntegratorContext>& ctx = contexts.local();
        if (!ctx) ctx = std::make_unique<IntegratorContext>(scene, tracer, s.environment->view());
        std::vector<SampleEstimate>& out = tileBuffers.local();
        out.resize(size_t(kScreenSpaceTile) * size_t(kScreenSpaceTile));
        for (int t = r.begin(); t != r.end(); ++t) {
          const PixelRect tile = PixelRect::tile(t, kScreenSpaceTile, s.width, s.height);
          std::fill_n(out.begin(), tile.size(), SampleEstimate{Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(0, 0, 0)});
          integrator.estimateTile(g, tile, *ctx, out.data());
          // Filtered layers go to the whole-image estimates (the filter
          // reads neighbours across tiles); the others straight to the sums.
          for (int y = tile.y0; y < tile.y1; ++y)
            for (int x = tile.x0; x < tile.x1; ++x) {
              const size_t i = g.index(x, y);
              if (tolerance > 0.0f)
                est[i] = out[tile.offset(x, y)];
              else if (g.covered(i))
                accumulate(i, out[tile.offset(x, y)]);
            }
        }
      });
      stats.screenSpaceSeconds += secondsSince(t);

      if (tolerance > 0.0f) {
        t = std::chrono::steady_clock::now();
        parallelRows(s.height, [&](int y0, int y1) {
          std::vector<SampleEstimate>& out = rowBuffers.local();
          out.resize(size_t(y1 - y0) * size_t(s.width));
          depthAwareBoxFilter(g, est.data(), tolerance, y0, y1, out.data());
          for (size_t i = g.index(0, y0), e = g.index(0, y1); i < e; ++i)
            if (g.covered(i)) accumulate(i, out[i - g.index(0, y0)]);
        });
        stats.filterSeconds += secondsSince(t);
      }
      progress.advance(1);
      if (schedule && uint32_t(si + 1) == schedule->maxTarget()) {  // a round ends
        parallelRows(s.height, [&](int y0, int y1) {
          for (size_t i = g.index(0, y0), e = g.index(0, y1); i < e; ++i) error[i] = pixelError(i, schedule->target(i));
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
    const auto pixelSums = [&](int y, int x) {
      const size_t i = size_t(y) * size_t(s.width) + size_t(x);
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
    parallelRows(s.height, [&](int y0, int y1) {
      for (int y = y0; y < y1; ++y)
        for (int x = 0; x < s.width; ++x) {
          const size_t i = size_t(y) * size_t(s.width) + size_t(x);
          const int spp = schedule ? int(schedule->taken(i)) : s.spp;
          resolvePixelSums(pixelSums(y, x), spp, integrator, wantAlbedo, light, film, x, y);
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
