#include "fuzz/fuzz_common.h"

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>

#include <obscura/error.h>
#include "core/image/image_io.h"

namespace obscura::fuzz {

const std::string& workDir() {
  // Never destroyed: the exit handler below still reads it.
  static const std::string& dir = *new std::string([] {
    const auto d = std::filesystem::temp_directory_path() / ("obscura_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    // A 4x4 ramp, the height map the seeds' extras.obscura.displacement name.
    std::vector<unsigned char> rgb(4 * 4 * 3);
    for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<unsigned char>(i * 5);
    writePngRgb8((d / "height.png").string(), 4, 4, rgb.data());
    // Warnings are expected on fuzzed input; they must not flood the log.
    Log::setWarningSink([](const std::string& w) { checkErrorLine(w.c_str()); });
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(workDir(), ec);
    });
    return d.string();
  }());
  return dir;
}

std::string writeInput(const std::string& name, const uint8_t* data, size_t size) {
  const std::string path = workDir() + "/" + name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  if (!out) std::abort();
  return path;
}

void loadAndTrace(const std::string& path, const SceneArgs& args, const std::string& cameraName) {
  Log::resetOnce();  // else the set of warnings seen grows with every input
  const int w = 8, h = 6;
  Camera camera;
  std::unique_ptr<Scene> scene = loadSceneAndCamera(args, path, cameraName, w, h, camera);
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find("ao");
  const ParamSet params(d.params, d.name);
  const auto integrator = d.create(params);
  RenderSettings s;
  s.width = w, s.height = h, s.spp = 1, s.threads = 1, s.tileSize = 8, s.aovs = false;
  RenderStats stats;
  render(*scene, camera, *integrator, passNeeds(d, params), s, stats);
}

void checkErrorLine(const char* message) {
  // One line of printable text: no control byte (UTF-8 text is fine).
  for (const char* p = message; *p; ++p) {
    const auto c = static_cast<unsigned char>(*p);
    if (c < 0x20 || c == 0x7f) {
      std::fprintf(stderr, "fuzz: message with control byte 0x%02x: %s\n", c, message);
      std::abort();
    }
  }
}

}  // namespace obscura::fuzz
