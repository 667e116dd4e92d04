// The benchmark's own large scene: a bumpy height-field terrain of
// 2 x 720 x 720 triangles with smooth vertex normals, 40 UV spheres (smooth
// normals) and 60 boxes (flat, no normals) resting on it - about 1.13 M
// triangles in three world-space primitives - and a look-at camera above it
// that sees terrain in the whole frame. Fully deterministic. Each primitive
// has a plain material below albedo 1 (terrain (0.5, 0.45, 0.35), spheres
// 0.8, boxes (0.3, 0.4, 0.6)): with glTF's default albedo 1 everywhere,
// `transfer`'s W would be exactly 1 (the white furnace) and nothing to measure.
#pragma once

#include <memory>

#include "core/scene/camera.h"
#include "core/scene/scene.h"

namespace obscura::bench {

// Adds the geometry to `scene` (not committed).
void buildGeneratedScene(Scene& scene);

// The camera used for the generated scene.
Camera generatedSceneCamera();

}  // namespace obscura::bench
