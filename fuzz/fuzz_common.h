// What the libFuzzer targets share: a work directory of their own, the
// CLI's scene path (load, camera, BVH build) followed by a few traced rays,
// and the rule that bad input may only end in one printable obscura::Error.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "app/options.h"
#include <obscura/error.h>

namespace obscura::fuzz {

// This process's own directory for inputs, made on first use. It holds
// "height.png", a small height map the seeds' displacement extras name.
const std::string& workDir();

// Writes the bytes to workDir()/name and returns the path.
std::string writeInput(const std::string& name, const uint8_t* data, size_t size);

// Loads `path` as `obscura render` does (loadSceneAndCamera, so an adaptive
// subdivision's camera probe too), then renders ambient occlusion at 8x6, one
// sample per pixel: every camera ray and AO ray goes through Embree's
// validity checks. `camera` as --camera ("": the file's first, else auto).
void loadAndTrace(const std::string& path, const SceneArgs& args, const std::string& camera = "");

// Runs `fn`. An obscura::Error is the expected answer to bad input: its
// message must be one printable line (else abort, a finding). Any other
// exception escapes, and libFuzzer reports it.
template <class F>
void expectOnlyErrors(F&& fn);

void checkErrorLine(const char* message);

template <class F>
void expectOnlyErrors(F&& fn) {
  try {
    fn();
  } catch (const Error& e) {
    checkErrorLine(e.what());
  }
}

}  // namespace obscura::fuzz
