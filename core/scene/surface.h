// The surface point a camera ray (or any closest-hit ray) found, with what
// integrators need to continue from it.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>

#include "core/scene/scene.h"
#include <obscura/math.h>
#include <obscura/surface_hit.h>

namespace obscura {

// Fills `out` for h when its primitive has texture coordinates and they are
// not degenerate there; false otherwise. dP/du, dP/dv are constant over a
// triangle (the linear map taking uv differences to edge vectors).
bool surfaceUvFrame(const Scene& scene, const SurfaceHit& h, UvFrame& out);

// The albedo of h's material at texture coordinates (u, v) in UvFrame's
// convention - elsewhere on
// the same surface, e.g. where a height field over it rises (decodes
// textures on first use). Without a texture: the material's factor.
Vec3 surfaceAlbedoAtUv(const Scene& scene, const SurfaceHit& h, float u, float v);

// The roughness of h's material (glTF roughnessFactor x the G channel of
// its metallicRoughnessTexture at h; a subdivision surface or a primitive
// without uvs: the factor alone; no material: glTF's default 1), in [0, 1].
// Decodes the texture on its first use (Texture::decode: throws
// obscura::Error naming the image if it is corrupt).
float surfaceRoughness(const Scene& scene, const SurfaceHit& h);

// Fills `out` (all but pixelKey/sampleIndex) from an Embree hit.
//   dir     : the incoming ray's direction (any length)
//   time    : the incoming ray's time (places a moving instance)
//   u, v    : Embree barycentrics, p = (1-u-v) v0 + u v1 + v v2
//   albedo  : also evaluate the material (decodes textures on first use)
void computeSurfaceHit(const Scene& scene, unsigned geomID, unsigned primID, unsigned instID,
                       float u, float v, float t, Vec3 dir, float time, bool albedo, SurfaceHit& out);
// The same from a traced RayHit, for every kind of primitive (triangle
// lists and Embree subdivision surfaces, whose hit point is the ray's).
void computeSurfaceHit(const Scene& scene, const RayHit& rh, bool albedo, SurfaceHit& out);

// computeSurfaceHit(scene, rays[lanes[i]], albedo, out[i]) for i < count,
// bit for bit, four hits at a time (SSE, structure of arrays over the
// lanes) where they are on still triangles: the camera stage of the render
// loop. Other hits (subdivision surfaces, moving instances) take the scalar
// form.
void computeSurfaceHits(const Scene& scene, const RayHit* rays, const uint32_t* lanes, size_t count, bool albedo,
                        SurfaceHit* out);

// The material albedo at barycentrics (u, v) of a hit (decodes textures on
// first use): what computeSurfaceHit(albedo = true) stores, alone.
Vec3 surfaceAlbedo(const Scene& scene, unsigned geomID, unsigned primID, unsigned instID, float u, float v);

}  // namespace obscura
