// libFuzzer target: an OBJ cage, subdivided. Byte 0 chooses the scheme
// (bit 0: Catmull-Clark or Loop), the level (bits 1-2: 0..2, small so each
// input stays fast) and whether the level is adaptive (bit 3: --subdiv-edge
// 4 px instead); the rest is the OBJ text. OpenSubdiv backend; loaded as
// `obscura render` loads it and traced (fuzz_common.h).
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace obscura;
  if (size < 1) return 0;
  const uint8_t mode = data[0];
  const std::string path = fuzz::writeInput("input.obj", data + 1, size - 1);
  SceneArgs args;
  args.subdiv = mode & 1 ? "loop" : "catmull-clark";
  args.subdivLevel = (mode >> 1) & 3;
  if (args.subdivLevel == 3) args.subdivLevel = 0;
  if (mode & 8) args.subdivEdge = 4;
  args.subdivBackend = "osd";
  args.maxMemoryGiB = 0.25;
  fuzz::expectOnlyErrors([&] { fuzz::loadAndTrace(path, args); });
  return 0;
}
