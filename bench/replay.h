// The benches' one raw-Embree yardstick: capture and replay.
//
// 1. Capture (untimed). A render runs with RenderSettings::recorder set to a
//    CaptureRecorder (core/scene/tracer.h, RayRecorder). For every batch the
//    render traces - camera and secondary alike, in each thread's order - it
//    stores the rays (origin, tnear, direction, tfar, mask, id: 40 bytes), traces the
//    batch with the renderer's own call and context, and stores what came
//    back (geomID, primID, instID, t: 16 bytes). Storage is per thread, in
//    64 Ki-ray blocks, capped (an over-the-cap capture says so and is
//    unusable). Its ray count must equal the render's RenderStats.rays.
// 2. Check (untimed). Replayer::run(ReplayMode::Check) replays the capture
//    once and counts hits that are not bit-equal to the captured ones
//    (geomID, primID, instID, the bits of t).
// 3. Replay (timed). The very same batches, with the same sizes, context
//    flags (camera batches COHERENT, the rest INCOHERENT) and thread count,
//    traced through rtcIntersect1M / rtcOccluded1M in a task_arena with
//    tbb::parallel_for over groups of `group` consecutive chunks of one
//    thread's capture (a chunk: a camera batch and the secondary batches
//    after it; pass spp so a group is one 16x16 tile's worth, the renderer's
//    unit of parallel work). Each batch is expanded from the capture into an
//    Embree ray array and traced: nothing else. Reading the capture streams
//    40 bytes a ray from memory, which the renderer does not pay, so the
//    replay is if anything slightly pessimistic.
//    Diagnostics: Surface adds computeSurfaceHit (with albedo) at every hit
//    of every intersect batch; SurfaceSample adds the next cosine direction
//    and spawnOrigin at every hit (as the path estimator draws it).
//
// The replay carries no occlusion-scope filter (the benches' scenes have no
// roles); a scene with scopes would show up as Check mismatches.
#pragma once

#include <embree3/rtcore.h>
#include <tbb/enumerable_thread_specific.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "bench/common.h"
#include "core/render/render.h"
#include "core/scene/scene.h"
#include "core/scene/tracer.h"

namespace obscura::bench {

struct RayIn {  // what the renderer put in a ray (time 0, flags 0: checked)
  float org[3], tnear, dir[3], tfar;
  unsigned mask, id;  // id: the object the ray leaves from (RayBatch::push)
};
struct HitOut {  // what Embree gave back; t = tfar after tracing (-inf: occluded)
  unsigned geomID, primID, instID;
  float t;
};
struct BatchRec {
  RayIn* rays;
  HitOut* hits;
  uint32_t n;
  uint32_t flags;  // RTCIntersectContext::flags the renderer traced it with
  bool occlusion;  // rtcOccluded1M (else rtcIntersect1M)
};

struct ThreadCapture {
  static constexpr size_t kBlock = size_t(1) << 16;  // rays per storage block
  struct Block {
    std::unique_ptr<RayIn[]> rays;
    std::unique_ptr<HitOut[]> hits;
    size_t used = 0, cap = 0;
  };
  std::vector<Block> blocks;
  std::vector<BatchRec> batches;
  uint64_t rays = 0;
  uint64_t malformed = 0;  // rays with time/flags other than 0 (not replayed as such)
  std::pair<RayIn*, HitOut*> allocate(size_t n);
};

class CaptureRecorder final : public RayRecorder {
 public:
  explicit CaptureRecorder(size_t maxBytes) : maxBytes_(maxBytes) {}
  void intersect(RTCScene scene, RTCIntersectContext& ctx, RTCRayHit* rays, unsigned n) override;
  void occluded(RTCScene scene, RTCIntersectContext& ctx, RTCRay* rays, unsigned n) override;

  bool overflowed() const { return overflow_.load(); }
  size_t bytes() const { return bytes_.load(); }
  std::vector<const ThreadCapture*> threads() const;
  uint64_t rays() const;
  uint64_t malformed() const;

 private:
  BatchRec* store(unsigned n, const RTCIntersectContext& ctx, bool occlusion);
  void copyIn(const RTCRay& r, RayIn& in);

  tbb::enumerable_thread_specific<ThreadCapture> logs_;
  std::atomic<size_t> bytes_{0};
  std::atomic<bool> overflow_{false};
  size_t maxBytes_;
};

// Only traces: the hook's cost when set (virtual call + branch), an upper
// bound for its cost when unset (the branch alone).
class PassThroughRecorder final : public RayRecorder {
 public:
  void intersect(RTCScene scene, RTCIntersectContext& ctx, RTCRayHit* rays, unsigned n) override {
    rtcIntersect1M(scene, &ctx, rays, n, sizeof(RTCRayHit));
  }
  void occluded(RTCScene scene, RTCIntersectContext& ctx, RTCRay* rays, unsigned n) override {
    rtcOccluded1M(scene, &ctx, rays, n, sizeof(RTCRay));
  }
};

enum class ReplayMode { Raw, Check, Surface, SurfaceSample };

struct ReplayTally {
  uint64_t rays = 0;
  uint64_t batches = 0;
  uint64_t mismatches = 0;  // Check: hits not bit-equal to the capture's
  uint64_t surfaces = 0;    // Surface: hits rebuilt
  double sink = 0;          // Surface: keeps the rebuilt hits observable
};

class Replayer {
 public:
  // Groups of `group` consecutive chunks of one thread's capture are the
  // parallel tasks.
  Replayer(const Scene& scene, const CaptureRecorder& cap, size_t group, int threads);
  ~Replayer();
  size_t tasks() const { return tasks_.size(); }
  // One replay of every captured batch; returns wall seconds of the
  // parallel loop (arena creation included, as in obscura::render).
  double run(ReplayMode mode, ReplayTally& tally);

 private:
  struct Task {
    const ThreadCapture* capture;
    size_t begin, end;  // batch indices
  };
  struct Scratch;
  void replayTask(const Task& task, ReplayMode mode, Scratch& s) const;

  const Scene& scene_;
  int threads_;
  size_t maxBatch_ = 0;
  std::vector<Task> tasks_;
  tbb::enumerable_thread_specific<std::unique_ptr<Scratch>> scratch_;
};

uint64_t totalRays(const RayCounters& c);  // camera + closest + occlusion
bool sameFilm(const Film& a, const Film& b);

// Capture + check of one render: what every bench does before timing.
struct Capture {
  std::unique_ptr<CaptureRecorder> recorder;
  std::unique_ptr<Replayer> replayer;
  Film film;               // the capture render's image (timed renders must equal it)
  RenderStats stats;       // the capture render's
  bool overflowed = false; // over maxBytes: nothing else is set
  uint64_t mismatches = 0; // replayed hits not bit-equal to the captured ones
  double mib() const { return double(recorder->bytes()) / (1024.0 * 1024.0); }
  // Every captured ray is well-formed, their count equals RenderStats.rays
  // and every replayed hit matched.
  bool ok() const;
};
// Renders once with a CaptureRecorder (render(settings) must call
// obscura::render with them), then replays the capture once in Check mode.
template <class RenderFn>
Capture captureRender(const Scene& scene, RenderSettings s, int spp, int threads, double maxGiB, RenderFn&& render) {
  Capture c;
  c.recorder = std::make_unique<CaptureRecorder>(size_t(maxGiB * 1024.0 * 1024.0 * 1024.0));
  s.recorder = c.recorder.get();
  c.film = render(s, c.stats);
  c.overflowed = c.recorder->overflowed();
  if (c.overflowed) return c;
  c.replayer = std::make_unique<Replayer>(scene, *c.recorder, size_t(spp), threads);
  ReplayTally check;
  c.replayer->run(ReplayMode::Check, check);
  c.mismatches = check.mismatches;
  return c;
}

}  // namespace obscura::bench
