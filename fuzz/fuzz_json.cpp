// libFuzzer target: a glTF document's JSON and its nesting (issue #37).
// Byte 0 picks where the rest goes:
//   even: the whole .gltf text, read as a GltfDocument only (the depth scan,
//         the type, length and extras-integer checks, tinygltf's parse, the
//         decoding of materials, nodes and cameras) - no BVH, no render, so a
//         run costs about a parse;
//   odd:  the raw value of nodes[0].extras of a one-quad scene (an embedded
//         buffer), where tinygltf turns JSON into its Values recursively and
//         extras.obscura is read; loaded as `obscura render` does and traced.
#include <string>

#include "core/load/gltf_document.h"
#include "fuzz/fuzz_common.h"

namespace {

// A quad [-1, 1]^2 at z = 0 (4 float positions, 6 uint16 indices) seen by a
// camera at z = 3; EXTRAS marks where the input goes.
constexpr const char* kScene =
    R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}],
"nodes": [{"mesh": 0, "extras": EXTRAS}, {"camera": 0, "translation": [0, 0, 3]}],
"cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}}],
"meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
"accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]},
              {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
"bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
"buffers": [{"byteLength": 60, "uri": "data:application/octet-stream;base64,AACAvwAAgL8AAAAAAACAPwAAgL8AAAAAAACAPwAAgD8AAAAAAACAvwAAgD8AAAAAAAABAAIAAAACAAMA"}]})";

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace obscura;
  if (size < 1) return 0;
  const std::string input(reinterpret_cast<const char*>(data) + 1, size - 1);
  if (data[0] % 2 == 0) {
    const std::string path = fuzz::writeInput("input.gltf", data + 1, size - 1);
    fuzz::expectOnlyErrors([&] {
      Log::resetOnce();
      GltfDocument doc(path);
    });
    return 0;
  }
  std::string text = kScene;
  text.replace(text.find("EXTRAS"), 6, input);
  const std::string path = fuzz::writeInput("input.gltf", reinterpret_cast<const uint8_t*>(text.data()), text.size());
  SceneArgs args;
  fuzz::expectOnlyErrors([&] { fuzz::loadAndTrace(path, args); });
  return 0;
}
