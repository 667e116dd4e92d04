// obscura_bench_ao: how close does `obscura render -i ao` get to raw Embree?
//
// On each scene, the rays the ao integrator traces (one closest-hit camera
// ray per pixel sample, plus one occlusion ray per camera hit - ao's default
// rays=1) are traced three ways straight through Embree with no shading -
//   (a) rtcIntersect1 / rtcOccluded1 single rays,
//   (b) rtcIntersect16 / rtcOccluded16 16-wide packets,
//   (c) rtcIntersect1M / rtcOccluded1M streams
// - each over the renderer's 16x16 tiles with tbb::parallel_for in a
// task_arena of the same thread count, camera rays COHERENT, AO rays
// INCOHERENT (ao_raw.h says exactly how the AO rays match the integrator's).
// Then obscura::render() runs in process with the registered `ao` integrator
// and the same resolution, spp, seed, camera and threads (AOVs off, so only
// the pass is timed). Every variant runs --runs times, interleaved with the
// order rotated each run (the machine is shared and noisy).
//
// The table: median wall s, Mrays/s = (camera + AO rays) / median wall s,
// median process CPU s and Mrays per CPU-second, and CPU use = CPU s /
// (wall s x threads), which exposes runs slowed by other processes. The
// verdict is the renderer's Mrays/s as a percentage of the best raw
// variant's (median wall clock; the goal is >= 85 %), followed by three
// cross-checks for a busy machine: the same ratio over "idle" runs only
// (CPU use >= 90 %), paired within each run (median of per-run ratios), and
// per CPU-second. Also printed: triangle count, BVH build time
// (Scene::buildSeconds), the RSS the scene added, the process's peak RSS
// (getrusage; cumulative over the scenes run so far), and ray counts of
// every variant as a check that all of them traced the same rays.
//
// Diagnostic (--variants ...,stream+hit): the stream variant plus the
// renderer's own hit reconstruction (computeSurfaceHit, shading-normal
// frame, spawnOrigin). It traces exactly the renderer's rays, so
// raw -> stream+hit -> renderer splits the renderer's loss into "surface
// reconstruction" and "render loop + integrator plumbing".
//
// Scenes: the viking room of ../shared/scenes (3.8 k triangles, auto camera,
// as `obscura render` picks it) and a generated ~1.13 M triangle terrain
// (generated_scene.h).
//
// Run:   build/bench/obscura_bench_ao                 both scenes, 1920x1080, 16 spp, 3 runs
//        build/bench/obscura_bench_ao --quick         480x270 smoke run
//        build/bench/obscura_bench_ao --scene generated --runs 5 --threads 1
//        build/bench/obscura_bench_ao --variants stream1M,stream+hit,renderer
// About 2-4 minutes at the defaults on 2 idle cores.
#include <CLI/CLI.hpp>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench/ao_raw.h"
#include "bench/common.h"
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
  int chunk = 256;
  std::string preview;
  std::string variants = "single,packet16,stream1M,renderer";
};

// The renderer side: obscura::render with the registered ao integrator.
struct RendererRun {
  const BenchScene& bs;
  BenchIntegrator integ;
  RenderSettings settings;
  Film lastFilm;

  RendererRun(const BenchScene& b, const std::string& distance, const RenderSettings& s)
      : bs(b), integ("ao", {{"distance", distance}, {"rays", "1"}}), settings(s) {}

  double run(RayTally& tally) {
    RenderStats st;
    lastFilm = integ.render(*bs.scene, bs.camera, settings, st);
    if (st.rays.closest != 0) throw Error("internal: ao traced secondary closest-hit rays");
    tally.camera = st.rays.camera;
    tally.ao = st.rays.occlusion;
    // R = (unoccluded AO rays of the pixel) / spp, exactly, with rays=1.
    tally.unoccluded = 0;
    const float* R = lastFilm.plane(kR);
    const size_t pixels = size_t(lastFilm.width()) * size_t(lastFilm.height());
    for (size_t i = 0; i < pixels; ++i) tally.unoccluded += uint64_t(std::llround(double(R[i]) * settings.spp));
    return st.seconds;
  }
};

// 0..2: the raw variants (RawApi order), 3: the renderer, 4: the
// stream1M + computeSurfaceHit diagnostic (never "best raw"; not run unless
// asked for with --variants).
constexpr int kVariants = 5;
constexpr int kRenderer = 3;
constexpr int kSurface = 4;
bool isRawCandidate(int v) { return v < 3; }
RawApi rawApiOf(int v) { return v == kSurface ? RawApi::StreamSurface : RawApi(v); }
const char* variantName(int v) { return v == kRenderer ? "renderer (obscura ao)" : rawApiName(rawApiOf(v)); }
const char* const kShortNames[kVariants] = {"single", "packet16", "stream1M", "renderer", "stream+hit"};

struct SceneResult {
  std::string label;
  size_t triangles = 0;
  double buildSeconds = 0, peakMiB = 0;
  bool compared = false;  // renderer and at least one raw variant ran
  int bestRaw = 0, bestRawCpu = 0;
  double rawMrays = 0, rendererMrays = 0;        // wall clock
  double rawCpuMrays = 0, rendererCpuMrays = 0;  // per CPU-second
  int bestRawIdle = -1;                             // -1: no idle runs to compare
  double rawIdleMrays = 0, rendererIdleMrays = 0;  // runs with all CPUs to ourselves
  bool busy = false;                               // other processes took CPU time
};

SceneResult benchScene(const std::string& which, const Options& o, const std::vector<int>& variants, int width,
                       int height, int threads, float aoDistance) {
  std::printf("\n== scene: %s\n", which == "generated" ? "generated" : which.c_str());
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

  RawSettings rs;
  rs.width = width;
  rs.height = height;
  rs.spp = o.spp;
  rs.threads = threads;
  rs.chunk = o.chunk;
  rs.aoDistance = aoDistance;
  RawAoTracer raw(*bs.scene, bs.camera, rs);

  RenderSettings s = benchRenderSettings(width, height, o.spp, threads);
  s.tileSize = rs.tileSize;
  RendererRun renderer(bs, o.distance, s);

  // Warm-up (untimed): worker threads, per-thread buffers, first touches.
  {
    RawSettings ws = rs;
    ws.width = std::min(width, 128);
    ws.height = std::min(height, 128);
    ws.spp = 1;
    RawAoTracer warm(*bs.scene, bs.camera, ws);
    RayTally t;
    for (int v = 0; v < 3; ++v) warm.run(RawApi(v), t);
    warm.run(RawApi::StreamSurface, t);
    RenderSettings wr = s;
    wr.width = ws.width;
    wr.height = ws.height;
    wr.spp = 1;
    RendererRun wrun(bs, o.distance, wr);
    wrun.run(t);
  }

  // Wall seconds (what the goal is about) and process CPU seconds (robust to
  // other processes taking cores on a shared machine) of every run.
  std::array<std::vector<double>, kVariants> wall, cpu;
  std::array<RayTally, kVariants> tally{};
  const int nv = int(variants.size());
  for (int r = 0; r < o.runs; ++r) {
    std::printf("   run %d/%d:", r + 1, o.runs);
    for (int k = 0; k < nv; ++k) {
      const int v = variants[size_t((k + r) % nv)];  // rotate the order every run
      RayTally t;
      const double c0 = processCpuSeconds();
      const double sec = v == kRenderer ? renderer.run(t) : raw.run(rawApiOf(v), t);
      const double c = processCpuSeconds() - c0;
      if (r > 0 && (t.camera != tally[v].camera || t.ao != tally[v].ao))
        std::printf(" [ray count changed between runs!]");
      tally[v] = t;
      wall[v].push_back(sec);
      cpu[v].push_back(c);
      std::printf("  %s %.3f s", kShortNames[v], sec);
      std::fflush(stdout);
    }
    std::printf("\n");
  }

  // A run is "idle" when the process got (nearly) all its threads' CPU time:
  // CPU s >= kIdleUse x wall s x threads. On a shared machine only those runs
  // measure the code rather than the neighbours.
  constexpr double kIdleUse = 0.9;
  std::array<double, kVariants> med{}, mrays{}, medCpu{}, cpuMrays{}, use{}, idleMrays{};
  std::array<int, kVariants> idleRuns{};
  int best = -1, bestCpu = -1, bestIdle = -1;
  for (int v : variants) {
    med[v] = median(wall[v]);
    medCpu[v] = median(cpu[v]);
    const double rays = double(tally[v].camera + tally[v].ao);
    mrays[v] = rays / med[v] * 1e-6;
    cpuMrays[v] = rays / medCpu[v] * 1e-6;
    std::vector<double> u, idle;
    for (size_t i = 0; i < wall[v].size(); ++i) {
      u.push_back(cpu[v][i] / (wall[v][i] * threads));
      if (u.back() >= kIdleUse) idle.push_back(wall[v][i]);
    }
    use[v] = median(u);
    idleRuns[v] = int(idle.size());
    idleMrays[v] = idle.empty() ? 0.0 : rays / median(idle) * 1e-6;
    if (!isRawCandidate(v)) continue;
    if (best < 0 || mrays[v] > mrays[best]) best = v;
    if (bestCpu < 0 || cpuMrays[v] > cpuMrays[bestCpu]) bestCpu = v;
    if (idleRuns[v] && (bestIdle < 0 || idleMrays[v] > idleMrays[bestIdle])) bestIdle = v;
  }
  const int refWall = best >= 0 ? best : variants[0];

  std::printf("\n   %-31s %8s %8s %7s  %8s %8s %5s  %10s   %s\n", "", "wall s", "Mrays/s", "% best", "CPU s", "Mr/CPUs",
              "CPU", "idle runs", "wall s of each run");
  for (int v : variants) {
    std::printf("   %-31s %8.3f %8.2f %6.1f%%  %8.3f %8.2f %4.0f%%  ", variantName(v), med[v], mrays[v],
                100.0 * mrays[v] / mrays[refWall], medCpu[v], cpuMrays[v], 100.0 * use[v]);
    if (idleRuns[v])
      std::printf("%6.2f (%d)  ", idleMrays[v], idleRuns[v]);
    else
      std::printf("%10s  ", "- (0)");
    for (double x : wall[v]) std::printf(" %.3f", x);
    std::printf("%s\n", v == best ? "  <- best raw" : "");
  }
  std::printf("   wall s, CPU s: medians over the runs; Mrays/s = (camera + AO rays) / median wall s;\n"
              "   Mr/CPUs = Mrays per CPU-second of the process; CPU = CPU s / (wall s x %d threads), median;\n"
              "   idle runs = Mrays/s from the median wall s of the runs with CPU >= %.0f%% (their count):\n"
              "   other processes took cores during the rest, which then measure the machine, not the code.\n",
              threads, 100.0 * kIdleUse);
  std::printf("\n   %-31s %12s %12s %11s\n", "rays traced", "camera", "AO", "unoccluded");
  for (int v : variants)
    std::printf("   %-31s %12llu %12llu %10.2f%%\n", variantName(v), (unsigned long long)tally[v].camera,
                (unsigned long long)tally[v].ao,
                tally[v].ao ? 100.0 * double(tally[v].unoccluded) / double(tally[v].ao) : 0.0);

  SceneResult res;
  res.label = bs.label;
  res.triangles = bs.triangles;
  res.buildSeconds = bs.buildSeconds;
  const bool haveRenderer = std::find(variants.begin(), variants.end(), kRenderer) != variants.end();
  if (haveRenderer && best >= 0) {
    const RayTally& rt = tally[kRenderer];
    const RayTally& bt = tally[best];
    const long long dAo = (long long)rt.ao - (long long)bt.ao;
    std::printf("   check: camera rays %s; AO rays renderer - raw = %lld (%.4f%%)\n",
                rt.camera == bt.camera ? "identical" : "DIFFER", dAo,
                bt.ao ? 100.0 * double(dAo) / double(bt.ao) : 0.0);
    const double ratio = mrays[kRenderer] / mrays[best];
    const double ratioCpu = cpuMrays[kRenderer] / cpuMrays[bestCpu];
    std::printf("\n   renderer / best raw, median wall clock (%s): %.1f%%   goal >= 85%%: %s\n", kShortNames[best],
                100.0 * ratio, ratio >= 0.85 ? "met" : "NOT met");
    if (bestIdle >= 0 && idleRuns[kRenderer])
      std::printf("   renderer / best raw, idle runs only (%s): %.1f%%\n", kShortNames[bestIdle],
                  100.0 * idleMrays[kRenderer] / idleMrays[bestIdle]);
    else
      std::printf("   renderer / best raw, idle runs only: n/a (no idle run of the renderer or of any raw variant)\n");
    // Paired: the ratio within each run (the two ran minutes apart at most,
    // so slow changes of the machine's load cancel), median over the runs.
    std::vector<double> paired;
    for (size_t i = 0; i < wall[kRenderer].size(); ++i)
      paired.push_back((double(rt.camera + rt.ao) / wall[kRenderer][i]) / (double(bt.camera + bt.ao) / wall[best][i]));
    std::printf("   renderer / best raw, paired by run (%s): %.1f%%  (runs:", kShortNames[best], 100.0 * median(paired));
    for (double x : paired) std::printf(" %.1f%%", 100.0 * x);
    std::printf(")\n");
    std::printf("   renderer / best raw, per CPU-second (%s): %.1f%%\n", kShortNames[bestCpu], 100.0 * ratioCpu);
    bool busy = false;
    for (int v : variants) busy = busy || use[v] < kIdleUse;
    if (busy)
      std::printf("   WARNING: other processes used the CPUs during this scene (CPU column < %.0f%%): the wall-clock\n"
                  "   ratio compares runs slowed by different amounts; rerun on an idle machine to judge the goal.\n",
                  100.0 * kIdleUse);
    res.compared = true;
    res.bestRaw = best;
    res.bestRawCpu = bestCpu;
    res.rawMrays = mrays[best];
    res.rendererMrays = mrays[kRenderer];
    res.rawCpuMrays = cpuMrays[bestCpu];
    res.rendererCpuMrays = cpuMrays[kRenderer];
    res.busy = busy;
    if (bestIdle >= 0 && idleRuns[kRenderer]) {
      res.bestRawIdle = bestIdle;
      res.rawIdleMrays = idleMrays[bestIdle];
      res.rendererIdleMrays = idleMrays[kRenderer];
    }
  }
  res.peakMiB = peakRssMiB();
  std::printf("   peak RSS of the process so far: %.1f MiB\n", res.peakMiB);
  std::fflush(stdout);

  if (!o.preview.empty() && haveRenderer) {
    const std::string path = o.preview + bs.label + ".png";
    writePreviewPng(path, renderer.lastFilm);
    std::printf("   preview    %s\n", path.c_str());
  }
  return res;
}

std::vector<int> parseVariants(const std::string& list) {
  std::vector<int> out;
  for (const std::string& name : splitCommaList(list)) {
    int v = -1;
    for (int i = 0; i < kVariants; ++i)
      if (name == kShortNames[i]) v = i;
    if (v < 0) throw Error("--variants: unknown '" + name + "' (single, packet16, stream1M, renderer, stream+hit)");
    if (std::find(out.begin(), out.end(), v) == out.end()) out.push_back(v);
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obscura_bench_ao: the ao integrator's rays through raw Embree vs obscura::render"};
  Options o;
  addCommonOptions(app, o, "Smoke run: 480x270 unless --res is given");
  app.add_option("--distance", o.distance, "AO distance R in scene units, or inf (default inf)");
  app.add_option("--chunk", o.chunk, "Camera samples per raw packet/stream batch, multiple of 16 (default 256, "
                                     "the renderer's chunk)");
  app.add_option("--variants", o.variants,
                 "Comma list of single, packet16, stream1M, renderer (default: these four) and the diagnostic "
                 "stream+hit (stream1M plus the renderer's computeSurfaceHit and shading-normal AO ray)");
  app.add_option("--preview", o.preview, "Write the renderer's image of each scene to PREFIX<scene>.png");
  CLI11_PARSE(app, argc, argv);

  try {
    if (o.quick && app.count("--res") == 0) o.res = "480x270";
    const auto [width, height] = checkCommonOptions(o);
    if (o.chunk < 16 || o.chunk % 16) throw Error("--chunk must be a positive multiple of 16");
    char* end = nullptr;
    const double R = std::strtod(o.distance.c_str(), &end);
    if (o.distance.empty() || *end != '\0' || !(R > 0)) throw Error("--distance: expected a positive number or inf");
    const float aoDistance = R > double(std::numeric_limits<float>::max()) ? INFINITY : float(R);
    const std::vector<int> variants = parseVariants(o.variants);

    const ThreadLimit limit(o.threads);
    const int threads = limit.threads();

    std::printf("obscura_bench_ao: ao rays through raw Embree vs obscura::render (-i ao)\n");
    printMachine(threads);
    std::printf("   settings   %dx%d, %d spp, AO distance %s, rays=1, seed 0, box filter, tiles 16x16\n", width,
                height, o.spp, o.distance.c_str());
    std::printf("   timing     median of %d run%s, variants interleaved (order rotated each run), raw chunk %d\n",
                o.runs, o.runs == 1 ? "" : "s", o.chunk);
    std::fflush(stdout);

    std::vector<SceneResult> results;
    for (const std::string& sc : o.scenes) results.push_back(benchScene(sc, o, variants, width, height, threads, aoDistance));

    std::printf("\n== summary: %dx%d, %d spp, %d threads, AO distance %s\n", width, height, o.spp, threads,
                o.distance.c_str());
    std::printf("   %-12s %10s %7s   %-26s %-26s %-26s\n", "", "", "", "median wall (the goal)", "idle runs only",
                "per CPU-second");
    std::printf("   %-12s %10s %7s   %-8s %5s %5s %5s  %-8s %5s %5s %5s  %-8s %5s %5s %5s\n", "scene", "triangles",
                "BVH s", "raw", "Mr/s", "rend", "ratio", "raw", "Mr/s", "rend", "ratio", "raw", "Mr/s", "rend",
                "ratio");
    for (const SceneResult& r : results) {
      if (!r.compared) {
        std::printf("   %-12s %10zu %7.3f   (renderer or raw variants not run)\n", r.label.c_str(), r.triangles,
                    r.buildSeconds);
        continue;
      }
      const auto pct = [](double a, double b) { return 100.0 * a / b; };
      std::printf("   %-12s %10zu %7.3f   %-8s %5.2f %5.2f %4.0f%%  ", r.label.c_str(), r.triangles, r.buildSeconds,
                  kShortNames[r.bestRaw], r.rawMrays, r.rendererMrays, pct(r.rendererMrays, r.rawMrays));
      if (r.bestRawIdle >= 0)
        std::printf("%-8s %5.2f %5.2f %4.0f%%  ", kShortNames[r.bestRawIdle], r.rawIdleMrays, r.rendererIdleMrays,
                    pct(r.rendererIdleMrays, r.rawIdleMrays));
      else
        std::printf("%-26s  ", "n/a");
      std::printf("%-8s %5.2f %5.2f %4.0f%%   goal: %s%s\n", kShortNames[r.bestRawCpu], r.rawCpuMrays,
                  r.rendererCpuMrays, pct(r.rendererCpuMrays, r.rawCpuMrays),
                  r.rendererMrays >= 0.85 * r.rawMrays ? "met" : "NOT met", r.busy ? " (machine busy)" : "");
    }
    std::printf("   (goal: renderer >= 85%% of the best raw variant's Mrays/s, median wall clock)\n");
    std::printf("   peak RSS %.1f MiB (whole process)\n", peakRssMiB());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_ao: error: %s\n", e.what());
    return 1;
  }
}
