// The benchmark's own large scene: a bumpy height-field terrain of
// 2 x 720 x 720 triangles with smooth vertex normals, 40 UV spheres (smooth
// normals) and 60 boxes (flat, no normals) resting on it - about 1.13 M
// triangles in three world-space primitives - and a look-at camera above it
// that sees terrain in the whole frame. Fully deterministic.
#pragma once

#include <memory>

#include "core/camera.h"
#include "core/scene.h"

namespace obscura::bench {

// Adds the geometry to `scene` (not committed).
void buildGeneratedScene(Scene& scene);

// The camera used for the generated scene.
Camera generatedSceneCamera();

}  // namespace obscura::bench
