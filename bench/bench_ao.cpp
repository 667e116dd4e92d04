// obscura_bench_ao: how close does `obscura render -i ao` get to raw Embree?
//
// On each scene one render with the registered `ao` integrator (rays=1, the
// resolution, spp, seed, camera and threads given; AOVs off, so only the
// pass is timed) is captured and its batches replayed through raw Embree
// (bench/replay.h: the very same rays, batch sizes and context flags through
// rtcIntersect1M / rtcOccluded1M; hits checked bit-equal, the capture
// render's image checked equal to every timed render's). Then, --runs times,
// interleaved with the order rotated each run (the machine is shared and
// noisy):
//   renderer     obscura::render() with `ao`;
//   replay       the captured batches through raw Embree streams, nothing else;
//   replay+hit   (diagnostic) replay plus computeSurfaceHit at every hit, so
//                replay -> replay+hit -> renderer splits the renderer's loss
//                into "surface reconstruction" and "render loop + integrator".
//
// The table: median wall s, Mrays/s = (camera + AO rays) / median wall s,
// median process CPU s / threads and Mrays per CPU-second, CPU use, and the
// renderer's Mrays/s as a percentage of the replay's (median wall clock; the
// goal is >= 85 %), cross-checked paired within each run (median of per-run
// ratios) and per CPU-second.
//
// (Before the replay, this bench rebuilt the ao rays outside the renderer and
// traced them as single rays, 16-wide packets and streams; the renderer uses
// streams, and the standard is the renderer's own rays through the same call,
// so the replay is the one yardstick now. A bare loop generating its rays
// with its own camera and RNG is obscura_bench_bare.)
//
// Run:   build/bench/obscura_bench_ao                 both scenes, 1920x1080, 16 spp, 3 runs
//        build/bench/obscura_bench_ao --quick         480x270 smoke run
//        build/bench/obscura_bench_ao --scene generated --runs 5 --threads 1
//        build/bench/obscura_bench_ao --variants replay,replay+hit,renderer
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "bench/common.h"
#include "bench/replay.h"
#include <obscura/error.h>
#include "core/image/image_io.h"
#include <obscura/integrator.h>
#include "core/render/render.h"

using namespace obscura;
using namespace obscura::bench;

namespace {

struct Options : CommonOptions {
  Options() { res = "1920x1080"; }
  std::string distance = "inf";
  std::string preview;
  std::string variants = "replay,renderer";
  double maxCaptureGiB = 8.0;
};

enum Variant { kReplay, kRenderer, kSurface, kVariants };
const char* const kShortNames[kVariants] = {"replay", "renderer", "replay+hit"};

struct SceneResult {
  std::string label;
  size_t triangles = 0;
  double buildSeconds = 0;
  bool compared = false, ok = false, busy = false;
  double rays = 0;
  std::array<Timings, kVariants> t;
  double ratio = 0, ratioCpu = 0, ratioPaired = 0;  // renderer / replay
};

SceneResult benchScene(const std::string& which, const Options& o, const std::vector<int>& variants, int width,
                       int height, int threads) {
  std::printf("\n== scene: %s\n", which.c_str());
  std::fflush(stdout);
  BenchScene bs = loadScene(which, float(width) / float(height));
  const Vec3 cp = bs.camera.position();
  std::printf("   source     %s\n", bs.source.c_str());
  std::printf("   triangles  %zu\n", bs.triangles);
  std::printf("   camera     '%s' at (%.4g, %.4g, %.4g), yfov %.3g rad\n", bs.camera.name.c_str(), cp.x, cp.y, cp.z,
              bs.camera.yfov);
  std::printf("   BVH build  %.3f s   (load + build %.3f s, scene added %.1f MiB resident)\n", bs.buildSeconds,
              bs.loadSeconds, bs.rssAddedMiB);
  std::fflush(stdout);

  SceneResult res;
  res.label = bs.label;
  res.triangles = bs.triangles;
  res.buildSeconds = bs.buildSeconds;
  const BenchIntegrator integ("ao", {{"distance", o.distance}, {"rays", "1"}});
  const RenderSettings s = benchRenderSettings(width, height, o.spp, threads);
  auto render = [&](const RenderSettings& rs, RenderStats& st) { return integ.render(*bs.scene, bs.camera, rs, st); };
  {  // warm-up (untimed): worker threads, per-thread scratch, first touches
    RenderStats st;
    render(benchRenderSettings(std::min(width, 128), std::min(height, 128), 1, threads), st);
  }
  Capture cap = captureRender(*bs.scene, s, o.spp, threads, o.maxCaptureGiB, render);
  if (cap.overflowed) {
    std::printf("   skipped: capture over --max-capture-gib %g (lower --res or --spp)\n", o.maxCaptureGiB);
    return res;
  }
  if (cap.stats.rays.closest != 0) throw Error("internal: ao traced secondary closest-hit rays");
  res.rays = double(totalRays(cap.stats.rays));
  std::printf("   capture    %llu camera + %llu AO rays (%llu captured, %llu malformed), %.0f MiB, replayed hits: "
              "%llu differ\n",
              (unsigned long long)cap.stats.rays.camera, (unsigned long long)cap.stats.rays.occlusion,
              (unsigned long long)cap.recorder->rays(), (unsigned long long)cap.recorder->malformed(), cap.mib(),
              (unsigned long long)cap.mismatches);
  bool filmsEqual = true;
  Film last;
  int jobs = 0;
  interleaved(o.runs, int(variants.size()), [&](int r, int k) {
    const int v = variants[size_t(k)];
    if (jobs++ % int(variants.size()) == 0) std::printf("   run %d/%d:", r + 1, o.runs);
    const double sec = timeRun(res.t[size_t(v)], threads, [&] {
      if (v == kRenderer) {
        RenderStats st;
        last = render(s, st);
        filmsEqual = filmsEqual && sameFilm(last, cap.film) && totalRays(st.rays) == totalRays(cap.stats.rays);
        return st.seconds;
      }
      ReplayTally t;
      return cap.replayer->run(v == kReplay ? ReplayMode::Raw : ReplayMode::Surface, t);
    });
    std::printf("  %s %.3f s", kShortNames[v], sec);
    if (jobs % int(variants.size()) == 0) std::printf("\n");
    std::fflush(stdout);
  });
  res.ok = cap.ok() && filmsEqual;

  std::printf("\n   %-12s %8s %8s %8s %8s %5s   %s\n", "", "wall s", "Mrays/s", "CPU s", "Mr/CPUs", "CPU",
              "wall s of each run");
  for (int v : variants) {
    const Timings& t = res.t[size_t(v)];
    std::printf("   %-12s %8.3f %8.2f %8.3f %8.2f %4.0f%%  ", kShortNames[v], t.medWall(),
                mraysPerSecond(res.rays, t.medWall()), t.medCpu(), mraysPerSecond(res.rays, t.medCpu()),
                100.0 * t.minUse());
    for (double x : t.wall) std::printf(" %.3f", x);
    std::printf("\n");
    res.busy = res.busy || t.busy();
  }
  std::printf("   medians over the runs; Mrays/s = (camera + AO rays) / median wall s; CPU s = process CPU s / %d\n"
              "   threads; CPU = the lowest CPU s / wall s of the runs (< 90%%: other processes took cores).\n",
              threads);
  const bool haveBoth = std::find(variants.begin(), variants.end(), kRenderer) != variants.end() &&
                        std::find(variants.begin(), variants.end(), kReplay) != variants.end();
  if (haveBoth) {
    const Timings &tr = res.t[kRenderer], &tp = res.t[kReplay];
    res.compared = true;
    res.ratio = tp.medWall() / tr.medWall();
    res.ratioCpu = tp.medCpu() / tr.medCpu();
    std::vector<double> paired;
    for (size_t i = 0; i < tr.wall.size(); ++i) paired.push_back(tp.wall[i] / tr.wall[i]);
    res.ratioPaired = median(paired);
    std::printf("\n   renderer / replay, median wall clock: %.1f%%   goal >= 85%%: %s\n", 100.0 * res.ratio,
                res.ratio >= 0.85 ? "met" : "NOT met");
    std::printf("   renderer / replay, paired by run: %.1f%%;  per CPU-second: %.1f%%\n", 100.0 * res.ratioPaired,
                100.0 * res.ratioCpu);
  }
  std::printf("   check: %s\n", res.ok ? "replayed hits bit-equal, ray counts and images equal" : "FAILED");
  if (!o.preview.empty() && last.width() > 0) {
    const std::string path = o.preview + bs.label + ".png";
    writePreviewPng(path, last);
    std::printf("   preview    %s\n", path.c_str());
  }
  std::fflush(stdout);
  return res;
}

std::vector<int> parseVariants(const std::string& list) {
  std::vector<int> out;
  for (const std::string& name : splitCommaList(list)) {
    int v = -1;
    for (int i = 0; i < kVariants; ++i)
      if (name == kShortNames[i]) v = i;
    if (v < 0) throw Error("--variants: unknown '" + name + "' (replay, renderer, replay+hit)");
    if (std::find(out.begin(), out.end(), v) == out.end()) out.push_back(v);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obscura_bench_ao: obscura::render (-i ao) vs its captured rays replayed through raw Embree"};
  Options o;
  addCommonOptions(app, o, "Smoke run: 480x270 unless --res is given");
  app.add_option("--distance", o.distance, "AO distance R in scene units, or inf (default inf)");
  app.add_option("--variants", o.variants,
                 "Comma list of replay, renderer (default: both) and the diagnostic replay+hit (the replay plus "
                 "computeSurfaceHit at every hit)");
  app.add_option("--max-capture-gib", o.maxCaptureGiB, "Memory cap of a scene's captured rays, GiB (default 8)");
  app.add_option("--preview", o.preview, "Write the renderer's image of each scene to PREFIX<scene>.png");
  CLI11_PARSE(app, argc, argv);

  try {
    if (o.quick && app.count("--res") == 0) o.res = "480x270";
    const auto [width, height] = checkCommonOptions(o);
    char* end = nullptr;
    const double R = std::strtod(o.distance.c_str(), &end);
    if (o.distance.empty() || *end != '\0' || !(R > 0)) throw Error("--distance: expected a positive number or inf");
    const std::vector<int> variants = parseVariants(o.variants);

    const ThreadLimit limit(o.threads);
    const int threads = limit.threads();
    std::printf("obscura_bench_ao: obscura::render (-i ao) vs its captured rays replayed through raw Embree\n");
    printMachine(threads);
    std::printf("   settings   %dx%d, %d spp, AO distance %s, rays=1, seed 0, box filter, tiles 16x16, AOVs off\n",
                width, height, o.spp, o.distance.c_str());
    std::printf("   timing     median of %d run%s, variants interleaved (order rotated each run)\n", o.runs,
                o.runs == 1 ? "" : "s");
    std::fflush(stdout);

    std::vector<SceneResult> results;
    for (const std::string& sc : o.scenes) results.push_back(benchScene(sc, o, variants, width, height, threads));

    std::printf("\n== Markdown (%dx%d, %d spp, %d threads, AO distance %s, median of %d runs)\n\n", width, height,
                o.spp, threads, o.distance.c_str(), o.runs);
    MarkdownTable t{{"scene", "triangles", "renderer Mrays/s", "replay Mrays/s", "ratio", "paired", "per CPU s"},
                    "lrrrrrr", {}};
    bool failed = false;
    for (const SceneResult& r : results) {
      failed = failed || !r.ok;
      if (!r.compared) continue;
      t.row({r.label + (r.busy ? " (busy)" : ""), std::to_string(r.triangles),
             fmt("%.2f", mraysPerSecond(r.rays, r.t[kRenderer].medWall())),
             fmt("%.2f", mraysPerSecond(r.rays, r.t[kReplay].medWall())), fmt("%.0f %%", 100.0 * r.ratio),
             fmt("%.0f %%", 100.0 * r.ratioPaired), fmt("%.0f %%", 100.0 * r.ratioCpu)});
    }
    t.print();
    std::printf("\npeak RSS %.1f MiB (whole process)\n", peakRssMiB());
    return failed ? 1 : 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_ao: error: %s\n", e.what());
    return 1;
  }
}
