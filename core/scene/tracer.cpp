#include "core/scene/tracer.h"

#include <cstddef>

namespace obscura {

// obscura::Ray, Hit and RayHit (obscura/ray_batch.h) are Embree's structures
// under other names: the batches are handed to Embree as they are.
#define OBSCURA_SAME_FIELD(A, B, f) static_assert(offsetof(A, f) == offsetof(B, f));
static_assert(sizeof(Ray) == sizeof(RTCRay) && alignof(Ray) == alignof(RTCRay));
static_assert(sizeof(Hit) == sizeof(RTCHit) && alignof(Hit) == alignof(RTCHit));
static_assert(sizeof(RayHit) == sizeof(RTCRayHit) && offsetof(RayHit, hit) == offsetof(RTCRayHit, hit));
static_assert(RTC_MAX_INSTANCE_LEVEL_COUNT == 1 && kInvalidGeometryId == RTC_INVALID_GEOMETRY_ID);
OBSCURA_SAME_FIELD(Ray, RTCRay, org_x) OBSCURA_SAME_FIELD(Ray, RTCRay, org_y) OBSCURA_SAME_FIELD(Ray, RTCRay, org_z)
OBSCURA_SAME_FIELD(Ray, RTCRay, tnear) OBSCURA_SAME_FIELD(Ray, RTCRay, dir_x) OBSCURA_SAME_FIELD(Ray, RTCRay, dir_y)
OBSCURA_SAME_FIELD(Ray, RTCRay, dir_z) OBSCURA_SAME_FIELD(Ray, RTCRay, time) OBSCURA_SAME_FIELD(Ray, RTCRay, tfar)
OBSCURA_SAME_FIELD(Ray, RTCRay, mask) OBSCURA_SAME_FIELD(Ray, RTCRay, id) OBSCURA_SAME_FIELD(Ray, RTCRay, flags)
OBSCURA_SAME_FIELD(Hit, RTCHit, Ng_x) OBSCURA_SAME_FIELD(Hit, RTCHit, Ng_y) OBSCURA_SAME_FIELD(Hit, RTCHit, Ng_z)
OBSCURA_SAME_FIELD(Hit, RTCHit, u) OBSCURA_SAME_FIELD(Hit, RTCHit, v) OBSCURA_SAME_FIELD(Hit, RTCHit, primID)
OBSCURA_SAME_FIELD(Hit, RTCHit, geomID) OBSCURA_SAME_FIELD(Hit, RTCHit, instID)
#undef OBSCURA_SAME_FIELD

namespace {
inline void initContext(RTCIntersectContext& ctx, RayCoherence c) {
  rtcInitIntersectContext(&ctx);
  ctx.flags = c == RayCoherence::Coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                                          : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
}

// The context of a trace through a scene with occlusion scopes: Embree's
// context first (Embree hands the filter a pointer to it), then the scopes.
struct ScopedContext {
  RTCIntersectContext embree;
  const OcclusionScopes* scopes;
};
static_assert(offsetof(ScopedContext, embree) == 0);

// Embree's context filter (RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION, set by
// Scene::commit only when some object's occlusion is self or others): a
// candidate hit is rejected when the ray's origin object (its id) is scoped
// and the object hit is, for `self`, another one, for `others`, itself.
// Camera rays and rays from surfaces of no object (id kNoObject) keep
// every hit.
void scopeFilter(const RTCFilterFunctionNArguments* a) {
  const OcclusionScopes& s = *reinterpret_cast<const ScopedContext*>(a->context)->scopes;
  for (unsigned i = 0; i < a->N; ++i) {
    if (a->valid[i] != -1) continue;
    const uint32_t from = RTCRayN_id(a->ray, a->N, i);
    if (from >= s.objectCount) continue;
    const auto scope = OcclusionScope(s.scope[from]);
    if (scope == OcclusionScope::All) continue;
    const unsigned inst = RTCHitN_instID(a->hit, a->N, i, 0);
    const unsigned top = inst != RTC_INVALID_GEOMETRY_ID ? inst : RTCHitN_geomID(a->hit, a->N, i);
    const bool same = s.objectOfTop[top] == from;
    if (same != (scope == OcclusionScope::Self)) a->valid[i] = 0;
  }
}
}  // namespace

void Tracer::occluded(OcclusionBatch& batch, RayCoherence c) const {
  if (batch.size() == 0) return;
  ScopedContext ctx;
  initContext(ctx.embree, c);
  if (scopes_) ctx.embree.filter = scopeFilter, ctx.scopes = scopes_;
  if (recorder_) [[unlikely]]  // benchmark capture only (RayRecorder)
    return recorder_->occluded(scene_, ctx.embree, embree(batch.data()), unsigned(batch.size()));
  rtcOccluded1M(scene_, &ctx.embree, embree(batch.data()), unsigned(batch.size()), sizeof(RTCRay));
}

void Tracer::intersect(IntersectBatch& batch, RayCoherence c) const {
  if (batch.size() == 0) return;
  ScopedContext ctx;
  initContext(ctx.embree, c);
  if (scopes_) ctx.embree.filter = scopeFilter, ctx.scopes = scopes_;
  if (recorder_) [[unlikely]]  // benchmark capture only (RayRecorder)
    return recorder_->intersect(scene_, ctx.embree, embree(batch.data()), unsigned(batch.size()));
  rtcIntersect1M(scene_, &ctx.embree, embree(batch.data()), unsigned(batch.size()), sizeof(RTCRayHit));
}

}  // namespace obscura
