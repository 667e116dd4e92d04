// "Model only what the scene and integrator need": the integrator's declared
// needs decide what is fetched and traced.
#include <gtest/gtest.h>

#include "core/load/gltf_loader.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

RenderSettings small(bool aovs) {
  RenderSettings s;
  s.width = 32;
  s.height = 18;
  s.spp = 2;
  s.aovs = aovs;
  return s;
}

// The default scene's ground is textured. An AO pass without AOVs reads no
// albedo, so the texture stays encoded; nor does one with every AOV but
// albedo (--no-albedo), ray-traced or screen-space; asking for the albedo
// AOV decodes it.
TEST(Needs, TexturesAreDecodedOnlyWhenAlbedoIsRead) {
  auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  ASSERT_FALSE(scene->textures.empty());
  renderWith(*scene, scene->cameras[0], "ao", {}, small(false));
  for (const auto& t : scene->textures) EXPECT_FALSE(t->decoded());
  RenderSettings noAlbedo = small(true);
  noAlbedo.albedoAov = false;
  for (const char* integrator : {"ao", "vo"}) {
    renderWith(*scene, scene->cameras[0], integrator, {}, noAlbedo);
    for (const auto& t : scene->textures) EXPECT_FALSE(t->decoded()) << integrator;
  }
  renderWith(*scene, scene->cameras[0], "ao", {}, small(true));
  for (const auto& t : scene->textures) EXPECT_TRUE(t->decoded());
}

// AO and the occlusion estimator of obscurance trace any-hit rays only; the
// distance estimator traces closest hits only.
TEST(Needs, OcclusionEstimatorsTraceNoClosestHits) {
  auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  const struct {
    std::string integrator;
    std::vector<std::string> params;
    bool closest;
  } cases[] = {
      {"ao", {"rays=2"}, false},
      {"obscurance", {"estimator=occlusion", "falloff=exponential", "sigma=2"}, false},
      {"obscurance", {"estimator=occlusion", "falloff=linear", "distance=1"}, false},
      {"obscurance", {"estimator=distance", "falloff=linear", "distance=1"}, true},
  };
  for (const auto& c : cases) {
    RenderStats stats;
    renderWith(*scene, scene->cameras[0], c.integrator, c.params, small(false), &stats);
    EXPECT_EQ(stats.rays.camera, 32u * 18u * 2u);
    if (c.closest) {
      EXPECT_GT(stats.rays.closest, 0u) << c.integrator;
      EXPECT_EQ(stats.rays.occlusion, 0u) << c.integrator;
    } else {
      EXPECT_EQ(stats.rays.closest, 0u) << c.integrator;
      EXPECT_GT(stats.rays.occlusion, 0u) << c.integrator;
    }
  }
}

}  // namespace
}  // namespace obscura::test
