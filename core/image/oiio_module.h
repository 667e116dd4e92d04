// The seam to OpenImageIO. OpenImageIO and the ~250 libraries it depends on
// take ~0.4 s to load, so the program does not link them: EXR files are
// written and read through OpenEXR directly (core/image_io), and the rest -
// height maps, passes and headers in formats other than EXR, `obscura
// merge` - lives in libobscura_oiio.so, a module installed next to
// libobscura.so and dlopen'ed the first time a file needs it
// (docs/architecture.md "OpenImageIO on demand").
#pragma once

#include <string>
#include <vector>

#include "core/image/metrics.h"

namespace obscura {

// Bumped whenever the table changes: the module and libobscura are built
// together, the check catches a stale module left in the directory.
inline constexpr int kOiioModuleAbi = 2;

struct OiioModule {
  int abi;
  // The first channel of the first subimage, rows top first, as floats.
  // Throws obscura::Error naming the file.
  void (*readFirstChannel)(const std::string& path, int& width, int& height, std::vector<float>& texels);
  // Linear RGB of an environment map, rows top first (8-bit sRGB decoded).
  void (*readRgb)(const std::string& path, int& width, int& height, std::vector<float>& rgb);
  // R, G, B, A of any image OpenImageIO reads (see core/image/metrics.h readPass).
  PassImage (*readPass)(const std::string& path);
  // A string attribute of the header ("" if absent).
  std::string (*readStringAttribute)(const std::string& path, const std::string& name);
  // app/merge.h mergeRegions.
  void (*mergeRegions)(const std::string& output, const std::vector<std::string>& tiles);
};

// The module, loaded on first call (thread-safe). If it cannot be loaded,
// throws obscura::Error "`file`: reading this file needs OpenImageIO: ..."
// naming the module it looked for and why.
const OiioModule& oiioModule(const std::string& file);

}  // namespace obscura

// The module's one exported symbol.
extern "C" const obscura::OiioModule* obscura_oiio_module();
