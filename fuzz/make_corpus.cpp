// Writes the fuzz targets' seed corpus (tests/fuzz_seeds.h) into DIR/gltf,
// DIR/obj and DIR/params: `obscura_fuzz_corpus DIR`.
#include <cstdio>

#include <obscura/error.h>
#include "tests/fuzz_seeds.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  try {
    obscura::test::writeFuzzSeeds(argv[1]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_fuzz_corpus: %s\n", e.what());
    return 1;
  }
  return 0;
}
