// Wavefront OBJ polygon meshes (quads and n-gons) through tinyobjloader:
// subdivision cages. Without subdivision a cage is rendered as it is (each
// polygon fanned into triangles, flat shaded); with it, refined by
// OpenSubdiv to the requested level and shaded with limit normals
// (core/subd/subdivision.h). All of the file's objects form one cage; materials,
// texture coordinates and normals in the file are not used (a cage's
// normals are the limit surface's). Errors name the file and the face.
#pragma once

#include <memory>
#include <string>

#include "core/load/gltf_loader.h"
#include "core/scene/scene.h"

namespace obscura {

std::unique_ptr<Scene> loadObj(const std::string& path, const LoadOptions& options = {});

}  // namespace obscura
