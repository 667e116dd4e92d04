// Several passes from one render (core/render/render.h, docs/production.md "Several passes in
// one render"): each pass in a combined render equals the same pass rendered
// alone, bit for bit - the ray-traced passes share one walk over the camera
// samples, the screen-space passes one G-buffer layer per sample - and the CLI's
// --pass/--primary write one layer per pass with every pass's parameters in
// the header.
#include <gtest/gtest.h>

#include <cstring>

#include <obscura/error.h>
#include "app/render_setup.h"
#include "core/load/gltf_loader.h"
#include "core/render/gbuffer.h"
#include "core/render/render.h"
#include "tests/support.h"

using namespace obscura;
using namespace obscura::test;

namespace {

struct PassConfig {
  std::string layer, integrator;
  std::vector<std::string> params;
};

struct Built {
  std::unique_ptr<Integrator> integrator;
  IntegratorNeeds needs;
};

Built build(const PassConfig& c) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find(c.integrator);
  ParamSet p(d.params, d.name);
  for (const auto& a : c.params) p.setAssignment(a);
  return {d.create(p), d.needs(p)};
}

// Bitwise equality of two planes (NaN-safe: the bits, not the values).
void expectSamePlane(const Film& a, int ca, const Film& b, int cb, const std::string& what) {
  const size_t n = size_t(a.width()) * size_t(a.height());
  ASSERT_EQ(n, size_t(b.width()) * size_t(b.height()));
  ASSERT_EQ(std::memcmp(a.plane(ca), b.plane(cb), n * sizeof(float)), 0) << what;
}

// Renders `configs` combined and each alone; every layer must equal its
// solo R,G,B, and the combined film's own channels the primary's solo film.
void checkCombinedEqualsSolo(const Scene& scene, const Camera& cam, const std::vector<PassConfig>& configs,
                             RenderSettings s) {
  std::vector<Built> built;
  std::vector<RenderPass> passes;
  for (const PassConfig& c : configs) built.push_back(build(c));
  for (size_t k = 0; k < configs.size(); ++k) passes.push_back({built[k].integrator.get(), built[k].needs, configs[k].layer});
  RenderStats stats;
  const Film combined = render(scene, cam, passes, s, stats);
  for (size_t k = 0; k < configs.size(); ++k) {
    const Film solo = renderWith(scene, cam, configs[k].integrator, configs[k].params, s);
    const int layer = combined.find(configs[k].layer + ".R");
    ASSERT_GE(layer, 0) << configs[k].layer;
    for (int c = 0; c < 3; ++c) expectSamePlane(combined, layer + c, solo, kR + c, configs[k].layer + " channel " + std::to_string(c));
    if (k == 0)
      for (int c : solo.channels()) expectSamePlane(combined, c, solo, c, "primary " + solo.name(c));
  }
}

class MultiPass : public ::testing::Test {
 protected:
  void SetUp() override {
    scene_ = loadGltf(sourcePath("scenes/default.gltf"));
    cam_ = scene_->cameras.at(0);
  }
  std::unique_ptr<Scene> scene_;
  Camera cam_;
};

}  // namespace

// Ray-traced passes with and without albedo (multibounce needs it; its
// resolvePixel reads it), a ratio estimator (transfer at depth 1), and a
// screen-space pass, with AOVs on and off: AOVs off is where a pass that
// does not need albedo must still resolve as it would alone.
TEST_F(MultiPass, EachPassEqualsItsSoloRender) {
  const std::vector<PassConfig> configs = {
      {"ao", "ao", {"distance=2"}},
      {"dirt", "obscurance", {"falloff=sqrt", "distance=1"}},
      {"tr", "transfer", {"depth=1"}},
      {"mb", "multibounce", {}},
      {"refl", "reflocc", {"distance=2"}},
      {"vo", "vo", {}},
  };
  RenderSettings s = passSettings(48, 27, 4, 7);
  s.aovs = true;
  checkCombinedEqualsSolo(*scene_, cam_, configs, s);
  s.aovs = false;
  checkCombinedEqualsSolo(*scene_, cam_, configs, s);
}

// A screen-space primary: the ray-traced passes render into a film of their
// own and are copied into their layers; the film's R,G,B,A and AOVs are the
// screen-space pass's.
TEST_F(MultiPass, ScreenSpacePrimary) {
  RenderSettings s = passSettings(40, 24, 2, 3);
  s.aovs = true;
  checkCombinedEqualsSolo(*scene_, cam_, {{"vo", "vo", {}}, {"ao", "ao", {}}, {"ssat", "ssat", {}}}, s);
}

// Screen-space passes share one G-buffer layer per camera sample
// (core/render/gbuffer.cpp renderScreenSpace): each reads it within its own
// guard band and moment levels, so each layer still equals its solo render
// bit for bit - passes with different bands (one fixed at 5 pixels, one
// without a band, which reads the image alone), depth moments of two band
// widths and with and without their pre-blur (built again for the pass
// that wants the other), the interleave filter, the bilateral blur, albedo
// and the occluders' radiance, a traced twin, gtao - under a
// ray-traced primary and a screen-space one, and with adaptive sampling,
// where each pass keeps its own schedule.
TEST_F(MultiPass, ScreenSpacePassesShareOneLayerAndEqualTheirSoloRenders) {
  const std::vector<PassConfig> screenSpace = {
      {"vo_area", "vo", {"samples=area", "radius=1"}},
      {"vo_small", "vo", {"samples=area", "radius=0.2", "guard-band=5"}},
      {"vo_il", "vo", {"samples=point", "interleave=on", "radius=0.5"}},
      {"ssat", "ssat", {"albedo=true", "distance=0.7"}},
      {"vo_none", "vo", {"guard-band=0"}},
      {"gtao", "gtao", {"radius=0.6"}},
      {"twin", "vo", {"depth=traced", "radius=0.7"}},
      {"vo_raw", "vo", {"samples=area", "prefilter=off", "radius=0.8"}},
      {"vo_blur", "vo", {"interleave=on", "blur=2", "kernel=quadratic"}},
      {"vo_sphere", "vo", {"samples=area", "normal=tangent-sphere"}},
      {"ssat_rad", "ssat", {"albedo=true", "occluder=radiance", "distance=0.5"}},
  };
  RenderSettings s = passSettings(44, 26, 3, 5);
  s.aovs = true;
  checkCombinedEqualsSolo(*scene_, cam_, screenSpace, s);
  std::vector<PassConfig> rayTracedFirst = {{"ao", "ao", {"distance=2"}}};
  rayTracedFirst.insert(rayTracedFirst.end(), screenSpace.begin(), screenSpace.end());
  checkCombinedEqualsSolo(*scene_, cam_, rayTracedFirst, s);
  RenderSettings adaptive = passSettings(44, 26, 16, 5);
  adaptive.targetError = 0.05f;
  adaptive.minSpp = 4;
  checkCombinedEqualsSolo(*scene_, cam_, {screenSpace[0], screenSpace[2], screenSpace[3]}, adaptive);
}

// One layer, not one per pass: the camera rays of passes sharing a layer
// are those of the widest pass's layer alone (the layers here nest: the
// widest contains each other's, asserted from layerGeometry).
TEST_F(MultiPass, ScreenSpacePassesTraceOneLayerOfCameraRays) {
  const std::vector<PassConfig> configs = {
      {"wide", "vo", {"samples=area", "radius=1"}},
      {"narrow", "vo", {"radius=0.3"}},
      {"ssat", "ssat", {"distance=0.5"}},
  };
  const RenderSettings s = passSettings(40, 24, 2, 1);
  std::vector<Built> built;
  std::vector<RenderPass> passes;
  for (const PassConfig& c : configs) built.push_back(build(c));
  for (size_t k = 0; k < configs.size(); ++k) passes.push_back({built[k].integrator.get(), built[k].needs, configs[k].layer});
  const PixelRect frame{0, 0, s.width, s.height};
  const LayerGeometry wide = layerGeometry(*built[0].integrator->screenSpace(), *scene_, cam_, s.width, s.height, frame);
  for (size_t k = 1; k < built.size(); ++k) {
    const LayerGeometry g = layerGeometry(*built[k].integrator->screenSpace(), *scene_, cam_, s.width, s.height, frame);
    ASSERT_LE(wide.originX, g.originX);
    ASSERT_LE(wide.originY, g.originY);
    ASSERT_GE(wide.originX + wide.width, g.originX + g.width);
    ASSERT_GE(wide.originY + wide.height, g.originY + g.height);
  }
  RenderStats stats;
  render(*scene_, cam_, passes, s, stats);
  EXPECT_EQ(stats.rays.camera, uint64_t(s.spp) * uint64_t(wide.width) * uint64_t(wide.height));
}

// Thread count and tile size do not change a combined render.
TEST_F(MultiPass, IndependentOfThreadsAndTiles) {
  const Built ao = build({"ao", "ao", {}}), tr = build({"tr", "transfer", {"depth=1"}});
  const std::vector<RenderPass> passes = {{ao.integrator.get(), ao.needs, "ao"}, {tr.integrator.get(), tr.needs, "tr"}};
  RenderSettings a = passSettings(37, 23, 3, 1), b = a;
  a.threads = 1, a.tileSize = 8;
  b.threads = 2, b.tileSize = 64;
  RenderStats st;
  const Film fa = render(*scene_, cam_, passes, a, st), fb = render(*scene_, cam_, passes, b, st);
  ASSERT_EQ(fa.channels(), fb.channels());
  for (int c : fa.channels()) expectSamePlane(fa, c, fb, c, fa.name(c));
}

TEST_F(MultiPass, RefusesAPassWithoutALayerAfterTheFirst) {
  const Built ao = build({"", "ao", {}});
  const std::vector<RenderPass> passes = {{ao.integrator.get(), ao.needs, "ao"}, {ao.integrator.get(), ao.needs, ""}};
  RenderStats st;
  EXPECT_THROW(render(*scene_, cam_, passes, passSettings(4, 4, 1), st), Error);
}

// The CLI: one EXR with a layer per pass, the primary also in R,G,B, every
// pass's parameters in the header, equal to the solo CLI renders; and one
// clear error line for each malformed --pass.
TEST(MultiPassCli, LayersHeaderAndErrors) {
  const std::string dir = tempDir("multipass_cli");
  const std::vector<std::string> common = {"render", "-q", "--res", "40x24", "--spp", "2"};
  const auto args = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = common;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  const std::vector<CliResult> runs = runClis(
      {args({"-o", dir + "/multi.exr", "--pass", "ao=ao:distance=2", "--pass", "dirt=obscurance:falloff=sqrt",
             "--primary", "dirt"}),
       args({"-o", dir + "/ao.exr", "-i", "ao", "-p", "distance=2"}),
       args({"-o", dir + "/dirt.exr", "-i", "obscurance", "-p", "falloff=sqrt"})},
      dir);
  for (const CliResult& r : runs) ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack multi = readExr(dir + "/multi.exr"), ao = readExr(dir + "/ao.exr"), dirt = readExr(dir + "/dirt.exr");
  for (const char* c : {"R", "G", "B"}) {
    EXPECT_EQ(multi.planes.at(std::string("ao.") + c), ao.planes.at(c)) << c;
    EXPECT_EQ(multi.planes.at(std::string("dirt.") + c), dirt.planes.at(c)) << c;
    EXPECT_EQ(multi.planes.at(c), dirt.planes.at(c)) << "primary " << c;  // --primary dirt
  }
  EXPECT_EQ(multi.planes.at("A"), dirt.planes.at("A"));
  EXPECT_EQ(multi.spec.get_string_attribute("obscura:integrator"), "obscurance");
  EXPECT_EQ(multi.spec.get_string_attribute("obscura:primaryPass"), "dirt");
  EXPECT_EQ(multi.spec.get_string_attribute("obscura:pass:ao:integrator"), "ao");
  EXPECT_EQ(multi.spec.get_string_attribute("obscura:pass:ao:param:distance"), "2");
  EXPECT_EQ(multi.spec.get_string_attribute("obscura:pass:dirt:param:falloff"), "sqrt");
  EXPECT_NE(multi.spec.get_string_attribute("obscura:passes").find("ao=ao:distance=2"), std::string::npos);

  struct Bad {
    std::vector<std::string> extra;
    std::string says;
  };
  const std::vector<Bad> bad = {
      {{"--pass", "ao"}, "expected LAYER=integrator"},
      {{"--pass", "1x=ao"}, "must be a letter"},
      {{"--pass", "Z=ao"}, "a layer Obscura writes itself"},
      {{"--pass", "CryptoObject=ao"}, "Cryptomatte"},
      {{"--pass", "Combined=ao"}, "render pass name of Blender"},
      {{"--pass", "depth=ao"}, "built-in layer of Nuke"},
      {{"--pass", "a=ao", "--pass", "a=obscurance"}, "already a pass"},
      {{"--pass", "a=nosuch"}, "nosuch"},
      {{"--pass", "a=ao:distance=-1"}, "distance"},
      {{"--pass", "a=ao", "-i", "ao"}, "replaces -i and -p"},
      {{"--pass", "a=ao", "--primary", "b"}, "no --pass has the layer 'b'"},
      {{"--primary", "a"}, "no --pass was given"},
  };
  std::vector<std::vector<std::string>> badArgs;
  for (const Bad& b : bad) {
    badArgs.push_back(args(b.extra));
    badArgs.back().push_back("-o");
    badArgs.back().push_back(dir + "/bad.exr");
  }
  const std::vector<CliResult> badRuns = runClis(badArgs, dir);
  for (size_t i = 0; i < bad.size(); ++i) {
    const Bad& b = bad[i];
    const CliResult& r = badRuns[i];
    EXPECT_EQ(r.exitCode, 1) << b.says;
    EXPECT_NE(r.stderrText.find(b.says), std::string::npos) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  }
}

// Issue #37: `--pass Combined=...` crashed Blender 3.4 on load (its reader
// files R,G,B,A under the pass Combined, so the layer made six colour
// channels of one pass), and Depth/Alpha were mixed into the passes and
// sockets it makes. Every reserved name, and every name a reserved prefix
// starts, is refused naming who reserves it; names differing only in case
// pass, as both readers match case-sensitively (`ao` is the docs' example).
TEST(MultiPassNames, LayerNamesCompositorsReserveAreRefused) {
  auto setupsFor = [](const std::string& pass) {
    RenderArgs a;
    a.passes = {pass + "=ao"};
    return passSetups(a);
  };
  for (const ReservedLayerName& r : reservedLayerNames()) {
    for (const std::string& name : r.prefix ? std::vector<std::string>{r.name, std::string(r.name) + "Extra_1"}
                                            : std::vector<std::string>{r.name}) {
      try {
        setupsFor(name);
        ADD_FAILURE() << "--pass " << name << "=ao was accepted";
      } catch (const Error& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("the layer name '" + name + "' is reserved: " + r.owner), std::string::npos) << what;
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
      }
    }
  }
  for (const char* free : {"ao", "dirt", "combined", "DEPTH", "Rgba", "W", "sppx", "W_error2", "bounce"})
    EXPECT_NO_THROW(setupsFor(free)) << free;
  // The names issue #37 found, and the new channel layers, are in the list.
  for (const char* must : {"Combined", "Depth", "Alpha", "rgba", "depth", "W_error", "spp", "lighting", "noisy"})
    EXPECT_THROW(setupsFor(must), Error) << must;
}
