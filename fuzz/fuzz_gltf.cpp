// libFuzzer target: a glTF scene, .glb when the input starts with the glb
// magic "glTF", else .gltf JSON. Written to a file so the real loader path
// runs (external uris resolve next to it, where "height.png" is), loaded as
// `obscura render` loads it and traced (fuzz_common.h). The input's length
// picks the scene options, so each seed is also read with adaptive
// subdivision (camera probe) and with Embree's subdivision backend.
#include <cstring>

#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace obscura;
  const bool glb = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  const std::string path = fuzz::writeInput(glb ? "input.glb" : "input.gltf", data, size);
  SceneArgs args;
  args.maxMemoryGiB = 0.25;  // a refinement beyond it is refused (and fast)
  if (size % 3 == 1) args.subdivEdge = 4;
  if (size % 3 == 2) args.subdivBackend = "embree";
  fuzz::expectOnlyErrors([&] { fuzz::loadAndTrace(path, args); });
  return 0;
}
