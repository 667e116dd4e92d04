// The image is a pure function of (scene, camera, settings, seed): bit-identical
// for any thread count and tile size (docs/architecture.md, "Deterministic sampling").
#include <gtest/gtest.h>

#include <cstring>

#include "core/load/gltf_loader.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

bool identical(const Film& a, const Film& b) {
  if (a.width() != b.width() || a.height() != b.height() || a.channels() != b.channels()) return false;
  for (int c : a.channels())
    if (std::memcmp(a.plane(c), b.plane(c), sizeof(float) * size_t(a.width()) * a.height()) != 0) return false;
  return true;
}

TEST(Determinism, BitIdenticalAcrossThreadsAndTiles) {
  auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  ASSERT_FALSE(scene->cameras.empty());
  for (const PixelFilter filter : {PixelFilter::Box, PixelFilter::Gaussian}) {
    RenderSettings s;
    s.width = 67;  // odd sizes: partial tiles at the right and bottom
    s.height = 41;
    s.spp = 5;
    s.filter = filter;
    s.seed = 42;
    s.threads = 1;
    s.tileSize = 16;
    const Film ref = renderWith(*scene, scene->cameras[0], "ao", {"rays=3", "distance=1.5"}, s);
    for (const int threads : {1, 2, 3}) {
      for (const int tile : {1, 7, 16, 64}) {
        if (threads == 1 && tile == 16) continue;
        s.threads = threads;
        s.tileSize = tile;
        const Film f = renderWith(*scene, scene->cameras[0], "ao", {"rays=3", "distance=1.5"}, s);
        EXPECT_TRUE(identical(ref, f)) << "threads " << threads << " tile " << tile;
      }
    }
  }
}

TEST(Determinism, SeedChangesTheNoiseOnly) {
  auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  RenderSettings s;
  s.width = 40;
  s.height = 24;
  s.spp = 8;
  s.aovs = false;
  s.seed = 1;
  const Film a = renderWith(*scene, scene->cameras[0], "ao", {}, s);
  s.seed = 2;
  const Film b = renderWith(*scene, scene->cameras[0], "ao", {}, s);
  EXPECT_FALSE(identical(a, b));
}

}  // namespace
}  // namespace obscura::test
