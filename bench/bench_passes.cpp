// obscura_bench_passes: several passes from one render against one render
// per pass (docs/production.md "Several passes in one render", "Speed").
//
// ao + obscurance (falloff=sqrt) + transfer + the bent-normal plugin, at
// 1920x1080 on the viking room by default, with the AOVs on (what
// `obscura render` writes): once as one multi-pass render (core/render/render.h:
// the passes share the camera rays, surface hits, albedo and AOVs), once as
// four solo renders. Runs interleave combined and separate (the machine is
// shared and noisy); the table gives medians of the render loop's wall time
// and the ratio of the medians, measured in the same run. Every run also
// checks that each layer of the combined film equals its solo render bit for
// bit.
//
// The bent-normal plugin is built by the test suite (ctest's
// plugin.build_out_of_tree); without it the bench runs the three built-ins
// and says so.
//
// Run:   build/bench/obscura_bench_passes                  1920x1080, 4 spp, 3 runs
//        build/bench/obscura_bench_passes --quick          smoke run (320x180, 1 spp, 1 run)
#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstring>
#include <filesystem>

#include "bench/common.h"
#include <obscura/error.h>
#include "core/render/plugin_loader.h"
#include <obscura/plugin.h>

using namespace obscura;
using namespace obscura::bench;

namespace {

struct PassDef {
  const char* layer;
  const char* integrator;
  std::vector<std::pair<std::string, std::string>> params;
};

bool samePlane(const Film& a, int ca, const Film& b, int cb) {
  return std::memcmp(a.plane(ca), b.plane(cb), sizeof(float) * size_t(a.width()) * size_t(a.height())) == 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Several passes in one render against one render per pass"};
  CommonOptions common;
  common.res = "1920x1080";
  common.spp = 4;
  common.runs = 3;
  addCommonOptions(app, common, "smoke run: 320x180, 1 spp, 1 run");
  std::string plugin = OBSCURA_BENT_PLUGIN_DEFAULT;
  app.add_option("--plugin", plugin, "The bent-normal plugin (default: the one the test suite builds)");
  CLI11_PARSE(app, argc, argv);
  try {
    if (common.quick) common.res = "320x180", common.spp = 1, common.runs = 1;
    if (common.scenes.empty()) common.scenes = {"viking"};
    const BenchSize size = checkCommonOptions(common);
    const ThreadLimit threads(common.threads);
    printMachine(threads.threads());

    std::vector<PassDef> defs = {{"ao", "ao", {}}, {"dirt", "obscurance", {{"falloff", "sqrt"}}}, {"transfer", "transfer", {}}};
    if (std::filesystem::exists(plugin)) {
      loadPlugin(plugin);
      defs.push_back({"bent", "bent-normal", {}});
    } else {
      std::printf("note: %s not found (run ctest -R plugin first): bent-normal left out\n", plugin.c_str());
    }
    std::vector<BenchIntegrator> integrators;
    for (const PassDef& d : defs) integrators.emplace_back(d.integrator, d.params);
    std::vector<RenderPass> passes;
    for (size_t k = 0; k < defs.size(); ++k) passes.push_back({integrators[k].integrator.get(), integrators[k].needs, defs[k].layer});

    RenderSettings s = benchRenderSettings(size.width, size.height, common.spp, threads.threads());
    s.aovs = true;  // as `obscura render` writes each pass
    for (const std::string& which : common.scenes) {
      const BenchScene scene = loadScene(which, float(size.width) / float(size.height));
      std::printf("\n%s: %zu triangles, %dx%d, %d spp, AOVs on, %zu passes, %d runs (medians)\n", scene.label.c_str(),
                  scene.triangles, size.width, size.height, common.spp, defs.size(), common.runs);
      std::vector<double> combined, separate;
      std::vector<std::vector<double>> solo(defs.size());
      uint64_t raysCombined = 0, raysSeparate = 0;
      bool identical = true;
      for (int run = 0; run < common.runs; ++run) {
        RenderStats st;
        const Film all = render(*scene.scene, scene.camera, passes, s, st);
        combined.push_back(st.seconds);
        raysCombined = st.rays.camera + st.rays.occlusion + st.rays.closest;
        double total = 0;
        raysSeparate = 0;
        for (size_t k = 0; k < defs.size(); ++k) {
          RenderStats one;
          const Film f = integrators[k].render(*scene.scene, scene.camera, s, one);
          solo[k].push_back(one.seconds);
          total += one.seconds;
          raysSeparate += one.rays.camera + one.rays.occlusion + one.rays.closest;
          const int layer = all.find(std::string(defs[k].layer) + ".R");
          for (int c = 0; c < 3; ++c) identical = identical && samePlane(all, layer + c, f, kR + c);
        }
        separate.push_back(total);
      }
      for (size_t k = 0; k < defs.size(); ++k)
        std::printf("  solo %-12s %8.3f s\n", defs[k].integrator, median(solo[k]));
      const double tc = median(combined), ts = median(separate);
      std::printf("  %-17s %8.3f s   %.1f Mrays\n", "separate (sum)", ts, double(raysSeparate) * 1e-6);
      std::printf("  %-17s %8.3f s   %.1f Mrays\n", "combined", tc, double(raysCombined) * 1e-6);
      std::printf("  combined / separate = %.3f   (layers bit-identical to solo renders: %s)\n", tc / ts,
                  identical ? "yes" : "NO");
      if (!identical) throw Error("a layer of the combined render differs from its solo render");
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "obscura_bench_passes: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
