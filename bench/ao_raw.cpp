#include "bench/ao_raw.h"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>

#include "bench/common.h"
#include <obscura/error.h>
#include <obscura/sampler.h>
#include "core/scene/surface.h"
#include <obscura/warp.h>

namespace obscura::bench {

const char* rawApiName(RawApi api) {
  switch (api) {
    case RawApi::Single: return "raw rtcIntersect1/Occluded1";
    case RawApi::Packet16: return "raw rtcIntersect16/Occluded16";
    case RawApi::Stream1M: return "raw rtcIntersect1M/Occluded1M";
    case RawApi::StreamSurface: return "stream1M + computeSurfaceHit";
  }
  return "?";
}

namespace {

constexpr unsigned kInvalid = RTC_INVALID_GEOMETRY_ID;

// Valid-lane masks for 16-wide calls: masks[n] enables lanes 0..n-1.
struct LaneMasks {
  alignas(64) int masks[17][16];
  LaneMasks() {
    for (int n = 0; n <= 16; ++n)
      for (int i = 0; i < 16; ++i) masks[n][i] = i < n ? -1 : 0;
  }
};
const LaneMasks kLanes;

// Per-thread scratch, allocated once per thread for the tracer's lifetime.
struct ThreadBuffers {
  explicit ThreadBuffers(size_t chunk)
      : hit16((chunk + 15) / 16), occ16((chunk + 15) / 16), hit1M(chunk), occ1M(chunk), key(chunk), sample(chunk) {}
  AlignedArray<RTCRayHit16> hit16;
  AlignedArray<RTCRay16> occ16;
  AlignedArray<RTCRayHit> hit1M;
  AlignedArray<RTCRay> occ1M;
  AlignedArray<uint32_t> key;     // pixel key of each camera lane of the chunk
  AlignedArray<uint32_t> sample;  // sample index of each camera lane
  RayTally tally;
};

// The AO ray of ao.cpp, from what Embree returned (see ao_raw.h).
struct AoRay {
  Vec3 org, dir;
};
inline AoRay makeAoRay(Vec3 o, Vec3 d, float t, Vec3 ngRaw, uint32_t key, uint32_t sampleIndex) {
  const RawHitFrame f = rawHitFrame(o, d, t, ngRaw);
  const Sample2 s = Sampler::get2D(key, sampleIndex, kFirstIntegratorDim);  // rays = 1: index = sample
  return {f.org, f.frame.toWorld(squareToCosineHemisphere(s.u, s.v))};
}

inline void setContext(RTCIntersectContext& ctx, RTCIntersectContextFlags flags) {
  rtcInitIntersectContext(&ctx);
  ctx.flags = flags;
}

}  // namespace

struct RawAoTracer::Impl {
  Impl(const Scene& sc, const Camera& cam, const RawSettings& s)
      : obscuraScene(sc), scene(sc.rtcScene()), raster(cam, s.width, s.height), sampler(s.seed), tnear(cam.znear),
        tfar(cam.zfar), set(s) {
    if (s.chunk < 16 || s.chunk % 16) throw Error("--chunk must be a positive multiple of 16");
    if (s.threads < 1) throw Error("internal: thread count must be resolved");
  }

  const Scene& obscuraScene;
  RTCScene scene;
  RasterCamera raster;
  Sampler sampler;
  float tnear, tfar;
  RawSettings set;
  tbb::enumerable_thread_specific<std::unique_ptr<ThreadBuffers>> buffers;

  ThreadBuffers& local() {
    std::unique_ptr<ThreadBuffers>& b = buffers.local();
    if (!b) b = std::make_unique<ThreadBuffers>(size_t(set.chunk));
    return *b;
  }

  // --- (a) one ray at a time: camera ray, then its AO ray ------------------
  void tileSingle(ThreadBuffers& b, int x0, int y0, int tw, int th) const {
    RTCIntersectContext cc, oc;
    setContext(cc, RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
    setContext(oc, RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
    const uint64_t total = uint64_t(tw) * uint64_t(th) * uint64_t(set.spp);
    SampleWalk w(sampler, x0, y0, tw, set.spp);
    uint64_t ao = 0, unoccluded = 0;
    for (uint64_t i = 0; i < total; ++i, w.next()) {
      const Vec3 d = w.direction(raster);
      alignas(16) RTCRayHit rh;
      setRayHit(rh, raster.org, d, tnear, tfar, 0);
      rtcIntersect1(scene, &cc, &rh);
      if (rh.hit.geomID == kInvalid) continue;
      const AoRay a = makeAoRay(raster.org, d, rh.ray.tfar, Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z), w.key, w.index);
      alignas(16) RTCRay r;
      setRay(r, a.org, a.dir, 0.0f, set.aoDistance, 0);
      rtcOccluded1(scene, &oc, &r);
      ++ao;
      unoccluded += r.tfar >= 0.0f ? 1 : 0;
    }
    b.tally.camera += total;
    b.tally.ao += ao;
    b.tally.unoccluded += unoccluded;
  }

  // --- (b) 16-wide SoA packets: a chunk of camera packets, then the chunk's
  // AO rays compacted into full packets ----------------------------------
  void tilePacket(ThreadBuffers& b, int x0, int y0, int tw, int th) const {
    RTCIntersectContext cc, oc;
    setContext(cc, RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
    setContext(oc, RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
    const uint64_t total = uint64_t(tw) * uint64_t(th) * uint64_t(set.spp);
    SampleWalk w(sampler, x0, y0, tw, set.spp);
    RTCRayHit16* const cam = b.hit16.p;
    RTCRay16* const occ = b.occ16.p;
    uint64_t ao = 0, unoccluded = 0;
    for (uint64_t begin = 0; begin < total; begin += uint64_t(set.chunk)) {
      const size_t n = size_t(std::min<uint64_t>(uint64_t(set.chunk), total - begin));
      for (size_t i = 0; i < n; ++i, w.next()) {
        const Vec3 d = w.direction(raster);
        RTCRayHit16& p = cam[i >> 4];
        const size_t l = i & 15;
        p.ray.org_x[l] = raster.org.x; p.ray.org_y[l] = raster.org.y; p.ray.org_z[l] = raster.org.z;
        p.ray.tnear[l] = tnear;
        p.ray.dir_x[l] = d.x; p.ray.dir_y[l] = d.y; p.ray.dir_z[l] = d.z;
        p.ray.time[l] = 0.0f; p.ray.tfar[l] = tfar; p.ray.mask[l] = 0xffffffffU;
        p.ray.id[l] = unsigned(i); p.ray.flags[l] = 0;
        p.hit.geomID[l] = kInvalid;
        p.hit.instID[0][l] = kInvalid;
        b.key.p[i] = w.key;
        b.sample.p[i] = w.index;
      }
      const size_t packets = (n + 15) / 16;
      for (size_t k = 0; k < packets; ++k)
        rtcIntersect16(kLanes.masks[std::min<size_t>(16, n - k * 16)], scene, &cc, &cam[k]);

      size_t m = 0;
      for (size_t i = 0; i < n; ++i) {
        const RTCRayHit16& p = cam[i >> 4];
        const size_t l = i & 15;
        if (p.hit.geomID[l] == kInvalid) continue;
        const AoRay a = makeAoRay(raster.org, Vec3(p.ray.dir_x[l], p.ray.dir_y[l], p.ray.dir_z[l]), p.ray.tfar[l],
                                  Vec3(p.hit.Ng_x[l], p.hit.Ng_y[l], p.hit.Ng_z[l]), b.key.p[i], b.sample.p[i]);
        RTCRay16& q = occ[m >> 4];
        const size_t j = m & 15;
        q.org_x[j] = a.org.x; q.org_y[j] = a.org.y; q.org_z[j] = a.org.z; q.tnear[j] = 0.0f;
        q.dir_x[j] = a.dir.x; q.dir_y[j] = a.dir.y; q.dir_z[j] = a.dir.z;
        q.time[j] = 0.0f; q.tfar[j] = set.aoDistance; q.mask[j] = 0xffffffffU; q.id[j] = unsigned(m); q.flags[j] = 0;
        ++m;
      }
      const size_t aoPackets = (m + 15) / 16;
      for (size_t k = 0; k < aoPackets; ++k)
        rtcOccluded16(kLanes.masks[std::min<size_t>(16, m - k * 16)], scene, &oc, &occ[k]);
      for (size_t j = 0; j < m; ++j) unoccluded += occ[j >> 4].tfar[j & 15] >= 0.0f ? 1 : 0;
      ao += m;
    }
    b.tally.camera += total;
    b.tally.ao += ao;
    b.tally.unoccluded += unoccluded;
  }

  // --- (c) streams: a chunk of RTCRayHit through rtcIntersect1M, then the
  // chunk's AO rays as an RTCRay array through rtcOccluded1M ---------------
  // (kSurface: the StreamSurface diagnostic, see ao_raw.h.)
  template <bool kSurface>
  void tileStream(ThreadBuffers& b, int x0, int y0, int tw, int th) const {
    RTCIntersectContext cc, oc;
    setContext(cc, RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
    setContext(oc, RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
    const uint64_t total = uint64_t(tw) * uint64_t(th) * uint64_t(set.spp);
    SampleWalk w(sampler, x0, y0, tw, set.spp);
    RTCRayHit* const cam = b.hit1M.p;
    RTCRay* const occ = b.occ1M.p;
    uint64_t ao = 0, unoccluded = 0;
    for (uint64_t begin = 0; begin < total; begin += uint64_t(set.chunk)) {
      const size_t n = size_t(std::min<uint64_t>(uint64_t(set.chunk), total - begin));
      for (size_t i = 0; i < n; ++i, w.next()) {
        setRayHit(cam[i], raster.org, w.direction(raster), tnear, tfar, unsigned(i));
        b.key.p[i] = w.key;
        b.sample.p[i] = w.index;
      }
      rtcIntersect1M(scene, &cc, cam, unsigned(n), sizeof(RTCRayHit));

      size_t m = 0;
      for (size_t i = 0; i < n; ++i) {
        const RTCRayHit& r = cam[i];
        if (r.hit.geomID == kInvalid) continue;
        AoRay a;
        if constexpr (kSurface) {
          SurfaceHit h;
          computeSurfaceHit(obscuraScene, r.hit.geomID, r.hit.primID, r.hit.instID[0], r.hit.u, r.hit.v, r.ray.tfar,
                            Vec3(r.ray.dir_x, r.ray.dir_y, r.ray.dir_z), r.ray.time, false, h);
          const Frame frame = Frame::fromNormal(h.ns);
          const Sample2 s = Sampler::get2D(b.key.p[i], b.sample.p[i], kFirstIntegratorDim);
          a.dir = frame.toWorld(squareToCosineHemisphere(s.u, s.v));
          a.org = spawnOrigin(h, a.dir);
        } else {
          a = makeAoRay(raster.org, Vec3(r.ray.dir_x, r.ray.dir_y, r.ray.dir_z), r.ray.tfar,
                        Vec3(r.hit.Ng_x, r.hit.Ng_y, r.hit.Ng_z), b.key.p[i], b.sample.p[i]);
        }
        setRay(occ[m], a.org, a.dir, 0.0f, set.aoDistance, unsigned(m));
        ++m;
      }
      rtcOccluded1M(scene, &oc, occ, unsigned(m), sizeof(RTCRay));
      for (size_t j = 0; j < m; ++j) unoccluded += occ[j].tfar >= 0.0f ? 1 : 0;
      ao += m;
    }
    b.tally.camera += total;
    b.tally.ao += ao;
    b.tally.unoccluded += unoccluded;
  }
};

RawAoTracer::RawAoTracer(const Scene& scene, const Camera& camera, const RawSettings& settings)
    : impl_(std::make_unique<Impl>(scene, camera, settings)) {}

RawAoTracer::~RawAoTracer() = default;

double RawAoTracer::run(RawApi api, RayTally& tally) {
  Impl& im = *impl_;
  const RawSettings& s = im.set;
  for (auto& b : im.buffers)
    if (b) b->tally = {};
  const int tilesX = (s.width + s.tileSize - 1) / s.tileSize, tilesY = (s.height + s.tileSize - 1) / s.tileSize;

  const auto t0 = std::chrono::steady_clock::now();
  tbb::task_arena arena(s.threads);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, tilesX * tilesY, 1), [&](const tbb::blocked_range<int>& r) {
      ThreadBuffers& b = im.local();
      for (int t = r.begin(); t != r.end(); ++t) {
        const int x0 = (t % tilesX) * s.tileSize, y0 = (t / tilesX) * s.tileSize;
        const int tw = std::min(s.tileSize, s.width - x0), th = std::min(s.tileSize, s.height - y0);
        switch (api) {
          case RawApi::Single: im.tileSingle(b, x0, y0, tw, th); break;
          case RawApi::Packet16: im.tilePacket(b, x0, y0, tw, th); break;
          case RawApi::Stream1M: im.tileStream<false>(b, x0, y0, tw, th); break;
          case RawApi::StreamSurface: im.tileStream<true>(b, x0, y0, tw, th); break;
        }
      }
    });
  });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  tally = {};
  for (const auto& b : im.buffers) {
    if (!b) continue;
    tally.camera += b->tally.camera;
    tally.ao += b->tally.ao;
    tally.unoccluded += b->tally.unoccluded;
  }
  return seconds;
}

}  // namespace obscura::bench
