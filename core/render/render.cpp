#include "core/render/render.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>

#include "core/render/adaptive.h"
#include "core/image/denoise.h"
#include "core/util/large_vector.h"
#include <obscura/error.h>
#include "core/render/gbuffer.h"
#include "core/render/pixel_sums.h"
#include "core/scene/surface.h"
#include "core/util/progress.h"
#include <obscura/sampler.h>
#include "core/util/option_names.h"

namespace obscura {
namespace {

// A pixel's mean albedo over its hits, or (1,1,1) for a pass whose solo
// render would not carry albedo (hits > 0).
Vec3 pixelAlbedo(const Sum3& albedo, uint32_t hits, bool wantAlbedo) {
  if (!wantAlbedo) return Vec3(1, 1, 1);
  const double invHits = 1.0 / double(hits);
  return Vec3(float(albedo.x * invHits), float(albedo.y * invHits), float(albedo.z * invHits));
}

// The error a pixel keeps after the filter: its error times the square root
// of the filter's variance reduction there (docs/math.md §13); kNoSurface
// (negative) and 0 pass as they are.
inline float filteredError(float error, float rootGain) { return error > 0.0f ? error * rootGain : error; }

// Camera samples per chunk. Large enough that per-chunk overhead
// vanishes, small enough that the batch and its hits stay in L1/L2.
constexpr size_t kChunk = 256;

// One chunk's lanes (camera samples) and what each stage leaves for the
// next, per thread, allocated once: the loop allocates nothing.
struct ThreadScratch {
  ThreadScratch(const Scene& scene, const Tracer& tracer, const EnvironmentView& env, size_t passes)
      : ctx(scene, tracer, env), W(passes * kChunk) {
    camera.reserve(kChunk);
    hits.reserve(kChunk);
  }
  IntegratorContext ctx;
  IntersectBatch camera;
  std::vector<SurfaceHit> hits;
  uint32_t lanePixel[kChunk];   // pixel (within tile) of each lane
  int32_t laneHit[kChunk];      // index into hits, or -1
  uint32_t hitLane[kChunk];     // the lane of hits[i]
  uint32_t laneKey[kChunk];     // Sampler key of the lane's pixel
  uint32_t laneSample[kChunk];  // sample index within the pixel
  // The pixel filter's draw of each lane (cameraRays): seeds, index, pixel.
  struct FilterLanes {
    uint32_t seedIndex[kChunk], seedX[kChunk], seedY[kChunk], index[kChunk];
    int px[kChunk], py[kChunk];
  } filter;
  std::vector<SampleEstimate> W;  // pass k's estimate of hit i: W[k * kChunk + i]
  std::vector<PixelSums> sums;  // the tile's pixels (the primary pass and the AOVs)
  std::vector<PassSums> passSums;  // the other passes: pixel j, pass k >= 1 at j * (passes - 1) + k - 1
  std::vector<HalfSums> even;   // the primary pass's even samples, per pixel
  // Where this tile's lanes accumulate: the vectors above (a fixed-spp
  // tile), or the window's sums that persist across adaptive rounds.
  PixelSums* sumsAt = nullptr;
  PassSums* passAt = nullptr;
  HalfSums* evenAt = nullptr;
  RayCounters cameraCounters;
  CryptomatteFilm::Tile crypto;  // empty unless Cryptomatte is on
};

// A pass as the tile loop sees it: its integrator, whether a solo render of
// it would carry albedo (so resolvePixel sees what it would see alone), and
// the film channel of its layer's R (G, B follow), or -1.
struct PassSlot {
  const Integrator* integrator;
  bool albedo;
  int layer;
  PixelLighting light;  // the primary's (slot 0) shaded.*
};

// The primary pass's lighting in `film` (PixelLighting), for settings whose
// environment is set (render() sets it).
PixelLighting primaryLighting(const RenderSettings& s, const Integrator& integrator, const IntegratorNeeds& needs,
                              const Film& film) {
  return {.env = &s.environment->view(), .shading = integrator.shading(), .bent = needs.bentE0,
          .plane = film.find(kLightingPlane)};
}

// Where a tile's walk through its samples stands. Pixel-major, sample-minor:
// each pixel's samples are summed in sample order whatever the chunking. The
// pixel's sampler key and filter seeds are hashed once per pixel.
struct SampleCursor {
  uint32_t pix = 0;          // the pixel's slot in the sums (ThreadScratch::sumsAt)
  uint32_t si = 0, end = 0;  // sample within the pixel, and the end of its samples this round
  int px = 0, py = 0;        // that pixel in the image
  // The keys of the pixel's two sample replicates (include/obscura/sampler.h
  // sampleStream: even samples, odd samples) and their filter seeds.
  uint32_t key[2] = {0, 0};
  Sampler::Seeds2 filterSeeds[2] = {};
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
  // The window's sums across adaptive rounds (window row-major).
  // On huge pages and first touched by all threads (core/util/large_vector.h):
  // at 1080p they hold ~350 MB, and faulting them in from one thread cost
  // a fifth of an adaptive render's CPU time (measured on this VM).
  struct WindowSums {
    LargeVector<PixelSums> sums;
    LargeVector<PassSums> passSums;
    LargeVector<HalfSums> even;
  };

  TileRenderer(const Scene& scene, const Camera& camera, std::span<const PassSlot> passes, const RenderSettings& s,
               const Tracer& tracer, Film& film, bool wantAlbedo, const CryptomatteFilm* crypto = nullptr)
      : scene_(scene), passes_(passes), s_(s), tracer_(tracer), film_(film), light_(passes[0].light),
        wantE0_(passes[0].light.wantsE0() && film.hasAlbedo()), shutter_(camera, s.width, s.height),
        sampler_(s.seed), tnear_(camera.znear), tfar_(camera.zfar), forward_(camera.toWorld.vector(Vec3(0, 0, -1))),
        wantAlbedo_(wantAlbedo), mattes_(scene.hasMattes()), crypto_(crypto), window_(renderWindow(s)),
        errorPlane_(film.find(kErrorPlane)), sppPlane_(film.find(kSppPlane)) {}

  // The tiles cut from the render's window (the frame, or --region).
  int tileCount() const { return PixelRect::tileCount(s_.tileSize, window_.width(), window_.height()); }
  PixelRect tileRect(int tile) const {
    PixelRect r = PixelRect::tile(tile, s_.tileSize, window_.width(), window_.height());
    r.x0 += window_.x0, r.x1 += window_.x0, r.y0 += window_.y0, r.y1 += window_.y0;
    return r;
  }

  // Adaptive rounds: each tile takes the samples `schedule` plans for its
  // pixels, into `sums`; resolveTile writes the film once they are done.
  void setSchedule(const SampleSchedule* schedule, WindowSums* sums) {
    schedule_ = schedule;
    window_sums_ = sums;
  }

  // Renders one tile's samples (of this round) into its sums and, at fixed
  // spp, into the film; returns the samples taken, or 0 when cancelled
  // (checked once per chunk: a relaxed load per kChunk samples).
  uint64_t renderTile(int tile, ThreadScratch& ts, const std::atomic<bool>* cancel) const {
    const PixelRect r = tileRect(tile);
    uint64_t total;
    if (schedule_) {
      total = schedule_->planned(r);
      if (total == 0) return 0;
      ts.sumsAt = window_sums_->sums.data();
      ts.passAt = window_sums_->passSums.data();
      ts.evenAt = window_sums_->even.data();
    } else {
      total = uint64_t(r.size()) * uint64_t(s_.spp);
      ts.sums.assign(r.size(), PixelSums{});
      ts.passSums.assign(r.size() * (passes_.size() - 1), PassSums{});
      ts.even.assign(r.size(), HalfSums{});
      ts.sumsAt = ts.sums.data(), ts.passAt = ts.passSums.data(), ts.evenAt = ts.even.data();
    }
    SampleCursor c;
    c.px = r.x0, c.py = r.y0;
    seekPixel(r, c);
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
    if (!schedule_) {
      resolve(r, ts.sums.data(), ts.passSums.data(), ts.even.data());
      if (crypto_) crypto_->endTile(ts.crypto);
    }
    return total;
  }

  // An adaptive render's tile into the film, once its rounds are done.
  // With `roundDone` between a round and SampleSchedule::next (which
  // moves each pixel's count on to its target): the film of the samples
  // taken so far, for the denoiser's gain.
  void resolveTile(int tile, bool roundDone = false) const {
    resolve(tileRect(tile), window_sums_->sums.data(), window_sums_->passSums.data(), window_sums_->even.data(),
            roundDone);
  }

  // The primary pass's composited standard error (compositedError) of
  // every pixel of the window (window row-major) from the adaptive sums:
  // what the schedule decides on. Only the pixels that took samples this
  // round (the schedule's running list) are recomputed: the others' sums,
  // and so their errors in `error` from an earlier round, have not changed
  // (late rounds touch few pixels). With `rootGain` (the square root of
  // the filter's variance reduction, docs/math.md §13), decide[i] =
  // error[i] x rootGain[i] for those pixels as well (kNoSurface and 0 as
  // they are).
  void windowErrors(float* error, const float* rootGain = nullptr, float* decide = nullptr) const {
    const LargeVector<uint32_t>& running = schedule_->running();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, running.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t k = r.begin(); k != r.end(); ++k) {
        const uint32_t i = running[k];
        const float e = scheduleError(window_sums_->sums[i], window_sums_->even[i], schedule_->target(i));
        error[i] = e;
        if (rootGain) decide[i] = filteredError(e, rootGain[i]);
      }
    });
  }

 private:
  float pixelError(const PixelSums& p, const HalfSums& even) const {
    const PassSlot& primary = passes_[0];
    return standardError(p.num, p.den, p.hits, even, *primary.integrator,
                         p.hits ? pixelAlbedo(p.albedo, p.hits, primary.albedo) : Vec3(1, 1, 1));
  }

  float scheduleError(const PixelSums& p, const HalfSums& even, uint32_t n) const {
    const PassSlot& primary = passes_[0];
    return compositedError(p.num, p.den, p.hits, even, *primary.integrator,
                           p.hits ? pixelAlbedo(p.albedo, p.hits, primary.albedo) : Vec3(1, 1, 1), n);
  }

  // Pixel (px, py)'s slot in the sums and its samples this round.
  uint32_t slotOf(const PixelRect& r, int px, int py) const {
    return uint32_t(schedule_ ? window_.offset(px, py) : r.offset(px, py));
  }

  // Moves c from pixel (c.px, c.py) on to the first pixel of the tile, in
  // row-major order, with samples this round (a fixed-spp round: that very
  // pixel), and sets its sample range, sampler key and filter seeds. The
  // caller knows the tile's sample count, so it never seeks past the last.
  void seekPixel(const PixelRect& r, SampleCursor& c) const {
    for (; c.py < r.y1;) {
      uint32_t begin = 0, end = uint32_t(s_.spp);
      if (schedule_) {
        const size_t i = window_.offset(c.px, c.py);
        begin = schedule_->taken(i), end = schedule_->target(i);
      }
      if (begin < end) {
        c.pix = slotOf(r, c.px, c.py);
        c.si = begin, c.end = end;
        break;
      }
      if (++c.px == r.x1) c.px = r.x0, ++c.py;
    }
    if (c.py >= r.y1) return;
    const uint32_t key = sampler_.pixelKey(uint32_t(c.px), uint32_t(c.py));
    for (uint32_t g = 0; g < 2; ++g) {
      c.key[g] = sampleStream(key, g).key;
      c.filterSeeds[g] = Sampler::seeds2D(c.key[g], kDimPixelFilter);
    }
  }

  // Camera samples -> rays: the next n samples of the tile into ts.camera,
  // with each lane's pixel, sampler key and sample index.
  void cameraRays(const PixelRect& r, SampleCursor& c, size_t n, ThreadScratch& ts) const {
    IntersectBatch& cam = ts.camera;
    cam.clear();
    // Each lane's pixel, filter seeds and index first; then the filter
    // samples of all lanes at once (Sampler::get2DLanes: SIMD), their film
    // positions (shared with the G-buffer: core/render/gbuffer.h), and the still
    // camera's directions across lanes (RasterCamera::directions: the
    // normalizations overlap).
    float fx[kChunk], fy[kChunk];
    ThreadScratch::FilterLanes& f = ts.filter;
    for (size_t l = 0; l < n; ++l) {
      // Sample si draws from replicate si & 1 at index si >> 1 (include/obscura/sampler.h).
      const uint32_t g = c.si & 1U;
      f.seedIndex[l] = c.filterSeeds[g].index, f.seedX[l] = c.filterSeeds[g].x, f.seedY[l] = c.filterSeeds[g].y;
      f.index[l] = c.si >> 1;
      f.px[l] = c.px, f.py[l] = c.py;
      ts.lanePixel[l] = c.pix;
      ts.laneKey[l] = c.key[g];
      ts.laneSample[l] = c.si;
      if (++c.si == c.end) {  // next pixel
        if (++c.px == r.x1) c.px = r.x0, ++c.py;
        seekPixel(r, c);
      }
    }
    Sampler::get2DLanes(f.seedIndex, f.seedX, f.seedY, f.index, n, fx, fy);
    for (size_t l = 0; l < n; ++l) cameraFilmPosition(s_.filter, {fx[l], fy[l]}, f.px[l], f.py[l], fx[l], fy[l]);
    if (s_.motionBlur) {
      for (size_t l = 0; l < n; ++l) {
        // The sample's moment in the shutter, from a dimension of its own:
        // the other dimensions - and so a still scene's image - are those
        // of a render without motion blur.
        const float time = Sampler::get1D(ts.laneKey[l], f.index[l], kDimShutterTime);
        const RasterCamera raster = shutter_.at(time);
        cam.pushCamera(raster.org, raster.direction(fx[l], fy[l]), tnear_, tfar_, time);
      }
    } else {
      const RasterCamera& raster = shutter_.still();
      Vec3 dir[kChunk];
      raster.directions(fx, fy, n, dir);
      for (size_t l = 0; l < n; ++l) cam.pushCamera(raster.org, dir[l], tnear_, tfar_);
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
  // pass 0; docs/production.md "Objects and roles").
  void surfaceHits(size_t n, ThreadScratch& ts) const {
    const IntersectBatch& cam = ts.camera;
    // The lanes that hit first, then their SurfaceHits four at a time
    // (computeSurfaceHits: SIMD across hits, bit for bit the scalar form).
    uint32_t count = 0;
    for (size_t l = 0; l < n; ++l) {
      if (!cam.hit(l) || (mattes_ && scene_.isMatte(scene_.objectOf(cam.geomID(l), cam.instID(l))))) {
        ts.laneHit[l] = -1;
        continue;
      }
      ts.laneHit[l] = int32_t(count);
      ts.hitLane[count++] = uint32_t(l);
    }
    // No clear(): computeSurfaceHits writes every field but albedo when it
    // is not asked for, and pixelKey/sampleIndex follow below; a render asks
    // for albedo in every chunk or in none (wantAlbedo_, and the scratch
    // lives for one render), so an unasked albedo stays the value-initialized
    // 0 of the element's first use, as a fresh element would have it -
    // without re-initializing every hit of every chunk.
    ts.hits.resize(count);
    computeSurfaceHits(scene_, cam.data(), ts.hitLane, count, wantAlbedo_, ts.hits.data());
    for (uint32_t i = 0; i < count; ++i) {
      SurfaceHit& h = ts.hits[i];
      const uint32_t l = ts.hitLane[i];
      h.pixelKey = ts.laneKey[l];  // the sample's replicate
      h.sampleIndex = ts.laneSample[l] >> 1;
    }
  }

  // The chunk's camera hits, in lane order (pixel-major, sample-minor),
  // into the Cryptomatte counts; holdouts and misses have no id.
  void cryptomatteHits(size_t n, ThreadScratch& ts) const {
    for (size_t l = 0; l < n; ++l)
      if (ts.laneHit[l] >= 0) crypto_->addHit(ts.crypto, ts.lanePixel[l], ts.hits[size_t(ts.laneHit[l])]);
  }

  // Each pass's estimate of every hit (ts.W), as one batch per pass: the
  // passes share the hits, not their samples.
  void estimate(ThreadScratch& ts) const {
    if (ts.hits.empty()) return;
    for (size_t k = 0; k < passes_.size(); ++k) {
      SampleEstimate* W = ts.W.data() + k * kChunk;
      for (size_t i = 0; i < ts.hits.size(); ++i) W[i] = {Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(0, 0, 0)};
      passes_[k].integrator->estimate(ts.hits, ts.ctx, W);
    }
  }

  // Each lane's estimate (and AOV values) into its pixel's sums, in lane
  // order, that is in sample order within a pixel.
  //
  // A pixel's samples are consecutive lanes (pixel-major), so its sums are
  // copied into locals for the run of its lanes and stored once after it:
  // the same additions in the same order (the same bits), but the compiler
  // keeps the running sums in registers instead of a chain of stores and
  // reloads through memory per lane (it cannot tell the sums from the
  // arrays the lane values come from).
  void accumulate(size_t n, ThreadScratch& ts) const {
    for (size_t run = 0; run < n;) {
      const uint32_t pix = ts.lanePixel[run];
      size_t runEnd = run + 1;
      while (runEnd < n && ts.lanePixel[runEnd] == pix) ++runEnd;
      PixelSums p = ts.sumsAt[pix];
      HalfSums even = ts.evenAt[pix];
      for (size_t l = run; l < runEnd; ++l) accumulateLane(l, ts, p, even);
      ts.sumsAt[pix] = p;
      ts.evenAt[pix] = even;
      run = runEnd;
    }
  }
  // One lane into its pixel's running sums (accumulate).
  void accumulateLane(size_t l, const ThreadScratch& ts, PixelSums& p, HalfSums& even) const {
    const int32_t hi = ts.laneHit[l];
    if (hi < 0) return;
    const SurfaceHit& h = ts.hits[size_t(hi)];
    p.num.add(ts.W[size_t(hi)].num);
    p.den.add(ts.W[size_t(hi)].den);
    if (p.hits == 0) p.object = h.object;
    p.hits += 1;
    // The even half for the error estimate (docs/math.md §13).
    if ((ts.laneSample[l] & 1u) == 0) even.add(ts.W[size_t(hi)]);
    for (size_t k = 1; k < passes_.size(); ++k) {
      PassSums& q = ts.passAt[size_t(ts.lanePixel[l]) * (passes_.size() - 1) + k - 1];
      const SampleEstimate& w = ts.W[k * kChunk + size_t(hi)];
      q.num.add(w.num);
      q.den.add(w.den);
    }
    if (wantAlbedo_) p.albedo.add(h.albedo);
    if (wantE0_) p.e0.add(light_.env->irradianceOverPi(h.ns));
    if (light_.bent) p.bent.add(ts.W[size_t(hi)].bent);
    if (s_.aovs) {
      p.N.add(h.ns);
      // Z is camera-plane depth: the hit's distance along the view axis,
      // t times the cosine between the (unit) ray and that axis.
      const Ray& ray = ts.camera.data()[l].ray;
      const Vec3 forward = shutter_.moves() ? normalize(shutter_.at(ray.time).axis) : forward_;
      p.Z += double(h.t) * double(dot(Vec3(ray.dir_x, ray.dir_y, ray.dir_z), forward));
    }
  }

  // The tile's sums (slots as slotOf) into the film, each pixel over the
  // samples it took. Each pixel belongs to exactly one tile, so no locking.
  void resolve(const PixelRect& r, const PixelSums* sums, const PassSums* passSums, const HalfSums* even,
               bool roundDone = false) const {
    const PassSlot& primary = passes_[0];
    for (int fy = r.y0; fy < r.y1; ++fy)
      for (int fx = r.x0; fx < r.x1; ++fx) {
        const size_t j = slotOf(r, fx, fy);
        const size_t i = window_.offset(fx, fy);
        const int n = schedule_ ? int(roundDone ? schedule_->target(i) : schedule_->taken(i)) : s_.spp;
        const PixelSums& p = sums[j];
        resolvePixelSums(p, n, *primary.integrator, primary.albedo, light_, film_, fx, fy);
        if (errorPlane_ >= 0) film_.at(errorPlane_, fx, fy) = writtenError(pixelError(p, even[j]), film_, fx, fy);
        if (sppPlane_ >= 0) film_.at(sppPlane_, fx, fy) = float(n);
        if (objects_) objects_[window_.offset(fx, fy)] = p.object;
        if (primary.layer >= 0)
          for (int c = 0; c < 3; ++c) film_.at(primary.layer + c, fx, fy) = film_.at(kR + c, fx, fy);
        for (size_t k = 1; k < passes_.size(); ++k) {
          const PassSums& q = passSums[j * (passes_.size() - 1) + k - 1];
          resolvePassLayer(q, p.hits, p.albedo, n, *passes_[k].integrator, passes_[k].albedo, film_,
                           passes_[k].layer, fx, fy);
        }
      }
  }

  const Scene& scene_;
  const std::span<const PassSlot> passes_;
  const RenderSettings& s_;
  const Tracer& tracer_;
  Film& film_;
  const PixelLighting light_;  // the primary's shaded.*
  const bool wantE0_;          // PixelSums::e0 is summed
  const ShutterCamera shutter_;
  const Sampler sampler_;
  const float tnear_, tfar_;
  const Vec3 forward_;  // the camera's view axis (world, unit)
  const bool wantAlbedo_;
  const bool mattes_;
  const CryptomatteFilm* crypto_;  // null: Cryptomatte off
  const PixelRect window_;
  const int errorPlane_, sppPlane_;  // film planes W_error and spp, or -1
  const SampleSchedule* schedule_ = nullptr;  // null: every pixel takes spp samples in one round
  WindowSums* window_sums_ = nullptr;
  uint32_t* objects_ = nullptr;  // --denoise: each pixel's first object (window row-major), else null
 public:
  void setObjects(uint32_t* objects) { objects_ = objects; }
};

}  // namespace

namespace {

// A pass's W at a pixel: the ratio of its sums, through resolvePixel.
Vec3 resolvePass(const Sum3& num, const Sum3& den, const Integrator& integrator, Vec3 albedo) {
  return integrator.resolvePixel(
      Vec3(resolveRatio(num.x, den.x), resolveRatio(num.y, den.y), resolveRatio(num.z, den.z)), albedo);
}

}  // namespace

void resolvePixelSums(const PixelSums& p, int spp, const Integrator& integrator, bool wantAlbedo,
                      const PixelLighting& light, Film& film, int fx, int fy) {
  const bool aovs = film.hasAovs();
  const double coverage = double(p.hits) / double(spp);
  film.at(kA, fx, fy) = float(coverage);
  if (p.hits == 0) {  // background: zero (premultiplied), Z far but finite
    if (aovs) film.at(kZ, fx, fy) = kBackgroundDepth;
    return;
  }
  // The pass and the albedo are means over the pixel's hits, then
  // premultiplied by coverage.
  const double invHits = 1.0 / double(p.hits);
  const Vec3 albedo = pixelAlbedo(p.albedo, p.hits, wantAlbedo);
  const Vec3 W = resolvePass(p.num, p.den, integrator, albedo);
  film.at(kR, fx, fy) = float(double(W.x) * coverage);
  film.at(kG, fx, fy) = float(double(W.y) * coverage);
  film.at(kB, fx, fy) = float(double(W.z) * coverage);
  if (!aovs) return;
  if (film.hasAlbedo()) {
    film.at(kAlbedoR, fx, fy) = float(double(albedo.x) * coverage);
    film.at(kAlbedoG, fx, fy) = float(double(albedo.y) * coverage);
    film.at(kAlbedoB, fx, fy) = float(double(albedo.z) * coverage);
    // shaded = albedo * W * lighting (docs/math.md §1, §14.6), from the
    // pixel's albedo and pass: exactly the product a compositor would form
    // (with lighting.R/G/B, written beside it under an environment map).
    const Vec3 sky = light.at(p);
    film.at(kShadedR, fx, fy) = float(double(albedo.x) * W.x * sky.x * coverage);
    film.at(kShadedG, fx, fy) = float(double(albedo.y) * W.y * sky.y * coverage);
    film.at(kShadedB, fx, fy) = float(double(albedo.z) * W.z * sky.z * coverage);
    if (light.plane >= 0) {
      film.at(light.plane, fx, fy) = float(double(sky.x) * coverage);
      film.at(light.plane + 1, fx, fy) = float(double(sky.y) * coverage);
      film.at(light.plane + 2, fx, fy) = float(double(sky.z) * coverage);
    }
  }
  const Vec3 nsum(float(p.N.x), float(p.N.y), float(p.N.z));
  const float nl = length(nsum);
  const Vec3 n = nl > 0.0f ? nsum * (1.0f / nl) : Vec3(0, 0, 0);
  film.at(kNX, fx, fy) = n.x;
  film.at(kNY, fx, fy) = n.y;
  film.at(kNZ, fx, fy) = n.z;
  film.at(kZ, fx, fy) = float(p.Z * invHits);
}


float writtenError(float se, const Film& film, int fx, int fy) {
  if (std::isfinite(se)) return se;
  const float a = film.at(kA, fx, fy);
  if (!(a > 0.0f)) return 0.0f;
  return std::max({std::fabs(film.at(kR, fx, fy)), std::fabs(film.at(kG, fx, fy)), std::fabs(film.at(kB, fx, fy))}) / a;
}

float standardError(const Sum3& num, const Sum3& den, uint32_t hits, const HalfSums& even,
                    const Integrator& integrator, Vec3 albedo) {
  if (hits == 0) return 0.0f;
  const uint32_t a = even.hits, b = hits - even.hits;
  if (a == 0 || b == 0) return std::numeric_limits<float>::infinity();
  const Sum3 oddNum{num.x - even.num.x, num.y - even.num.y, num.z - even.num.z};
  const Sum3 oddDen{den.x - even.den.x, den.y - even.den.y, den.z - even.den.z};
  const Vec3 We = resolvePass(even.num, even.den, integrator, albedo);
  const Vec3 Wo = resolvePass(oddNum, oddDen, integrator, albedo);
  // Var(W_e - W_o) = s^2 (1/a + 1/b) and Var(W) = s^2 / (a + b) for
  // per-hit variance s^2, so se(W) = |W_e - W_o| sqrt(ab) / (a + b)
  // (docs/math.md §13); = |W_e - W_o| / 2 for equal halves.
  const double scale = std::sqrt(double(a) * double(b)) / double(a + b);
  const double d = std::max({std::fabs(double(We.x) - Wo.x), std::fabs(double(We.y) - Wo.y), std::fabs(double(We.z) - Wo.z)});
  return float(d * scale);
}

float compositedError(const Sum3& num, const Sum3& den, uint32_t hits, const HalfSums& even,
                      const Integrator& integrator, Vec3 albedo, uint32_t n) {
  if (hits == 0) return kNoSurface;
  if (n < 2) return std::numeric_limits<float>::infinity();
  // The composited pass of each half, P = (hits / samples) W: the even half
  // took ceil(n/2) samples, the odd half floor(n/2); a half without a hit
  // composites to 0, so P_e and P_o are defined wherever the pixel has a
  // hit. They are independent replicates (docs/math.md §13): for a
  // per-sample variance v of P, Var(P_e - P_o) = v (1/n_e + 1/n_o) and
  // Var(P) = v / n, so se(P) = |P_e - P_o| sqrt(n_e n_o) / n - se(W)
  // where the pixel is fully covered, and with its coverage's noise where
  // it is not.
  const uint32_t ne = (n + 1) / 2, no = n / 2;
  const uint32_t a = even.hits, b = hits - even.hits;
  const Sum3 oddNum{num.x - even.num.x, num.y - even.num.y, num.z - even.num.z};
  const Sum3 oddDen{den.x - even.den.x, den.y - even.den.y, den.z - even.den.z};
  const Vec3 We = a ? resolvePass(even.num, even.den, integrator, albedo) : Vec3(0, 0, 0);
  const Vec3 Wo = b ? resolvePass(oddNum, oddDen, integrator, albedo) : Vec3(0, 0, 0);
  const double ce = double(a) / double(ne), co = double(b) / double(no);
  const double d = std::max({std::fabs(ce * We.x - co * Wo.x), std::fabs(ce * We.y - co * Wo.y),
                             std::fabs(ce * We.z - co * Wo.z)});
  return float(d * std::sqrt(double(ne) * double(no)) / double(n));
}

void resolvePassLayer(const PassSums& q, uint32_t hits, const Sum3& albedo, int spp, const Integrator& integrator,
                      bool wantAlbedo, Film& film, int layer, int fx, int fy) {
  if (hits == 0) return;  // background: the planes' zeros
  // The same arithmetic as resolvePixelSums' R,G,B, so a pass in a layer
  // equals its solo render bit for bit.
  const double coverage = double(hits) / double(spp);
  const Vec3 W = resolvePass(q.num, q.den, integrator, pixelAlbedo(albedo, hits, wantAlbedo));
  film.at(layer + 0, fx, fy) = float(double(W.x) * coverage);
  film.at(layer + 1, fx, fy) = float(double(W.y) * coverage);
  film.at(layer + 2, fx, fy) = float(double(W.z) * coverage);
}

void checkRegion(const PixelRect& r, int width, int height) {
  const std::string text = "--region " + std::to_string(r.x0) + "," + std::to_string(r.y0) + "," + std::to_string(r.x1) +
                           "," + std::to_string(r.y1) + ": ";
  if (r.x1 <= r.x0 || r.y1 <= r.y0) throw Error(text + "empty: X1 must exceed X0 and Y1 must exceed Y0");
  if (r.x0 < 0 || r.y0 < 0 || r.x1 > width || r.y1 > height)
    throw Error(text + "outside the " + std::to_string(width) + "x" + std::to_string(height) +
                " image (pixels [0," + std::to_string(width) + ") x [0," + std::to_string(height) + "))");
}

void checkRegionPasses(const RenderSettings& s, bool anyScreenSpace) {
  // --region with a screen-space pass: its layers carry a guard band, so
  // its pixels read what the full frame's do (renderScreenSpace refuses a
  // pass without one).
  // A G-buffer holds one instant of the scene per pixel layer, and its
  // passes compare depths across pixels: samples at different times in the
  // shutter would be compared as if they were one surface.
  if (s.motionBlur && anyScreenSpace)
    throw Error("--shutter: motion blur is not available with a screen-space pass (its G-buffer holds one instant); "
                "render it without --shutter or use a ray-traced pass");
}

void checkCheckpointPasses(const RenderSettings& s, bool anyScreenSpace) {
  if (s.checkpoint && anyScreenSpace)
    throw Error("--checkpoint: not available with a screen-space pass (its G-buffer loop has no tiles to save); "
                "render without --checkpoint");
}

void checkAlbedoPasses(const RenderSettings& s, const IntegratorNeeds& primary) {
  // A pass whose W depends on the pixel's albedo is denoised with albedo
  // edges as edges: the filter reads the film's albedo planes.
  if (s.denoise && !s.albedoAov && primary.pixelAlbedo)
    throw Error("--no-albedo: the denoiser of the primary pass is guided by the albedo AOV (its W depends on "
                "albedo); drop --no-albedo or --denoise");
}

namespace {

RayCounters threadRays(const ThreadScratch& ts) {
  return {ts.cameraCounters.camera, ts.ctx.counters.occlusion, ts.ctx.counters.closest};
}

void checkSettings(const RenderSettings& s) {
  if (s.width <= 0 || s.height <= 0) throw Error("resolution must be positive");
  if (s.spp <= 0) throw Error(settingName(Setting::Spp) + " must be at least 1");
  if (s.tileSize <= 0) throw Error("tile size must be at least 1");
  if (s.cryptomatte.any()) checkCryptomatteRanks(s.cryptomatte.ranks);
  if (hasRegion(s)) checkRegion(s.region, s.width, s.height);
  checkAdaptiveSettings(s);
  if (adaptiveSampling(s)) {
    const std::string what = s.targetError > 0.0f ? settingName(Setting::TargetError) : settingName(Setting::TimeLimit);
    // Both keep per-tile state that a tile's last sample completes; an
    // adaptive tile is revisited round after round.
    if (s.cryptomatte.any())
      throw Error(what + ": adaptive sampling does not yet write Cryptomatte layers; render them at a fixed spp");
    if (s.checkpoint)
      throw Error(what + ": adaptive sampling cannot be checkpointed (its rounds revisit every tile); "
                         "render without --checkpoint");
  }
  if (s.denoise && !s.aovs)
    throw Error("--denoise: the denoiser is guided by the AOVs (N, Z, W_error); drop --no-aovs");
  // The filter reads neighbours up to 62 pixels away: a region's edge pixels
  // would be filtered with fewer neighbours than the full frame's, so merged
  // tiles would show seams; and a checkpoint's saved tiles do not keep the
  // object guide, so a resumed render would be filtered differently.
  if (s.denoise && hasRegion(s))
    throw Error("--denoise: not available with --region (the filter reads neighbouring pixels across tile edges); "
                "render the full frame to denoise it");
  if (s.denoise && s.checkpoint)
    throw Error("--denoise: not available with --checkpoint (saved tiles do not keep the denoiser's object guide); "
                "render without --checkpoint to denoise");
}

// The denoiser's settings for the primary pass (the filter's defaults:
// docs/denoise.md measures them per integrator).
DenoiseSettings denoiseSettings(const RenderSettings& s) {
  DenoiseSettings ds;
  ds.threads = s.threads;
  return ds;
}

// The denoiser's input from the film: the pass in the planes from `color`
// on (R,G,B or noisy.*), its variance W_error^2 (into `variance`), the
// guides, the albedo planes only for a pass whose W follows the pixel's albedo.
DenoiseInput denoiseInput(const Film& film, int color, const IntegratorNeeds& needs, const uint32_t* objects,
                          LargeVector<float>& variance) {
  const size_t n = size_t(film.width()) * size_t(film.height());
  variance.resize(n);
  const float* error = film.plane(film.find(kErrorPlane));
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, size_t(1) << 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) variance[i] = error[i] * error[i];
  });
  DenoiseInput in;
  in.width = film.width(), in.height = film.height();
  for (int c = 0; c < 3; ++c) {
    in.color[c] = film.plane(color + c);
    in.normal[c] = film.plane(kNX + c);
    in.albedo[c] = needs.pixelAlbedo ? film.plane(kAlbedoR + c) : nullptr;
  }
  in.alpha = film.plane(kA);
  in.variance = variance.data();
  in.depth = film.plane(kZ);
  in.object = objects;
  // The taps weigh their pixel's samples (adaptive rounds take uneven counts).
  const int spp = film.find(kSppPlane);
  in.samples = spp >= 0 ? film.plane(spp) : nullptr;
  return in;
}

// The ray-traced passes `slots` (slots[0] into R,G,B) in one walk over the
// camera samples, into `film` (with its Cryptomatte layers if s asks).
void renderRayTraced(const Scene& scene, const Camera& camera, std::span<const PassSlot> slots, bool wantAlbedo,
                     const RenderSettings& s, Film& film, RenderStats& stats, const std::atomic<bool>* cancel,
                     uint32_t* objects, const IntegratorNeeds* denoised = nullptr,
                     DenoiseWorkspace* denoiseWorkspace = nullptr) {
  if (wantAlbedo)  // decode once, up front: the hot loop never throws or blocks
    for (const auto& t : scene.textures) t->decode();

  const Tracer tracer(scene.rtcScene(), s.recorder, scene.occlusionScopes());
  std::optional<CryptomatteFilm> crypto;
  if (s.cryptomatte.any()) crypto.emplace(scene, s.cryptomatte, s.spp, film);
  TileRenderer tiles(scene, camera, slots, s, tracer, film, wantAlbedo, crypto ? &*crypto : nullptr);
  tiles.setObjects(objects);

  tbb::enumerable_thread_specific<std::unique_ptr<ThreadScratch>> scratch;
  // Adaptive renders count samples, against the most they may take (every
  // pixel at spp) until the rounds' forecast revises it; fixed ones count
  // pixels.
  const bool adaptive = adaptiveSampling(s);
  const uint64_t window = uint64_t(renderWindow(s).size());
  Progress progress("render", adaptive ? window * uint64_t(s.spp) : window, s.progress);
  // The saved tiles of a resumed render are in the film before any other
  // tile starts, and are skipped.
  Checkpoint* const checkpoint = s.checkpoint;
  if (checkpoint) {
    checkpoint->start(film, s.tileSize, tiles.tileCount());
    const PixelRect w = renderWindow(s);
    for (int t = 0; t < tiles.tileCount(); ++t)
      if (checkpoint->done(t)) progress.advance(PixelRect::tile(t, s.tileSize, w.width(), w.height()).size());
  }
  const auto t0 = std::chrono::steady_clock::now();

  const auto renderTile = [&](int tile) {
    if (cancel && cancel->load(std::memory_order_relaxed)) return;
    if (checkpoint && checkpoint->done(tile)) return;
    std::unique_ptr<ThreadScratch>& slot = scratch.local();
    if (!slot) slot = std::make_unique<ThreadScratch>(scene, tracer, s.environment->view(), slots.size());
    const RayCounters before = threadRays(*slot);
    if (const uint64_t samples = tiles.renderTile(tile, *slot, cancel)) {
      progress.advance(adaptive ? samples : tiles.tileRect(tile).size());
      // Between tiles, on this thread: the hot loop never sees the checkpoint.
      if (checkpoint) {
        const RayCounters after = threadRays(*slot);
        checkpoint->finished(tile, {after.camera - before.camera, after.occlusion - before.occlusion,
                                    after.closest - before.closest});
      }
    }
  };

  const int threads = s.threads > 0 ? s.threads : tbb::this_task_arena::max_concurrency();
  tbb::task_arena arena(threads);
  const auto eachTile = [&](const auto& f) {
    tbb::parallel_for(tbb::blocked_range<int>(0, tiles.tileCount(), 1), [&](const tbb::blocked_range<int>& r) {
      for (int t = r.begin(); t != r.end(); ++t) f(t);
    });
  };
  const auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  stats.meanSpp = s.spp;
  if (!adaptive) {
    arena.execute([&] { eachTile(renderTile); });
  } else {
    // Rounds (core/render/adaptive.h): every round takes the samples the schedule
    // plans from the errors at the end of the one before; the film is
    // written once, from the sums the rounds leave.
    SampleSchedule schedule(renderWindow(s), s);
    TileRenderer::WindowSums sums;
    LargeVector<float> error(window);  // every pixel takes samples in the first round: all written
    // --denoise with a target (docs/sampling.md "Adaptive sampling"): the marginal
    // rule on each pixel's error times the square root of the filter's
    // variance reduction there (docs/math.md §13), the gain measured once,
    // on the first round's film. Not when the first round already takes
    // every sample a pixel may (--spp at most the first round's): no round
    // follows, and the gain would cost a filter pass for nothing.
    const bool forFilter = denoised && s.targetError > 0.0f && s.spp > firstRoundSpp(s);
    if (forFilter) schedule.setMarginal(true);
    LargeVector<float> rootGain, decide;
    arena.execute([&] {
      parallelFill(sums.sums, window, PixelSums{});
      parallelFill(sums.passSums, window * (slots.size() - 1), PassSums{});
      parallelFill(sums.even, window, HalfSums{});
      tiles.setSchedule(&schedule, &sums);
      for (;;) {
        eachTile(renderTile);
        if (cancel && cancel->load()) return;
        // Once the gain is known, each round's decision errors are updated
        // with the errors, for the running pixels only.
        const bool haveGain = !rootGain.empty();
        tiles.windowErrors(error.data(), haveGain ? rootGain.data() : nullptr, haveGain ? decide.data() : nullptr);
        const float* decision = haveGain ? decide.data() : error.data();
        // The survey's decision reads only which pixels have a surface.
        if (forFilter && !haveGain && schedule.phase() != SampleSchedule::Phase::Survey) {
          // The film at --min-spp (resolved again at the end), through
          // the filter the render ends with; only its gain is kept. The
          // filter reads the whole film and the gain is indexed like the
          // window's errors: the same pixels, as --denoise refuses --region
          // (checkSettings), so the window is the frame.
          assert(window == uint64_t(film.width()) * uint64_t(film.height()));
          eachTile([&](int t) { tiles.resolveTile(t, true); });
          LargeVector<float> variance;
          const DenoiseInput in = denoiseInput(film, kR, *denoised, objects, variance);
          rootGain.resize(window);
          denoise(in, denoiseSettings(s), nullptr, rootGain.data(), denoiseWorkspace);  // the gain alone
          // The error the filtered pixel keeps (error x sqrt(gain));
          // kNoSurface and 0 as they are.
          decide.resize(window);
          tbb::parallel_for(tbb::blocked_range<size_t>(0, size_t(window), size_t(1) << 15),
                            [&](const tbb::blocked_range<size_t>& r) {
                              for (size_t i = r.begin(); i != r.end(); ++i) {
                                rootGain[i] = std::sqrt(rootGain[i]);
                                decide[i] = filteredError(error[i], rootGain[i]);
                              }
                            });
          decision = decide.data();
        }
        const uint64_t planned = schedule.next(decision);
        // The bar's total: what is taken and what the pixels' estimates
        // say is still to come.
        progress.setTotal(progress.done() + schedule.expectedRemaining());
        if (planned == 0) break;
        // --time-limit: no round starts that would end past it, at the rate
        // the rounds so far ran (samples per second).
        const double seconds = elapsed();
        if (s.timeLimit > 0.0 && schedule.phase() == SampleSchedule::Phase::Rounds &&
            seconds + seconds / double(schedule.total()) * double(planned) > s.timeLimit) {
          schedule.dropPlan();
          progress.setTotal(progress.done());
          break;
        }
      }
      eachTile([&](int t) { tiles.resolveTile(t); });
    });
    stats.meanSpp = schedule.meanSpp();
    stats.rounds = schedule.rounds();
    stats.backgroundSpp = int(schedule.backgroundSpp());
  }
  stats.seconds = elapsed();
  progress.finish();
  stats.rays = {};
  for (const auto& slot : scratch) {
    if (!slot) continue;
    const ThreadScratch& ts = *slot;
    stats.rays.camera += ts.cameraCounters.camera;
    stats.rays.occlusion += ts.ctx.counters.occlusion;
    stats.rays.closest += ts.ctx.counters.closest;
  }
  if (checkpoint) {
    // Only finished tiles count: a resumed render reports the rays of an
    // uninterrupted one, and the render-loop time of all its runs.
    stats.rays = checkpoint->rays();
    stats.seconds += checkpoint->earlierSeconds();
    if (cancel && cancel->load()) checkpoint->save();  // the last save of an interrupted render
  }
}


void copyPlanes(const Film& from, int fromChannel, Film& to, int toChannel, int count) {
  const size_t n = size_t(from.width()) * size_t(from.height());
  for (int c = 0; c < count; ++c) std::copy_n(from.plane(fromChannel + c), n, to.plane(toChannel + c));
}

// --denoise: the film's R,G,B through the edge-aware filter (core/image/denoise.h),
// the raw pass kept as noisy.R/G/B; the primary's layer copy and shaded.*
// (albedo x W x sky, premultiplied: albedo_pm W_pm sky / A) follow the
// denoised W, so the film stays one consistent pass.
void denoisePrimary(Film& film, const IntegratorNeeds& needs, const uint32_t* objects, const RenderSettings& s,
                    int layer, DenoiseWorkspace& workspace) {
  const size_t n = size_t(film.width()) * size_t(film.height());
  const int noisy = film.addPlane("noisy.R");
  film.addPlane("noisy.G"), film.addPlane("noisy.B");
  // On the render's threads (--threads), like the filter itself.
  tbb::task_arena arena(s.threads > 0 ? s.threads : tbb::this_task_arena::max_concurrency());
  arena.execute([&] {
    copyPlanes(film, kR, film, noisy, 3);
    LargeVector<float> variance;
    const DenoiseInput in = denoiseInput(film, noisy, needs, objects, variance);
    float* out[3] = {film.plane(kR), film.plane(kG), film.plane(kB)};
    denoise(in, denoiseSettings(s), out, nullptr, &workspace);
    if (layer >= 0) copyPlanes(film, kR, film, layer, 3);
    if (!film.hasAlbedo()) return;
    // The lighting: its planes (premultiplied, as the albedo), or the constant sky's.
    const Vec3 L = s.environment->meanRadiance();
    const double sky[3] = {L.x, L.y, L.z};
    const int light = film.find(kLightingPlane);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, size_t(1) << 16), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        const float a = film.plane(kA)[i];
        for (int c = 0; c < 3; ++c) {
          const double lighting = light >= 0 ? double(film.plane(light + c)[i]) / a : sky[c];
          film.plane(kShadedR + c)[i] =
              a > 0.0f ? float(double(film.plane(kAlbedoR + c)[i]) * film.plane(kR + c)[i] * lighting / a) : 0.0f;
        }
      }
    });
  });
}

}  // namespace

void addStats(RenderStats& total, const RenderStats& part) {
  total.seconds += part.seconds;
  total.rays.camera += part.rays.camera;
  total.rays.occlusion += part.rays.occlusion;
  total.rays.closest += part.rays.closest;
  total.gbufferSeconds += part.gbufferSeconds;
  total.screenSpaceSeconds += part.screenSpaceSeconds;
  total.filterSeconds += part.filterSeconds;
  // The primary pass's loop runs first: its samples per pixel are the film's.
  if (total.meanSpp == 0) total.meanSpp = part.meanSpp, total.rounds = part.rounds, total.backgroundSpp = part.backgroundSpp;
}

Film render(const Scene& scene, const Camera& camera, const Integrator& integrator, const IntegratorNeeds& needs,
            const RenderSettings& s, RenderStats& stats, const std::atomic<bool>* cancel) {
  const RenderPass pass{&integrator, needs, ""};
  return render(scene, camera, std::span<const RenderPass>(&pass, 1), s, stats, cancel);
}

void addLightingPlanes(Film& film, const RenderSettings& s) {
  if (!s.environment || s.environment->isConstant() || !film.hasAlbedo() || film.find(kLightingPlane) >= 0) return;
  film.addPlane("lighting.R"), film.addPlane("lighting.G"), film.addPlane("lighting.B");
}

RenderSettings withEnvironment(const RenderSettings& s) {
  RenderSettings out = s;
  if (!out.environment) out.environment = Environment::constant(s.sky);
  return out;
}

Film render(const Scene& scene, const Camera& camera, std::span<const RenderPass> passes,
            const RenderSettings& settings, RenderStats& stats, const std::atomic<bool>* cancel) {
  const RenderSettings s = withEnvironment(settings);
  checkSettings(s);
  if (passes.empty()) throw Error("nothing to render: no pass");
  for (size_t k = 1; k < passes.size(); ++k)
    if (passes[k].layer.empty()) throw Error("every pass but the first needs a layer name");
  stats = {};
  const auto screenSpace = [&](size_t k) { return passes[k].integrator->screenSpace(); };
  const bool anyScreenSpace =
      std::any_of(passes.begin(), passes.end(), [](const RenderPass& p) { return p.integrator->screenSpace() != nullptr; });
  checkRegionPasses(s, anyScreenSpace);
  checkCheckpointPasses(s, anyScreenSpace);
  checkAlbedoPasses(s, passes[0].needs);
  // Decode what the passes read, once, up front: estimate() never throws or
  // blocks on a lazy decode (the albedo textures: in each loop).
  if (std::any_of(passes.begin(), passes.end(), [](const RenderPass& p) { return p.needs.roughness; }))
    for (const auto& t : scene.dataTextures) t->decode();
  // Normal maps bend the shading normal every pass reads (the hit's ns, the
  // N AOV, the G-buffer's normal): decoded whenever the scene kept them.
  scene.decodeNormalMaps();

  // The loops after the primary's leave the ID mattes to it.
  RenderSettings others = s;
  others.cryptomatte = {};
  // Their films give only their R,G,B to a layer: no albedo AOV to look up.
  others.albedoAov = false;
  // The screen-space passes: one layer loop for all of them, sharing each
  // G-buffer layer (core/render/gbuffer.cpp); the primary's first when it
  // is one. Run first when the primary is one of them, after the
  // ray-traced walk otherwise (the primary's loop gives the stats' spp).
  std::vector<ScreenSpaceJob> jobs;
  std::vector<size_t> jobOf(passes.size(), SIZE_MAX);
  for (size_t k = 0; k < passes.size(); ++k)
    if (screenSpace(k)) {
      jobOf[k] = jobs.size();
      jobs.push_back({screenSpace(k), passes[k].needs, k == 0 ? s : others});
    }
  std::vector<Film> screenSpaceFilms;
  RenderStats part;
  if (screenSpace(0)) screenSpaceFilms = renderScreenSpace(scene, camera, jobs, part, cancel);

  // The film: the primary pass's loop fills R,G,B,A and the AOVs.
  Film film = screenSpace(0) ? std::move(screenSpaceFilms[0])
                             : Film(renderWindow(s), s.width, s.height, s.aovs, s.albedoAov);
  if (!screenSpace(0) && s.aovs) film.addPlane(kErrorPlane), film.addPlane(kSppPlane);
  if (!screenSpace(0)) addLightingPlanes(film, s);
  addStats(stats, part);
  // Layer planes in pass order, after the fixed channels (and the
  // Cryptomatte layers of a screen-space primary).
  const auto addLayers = [&](Film& f) {
    std::vector<int> layer(passes.size(), -1);
    for (size_t k = 0; k < passes.size(); ++k)
      if (!passes[k].layer.empty()) {
        layer[k] = f.addPlane(passes[k].layer + ".R");
        f.addPlane(passes[k].layer + ".G");
        f.addPlane(passes[k].layer + ".B");
      }
    return layer;
  };
  const std::vector<int> layer = addLayers(film);

  // The ray-traced passes: one shared walk over the camera samples.
  std::vector<size_t> rayTraced;
  // The albedo AOV's lookups only where the output film keeps it (the
  // walk's film is the output when the primary is ray-traced); a pass that
  // reads albedo looks it up either way.
  const bool albedoAov = s.aovs && s.albedoAov && !screenSpace(0);
  bool wantAlbedo = albedoAov;
  for (size_t k = 0; k < passes.size(); ++k)
    if (!screenSpace(k)) {
      rayTraced.push_back(k);
      wantAlbedo = wantAlbedo || passes[k].needs.albedo;
    }
  const auto slotsFor = [&](const std::vector<int>& layerOf, const Film& film) {
    std::vector<PassSlot> slots;
    for (size_t k : rayTraced)
      slots.push_back({passes[k].integrator, passes[k].needs.albedo || albedoAov, layerOf[k],
                       primaryLighting(s, *passes[k].integrator, passes[k].needs, film)});
    return slots;
  };
  // The denoiser's object guide: each pixel's first object, from the
  // ray-traced primary's walk (a screen-space primary: normal and depth only).
  std::vector<uint32_t> objects(s.denoise && !screenSpace(0) ? renderWindow(s).size() : 0, ~0U);
  // The filter's planes, shared by the adaptive rounds' gain pass and the
  // final filter (core/image/denoise.h).
  DenoiseWorkspace denoiseWorkspace;
  if (!rayTraced.empty()) {
    part = {};
    if (!screenSpace(0)) {
      renderRayTraced(scene, camera, slotsFor(layer, film), wantAlbedo, s, film, part, cancel,
                      objects.empty() ? nullptr : objects.data(), s.denoise ? &passes[0].needs : nullptr,
                      &denoiseWorkspace);
    } else {
      // The first ray-traced pass lands in R,G,B of a film of its own; every
      // ray-traced pass's layer is copied over.
      Film rt(renderWindow(s), s.width, s.height, others.aovs, others.albedoAov);
      const std::vector<int> rtLayer = addLayers(rt);
      renderRayTraced(scene, camera, slotsFor(rtLayer, rt), wantAlbedo, others, rt, part, cancel, nullptr);
      for (size_t k : rayTraced) copyPlanes(rt, rtLayer[k], film, layer[k], 3);
    }
    addStats(stats, part);
  }

  // Every other screen-space pass: its R,G,B to its layer.
  if (!screenSpace(0) && !jobs.empty() && !(cancel && cancel->load())) {
    part = {};
    screenSpaceFilms = renderScreenSpace(scene, camera, jobs, part, cancel);
    addStats(stats, part);
  }
  for (size_t k = 1; k < passes.size(); ++k)
    if (jobOf[k] < screenSpaceFilms.size()) copyPlanes(screenSpaceFilms[jobOf[k]], kR, film, layer[k], 3);
  if (screenSpace(0) && layer[0] >= 0) copyPlanes(film, kR, film, layer[0], 3);
  if (cancel && cancel->load()) {
    stats.seconds = -1;
    return film;
  }
  if (s.denoise) {
    const auto t0 = std::chrono::steady_clock::now();
    denoisePrimary(film, passes[0].needs, objects.empty() ? nullptr : objects.data(), s, layer[0], denoiseWorkspace);
    stats.denoiseSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  return film;
}

}  // namespace obscura
