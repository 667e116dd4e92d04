// obscura_bench_screen_space: the screen-space integrators (`vo`, `ssat`)
// against the ray-traced `obscurance` at equal estimator samples.
//
// One camera sample per pixel (--spp 1) and N samples per pixel (--count,
// default 16): `obscurance rays=N` (step falloff, distance R, the distance
// estimator) against `vo count=N` (point, line, area) and `ssat count=N`
// (interleaving on and off), all with the same R (--radius-fraction of the
// scene's bounding-box diagonal). Each render is obscura::render() in
// process - the screen-space ones include their G-buffer's camera rays -
// timed as the median of --runs; the screen-space renders also report the
// split G-buffer / screen-space pass / filter, and the screen-space pass's
// rate in depth-buffer samples per second (pixels x N / its seconds).
//
// Run:   build/bench/obscura_bench_screen_space                  viking + generated, 1920x1080, 1 spp, 3 runs
//        build/bench/obscura_bench_screen_space --quick          smoke run (320x180, 1 run)
//        build/bench/obscura_bench_screen_space --scene viking --count 16 --runs 5
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "bench/common.h"
#include <obscura/error.h>
#include <obscura/integrator.h>
#include <obscura/params.h>

using namespace obscura;
using namespace obscura::bench;

namespace {

struct Options : CommonOptions {
  int count = 16;
  double radiusFraction = 0.02;
  std::string only;  // substring of the screen-space configs to time (empty: all)
};

struct Row {
  std::string config;
  double seconds = 0, gbuffer = 0, pass = 0, filter = 0;
  bool screenSpace = false;
};

Row timeConfig(const BenchScene& bs, const std::string& name, const std::vector<std::string>& params,
               const RenderSettings& s, int runs) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find(name);
  ParamSet p(d.params, d.name);
  std::string label = name;
  for (const std::string& a : params) {
    p.setAssignment(a);
    label += (label == name ? ":" : ",") + a;
  }
  const auto integ = d.create(p);
  const IntegratorNeeds needs = passNeeds(d, p);
  std::vector<double> t, g, q, f;
  for (int r = 0; r < runs; ++r) {
    RenderStats st;
    render(*bs.scene, bs.camera, *integ, needs, s, st);
    t.push_back(st.seconds), g.push_back(st.gbufferSeconds), q.push_back(st.screenSpaceSeconds),
        f.push_back(st.filterSeconds);
  }
  return {label, median(t), median(g), median(q), median(f), d.kind == IntegratorKind::ScreenSpace};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obscura_bench_screen_space: vo and ssat against ray-traced obscurance at equal samples"};
  Options o;
  o.spp = 1;
  o.res = "1920x1080";
  addCommonOptions(app, o, "Smoke run: 320x180, 1 run");
  app.add_option("--count", o.count, "Estimator samples per pixel: obscurance rays and the screen-space count (16)");
  app.add_option("--radius-fraction", o.radiusFraction, "R as a fraction of the scene's bounding-box diagonal (0.02)");
  app.add_option("--only", o.only, "Time only the screen-space configs whose label contains this (e.g. ssat)");
  CLI11_PARSE(app, argc, argv);
  try {
    if (o.quick) {
      if (app.count("--res") == 0) o.res = "320x180";
      if (app.count("--runs") == 0) o.runs = 1;
    }
    const auto [width, height] = checkCommonOptions(o);
    if (o.count < 1 || o.count > 256) throw Error("--count must be in [1, 256]");
    if (!(o.radiusFraction > 0) || !std::isfinite(o.radiusFraction))
      throw Error("--radius-fraction must be a positive number");
    const ThreadLimit limit(o.threads);
    const int threads = limit.threads();
    std::printf("obscura_bench_screen_space: screen-space passes vs ray-traced obscurance, equal samples\n");
    printMachine(threads);
    std::printf("   settings   %dx%d, %d spp, %d samples per pixel, R = %g x diagonal, median of %d run%s\n", width,
                height, o.spp, o.count, o.radiusFraction, o.runs, o.runs == 1 ? "" : "s");
    for (const std::string& which : o.scenes) {
      const BenchScene bs = loadScene(which, float(width) / float(height));
      const std::string R = "=" + std::to_string(o.radiusFraction * bs.diagonal);
      const std::string n = "=" + std::to_string(o.count);
      const RenderSettings s = benchRenderSettings(width, height, o.spp, threads);
      std::vector<std::pair<std::string, std::vector<std::string>>> configs;
      for (const char* kind : {"point", "line", "area"})
        configs.push_back({"vo", {std::string("samples=") + kind, "radius" + R, "count" + n}});
      configs.push_back({"vo", {"samples=line", "radius" + R, "count" + n, "interleave=on"}});
      for (const char* inter : {"on", "off"})
        configs.push_back({"ssat", {"distance" + R, "count" + n, std::string("interleave=") + inter}});
      std::vector<Row> rows;
      rows.push_back(timeConfig(bs, "obscurance", {"distance" + R, "rays" + n}, s, o.runs));
      for (const auto& [name, params] : configs) {
        std::string label = name;
        for (const std::string& a : params) label += "," + a;
        if (label.find(o.only) != std::string::npos) rows.push_back(timeConfig(bs, name, params, s, o.runs));
      }
      std::printf("\n== %s (%zu triangles, diagonal %.3g)\n", bs.label.c_str(), bs.triangles, bs.diagonal);
      std::printf("| config | render s | speed-up vs obscurance | G-buffer s | screen-space s | filter s | "
                  "depth samples/s (screen-space pass) | bound: obscurance / G-buffer |\n"
                  "|---|---|---|---|---|---|---|---|\n");
      const double samples = double(width) * height * o.spp * o.count;
      for (const Row& r : rows) {
        if (!r.screenSpace) {
          std::printf("| `%s` | %.3f | 1 | | | | | |\n", r.config.c_str(), r.seconds);
          continue;
        }
        std::printf("| `%s` | %.3f | %.1fx | %.3f | %.3f | %.3f | %.0f M | %.1fx |\n", r.config.c_str(), r.seconds,
                    rows[0].seconds / r.seconds, r.gbuffer, r.pass, r.filter, samples / r.pass * 1e-6,
                    rows[0].seconds / r.gbuffer);
      }
      std::fflush(stdout);
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_screen_space: error: %s\n", e.what());
    return 1;
  }
}
