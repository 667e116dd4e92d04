// Plugins: the bent-normal plugin, built out of tree against the installed
// package (CTest fixture plugin.build_out_of_tree), loads and computes its
// analytic values; broken plugins give clear errors, never a crash.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/plugin.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

void expectLoadError(const std::string& path, const std::string& needle) {
  try {
    loadPlugin(path);
    ADD_FAILURE() << path << " loaded without an error";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find(needle), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
}

TEST(Plugin, BentNormalLoadsAndIsListed) {
  loadPlugin(OBSCURA_BENT_PLUGIN);
  loadPlugin(OBSCURA_BENT_PLUGIN);  // the same library twice is one plugin
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find("bent-normal");
  EXPECT_EQ(d.params.size(), 2u);
  EXPECT_NO_THROW(IntegratorRegistry::instance().find("ao"));
}

TEST(Plugin, EnvironmentPathLoadsPlugins) {
  ASSERT_EQ(setenv("OBSCURA_PLUGIN_PATH", (std::string("/nonexistent-dir-is-an-error:") + OBSCURA_BENT_PLUGIN).c_str(), 1), 0);
  EXPECT_THROW(loadPluginsFromEnvironment(), Error);
  ASSERT_EQ(setenv("OBSCURA_PLUGIN_PATH", OBSCURA_BENT_PLUGIN, 1), 0);
  EXPECT_NO_THROW(loadPluginsFromEnvironment());
  unsetenv("OBSCURA_PLUGIN_PATH");
  EXPECT_NO_THROW(IntegratorRegistry::instance().find("bent-normal"));
}

TEST(Plugin, BrokenPluginsGiveClearErrors) {
  expectLoadError(OBSCURA_BAD_ABI_PLUGIN, "ABI version 999");
  expectLoadError(OBSCURA_NO_REGISTER_PLUGIN, "obscura_plugin_register");
  expectLoadError(OBSCURA_DUPLICATE_PLUGIN, "'ao' is already registered by built-in");
  expectLoadError("/nonexistent/plugin.so", "no such file");
  const std::string dir = tempDir("bad_plugins");
  writeText(dir + "/garbage.so", "this is not an ELF file");
  expectLoadError(dir + "/garbage.so", "cannot load plugin");
  // A real shared library that is not a plugin.
  const char* zlib = "/lib/x86_64-linux-gnu/libz.so.1";
  if (std::ifstream(zlib).good()) expectLoadError(zlib, "not an Obscura plugin");
  // The impostor did not replace the built-in.
  EXPECT_EQ(IntegratorRegistry::instance().find("ao").doc.find("impostor"), std::string::npos);
}

// Unoccluded plane: B = E[w] under cos/pi about n = (0,0,2/3) in the normal's
// frame. Per-ray variances: Var(w_z) = E[z^2] - 4/9 = 1/2 - 4/9 = 1/18,
// Var(w_x) = Var(w_y) = E[x^2] = 1/4.
TEST(Plugin, BentNormalOfAnOpenPlane) {
  loadPlugin(OBSCURA_BENT_PLUGIN);
  Scene scene;
  addPlane(scene, 1e4f, 0.0f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0.5f, -3, 2), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "plane");
  const int w = 32, h = 32, spp = 32, rays = 2;
  const Film film = renderWith(scene, cam, "bent-normal", {"rays=" + std::to_string(rays)}, passSettings(w, h, spp));
  size_t n = 0;
  const double bx = meanCovered(film, kR, &n), by = meanCovered(film, kG), bz = meanCovered(film, kB);
  ASSERT_EQ(n, size_t(w * h));
  const double N = double(n) * spp * rays;
  EXPECT_NEAR(bx, 0.0, 4.0 * std::sqrt(0.25 / N));
  EXPECT_NEAR(by, 0.0, 4.0 * std::sqrt(0.25 / N));
  EXPECT_NEAR(bz, 2.0 / 3.0, 4.0 * std::sqrt(1.0 / 18.0 / N));
}

// From the wall point opposite the hole of the spherical cavity (MATH.md
// section 7), the open directions are the cone theta < alpha/2 about the
// normal n = +z:  B = n (2/3)(1 - c0^3), c0 = cos(alpha/2); per ray
// E[V z^2] = (1 - c0^4)/2.
TEST(Plugin, BentNormalInTheSphericalCavity) {
  loadPlugin(OBSCURA_BENT_PLUGIN);
  const double alpha = 1.2;
  Scene scene;
  addSphereCavity(scene, 1.0f, alpha, 256, 512);
  scene.setRobust(true);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 1, 0), 1e-4f, "antipode");
  const int w = 16, h = 16, spp = 256, rays = 4;
  const Film film = renderWith(scene, cam, "bent-normal", {"rays=" + std::to_string(rays)}, passSettings(w, h, spp));
  const double c0 = std::cos(alpha / 2);
  const double expected = 2.0 / 3.0 * (1 - c0 * c0 * c0);
  const double var = (1 - c0 * c0 * c0 * c0) / 2 - expected * expected;
  size_t n = 0;
  const double bz = meanCovered(film, kB, &n);
  ASSERT_EQ(n, size_t(w * h));
  const double N = double(n) * spp * rays;
  const double tessellation = std::pow(2 * M_PI / 512, 2);  // as in test_ao_analytic.cpp
  EXPECT_NEAR(bz, expected, 4.0 * std::sqrt(var / N) + tessellation);
  // The cone is symmetric about n: no sideways component.
  const double sideVar = (1 - c0 * c0) * (1 - c0 * c0) / 4 * 2;  // generous bound on E[V x^2]
  EXPECT_NEAR(meanCovered(film, kR), 0.0, 4.0 * std::sqrt(sideVar / N) + tessellation);
}

TEST(Plugin, CliListsAndRendersWithPlugin) {
  const std::string dir = tempDir("plugin_cli");
  const CliResult list = runCli({"integrators", "--plugin", OBSCURA_BENT_PLUGIN}, dir + "/list.txt");
  EXPECT_EQ(list.exitCode, 0) << list.stderrText;
  const CliResult render = runCli({"render", "--plugin", OBSCURA_BENT_PLUGIN, "-i", "bent-normal", "-o",
                                   dir + "/bent.exr", "--res", "16x9", "--spp", "2", "-q"},
                                  dir + "/render.txt");
  EXPECT_EQ(render.exitCode, 0) << render.stderrText;
  const ReadBack r = readExr(dir + "/bent.exr");
  EXPECT_EQ(r.spec.get_string_attribute("obscura:integrator"), "bent-normal");
  const CliResult bad = runCli({"render", "--plugin", OBSCURA_BAD_ABI_PLUGIN, "-o", dir + "/x.exr", "-q"},
                               dir + "/bad.txt");
  EXPECT_EQ(bad.exitCode, 1);
  EXPECT_EQ(bad.stderrText.rfind("obscura: error: ", 0), 0u) << bad.stderrText;
  EXPECT_NE(bad.stderrText.find("ABI version 999"), std::string::npos) << bad.stderrText;
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.exr"));
}

}  // namespace
}  // namespace obscura::test
