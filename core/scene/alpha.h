// Alpha cut-outs (glTF alphaMode MASK and BLEND) as Embree filter functions
// on the geometries whose material has them, and only those: a scene
// without alpha traces exactly as before.
//
// alpha = the material's alpha factor x its texture's alpha at the hit's uv.
// - MASK: the hit counts when alpha >= alphaCutoff (glTF 2.0 3.9.4), so the
//   cut-out parts are transparent to camera rays (coverage) and to every
//   secondary ray.
// - BLEND: a ray passes with probability 1 - alpha: the hit counts when a
//   uniform number u < alpha, u a hash of the ray (origin, direction) and
//   of the primitive hit. Rays are deterministic functions of their
//   samples, so images stay reproducible (independent of threads and
//   batching, and of Embree reporting one hit twice), and each crossing is
//   an independent Bernoulli(alpha) draw, so the expected transmission
//   through a layer is exactly 1 - alpha: unbiased.
#pragma once

#include <cstdint>

#include "core/scene/scene.h"

namespace obscura {

struct AlphaSurface {
  const uint32_t* indices = nullptr;  // 3 per triangle (Embree's index buffer)
  const float* uvs = nullptr;         // 2 per vertex, or null: the factor alone
  const Texture* texture = nullptr;   // null: the factor alone
  WrapMode wrapS = WrapMode::Repeat, wrapT = WrapMode::Repeat;
  UvTransform transform;  // the base colour texture's KHR_texture_transform
  AlphaMode mode = AlphaMode::Opaque;
  float alpha = 1.0f, cutoff = 0.5f;

  // alpha at barycentrics (u, v) of triangle prim.
  float alphaAt(uint32_t prim, float u, float v) const;
};

// For a primitive with a cutting-out material (Material::cutsOut): the
// surface, and its filter functions installed on the primitive's geometry
// (which must be committed again afterwards). The texture must be decoded.
void attachAlphaFilter(const Primitive& prim, AlphaSurface& surface);

// The uniform number in [0, 1) a BLEND hit is decided by (exposed for tests).
float blendSample(const float org[3], const float dir[3], uint32_t geomID, uint32_t primID, uint32_t instID);

}  // namespace obscura
