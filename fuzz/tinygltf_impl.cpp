// The fuzz build only (CMake OBSCURA_FUZZ): tinygltf's implementation,
// compiled from Debian's header with the fuzzer's coverage and the
// sanitizers instead of linked from Debian's libtinygltf.so, so libFuzzer
// can steer inputs through its JSON walk. stb_image comes from libstb.
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
