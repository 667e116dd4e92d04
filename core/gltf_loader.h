// glTF 2.0 (.gltf with external or embedded buffers, and .glb) to Scene.
//
// Supported: the node hierarchy (matrix or TRS), triangle primitives
// (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN; indexed or not), POSITION,
// NORMAL, TEXCOORD_0, perspective cameras, and the diffuse albedo
// baseColorFactor x baseColorTexture (sRGB decoded, sampler wrap modes).
// Everything else in the file is reported once as a warning and ignored.
// Malformed data (bad indices, out-of-range accessors, NaN, missing files)
// throws obscura::Error naming the file and the field.
#pragma once

#include <memory>
#include <string>

#include "core/scene.h"
#include "core/subdivision.h"

namespace obscura {

struct LoadOptions {
  bool robust = false;  // Scene::setRobust
  // Subdivision of polygon cages (OBJ): off by default; the scheme and the
  // uniform level when on, and the memory a refinement may take.
  bool subdivision = false;
  SubdivisionScheme scheme = SubdivisionScheme::CatmullClark;
  int subdivisionLevel = 2;
  size_t maxMemoryBytes = size_t(8) << 30;
  // Displacement of subdivided OBJ cages: a height map, moved along the
  // limit normal by scale * (h - midlevel) (scene units).
  std::string displacementMap;
  double displacementScale = 0.1;
  double displacementMidlevel = 0.5;
};

std::unique_ptr<Scene> loadGltf(const std::string& path, const LoadOptions& options = {});
// By extension: .obj (core/obj_loader.h), else glTF.
std::unique_ptr<Scene> loadScene(const std::string& path, const LoadOptions& options = {});

}  // namespace obscura
