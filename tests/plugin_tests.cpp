// Plugins: the bent-normal plugin, built out of tree against the installed
// package (CTest fixture plugin.build_out_of_tree), loads and computes its
// analytic values; broken plugins give clear errors, never a crash.
#include <gtest/gtest.h>

#include <elf.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <obscura/error.h>
#include "core/render/plugin_loader.h"
#include <obscura/plugin.h>
#include "core/render/render.h"
#include "tests/integrator_table.h"
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
  EXPECT_EQ(readPluginAbiVersion(OBSCURA_BENT_PLUGIN), OBSCURA_PLUGIN_ABI_VERSION);
  loadPlugin(OBSCURA_BENT_PLUGIN);
  loadPlugin(OBSCURA_BENT_PLUGIN);  // the same library twice is one plugin
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find("bent-normal");
  EXPECT_EQ(d.params.size(), 6u);  // distance, rays, the lobe controls inside, spread, near, and e0
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
  expectLoadError(OBSCURA_BAD_ABI_PLUGIN, "ABI version 999, this obscura needs");
  expectLoadError(OBSCURA_NO_REGISTER_PLUGIN, "obscura_plugin_register");
  expectLoadError(OBSCURA_DUPLICATE_PLUGIN, "'ao' is already registered by built-in");
  expectLoadError("/nonexistent/plugin.so", "no such file");
  const std::string dir = tempDir("bad_plugins");
  writeText(dir + "/garbage.so", "this is not an ELF file");
  expectLoadError(dir + "/garbage.so", "not an ELF shared object");
  // A real shared library that is not a plugin.
  const char* zlib = "/lib/x86_64-linux-gnu/libz.so.1";
  if (std::ifstream(zlib).good()) expectLoadError(zlib, "not an Obscura plugin");
  // The impostor did not replace the built-in.
  EXPECT_EQ(IntegratorRegistry::instance().find("ao").doc.find("impostor"), std::string::npos);
}

std::string readBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void writeBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(bytes.size()));
}

// readPluginAbiVersion on a malformed file: a value or one obscura::Error line
// naming the file, never a crash or another exception.
void expectValueOrError(const std::string& path, const std::string& what) {
  try {
    (void)readPluginAbiVersion(path);
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_EQ(m.rfind(path + ": ", 0), 0u) << what << ": " << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << what << ": " << m;
  } catch (...) {
    ADD_FAILURE() << what << ": not an obscura::Error";
  }
}

// The ABI version is read from the file before dlopen, so a library built for
// another ABI never runs a line of its code - not even a static constructor.
TEST(Plugin, AbiIsCheckedBeforeAnyPluginCodeRuns) {
  const std::string marker = tempDir("plugin_ctor") + "/constructor_ran";
  std::filesystem::remove(marker);
  ASSERT_EQ(setenv("OBSCURA_TEST_CTOR_MARKER", marker.c_str(), 1), 0);
  expectLoadError(OBSCURA_CTOR_BAD_ABI_PLUGIN, "plugin ABI version 999, this obscura needs");
  EXPECT_FALSE(std::filesystem::exists(marker)) << "the static constructor of a foreign-ABI plugin ran";
  // Control: the same constructor in a plugin of the right ABI does run on
  // load (the library then fails for lack of a register function).
  expectLoadError(OBSCURA_CTOR_GOOD_ABI_PLUGIN, "obscura_plugin_register");
  EXPECT_TRUE(std::filesystem::exists(marker)) << "the marker mechanism does not work";
  unsetenv("OBSCURA_TEST_CTOR_MARKER");
}

// The value read from the file is the one compiled in (999 for the bad plugin,
// the header's constant for the others), also after strip.
TEST(Plugin, AbiVersionIsReadFromTheFile) {
  EXPECT_EQ(readPluginAbiVersion(OBSCURA_BAD_ABI_PLUGIN), 999u);
  EXPECT_EQ(readPluginAbiVersion(OBSCURA_CTOR_BAD_ABI_PLUGIN), 999u);
  EXPECT_EQ(readPluginAbiVersion(OBSCURA_NO_REGISTER_PLUGIN), OBSCURA_PLUGIN_ABI_VERSION);
  EXPECT_EQ(readPluginAbiVersion(OBSCURA_DUPLICATE_PLUGIN), OBSCURA_PLUGIN_ABI_VERSION);
  const std::string dir = tempDir("plugin_abi_file");
  const std::string stripped = dir + "/stripped.so";
  std::filesystem::copy_file(OBSCURA_BAD_ABI_PLUGIN, stripped, std::filesystem::copy_options::overwrite_existing);
  if (std::system(("strip --strip-all '" + stripped + "' 2>/dev/null").c_str()) == 0)
    EXPECT_EQ(readPluginAbiVersion(stripped), 999u);  // .dynsym survives strip
  const char* zlib = "/lib/x86_64-linux-gnu/libz.so.1";
  if (std::ifstream(zlib).good()) {
    try {
      (void)readPluginAbiVersion(zlib);
      ADD_FAILURE() << "libz has an ABI version";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("no obscura_plugin_abi_version symbol"), std::string::npos) << e.what();
    }
  }
}

// Truncated and corrupted copies of a plugin: every one gives a value or one
// error line, and loading a truncated one fails before dlopen.
TEST(Plugin, MalformedPluginFilesGiveOneErrorLine) {
  const std::string good = readBytes(OBSCURA_BAD_ABI_PLUGIN);
  ASSERT_GT(good.size(), sizeof(Elf64_Ehdr));
  Elf64_Ehdr eh;
  std::memcpy(&eh, good.data(), sizeof eh);
  const std::string dir = tempDir("plugin_malformed");
  const std::string path = dir + "/bad.so";

  // The section header table is at the end: every truncation loses it.
  for (size_t n = 0; n < good.size(); n += (n < 128 ? 1 : 509)) {
    writeBytes(path, good.substr(0, n));
    expectLoadError(path, "not an ELF shared object");
  }
  const auto variant = [&](const std::string& what, auto&& edit) {
    std::string bytes = good;
    edit(bytes);
    writeBytes(path, bytes);
    expectValueOrError(path, what);
  };
  const auto expectMessage = [&](const std::string& what, auto&& edit, const std::string& needle) {
    variant(what, edit);
    try {
      (void)readPluginAbiVersion(path);
      ADD_FAILURE() << what << ": accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << what << ": " << e.what();
    }
  };
  expectMessage("ELF32", [](std::string& b) { b[EI_CLASS] = ELFCLASS32; }, "not 64-bit ELF");
  expectMessage("big-endian", [](std::string& b) { b[EI_DATA] = ELFDATA2MSB; }, "not 64-bit ELF");
  expectMessage("executable", [](std::string& b) { b[16] = char(ET_EXEC); b[17] = 0; }, "not ET_DYN");
  expectMessage("no section headers", [](std::string& b) { std::memset(&b[40], 0, 8); }, "no section header table");
  expectMessage("huge section count", [](std::string& b) { b[60] = char(0xff); b[61] = char(0xff); },
                "section header table outside the file");
  // Every byte of the ELF header and of the section header table, and a
  // sample of the rest, flipped one at a time.
  const uint64_t tableEnd = eh.e_shoff + uint64_t(eh.e_shnum) * sizeof(Elf64_Shdr);
  ASSERT_LE(tableEnd, good.size());
  for (size_t i = 0; i < good.size(); i += (i < sizeof(Elf64_Ehdr) || i >= eh.e_shoff ? 1 : 61))
    variant("byte " + std::to_string(i) + " flipped", [i](std::string& b) { b[i] = char(~b[i]); });
}

// docs/integrators.md's rows marked "(plugin)" against the loaded plugin's descriptor
// (the built-in rows are checked in test_docs_consistency.cpp).
TEST(Plugin, IntegratorTableRowMatchesThePlugin) {
  loadPlugin(OBSCURA_BENT_PLUGIN);
  const auto rows = integratorTableRows(readBytes(std::string(OBSCURA_SOURCE_DIR) + "/" + kIntegratorTableDoc));
  int pluginRows = 0;
  for (const IntegratorTableRow& row : rows) {
    if (!row.plugin) continue;
    ++pluginRows;
    const IntegratorDescriptor& d = IntegratorRegistry::instance().find(row.name);
    for (const std::string& p : integratorRowProblems(row, d, IntegratorRegistry::instance().all())) ADD_FAILURE() << p;
  }
  EXPECT_EQ(pluginRows, 1) << kIntegratorTableDoc << " documents the bent-normal plugin in one row";
}

// Unoccluded plane: B = E[w] under cos/pi about n = (0,0,2/3) in the normal's
// frame. Per-ray variances: Var(w_z) = E[z^2] - 4/9 = 1/2 - 4/9 = 1/18,
// Var(w_x) = Var(w_y) = E[x^2] = 1/4.
// The lobe controls (include/obscura/lobe.h, docs/math.md §11) in the plugin, which
// inlines the core's lobe code: explicit defaults are the defaults bit for
// bit; the inside lobe is the outside one mirrored - B_z exactly negated,
// since both frames put the warp's z on +-z alone (the normal is exactly
// +-z, so the tangents add zeros there) - and the cone of sin(thetaMax) = s
// has B_z = E[cos] = 2 (1 - (1 - s^2)^(3/2)) / (3 s^2), per-ray
// Var(z) = E[cos^2] - B_z^2 = 1 - s^2/2 - B_z^2.
// The bent-normal plugin loaded, and an open plane seen from above at an
// angle: every pixel covered, nothing occludes (bent normal = n, W exact).
struct BentNormalPlane {
  Scene scene;
  Camera cam;
  BentNormalPlane() {
    loadPlugin(OBSCURA_BENT_PLUGIN);
    addPlane(scene, 1e4f, 0.0f);
    scene.commit();
    cam = makeLookAtCamera(Vec3(0.5f, -3, 2), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "plane");
  }
};

TEST(Plugin, BentNormalOfAnOpenPlane) {
  const BentNormalPlane plane;
  const Scene& scene = plane.scene;
  const Camera& cam = plane.cam;
  const int w = 32, h = 32, spp = 32, rays = 2;
  const auto run = [&](std::vector<std::string> p) {
    p.push_back("rays=" + std::to_string(rays));
    return renderWith(scene, cam, "bent-normal", p, passSettings(w, h, spp));
  };
  const Film film = run({});
  size_t n = 0;
  const double bx = meanCovered(film, kR, &n), by = meanCovered(film, kG), bz = meanCovered(film, kB);
  ASSERT_EQ(n, size_t(w * h));
  const double N = double(n) * spp * rays;
  EXPECT_NEAR(bx, 0.0, 4.0 * std::sqrt(0.25 / N));
  EXPECT_NEAR(by, 0.0, 4.0 * std::sqrt(0.25 / N));
  EXPECT_NEAR(bz, 2.0 / 3.0, 4.0 * std::sqrt(1.0 / 18.0 / N));

  const Film defaults = run({"inside=false", "spread=1", "near=0"}), inside = run({"inside=true"});
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 4; ++c) ASSERT_EQ(defaults.at(c, x, y), film.at(c, x, y)) << x << "," << y << " c " << c;
      ASSERT_EQ(inside.at(kB, x, y), -film.at(kB, x, y)) << x << "," << y;
    }
  const double s = std::sin(0.5 * M_PI / 2);
  const double cone = 2 * (1 - std::pow(1 - s * s, 1.5)) / (3 * s * s);
  EXPECT_NEAR(meanCovered(run({"spread=0.5"}), kB), cone, 4.0 * std::sqrt((1 - s * s / 2 - cone * cone) / N));
}

// Adaptive sampling and the denoiser work on a plugin's pass as on a
// built-in's: the image does not depend on threads, pixels stop between
// --min-spp and --spp on their error, and a target no pixel can meet leaves
// every pixel equal to the fixed render.
TEST(Plugin, BentNormalAdaptsAndDenoises) {
  const BentNormalPlane plane;
  const Scene& scene = plane.scene;
  const Camera& cam = plane.cam;
  RenderSettings s = passSettings(24, 16, 64);
  s.aovs = true;
  // Below the filtered error the first round leaves (the 5 x 5 pooled
  // sqrt(G) se: every pixel stops at 8 spp with E = 0.05, a few go on at
  // 0.02), so rounds follow: 13 mean spp.
  s.targetError = 0.01f;
  s.minSpp = 8;
  s.denoise = true;
  RenderStats stats;
  const Film a = renderWith(scene, cam, "bent-normal", {}, s, &stats);
  s.threads = 1;
  const Film b = renderWith(scene, cam, "bent-normal", {}, s);
  for (int c : a.channels())
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 24; ++x) ASSERT_EQ(a.at(c, x, y), b.at(c, x, y)) << a.name(c) << " at " << x << "," << y;
  EXPECT_GT(stats.meanSpp, 8.0);
  EXPECT_LT(stats.meanSpp, 64.0);
  // A target of 0: every pixel takes --spp samples, equal to the fixed render.
  s.targetError = 1e-30f;
  s.denoise = false;
  const Film all = renderWith(scene, cam, "bent-normal", {}, s);
  RenderSettings fixed = passSettings(24, 16, 64);
  fixed.aovs = true;
  const Film ref = renderWith(scene, cam, "bent-normal", {}, fixed);
  for (int c = 0; c < 4; ++c)
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 24; ++x) ASSERT_EQ(all.at(c, x, y), ref.at(c, x, y)) << c << " at " << x << "," << y;
}

// A plugin takes part in a multi-pass render like a built-in (core/render/render.h):
// its layer equals its solo render bit for bit, and so does the built-in's.
TEST(Plugin, BentNormalInAMultiPassRender) {
  loadPlugin(OBSCURA_BENT_PLUGIN);
  Scene scene;
  addPlane(scene, 4.0f, 0.0f);
  addPlane(scene, 0.5f, 0.3f);  // an occluder, so the passes are not trivial
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0.5f, -3, 2), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "plane");
  const RenderSettings s = passSettings(24, 16, 4, 5);
  const auto make = [](const std::string& name) {
    const IntegratorDescriptor& d = IntegratorRegistry::instance().find(name);
    const ParamSet p(d.params, d.name);
    return std::make_pair(d.create(p), d.needs(p));
  };
  const auto bent = make("bent-normal"), ao = make("ao");
  const std::vector<RenderPass> passes = {{ao.first.get(), ao.second, "ao"}, {bent.first.get(), bent.second, "bent"}};
  RenderStats st;
  const Film both = render(scene, cam, passes, s, st);
  const Film soloBent = renderWith(scene, cam, "bent-normal", {}, s), soloAo = renderWith(scene, cam, "ao", {}, s);
  const size_t n = size_t(s.width) * size_t(s.height);
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(std::memcmp(both.plane(both.find("bent.R") + c), soloBent.plane(kR + c), n * sizeof(float)), 0) << c;
    EXPECT_EQ(std::memcmp(both.plane(both.find("ao.R") + c), soloAo.plane(kR + c), n * sizeof(float)), 0) << c;
  }
}

// Issue 15's whole file: one `obscura render` writes ao + transfer +
// bent-normal (a plugin) + reflocc layers and Cryptomatte into one EXR; each
// layer equals its solo CLI render bit for bit, and the ID mattes do not
// change any pass.
TEST(Plugin, OneRenderWritesEveryCompositingLayer) {
  const std::string dir = tempDir("plugin_compositing");
  const std::vector<std::string> common = {"render", "-q", "--res", "48x27", "--spp", "4", "--plugin", OBSCURA_BENT_PLUGIN};
  const auto args = [&](const std::string& out, std::vector<std::string> extra) {
    std::vector<std::string> a = common;
    a.push_back("-o");
    a.push_back(dir + "/" + out);
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  const std::vector<std::pair<std::string, std::vector<std::string>>> solo = {
      {"ao", {"-i", "ao", "-p", "distance=2"}},
      {"transfer", {"-i", "transfer", "-p", "depth=1"}},
      {"bent", {"-i", "bent-normal"}},
      {"refl", {"-i", "reflocc", "-p", "roughness=0.3"}},
  };
  std::vector<std::vector<std::string>> runs = {
      args("all.exr", {"--pass", "ao=ao:distance=2", "--pass", "transfer=transfer:depth=1", "--pass", "bent=bent-normal",
                       "--pass", "refl=reflocc:roughness=0.3", "--cryptomatte", "object,material"})};
  for (const auto& [layer, extra] : solo) runs.push_back(args(layer + ".exr", extra));
  for (const CliResult& r : runClis(runs, dir)) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack all = readExr(dir + "/all.exr");
  ASSERT_TRUE(all.ok);
  for (const auto& [layer, extra] : solo) {
    const ReadBack one = readExr(dir + "/" + layer + ".exr");
    for (const char* c : {"R", "G", "B"}) EXPECT_EQ(all.planes.at(layer + "." + c), one.planes.at(c)) << layer << c;
  }
  for (const char* c : {"CryptoObject00.R", "CryptoObject00.G", "CryptoMaterial00.R", "CryptoMaterial00.G"})
    EXPECT_EQ(all.planes.count(c), 1u) << c;
  EXPECT_FALSE(all.spec.get_string_attribute("obscura:pass:bent:integrator").empty());
}

// From the wall point opposite the hole of the spherical cavity
// (docs/math.md §7), the open directions are the cone theta < alpha/2 about the
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

// A screen-space integrator from a plugin: registered with its kind, run on
// the core's G-buffer tiles. covered-neighbours' W at a covered pixel is the
// covered fraction of its neighbours (window of half-size r, inside the
// image), which the test recounts from the film's coverage: with one camera
// sample per pixel, A is the layer's coverage, 0 or 1. A plane seen from
// above fills the middle of the frame, so the window straddles its edges.
TEST(Plugin, ScreenSpacePluginReadsTheGBuffer) {
  loadPlugin(OBSCURA_SCREEN_SPACE_PLUGIN);
  EXPECT_EQ(IntegratorRegistry::instance().find("covered-neighbours").kind, IntegratorKind::ScreenSpace);
  Scene scene;
  addPlane(scene, 1.0f, 0.0f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 4), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.7f, "top");
  const int w = 40, h = 30;
  for (int r : {1, 3}) {
    const Film film = renderWith(scene, cam, "covered-neighbours", {"radius=" + std::to_string(r)}, passSettings(w, h, 1));
    int covered = 0, partial = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float a = film.at(kA, x, y);
        ASSERT_TRUE(a == 0.0f || a == 1.0f) << x << "," << y << ": A " << a;
        if (a == 0.0f) continue;
        ++covered;
        int c = 0, total = 0;
        for (int yy = std::max(0, y - r); yy <= std::min(h - 1, y + r); ++yy)
          for (int xx = std::max(0, x - r); xx <= std::min(w - 1, x + r); ++xx)
            if (xx != x || yy != y) ++total, c += film.at(kA, xx, yy) == 1.0f;
        const float expected = float(c) / float(total);
        partial += expected < 1.0f;
        EXPECT_FLOAT_EQ(film.at(kR, x, y), expected) << "r " << r << " at " << x << "," << y;
      }
    EXPECT_GT(covered, 100) << r;
    EXPECT_GT(partial, 20) << r;  // the plane's edges are in the frame
  }
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
  // A screen-space plugin from the CLI, beside a built-in in compare.
  const CliResult ss = runCli({"render", "--plugin", OBSCURA_SCREEN_SPACE_PLUGIN, "-i", "covered-neighbours", "-p",
                               "radius=2", "-o", dir + "/ss.exr", "--res", "16x9", "--spp", "2", "-q"},
                              dir + "/ss.txt");
  EXPECT_EQ(ss.exitCode, 0) << ss.stderrText;
  EXPECT_EQ(readExr(dir + "/ss.exr").spec.get_string_attribute("obscura:integrator"), "covered-neighbours");
  const CliResult cmp = runCli({"compare", "--plugin", OBSCURA_SCREEN_SPACE_PLUGIN, "-o", dir + "/cmp", "--res", "16x9",
                                "--spp", "2", "--reference-spp", "8", "--seeds", "1", "-q", "-c", "ao", "-c",
                                "covered-neighbours:radius=2"},
                               dir + "/cmp.txt");
  EXPECT_EQ(cmp.exitCode, 0) << cmp.stderrText;
  const CliResult bad = runCli({"render", "--plugin", OBSCURA_BAD_ABI_PLUGIN, "-o", dir + "/x.exr", "-q"},
                               dir + "/bad.txt");
  EXPECT_EQ(bad.exitCode, 1);
  EXPECT_EQ(bad.stderrText.rfind("obscura: error: ", 0), 0u) << bad.stderrText;
  EXPECT_NE(bad.stderrText.find("ABI version 999"), std::string::npos) << bad.stderrText;
  EXPECT_FALSE(std::filesystem::exists(dir + "/x.exr"));
}

}  // namespace
}  // namespace obscura::test
