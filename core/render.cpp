#include "core/render.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <optional>

#include "core/error.h"
#include "core/gbuffer.h"
#include "core/pixel_sums.h"
#include "core/progress.h"
#include "core/sampler.h"
#include "core/settings.h"

namespace obscura {
namespace {

// Camera samples per chunk. Large enough that per-chunk overhead
// vanishes, small enough that the batch and its hits stay in L1/L2.
constexpr size_t kChunk = 256;

// One chunk's lanes (camera samples) and what each stage leaves for the
// next, per thread, allocated once: the loop allocates nothing.
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
  SampleEstimate W[kChunk];     // the integrator's estimate of each hit
  std::vector<PixelSums> sums;  // the tile's pixels
  RayCounters cameraCounters;
  CryptomatteFilm::Tile crypto;  // empty unless Cryptomatte is on
};


// Where a tile's walk through its samples stands. Pixel-major, sample-minor:
// each pixel's samples are summed in sample order whatever the chunking. The
// pixel's sampler key and filter seeds are hashed once per pixel.
struct SampleCursor {
  uint32_t pix = 0, si = 0;  // pixel within the tile, sample within the pixel
  int px, py;                // that pixel in the image
  uint32_t key;
  Sampler::Seeds2 filterSeeds;
};

// The render loop's stages for one tile, chunk by chunk:
//   camera samples -> surface hits:  cameraRays, traceCamera, surfaceHits
//   estimate + accumulate:           estimate, accumulate
// and, once the tile's samples are done, resolve into the film. Each stage
// reads and writes the ThreadScratch lane tables (lanePixel/laneKey/
// laneSample -> camera batch -> hits/laneHit -> W -> sums), so another
// source of surface hits only has to fill hits, laneHit and lanePixel.
class TileRenderer {
 public:
  TileRenderer(const Scene& scene, const Camera& camera, const Integrator& integrator, const RenderSettings& s,
               const Tracer& tracer, Film& film, bool wantAlbedo, const CryptomatteFilm* crypto = nullptr)
      : scene_(scene), integrator_(integrator), s_(s), tracer_(tracer), film_(film), raster_(camera, s.width, s.height),
        sampler_(s.seed), tnear_(camera.znear), tfar_(camera.zfar),
        wantAlbedo_(wantAlbedo), mattes_(scene.hasMattes()), crypto_(crypto) {}

  int tileCount() const { return PixelRect::tileCount(s_.tileSize, s_.width, s_.height); }

  // Renders one tile into the film; returns its pixel count, or 0 when
  // cancelled (checked once per chunk: a relaxed load per kChunk samples).
  size_t renderTile(int tile, ThreadScratch& ts, const std::atomic<bool>* cancel) const {
    const PixelRect r = tileRect(tile);
    ts.sums.assign(r.size(), PixelSums{});
    const uint64_t total = uint64_t(r.size()) * uint64_t(s_.spp);
    SampleCursor c = startCursor(r);
    if (crypto_) crypto_->beginTile(r, ts.crypto);
    for (uint64_t begin = 0; begin < total; begin += kChunk) {
      if (cancel && cancel->load(std::memory_order_relaxed)) return 0;
      const size_t n = size_t(std::min<uint64_t>(kChunk, total - begin));
      cameraRays(r, c, n, ts);
      traceCamera(n, ts);
      surfaceHits(n, ts);
      if (crypto_) cryptomatteHits(n, ts);
      estimate(ts);
      accumulate(n, ts);
    }
    resolve(r, ts);
    if (crypto_) crypto_->endTile(ts.crypto);
    return r.size();
  }

 private:
  PixelRect tileRect(int tile) const { return PixelRect::tile(tile, s_.tileSize, s_.width, s_.height); }

  SampleCursor startCursor(const PixelRect& r) const {
    SampleCursor c;
    c.px = r.x0, c.py = r.y0;
    c.key = sampler_.pixelKey(uint32_t(r.x0), uint32_t(r.y0));
    c.filterSeeds = Sampler::seeds2D(c.key, kDimPixelFilter);
    return c;
  }

  // Camera samples -> rays: the next n samples of the tile into ts.camera,
  // with each lane's pixel, sampler key and sample index.
  void cameraRays(const PixelRect& r, SampleCursor& c, size_t n, ThreadScratch& ts) const {
    IntersectBatch& cam = ts.camera;
    cam.clear();
    for (size_t l = 0; l < n; ++l) {
      float fx, fy;  // the pixel filter's film position (shared with the G-buffer: core/gbuffer.h)
      cameraSampleFilm(s_.filter, c.filterSeeds, c.si, c.px, c.py, fx, fy);
      cam.pushCamera(raster_.org, raster_.direction(fx, fy), tnear_, tfar_);
      ts.lanePixel[l] = c.pix;
      ts.laneKey[l] = c.key;
      ts.laneSample[l] = c.si;
      if (++c.si == uint32_t(s_.spp)) {  // next pixel
        c.si = 0;
        ++c.pix;
        if (++c.px == r.x1) c.px = r.x0, ++c.py;
        c.key = sampler_.pixelKey(uint32_t(c.px), uint32_t(c.py));
        c.filterSeeds = Sampler::seeds2D(c.key, kDimPixelFilter);
      }
    }
  }

  // One coherent stream for the chunk's camera rays.
  void traceCamera(size_t n, ThreadScratch& ts) const {
    tracer_.intersect(ts.camera, RayCoherence::Coherent);
    ts.cameraCounters.camera += n;
  }

  // Rays -> surface hits: one SurfaceHit per lane that hit (ts.hits, in
  // lane order), ts.laneHit its index or -1. A hit on a matte object is a
  // holdout: it hides what is behind it and counts as a miss (alpha 0,
  // pass 0; README "Objects and roles").
  void surfaceHits(size_t n, ThreadScratch& ts) const {
    const IntersectBatch& cam = ts.camera;
    ts.hits.clear();
    for (size_t l = 0; l < n; ++l) {
      if (!cam.hit(l) || (mattes_ && scene_.isMatte(scene_.objectOf(cam.geomID(l), cam.instID(l))))) {
        ts.laneHit[l] = -1;
        continue;
      }
      ts.laneHit[l] = int32_t(ts.hits.size());
      SurfaceHit& h = ts.hits.emplace_back();
      computeSurfaceHit(scene_, cam.data()[l], wantAlbedo_, h);
      h.pixelKey = ts.laneKey[l];
      h.sampleIndex = ts.laneSample[l];
    }
  }

  // The chunk's camera hits, in lane order (pixel-major, sample-minor),
  // into the Cryptomatte counts; holdouts and misses have no id.
  void cryptomatteHits(size_t n, ThreadScratch& ts) const {
    for (size_t l = 0; l < n; ++l)
      if (ts.laneHit[l] >= 0) crypto_->addHit(ts.crypto, ts.lanePixel[l], ts.hits[size_t(ts.laneHit[l])]);
  }

  // The integrator's estimate of every hit (ts.W), as one batch.
  void estimate(ThreadScratch& ts) const {
    if (ts.hits.empty()) return;
    for (size_t i = 0; i < ts.hits.size(); ++i) ts.W[i] = {Vec3(0, 0, 0), Vec3(1, 1, 1)};
    integrator_.estimate(ts.hits, ts.ctx, ts.W);
  }

  // Each lane's estimate (and AOV values) into its pixel's sums, in lane
  // order, that is in sample order within a pixel.
  void accumulate(size_t n, ThreadScratch& ts) const {
    for (size_t l = 0; l < n; ++l) {
      const int32_t hi = ts.laneHit[l];
      if (hi < 0) continue;
      const SurfaceHit& h = ts.hits[size_t(hi)];
      PixelSums& p = ts.sums[ts.lanePixel[l]];
      p.num.add(ts.W[hi].num);
      p.den.add(ts.W[hi].den);
      p.hits += 1;
      if (wantAlbedo_) p.albedo.add(h.albedo);
      if (s_.aovs) {
        p.N.add(h.ns);
        p.Z += double(h.t);
      }
    }
  }

  // The tile's sums into the film. Each pixel belongs to exactly one tile,
  // so no locking.
  void resolve(const PixelRect& r, const ThreadScratch& ts) const {
    for (int y = 0; y < r.height(); ++y)
      for (int x = 0; x < r.width(); ++x)
        resolvePixelSums(ts.sums[size_t(y) * size_t(r.width()) + size_t(x)], s_.spp, integrator_, wantAlbedo_, s_.sky, film_, r.x0 + x,
                         r.y0 + y);
  }

  const Scene& scene_;
  const Integrator& integrator_;
  const RenderSettings& s_;
  const Tracer& tracer_;
  Film& film_;
  const RasterCamera raster_;
  const Sampler sampler_;
  const float tnear_, tfar_;
  const bool wantAlbedo_;
  const bool mattes_;
  const CryptomatteFilm* crypto_;  // null: Cryptomatte off
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
  // shaded = albedo * W * La (docs/math.md §1), from the pixel's
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
  if (s.spp <= 0) throw Error(settingName(Setting::Spp) + " must be at least 1");
  if (s.tileSize <= 0) throw Error("tile size must be at least 1");
  if (s.cryptomatte.any()) checkCryptomatteRanks(s.cryptomatte.ranks);
  if (const ScreenSpaceIntegrator* ss = integrator.screenSpace())
    return renderScreenSpace(scene, camera, *ss, needs, s, stats, cancel);
  const bool wantAlbedo = needs.albedo || s.aovs;
  if (wantAlbedo)  // decode once, up front: the hot loop never throws or blocks
    for (const auto& t : scene.textures) t->decode();

  Film film(s.width, s.height, s.aovs);
  const Tracer tracer(scene.rtcScene(), s.recorder, scene.occlusionScopes());
  std::optional<CryptomatteFilm> crypto;
  if (s.cryptomatte.any()) crypto.emplace(scene, s.cryptomatte, s.spp, film);
  const TileRenderer tiles(scene, camera, integrator, s, tracer, film, wantAlbedo, crypto ? &*crypto : nullptr);

  tbb::enumerable_thread_specific<std::unique_ptr<ThreadScratch>> scratch;
  Progress progress("render", uint64_t(s.width) * s.height, s.progress);
  const auto t0 = std::chrono::steady_clock::now();

  const auto renderTile = [&](int tile) {
    if (cancel && cancel->load(std::memory_order_relaxed)) return;
    std::unique_ptr<ThreadScratch>& slot = scratch.local();
    if (!slot) slot = std::make_unique<ThreadScratch>(scene, tracer);
    if (const size_t pixels = tiles.renderTile(tile, *slot, cancel)) progress.advance(pixels);
  };

  const int threads = s.threads > 0 ? s.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, tiles.tileCount(), 1), [&](const tbb::blocked_range<int>& r) {
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
