// libFuzzer target: the camera set-up (issue #37) - a glTF camera with
// extreme numbers, or the automatic camera framing the scene's bounds, over a
// quad whose size and place come from the input too. Byte 0: bit 0 the
// automatic camera (`--camera auto`) instead of the file's, bit 1 a second
// instance of the quad; then up to 15 little-endian doubles (8 bytes each;
// missing ones take the default in brackets):
//   0 yfov (0.8)  1 znear (0.01)  2 zfar (0: none)  3-5 camera translation (0, 0, 3)
//   6-9 camera rotation xyzw (0, 0, 0, 1)  10 the root's uniform scale (1)
//   11 the quad's scale (1)  12-14 the second quad's translation (2, 0, 0)
// written as a .gltf (a non-finite double becomes JSON null, a type error),
// loaded as `obscura render` does and traced at 8x6.
#include <cstring>

#include <nlohmann/json.hpp>

#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace obscura;
  using json = nlohmann::json;
  if (size < 1) return 0;
  double v[15] = {0.8, 0.01, 0, 0, 0, 3, 0, 0, 0, 1, 1, 1, 2, 0, 0};
  for (size_t i = 0; i < 15 && 1 + 8 * (i + 1) <= size; ++i) std::memcpy(&v[i], data + 1 + 8 * i, 8);
  const bool autoCamera = data[0] & 1, twice = data[0] & 2;
  json cam = {{"type", "perspective"}, {"perspective", {{"yfov", v[0]}, {"znear", v[1]}}}};
  if (v[2] != 0) cam["perspective"]["zfar"] = v[2];
  json nodes = json::array({
      {{"children", twice ? json{1, 2, 3} : json{1, 2}}, {"scale", {v[10], v[10], v[10]}}},
      {{"mesh", 0}, {"scale", {v[11], v[11], v[11]}}},
      {{"camera", 0}, {"translation", {v[3], v[4], v[5]}}, {"rotation", {v[6], v[7], v[8], v[9]}}},
  });
  if (twice) nodes.push_back({{"mesh", 0}, {"translation", {v[12], v[13], v[14]}}});
  const json doc = {
      {"asset", {{"version", "2.0"}}}, {"scene", 0}, {"scenes", {{{"nodes", {0}}}}}, {"nodes", nodes}, {"cameras", {cam}},
      {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}, {"indices", 1}}}}}}},
      {"accessors",
       {{{"bufferView", 0}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}, {"min", {-1, -1, 0}}, {"max", {1, 1, 0}}},
        {{"bufferView", 1}, {"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}}}},
      {"bufferViews", {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 48}}, {{"buffer", 0}, {"byteOffset", 48}, {"byteLength", 12}}}},
      {"buffers",
       {{{"byteLength", 60},
         {"uri", "data:application/octet-stream;base64,"
                 "AACAvwAAgL8AAAAAAACAPwAAgL8AAAAAAACAPwAAgD8AAAAAAACAvwAAgD8AAAAAAAABAAIAAAACAAMA"}}}}};
  const std::string text = doc.dump();
  const std::string path = fuzz::writeInput("input.gltf", reinterpret_cast<const uint8_t*>(text.data()), text.size());
  SceneArgs args;
  fuzz::expectOnlyErrors([&] { fuzz::loadAndTrace(path, args, autoCamera ? "auto" : ""); });
  return 0;
}
