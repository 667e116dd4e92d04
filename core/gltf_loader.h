// glTF 2.0 (.gltf with external or embedded buffers, and .glb) to Scene.
//
// Supported: the node hierarchy (matrix or TRS), triangle primitives
// (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN; indexed or not), POSITION,
// NORMAL, TEXCOORD_0, perspective cameras, and the diffuse albedo
// baseColorFactor x baseColorTexture (sRGB decoded, sampler wrap modes),
// and Obscura's mesh/node extras: subdivision (with uvs) and displacement
// (README "Scenes").
// Everything else in the file is reported once as a warning and ignored.
// Malformed data (bad indices, out-of-range accessors, NaN, missing files)
// throws obscura::Error naming the file and the field.
#pragma once

#include <memory>
#include <string>

#include "core/load_options.h"
#include "core/scene.h"

namespace obscura {


std::unique_ptr<Scene> loadGltf(const std::string& path, const LoadOptions& options = {});
// By extension: .obj (core/obj_loader.h), else glTF.
std::unique_ptr<Scene> loadScene(const std::string& path, const LoadOptions& options = {});

}  // namespace obscura
