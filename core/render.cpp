#include "core/render.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>

#include "core/error.h"
#include "core/gbuffer.h"
#include "core/pixel_sums.h"
#include "core/progress.h"
#include "core/sampler.h"

namespace obscura {
namespace {

// Camera samples per chunk. Large enough that per-chunk overhead
// vanishes, small enough that the batch and its hits stay in L1/L2.
constexpr size_t kChunk = 256;

struct ThreadScratch {
  ThreadScratch(const Scene& scene, const Tracer& tracer) : ctx(scene, tracer) {
    camera.reserve(kChunk);
    hits.reserve(kChunk);
  }
  IntegratorContext ctx;
  IntersectBatch camera;
  std::vector<SurfaceHit> hits;
  uint32_t lanePixel[kChunk];   // pixel (within tile) of each lane
  int32_t laneHit[kChunk];      // index into hits, or -1
  uint32_t laneKey[kChunk];     // Sampler key of the lane's pixel
  uint32_t laneSample[kChunk];  // sample index within the pixel
  SampleEstimate W[kChunk];
  std::vector<PixelSums> sums;
  RayCounters cameraCounters;
};

}  // namespace

void resolvePixelSums(const PixelSums& p, int spp, const Integrator& integrator, bool wantAlbedo, Vec3 sky,
                      Film& film, int fx, int fy) {
  const bool aovs = film.hasAovs();
  const double coverage = double(p.hits) / double(spp);
  film.at(kA, fx, fy) = float(coverage);
  if (p.hits == 0) {  // background: zero (premultiplied), Z = inf
    if (aovs) film.at(kZ, fx, fy) = kInfinity;
    return;
  }
  // The pass and the albedo are means over the pixel's hits, then
  // premultiplied by coverage.
  const double invHits = 1.0 / double(p.hits);
  const Vec3 albedo = wantAlbedo ? Vec3(float(p.albedo.x * invHits), float(p.albedo.y * invHits),
                                        float(p.albedo.z * invHits))
                                 : Vec3(1, 1, 1);
  const Vec3 W = integrator.resolvePixel(
      Vec3(resolveRatio(p.num.x, p.den.x), resolveRatio(p.num.y, p.den.y), resolveRatio(p.num.z, p.den.z)), albedo);
  film.at(kR, fx, fy) = float(double(W.x) * coverage);
  film.at(kG, fx, fy) = float(double(W.y) * coverage);
  film.at(kB, fx, fy) = float(double(W.z) * coverage);
  if (!aovs) return;
  film.at(kAlbedoR, fx, fy) = float(double(albedo.x) * coverage);
  film.at(kAlbedoG, fx, fy) = float(double(albedo.y) * coverage);
  film.at(kAlbedoB, fx, fy) = float(double(albedo.z) * coverage);
  // shaded = albedo * W * La (MATH.md section 1), from the pixel's
  // albedo and pass: exactly the product a compositor would form.
  film.at(kShadedR, fx, fy) = float(double(albedo.x) * W.x * sky.x * coverage);
  film.at(kShadedG, fx, fy) = float(double(albedo.y) * W.y * sky.y * coverage);
  film.at(kShadedB, fx, fy) = float(double(albedo.z) * W.z * sky.z * coverage);
  const Vec3 nsum(float(p.N.x), float(p.N.y), float(p.N.z));
  const float nl = length(nsum);
  const Vec3 n = nl > 0.0f ? nsum * (1.0f / nl) : Vec3(0, 0, 0);
  film.at(kNX, fx, fy) = n.x;
  film.at(kNY, fx, fy) = n.y;
  film.at(kNZ, fx, fy) = n.z;
  film.at(kZ, fx, fy) = float(p.Z * invHits);
}

Film render(const Scene& scene, const Camera& camera, const Integrator& integrator, const IntegratorNeeds& needs,
            const RenderSettings& s, RenderStats& stats, const std::atomic<bool>* cancel) {
  if (s.width <= 0 || s.height <= 0) throw Error("resolution must be positive");
  if (s.spp <= 0) throw Error("--spp must be at least 1");
  if (s.tileSize <= 0) throw Error("tile size must be at least 1");
  if (const ScreenSpaceIntegrator* ss = integrator.screenSpace())
    return renderScreenSpace(scene, camera, *ss, needs, s, stats, cancel);
  const bool wantAlbedo = needs.albedo || s.aovs;
  if (wantAlbedo)  // decode once, up front: the hot loop never throws or blocks
    for (const auto& t : scene.textures) t->decode();

  Film film(s.width, s.height, s.aovs);
  const Tracer tracer(scene.rtcScene(), s.recorder);
  const RasterCamera raster(camera, s.width, s.height);
  const Sampler sampler(s.seed);
  const int tilesX = (s.width + s.tileSize - 1) / s.tileSize, tilesY = (s.height + s.tileSize - 1) / s.tileSize;
  const float tnear = camera.znear;
  const float tfar = camera.zfar;

  tbb::enumerable_thread_specific<std::unique_ptr<ThreadScratch>> scratch;
  Progress progress("render", uint64_t(s.width) * s.height, s.progress);
  const auto t0 = std::chrono::steady_clock::now();

  auto renderTile = [&](int tile) {
    if (cancel && cancel->load(std::memory_order_relaxed)) return;
    std::unique_ptr<ThreadScratch>& slot = scratch.local();
    if (!slot) slot = std::make_unique<ThreadScratch>(scene, tracer);
    ThreadScratch& ts = *slot;
    const int x0 = (tile % tilesX) * s.tileSize, y0 = (tile / tilesX) * s.tileSize;
    const int tw = std::min(s.tileSize, s.width - x0), th = std::min(s.tileSize, s.height - y0);
    const size_t pixels = size_t(tw) * th;
    ts.sums.assign(pixels, PixelSums{});
    const uint64_t total = uint64_t(pixels) * uint64_t(s.spp);

    // Pixel-major, sample-minor order: each pixel's samples are summed in
    // sample order whatever the chunking. (pix, si) walk that order; the
    // pixel's sampler key is hashed once per pixel.
    uint32_t pix = 0, si = 0;
    uint32_t key = sampler.pixelKey(uint32_t(x0), uint32_t(y0));
    Sampler::Seeds2 filterSeeds = Sampler::seeds2D(key, kDimPixelFilter);
    int px = x0, py = y0;
    for (uint64_t begin = 0; begin < total; begin += kChunk) {
      const size_t n = size_t(std::min<uint64_t>(kChunk, total - begin));
      IntersectBatch& cam = ts.camera;
      cam.clear();
      for (size_t l = 0; l < n; ++l) {
        float fx, fy;
        cameraSampleFilm(s.filter, filterSeeds, si, px, py, fx, fy);
        cam.push(raster.org, raster.direction(fx, fy), tnear, tfar);
        ts.lanePixel[l] = pix;
        ts.laneKey[l] = key;
        ts.laneSample[l] = si;
        if (++si == uint32_t(s.spp)) {  // next pixel
          si = 0;
          ++pix;
          if (++px == x0 + tw) px = x0, ++py;
          key = sampler.pixelKey(uint32_t(px), uint32_t(py));
          filterSeeds = Sampler::seeds2D(key, kDimPixelFilter);
        }
      }
      tracer.intersect(cam, RayCoherence::Coherent);
      ts.cameraCounters.camera += n;

      ts.hits.clear();
      for (size_t l = 0; l < n; ++l) {
        if (!cam.hit(l)) {
          ts.laneHit[l] = -1;
          continue;
        }
        ts.laneHit[l] = int32_t(ts.hits.size());
        SurfaceHit& h = ts.hits.emplace_back();
        computeSurfaceHit(scene, cam.data()[l], wantAlbedo, h);
        h.pixelKey = ts.laneKey[l];
        h.sampleIndex = ts.laneSample[l];
      }
      if (!ts.hits.empty()) {
        for (size_t i = 0; i < ts.hits.size(); ++i) ts.W[i] = {Vec3(0, 0, 0), Vec3(1, 1, 1)};
        integrator.estimate(ts.hits, ts.ctx, ts.W);
      }

      for (size_t l = 0; l < n; ++l) {
        const int32_t hi = ts.laneHit[l];
        if (hi < 0) continue;
        const SurfaceHit& h = ts.hits[size_t(hi)];
        PixelSums& p = ts.sums[ts.lanePixel[l]];
        p.num.add(ts.W[hi].num);
        p.den.add(ts.W[hi].den);
        p.hits += 1;
        if (wantAlbedo) p.albedo.add(h.albedo);
        if (s.aovs) {
          p.N.add(h.ns);
          p.Z += double(h.t);
        }
      }
    }

    // Resolve: each pixel belongs to exactly one tile, so no locking.
    for (int y = 0; y < th; ++y)
      for (int x = 0; x < tw; ++x)
        resolvePixelSums(ts.sums[size_t(y) * tw + x], s.spp, integrator, wantAlbedo, s.sky, film, x0 + x, y0 + y);
    progress.advance(pixels);
  };

  const int threads = s.threads > 0 ? s.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, tilesX * tilesY, 1), [&](const tbb::blocked_range<int>& r) {
      for (int t = r.begin(); t != r.end(); ++t) renderTile(t);
    });
  });
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  progress.finish();
  stats.rays = {};
  for (const auto& slot : scratch) {
    if (!slot) continue;
    const ThreadScratch& ts = *slot;
    stats.rays.camera += ts.cameraCounters.camera;
    stats.rays.occlusion += ts.ctx.counters.occlusion;
    stats.rays.closest += ts.ctx.counters.closest;
  }
  if (cancel && cancel->load()) stats.seconds = -1;
  return film;
}

}  // namespace obscura
