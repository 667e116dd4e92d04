#include "bench/replay.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstring>

#include <obscura/sampler.h>
#include "core/scene/surface.h"
#include <obscura/warp.h>

namespace obscura::bench {

namespace {
constexpr unsigned kInvalid = RTC_INVALID_GEOMETRY_ID;

void fill(const RayIn& in, RTCRay& r) {
  r.org_x = in.org[0]; r.org_y = in.org[1]; r.org_z = in.org[2]; r.tnear = in.tnear;
  r.dir_x = in.dir[0]; r.dir_y = in.dir[1]; r.dir_z = in.dir[2]; r.time = 0.0f;
  r.tfar = in.tfar; r.mask = in.mask; r.id = in.id; r.flags = 0;
}

bool sameBits(float a, float b) { return std::bit_cast<uint32_t>(a) == std::bit_cast<uint32_t>(b); }
}  // namespace

// ---------------------------------------------------------------------------
// Capture.

std::pair<RayIn*, HitOut*> ThreadCapture::allocate(size_t n) {
  if (blocks.empty() || blocks.back().cap - blocks.back().used < n) {
    Block b;
    b.cap = std::max(kBlock, n);
    b.rays.reset(new RayIn[b.cap]);
    b.hits.reset(new HitOut[b.cap]);
    blocks.push_back(std::move(b));
  }
  Block& b = blocks.back();
  const size_t at = b.used;
  b.used += n;
  return {b.rays.get() + at, b.hits.get() + at};
}

void CaptureRecorder::intersect(RTCScene scene, RTCIntersectContext& ctx, RTCRayHit* rays, unsigned n) {
  BatchRec* b = store(n, ctx, false);
  if (b)
    for (unsigned i = 0; i < n; ++i) copyIn(rays[i].ray, b->rays[i]);
  rtcIntersect1M(scene, &ctx, rays, n, sizeof(RTCRayHit));
  if (b)
    for (unsigned i = 0; i < n; ++i)
      b->hits[i] = {rays[i].hit.geomID, rays[i].hit.primID, rays[i].hit.instID[0], rays[i].ray.tfar};
}

void CaptureRecorder::occluded(RTCScene scene, RTCIntersectContext& ctx, RTCRay* rays, unsigned n) {
  BatchRec* b = store(n, ctx, true);
  if (b)
    for (unsigned i = 0; i < n; ++i) copyIn(rays[i], b->rays[i]);
  rtcOccluded1M(scene, &ctx, rays, n, sizeof(RTCRay));
  if (b)
    for (unsigned i = 0; i < n; ++i) b->hits[i] = {kInvalid, kInvalid, kInvalid, rays[i].tfar};
}

std::vector<const ThreadCapture*> CaptureRecorder::threads() const {
  std::vector<const ThreadCapture*> v;
  for (const ThreadCapture& t : logs_) v.push_back(&t);
  return v;
}
uint64_t CaptureRecorder::rays() const {
  uint64_t n = 0;
  for (const ThreadCapture& t : logs_) n += t.rays;
  return n;
}
uint64_t CaptureRecorder::malformed() const {
  uint64_t n = 0;
  for (const ThreadCapture& t : logs_) n += t.malformed;
  return n;
}

// A new batch record with room for n rays, or null once over the cap (the
// render goes on; the capture is then unusable and reported as such).
BatchRec* CaptureRecorder::store(unsigned n, const RTCIntersectContext& ctx, bool occlusion) {
  if (overflow_.load(std::memory_order_relaxed)) return nullptr;
  const size_t add = size_t(n) * (sizeof(RayIn) + sizeof(HitOut));
  if (bytes_.fetch_add(add) + add > maxBytes_) {
    overflow_ = true;
    return nullptr;
  }
  ThreadCapture& t = logs_.local();
  const auto [in, out] = t.allocate(n);
  t.rays += n;
  return &t.batches.emplace_back(BatchRec{in, out, n, uint32_t(ctx.flags), occlusion});
}

void CaptureRecorder::copyIn(const RTCRay& r, RayIn& in) {
  in = {{r.org_x, r.org_y, r.org_z}, r.tnear, {r.dir_x, r.dir_y, r.dir_z}, r.tfar, r.mask, r.id};
  if (r.time != 0.0f || r.flags != 0) ++logs_.local().malformed;
}

// ---------------------------------------------------------------------------
// Replay.

struct Replayer::Scratch {
  explicit Scratch(size_t n) : hit(std::max<size_t>(n, 1)), occ(std::max<size_t>(n, 1)) {}
  AlignedArray<RTCRayHit> hit;
  AlignedArray<RTCRay> occ;
  ReplayTally tally;
};

Replayer::Replayer(const Scene& scene, const CaptureRecorder& cap, size_t group, int threads)
    : scene_(scene), threads_(threads) {
  for (const ThreadCapture* t : cap.threads()) {
    size_t chunks = 0, begin = 0;
    for (size_t i = 0; i < t->batches.size(); ++i) {
      const BatchRec& b = t->batches[i];
      maxBatch_ = std::max<size_t>(maxBatch_, b.n);
      const bool camera = !b.occlusion && (b.flags & RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
      if (camera && chunks++ == group) {  // a group is full: it ends before this camera batch
        tasks_.push_back({t, begin, i});
        begin = i;
        chunks = 1;
      }
    }
    if (begin < t->batches.size()) tasks_.push_back({t, begin, t->batches.size()});
  }
}

Replayer::~Replayer() = default;

double Replayer::run(ReplayMode mode, ReplayTally& tally) {
  for (auto& s : scratch_)
    if (s) s->tally = {};
  const auto t0 = std::chrono::steady_clock::now();
  tbb::task_arena arena(threads_);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tasks_.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
      std::unique_ptr<Scratch>& slot = scratch_.local();
      if (!slot) slot = std::make_unique<Scratch>(maxBatch_);
      for (size_t t = r.begin(); t != r.end(); ++t) replayTask(tasks_[t], mode, *slot);
    });
  });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  tally = {};
  for (const auto& s : scratch_) {
    if (!s) continue;
    tally.rays += s->tally.rays;
    tally.batches += s->tally.batches;
    tally.mismatches += s->tally.mismatches;
    tally.surfaces += s->tally.surfaces;
    tally.sink += s->tally.sink;
  }
  return seconds;
}

void Replayer::replayTask(const Task& task, ReplayMode mode, Scratch& s) const {
  const RTCScene scene = scene_.rtcScene();
  for (size_t bi = task.begin; bi < task.end; ++bi) {
    const BatchRec& b = task.capture->batches[bi];
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTCIntersectContextFlags(b.flags);
    if (b.occlusion) {
      RTCRay* rays = s.occ.p;
      for (unsigned i = 0; i < b.n; ++i) fill(b.rays[i], rays[i]);
      rtcOccluded1M(scene, &ctx, rays, b.n, sizeof(RTCRay));
      if (mode == ReplayMode::Check)
        for (unsigned i = 0; i < b.n; ++i) s.tally.mismatches += sameBits(rays[i].tfar, b.hits[i].t) ? 0 : 1;
    } else {
      RTCRayHit* rays = s.hit.p;
      for (unsigned i = 0; i < b.n; ++i) {
        fill(b.rays[i], rays[i].ray);
        rays[i].hit.geomID = kInvalid;
        rays[i].hit.instID[0] = kInvalid;
      }
      rtcIntersect1M(scene, &ctx, rays, b.n, sizeof(RTCRayHit));
      if (mode == ReplayMode::Check) {
        for (unsigned i = 0; i < b.n; ++i) {
          const RTCHit& h = rays[i].hit;
          const HitOut& c = b.hits[i];
          const bool same = h.geomID == c.geomID && sameBits(rays[i].ray.tfar, c.t) &&
                            (h.geomID == kInvalid || (h.primID == c.primID && h.instID[0] == c.instID));
          s.tally.mismatches += same ? 0 : 1;
        }
      } else if (mode != ReplayMode::Raw) {
        SurfaceHit sh;
        for (unsigned i = 0; i < b.n; ++i) {
          const RTCRayHit& r = rays[i];
          if (r.hit.geomID == kInvalid) continue;
          computeSurfaceHit(scene_, r.hit.geomID, r.hit.primID, r.hit.instID[0], r.hit.u, r.hit.v, r.ray.tfar,
                            Vec3(r.ray.dir_x, r.ray.dir_y, r.ray.dir_z), r.ray.time, true, sh);
          s.tally.sink += double(sh.albedo.x) + double(sh.eps);
          ++s.tally.surfaces;
          if (mode != ReplayMode::SurfaceSample) continue;
          // The next direction as the path estimator draws it (key and
          // index stand in for the pixel's: the cost is the same).
          const Sample2 u = Sampler::get2D(uint32_t(bi), i, kFirstIntegratorDim);
          const Vec3 w = Frame::fromNormal(sh.ns).toWorld(squareToCosineHemisphere(u.u, u.v));
          const Vec3 o = spawnOrigin(sh, w);
          s.tally.sink += intoSurface(sh, w) ? 0.0 : double(o.x + w.y);
        }
      }
    }
    s.tally.rays += b.n;
    ++s.tally.batches;
  }
}

uint64_t totalRays(const RayCounters& c) { return c.camera + c.occlusion + c.closest; }

bool sameFilm(const Film& a, const Film& b) {
  if (a.width() != b.width() || a.height() != b.height()) return false;
  const size_t n = size_t(a.width()) * size_t(a.height());
  for (int c : {kR, kG, kB, kA})
    if (std::memcmp(a.plane(c), b.plane(c), n * sizeof(float)) != 0) return false;
  return true;
}

bool Capture::ok() const {
  return !overflowed && mismatches == 0 && recorder->malformed() == 0 && recorder->rays() == totalRays(stats.rays);
}

}  // namespace obscura::bench
