// glTF 2.0 (.gltf with external or embedded buffers, and .glb) to Scene.
//
// Supported: the node hierarchy (matrix or TRS), triangle primitives
// (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN; indexed or not), POSITION,
// NORMAL, TEXCOORD_0, perspective cameras, and the diffuse albedo
// baseColorFactor x baseColorTexture (sRGB decoded, sampler wrap modes),
// and Obscura's mesh/node extras: subdivision (with uvs) and displacement
// (docs/scenes.md "Scenes").
// Everything else in the file is reported once as a warning and ignored.
// Malformed data (bad indices, out-of-range accessors, NaN, coordinates
// beyond what Embree traces, fields of the wrong JSON type, missing files)
// and a scene with no triangles throw obscura::Error naming the file and the
// field. Reading and decoding the file is core/load/gltf_document.h; this part
// adds Obscura's extras (subdivision cages, displacement) and builds scenes.
#pragma once

#include <memory>
#include <string>

#include "core/load/gltf_document.h"
#include "core/load/load_options.h"
#include "core/scene/scene.h"
#include "core/util/memory_budget.h"

namespace obscura {


std::unique_ptr<Scene> loadGltf(const std::string& path, const LoadOptions& options = {});
// A scene from a document already read: as often as needed, never reading
// the file again.
std::unique_ptr<Scene> buildGltfScene(const GltfDocument& document, const LoadOptions& options);

// What building `document` with `options` will take, from counts and
// headers, before any of it is allocated (core/util/memory_budget.h):
// decoded textures, the node tables, geometry and BVH, motion grids. The
// scene build refuses past the budget; `obscura info` prints it.
MemoryEstimate estimateSceneMemory(const GltfDocument& document, const LoadOptions& options);
// Bytes of Embree BVH per triangle or instance, measured (docs/cli.md "Memory").
inline constexpr uint64_t kBvhBytesPerPrimitive = 110;

// A scene file read once, from which scenes are built with different
// options (adaptive subdivision first builds the unrefined scene to find the
// camera, then the scene): a glTF file is parsed and decoded once; an OBJ
// cage is read per build (it is one small text file).
class SceneSource {
 public:
  explicit SceneSource(std::string path);  // throws obscura::Error for a bad glTF
  ~SceneSource();
  const std::string& path() const { return path_; }
  std::unique_ptr<Scene> build(const LoadOptions& options) const;
  // The parsed glTF file (its animations, for listings); null for OBJ.
  const GltfDocument* document() const { return gltf_.get(); }

 private:
  std::string path_;
  std::unique_ptr<GltfDocument> gltf_;  // null for OBJ
};

// By extension: .obj (core/load/obj_loader.h), else glTF; SceneSource(path).build(options).
std::unique_ptr<Scene> loadScene(const std::string& path, const LoadOptions& options = {});

}  // namespace obscura
