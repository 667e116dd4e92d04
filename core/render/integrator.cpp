#include <obscura/integrator.h>

#include <algorithm>

#include "core/render/plugin_loader.h"
#include "core/scene/scene.h"
#include "core/scene/surface.h"
#include "core/scene/tracer.h"
#include <obscura/error.h>
#include <obscura/plugin.h>

namespace obscura {

// IntegratorContext: the SDK's calls into the scene, out of line.
void IntegratorContext::trace(OcclusionBatch& b) {
  tracer_.occluded(b);
  counters.occlusion += b.size();
}
void IntegratorContext::trace(IntersectBatch& b) {
  tracer_.intersect(b);
  counters.closest += b.size();
}
void IntegratorContext::surfaceAt(const IntersectBatch& b, size_t i, bool albedo, uint32_t pixelKey,
                                  uint32_t sampleIndex, SurfaceHit& out) const {
  computeSurfaceHit(scene_, b.data()[i], albedo, out);
  out.pixelKey = pixelKey;
  out.sampleIndex = sampleIndex;
}
Vec3 IntegratorContext::albedoAt(const IntersectBatch& b, size_t i) const {
  return surfaceAlbedo(scene_, b.geomID(i), b.primID(i), b.instID(i), b.u(i), b.v(i));
}
float IntegratorContext::roughnessAt(const SurfaceHit& h) const { return surfaceRoughness(scene_, h); }
bool IntegratorContext::uvFrameAt(const SurfaceHit& h, UvFrame& out) const { return surfaceUvFrame(scene_, h, out); }
std::string IntegratorContext::surfaceName(const SurfaceHit& h) const {
  return scene_.surfaceName(h.geomID, h.instID);
}
Vec3 IntegratorContext::albedoAtUv(const SurfaceHit& h, float u, float v) const {
  return surfaceAlbedoAtUv(scene_, h, u, v);
}

IntegratorRegistry& IntegratorRegistry::instance() {
  static IntegratorRegistry r;
  static const bool builtins = (loadBuiltinPlugins(r), true);
  (void)builtins;
  return r;
}

void IntegratorRegistry::add(IntegratorDescriptor d, const std::string& origin) {
  const bool nameOk = !d.name.empty() && std::all_of(d.name.begin(), d.name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  });
  if (!nameOk) throw Error(origin + ": invalid integrator name '" + d.name + "' (use [a-z0-9_-])");
  if (!d.create || !d.needs) throw Error(origin + ": integrator '" + d.name + "' lacks create() or needs()");
  for (size_t i = 0; i < all_.size(); ++i)
    if (all_[i].name == d.name)
      throw Error(origin + ": integrator '" + d.name + "' is already registered by " + origins_[i]);
  if (d.shading == Shading::Irradiance &&
      std::none_of(d.params.begin(), d.params.end(), [](const ParamSpec& p) { return p.name == "e0"; }))
    d.params.push_back({.name = "e0", .type = ParamType::Enum, .defaultValue = "normal", .choices = {"normal", "bent"},
                        .doc = "where shaded.* looks up the environment's irradiance E0: the shading normal, or "
                               "this pass's bent normal (docs/math.md §14.6)"});
  // Validate the declared defaults now, so a bad plugin fails at load time.
  ParamSet check(d.params, d.name);
  (void)check;
  all_.push_back(std::move(d));
  origins_.push_back(origin);
  std::vector<size_t> order(all_.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return all_[a].name < all_[b].name; });
  std::vector<IntegratorDescriptor> sorted;
  std::vector<std::string> sortedOrigins;
  for (size_t i : order) {
    sorted.push_back(std::move(all_[i]));
    sortedOrigins.push_back(std::move(origins_[i]));
  }
  all_ = std::move(sorted);
  origins_ = std::move(sortedOrigins);
}

const IntegratorDescriptor& IntegratorRegistry::find(const std::string& name) const {
  for (const auto& e : all_)
    if (e.name == name) return e;
  std::string known;
  for (const auto& e : all_) known += (known.empty() ? "" : ", ") + e.name;
  throw Error("unknown integrator '" + name + "' (available: " + known + ")");
}

}  // namespace obscura

namespace obscura {

IntegratorNeeds passNeeds(const IntegratorDescriptor& desc, const ParamSet& params) {
  IntegratorNeeds needs = desc.needs(params);
  needs.bentE0 = false;
  if (desc.shading == Shading::Irradiance && params.getEnum("e0") == "bent") {
    if (!desc.bentNormal)
      throw Error("integrator '" + desc.name + "': e0=bent: this integrator estimates no bent normal (use e0=normal)");
    needs.bentE0 = true;
  }
  return needs;
}

}  // namespace obscura
