// The seed corpus of the libFuzzer targets (fuzz/, docs/testing.md "Fuzzing"):
// representative valid inputs, written by obscura_fuzz_corpus for
// scripts/fuzz.sh and checked to load by tests/test_loader_hardening.cpp.
#pragma once

#include <string>

namespace obscura::test {

// Writes dir/gltf (glTF and glb scenes: cameras, instancing, strips and
// fans, every index type, textures, subdivision and displacement extras
// naming "height.png"), dir/obj (a mode byte, then an OBJ cage: see
// fuzz/fuzz_obj.cpp; those named bad_* are refused), dir/params (an
// integrator name, then key=value lines: every integrator with its defaults,
// and some non-defaults), dir/json (fuzz/fuzz_json.cpp: a mode byte, then a
// document or a node's extras) and dir/camera (fuzz/fuzz_camera.cpp: a mode
// byte, then doubles).
void writeFuzzSeeds(const std::string& dir);

}  // namespace obscura::test
