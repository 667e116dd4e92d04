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
  if (recorder_) [[unlikely]]  // benchmark capture only (RayRecorder)
    return recorder_->occluded(scene_, ctx, batch.data(), unsigned(batch.size()));
  rtcOccluded1M(scene_, &ctx, batch.data(), unsigned(batch.size()), sizeof(RTCRay));
}

void Tracer::intersect(IntersectBatch& batch, RayCoherence c) const {
  if (batch.size() == 0) return;
  RTCIntersectContext ctx;
  initContext(ctx, c);
  if (recorder_) [[unlikely]]  // benchmark capture only (RayRecorder)
    return recorder_->intersect(scene_, ctx, batch.data(), unsigned(batch.size()));
  rtcIntersect1M(scene_, &ctx, batch.data(), unsigned(batch.size()), sizeof(RTCRayHit));
}

}  // namespace obscura
