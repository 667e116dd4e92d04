#include "core/tracer.h"

namespace obscura {
namespace {
inline void initContext(RTCIntersectContext& ctx, RayCoherence c) {
  rtcInitIntersectContext(&ctx);
  ctx.flags = c == RayCoherence::Coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                                          : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
}
}  // namespace

void Tracer::occluded(OcclusionBatch& batch, RayCoherence c) const {
  if (batch.size() == 0) return;
  RTCIntersectContext ctx;
  initContext(ctx, c);
  rtcOccluded1M(scene_, &ctx, batch.data(), unsigned(batch.size()), sizeof(RTCRay));
}

void Tracer::intersect(IntersectBatch& batch, RayCoherence c) const {
  if (batch.size() == 0) return;
  RTCIntersectContext ctx;
  initContext(ctx, c);
  rtcIntersect1M(scene_, &ctx, batch.data(), unsigned(batch.size()), sizeof(RTCRayHit));
}

}  // namespace obscura
