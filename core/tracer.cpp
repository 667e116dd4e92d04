#include "core/tracer.h"

namespace obscura {
namespace {
// Lane masks for a full packet and for the tail packet of n % 16 rays.
struct ValidMasks {
  alignas(64) int full[16];
  alignas(64) int tail[17][16];
  ValidMasks() {
    for (int i = 0; i < 16; ++i) full[i] = -1;
    for (int n = 0; n <= 16; ++n)
      for (int i = 0; i < 16; ++i) tail[n][i] = i < n ? -1 : 0;
  }
};
const ValidMasks kMasks;

inline void initContext(RTCIntersectContext& ctx, RayCoherence c) {
  rtcInitIntersectContext(&ctx);
  ctx.flags = c == RayCoherence::Coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                                          : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
}
}  // namespace

// Whole packets with the full mask, then the tail packet with a partial one.
template <class Batch, class Fn>
inline void tracePackets(Batch& batch, Fn&& fn) {
  const size_t n = batch.size(), full = n / 16, rest = n % 16;
  auto* p = batch.packets();
  for (size_t k = 0; k < full; ++k) fn(kMasks.full, &p[k]);
  if (rest) fn(kMasks.tail[rest], &p[full]);
}

void Tracer::occluded(OcclusionBatch& batch, RayCoherence c) const {
  RTCIntersectContext ctx;
  initContext(ctx, c);
  tracePackets(batch, [&](const int* valid, RTCRay16* p) { rtcOccluded16(valid, scene_, &ctx, p); });
}

void Tracer::intersect(IntersectBatch& batch, RayCoherence c) const {
  RTCIntersectContext ctx;
  initContext(ctx, c);
  tracePackets(batch, [&](const int* valid, RTCRayHit16* p) { rtcIntersect16(valid, scene_, &ctx, p); });
}

}  // namespace obscura
