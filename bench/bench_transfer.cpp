// obscura_bench_transfer: rays per second of the `transfer` and `gi`
// integrators against raw Embree tracing the very same rays.
//
// Both integrators are configurations of the wavefront path estimator
// (integrators/ambient_paths.h): per chunk of <= 256 camera hits it traces
// one rtcIntersect1M batch per bounce, rebuilds every hit that goes on
// (computeSurfaceHit), reads occluder albedo, samples the next direction and
// keeps the paths' throughputs. Which rays a bounce traces depends on the
// previous bounces' hits, so instead of rebuilding the rays outside the
// renderer (as bench_ao and bench_obscurance do) this bench captures them:
//
// 1. Capture (untimed). One render with RenderSettings::recorder set to a
//    recorder (core/scene/tracer.h, RayRecorder) that, for every batch the render
//    traces - camera and secondary alike, in each thread's order - stores the
//    rays (origin, tnear, direction, tfar: 32 bytes), traces the batch with
//    the same Embree call and context, and stores what came back (geomID,
//    primID, instID, t: 16 bytes). Storage is per thread, in 64 Ki-ray
//    blocks, capped by --max-capture-gib (a config over the cap is skipped
//    and says so). The ray count must equal the render's RenderStats.rays.
// 2. Check (untimed). The capture is replayed once through rtcIntersect1M
//    and every hit must be bit-equal to the captured one (geomID, primID,
//    instID, and the bits of t); the film of the capture render must equal
//    the timed renders' films (the recorder changes nothing).
// 3. Timed runs, interleaved with the order rotated each run:
//    - renderer: obscura::render() with the integrator (no recorder, AOVs
//      off, box filter, 16x16 tiles, seed 0). Mrays/s = RenderStats.rays
//      (camera + closest + occlusion) / wall s of the render loop.
//    - raw: the captured batches replayed through rtcIntersect1M (or
//      rtcOccluded1M) with the same batch sizes, the same context flags
//      (camera batches COHERENT, the rest INCOHERENT) and the same thread
//      count, in a task_arena with tbb::parallel_for over groups of `spp`
//      consecutive chunks of one thread's capture (a chunk: a camera batch
//      and the secondary batches after it; `spp` chunks are one 16x16 tile's
//      worth, the renderer's unit of parallel work). Each batch is expanded
//      from the capture into an RTCRayHit array and traced: nothing else.
//      Reading the capture streams 32 bytes a ray from memory, which the
//      renderer does not pay, so raw is if anything slightly pessimistic.
//    - raw+hit (diagnostic): raw plus computeSurfaceHit (with albedo) for
//      every hit of every intersect batch. The renderer rebuilds camera hits
//      and hits that continue a path, and reads only the albedo of a path's
//      last occluder, so this overstates reconstruction a little.
//    - raw+hit+dir (diagnostic): raw+hit plus, at every hit, the next
//      direction drawn as the path estimator draws it (Sobol' pair, shading
//      frame, cosine warp, spawnOrigin, the below-the-surface test).
//    The ratio renderer / raw is what the renderer keeps of Embree's speed;
//    the gap (renderer s - raw s) splits into hit reconstruction and albedo
//    (raw+hit - raw), direction sampling (raw+hit+dir - raw+hit) and the
//    rest (camera ray generation, path state and bookkeeping, accumulation,
//    film): shares of the gap, from medians, so they are approximate.
//    Times are medians over --runs. Process CPU s / threads is measured too:
//    when other processes took cores in some run (CPU s < 90 % of wall s x
//    threads), the table is printed again from CPU time, which such
//    contention barely moves.
//
// Configurations (R = 10 % of the scene's bounding-box diagonal):
//   transfer           depth=0 (the closed form), falloff=exponential sigma=1/R distance=inf
//   transfer-step      depth=0, falloff=step distance=inf
//   transfer-d2        depth=2, falloff=exponential sigma=1/R distance=inf
//   gi                 defaults: vacuum, unlimited depth, Russian roulette
//   gi-sigma           sigma=1/R (the ambient medium)
//
// --hook-check adds one more variant: the renderer with a pass-through
// recorder (it only traces), which costs the hook's null check plus a
// virtual call per batch, so it bounds what the null check alone costs.
//
// Run:   build/bench/obscura_bench_transfer                  both scenes, 960x540, 8 spp, 3 runs
//        build/bench/obscura_bench_transfer --quick          smoke run (320x180, 2 spp, 1 run)
//        build/bench/obscura_bench_transfer --scene generated --configs gi,gi-sigma --runs 5
#include <CLI/CLI.hpp>
#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "bench/common.h"
#include "bench/replay.h"
#include <obscura/error.h>
#include <obscura/integrator.h>
#include "core/render/render.h"
#include <obscura/sampler.h>
#include "core/scene/surface.h"
#include <obscura/warp.h>

using namespace obscura;
using namespace obscura::bench;

namespace {

// ---------------------------------------------------------------------------
// Configurations.

struct Config {
  std::string name;        // short name (--configs)
  std::string integrator;  // registry name
  std::vector<std::pair<std::string, std::string>> params;
};

const char* const kConfigNames[] = {"transfer", "transfer-step", "transfer-d2", "gi", "gi-sigma"};

std::string number(double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", x);
  return buf;
}

Config makeConfig(const std::string& name, double R) {
  const std::string sigma = number(1.0 / R);
  if (name == "transfer")
    return {name, "transfer", {{"falloff", "exponential"}, {"sigma", sigma}, {"distance", "inf"}, {"depth", "0"}}};
  if (name == "transfer-step") return {name, "transfer", {{"falloff", "step"}, {"distance", "inf"}, {"depth", "0"}}};
  if (name == "transfer-d2")
    return {name, "transfer", {{"falloff", "exponential"}, {"sigma", sigma}, {"distance", "inf"}, {"depth", "2"}}};
  if (name == "gi") return {name, "gi", {}};
  if (name == "gi-sigma") return {name, "gi", {{"sigma", sigma}}};
  throw Error("--configs: unknown '" + name + "' (transfer, transfer-step, transfer-d2, gi, gi-sigma)");
}

std::string paramString(const Config& c) {
  std::string s = c.integrator;
  for (const auto& [k, v] : c.params) s += " " + k + "=" + v;
  return s;
}

// ---------------------------------------------------------------------------
// The renderer side.

struct RendererRun {
  BenchIntegrator integ;
  explicit RendererRun(const Config& c) : integ(c.integrator, c.params) {}
  Film run(const BenchScene& bs, const RenderSettings& s, RenderStats& st) const {
    return integ.render(*bs.scene, bs.camera, s, st);
  }
};

// ---------------------------------------------------------------------------
// One scene.

struct Options : CommonOptions {
  Options() {
    res = "960x540";
    spp = 8;
  }
  std::string configs = "transfer,transfer-step,transfer-d2,gi,gi-sigma";
  double radiusFraction = 0.1;
  double maxCaptureGiB = 6.0;
  bool hookCheck = false;
};

// Variants of the timed runs.
enum Variant { kRenderer, kRaw, kRawHit, kRawHitSample, kHooked, kVariants };
const char* const kVariantNames[kVariants] = {"renderer", "raw", "raw+hit", "raw+hit+dir", "renderer+hook"};

struct Result {
  std::string scene;
  Config config;
  bool skipped = false;
  std::string why;  // when skipped
  RayCounters rays;
  uint64_t captured = 0, malformed = 0, mismatches = 0;
  bool filmsEqual = true;
  double captureMiB = 0, captureSeconds = 0;
  std::array<Timings, kVariants> t;
  std::array<double, kVariants> medWall{}, medCpu{}, mrays{}, mraysCpu{};
  double minUse = 1;  // lowest CPU s / (wall s x threads) over all timed runs
  bool busy() const { return minUse < 0.9; }  // other processes took cores in some run
};

Result benchConfig(const BenchScene& bs, const Config& c, const Options& o, int w, int h, int threads) {
  Result res;
  res.scene = bs.label;
  res.config = c;
  const RendererRun rr(c);
  const RenderSettings s = benchRenderSettings(w, h, o.spp, threads);

  // Warm-up (untimed): worker threads, per-thread scratch, textures.
  {
    RenderSettings ws = benchRenderSettings(std::min(w, 128), std::min(h, 128), 1, threads);
    RenderStats st;
    rr.run(bs, ws, st);
  }

  // 1-2. Capture and check (bench/replay.h).
  Capture cap = captureRender(*bs.scene, s, o.spp, threads, o.maxCaptureGiB,
                              [&](const RenderSettings& cs, RenderStats& st) { return rr.run(bs, cs, st); });
  res.captureSeconds = cap.stats.seconds;
  res.captureMiB = cap.mib();
  if (cap.overflowed) {
    res.skipped = true;
    res.why = "capture over --max-capture-gib " + number(o.maxCaptureGiB) + " (lower --res or --spp)";
    std::printf("   %-14s skipped: %s\n", c.name.c_str(), res.why.c_str());
    return res;
  }
  res.rays = cap.stats.rays;
  res.captured = cap.recorder->rays();
  res.malformed = cap.recorder->malformed();
  res.mismatches = cap.mismatches;
  Replayer& replay = *cap.replayer;

  // 3. Timed runs.
  std::vector<int> variants = {kRenderer, kRaw, kRawHit, kRawHitSample};
  if (o.hookCheck) variants.push_back(kHooked);
  PassThroughRecorder pass;
  interleaved(o.runs, int(variants.size()), [&](int, int k) {
    const int v = variants[size_t(k)];
    timeRun(res.t[size_t(v)], threads, [&] {
      if (v == kRenderer || v == kHooked) {
        RenderSettings rs = s;
        if (v == kHooked) rs.recorder = &pass;
        RenderStats st;
        const Film film = rr.run(bs, rs, st);
        if (totalRays(st.rays) != totalRays(res.rays)) std::printf(" [renderer ray count changed between runs!]");
        if (!sameFilm(film, cap.film)) res.filmsEqual = false;
        return st.seconds;
      }
      ReplayTally t;
      return replay.run(v == kRaw      ? ReplayMode::Raw
                        : v == kRawHit ? ReplayMode::Surface
                                       : ReplayMode::SurfaceSample,
                        t);
    });
  });
  const double rays = double(totalRays(res.rays));
  for (int v : variants) {
    const Timings& t = res.t[size_t(v)];
    res.medWall[size_t(v)] = t.medWall();
    res.medCpu[size_t(v)] = t.medCpu();
    res.mrays[size_t(v)] = mraysPerSecond(rays, res.medWall[size_t(v)]);
    res.mraysCpu[size_t(v)] = mraysPerSecond(rays, res.medCpu[size_t(v)]);
    res.minUse = std::min(res.minUse, t.minUse());
  }

  std::printf("   %-14s %11llu rays (%5.2f / camera ray), capture %7.1f MiB, %5zu tasks, hits %s, films %s;", c.name.c_str(),
              (unsigned long long)totalRays(res.rays),
              rays / double(std::max<uint64_t>(res.rays.camera, 1)), res.captureMiB, replay.tasks(),
              res.mismatches == 0 ? "bit-equal" : "DIFFER", res.filmsEqual ? "equal" : "DIFFER");
  for (int v : variants) {
    std::printf(" %s", kVariantNames[v]);
    for (double x : res.t[size_t(v)].wall) std::printf(" %.3f", x);
    std::printf(";");
  }
  std::printf("\n");
  std::fflush(stdout);
  return res;
}

std::vector<Result> benchScene(const std::string& which, const Options& o, const std::vector<std::string>& configs,
                               int w, int h, int threads) {
  std::printf("\n== scene: %s\n", which.c_str());
  std::fflush(stdout);
  const BenchScene bs = loadScene(which, float(w) / float(h));
  const double R = o.radiusFraction * bs.diagonal;
  const Vec3 cp = bs.camera.position();
  std::printf("   source     %s\n", bs.source.c_str());
  std::printf("   triangles  %zu, bbox diagonal %.4g -> R = %.4g, sigma = 1/R = %.4g\n", bs.triangles, bs.diagonal, R,
              1.0 / R);
  std::printf("   camera     '%s' at (%.4g, %.4g, %.4g), yfov %.3g rad\n", bs.camera.name.c_str(), cp.x, cp.y, cp.z,
              bs.camera.yfov);
  std::printf("   wall s of each run, in run order:\n");
  std::fflush(stdout);
  std::vector<Result> out;
  for (const std::string& name : configs) out.push_back(benchConfig(bs, makeConfig(name, R), o, w, h, threads));
  std::printf("   peak RSS of the process so far: %.0f MiB\n", peakRssMiB());
  return out;
}

// The renderer's loss against raw, split by the diagnostics: shares of
// (renderer s - raw s) taken by hit reconstruction (raw+hit - raw), by
// drawing the next direction (raw+hit+dir - raw+hit) and by the rest.
struct Gap {
  double hit = 0, dir = 0, rest = 0;
};
Gap gapOf(const Result& r, bool cpu) {
  const auto& T = cpu ? r.medCpu : r.medWall;
  Gap g;
  const double gap = T[kRenderer] - T[kRaw];
  if (!(gap > 0)) return g;
  g.hit = (T[kRawHit] - T[kRaw]) / gap;
  g.dir = (T[kRawHitSample] - T[kRawHit]) / gap;
  g.rest = 1.0 - g.hit - g.dir;
  return g;
}

void printTable(const std::vector<Result>& results, bool hookCheck, int threads) {
  std::printf("\n== results: Mrays/s = (camera + secondary rays) / median wall s; ratio = renderer / raw\n");
  std::printf("   %-12s %-14s %10s %5s | %8s %8s %6s | %7s %7s %7s %7s | %5s %5s %5s",
              "scene", "config", "rays", "r/cam", "renderer", "raw", "ratio", "rend s", "raw s", "+hit s", "+dir s",
              "hit", "dir", "rest");
  if (hookCheck) std::printf(" | %8s %6s", "hooked", "hook");
  std::printf(" | %7s %5s\n", "ratio/c", "CPU");
  for (const Result& r : results) {
    if (r.skipped) {
      std::printf("   %-12s %-14s skipped: %s\n", r.scene.c_str(), r.config.name.c_str(), r.why.c_str());
      continue;
    }
    const Gap g = gapOf(r, false);
    std::printf("   %-12s %-14s %10llu %5.2f | %8.2f %8.2f %5.1f%% | %7.3f %7.3f %7.3f %7.3f | %4.0f%% %4.0f%% %4.0f%%",
                r.scene.c_str(), r.config.name.c_str(), (unsigned long long)totalRays(r.rays),
                double(totalRays(r.rays)) / double(std::max<uint64_t>(r.rays.camera, 1)), r.mrays[kRenderer],
                r.mrays[kRaw], 100.0 * r.mrays[kRenderer] / r.mrays[kRaw], r.medWall[kRenderer], r.medWall[kRaw],
                r.medWall[kRawHit], r.medWall[kRawHitSample], 100.0 * g.hit, 100.0 * g.dir, 100.0 * g.rest);
    if (hookCheck)
      std::printf(" | %8.2f %+5.1f%%", r.mrays[kHooked], 100.0 * (r.medWall[kHooked] / r.medWall[kRenderer] - 1.0));
    std::printf(" | %6.1f%% %4.0f%%%s\n", 100.0 * r.mraysCpu[kRenderer] / r.mraysCpu[kRaw], 100.0 * r.minUse,
                r.busy() ? " busy" : "");
  }
  std::printf("   r/cam = rays per camera ray; +hit s = raw replay + computeSurfaceHit (albedo) at every hit; +dir s =\n"
              "   that + the next cosine direction and origin at every hit; hit / dir / rest = shares of the gap\n"
              "   (rend s - raw s): hit reconstruction and albedo (+hit - raw), direction sampling (+dir - +hit), the\n"
              "   rest (camera rays, path bookkeeping, accumulation, film); ratio/c = the ratio from process CPU s /\n"
              "   %d threads; CPU = the lowest CPU s / (wall s x threads) of the configuration's timed runs (< 90%%,\n"
              "   busy: other processes took cores, and the wall-clock columns measure them too).%s\n",
              threads,
              hookCheck ? "\n   hooked = the renderer with a pass-through recorder (null check + virtual call per batch);\n"
                          "   hook = its median wall s relative to the plain renderer's."
                        : "");
}

// cpu: times from process CPU s / threads instead of the wall clock.
void printMarkdown(const std::vector<Result>& results, int w, int h, int spp, int threads, int runs, bool cpu) {
  std::printf("\n== Markdown (%dx%d, %d spp, %d threads, median of %d runs%s)\n\n", w, h, spp, threads, runs,
              cpu ? "; times = process CPU s / threads" : "");
  std::printf("| scene | config | rays | renderer Mrays/s | raw Mrays/s | ratio | time s | gap: hit / dir / rest |\n");
  std::printf("|---|---|---:|---:|---:|---:|---:|---:|\n");
  for (const Result& r : results) {
    if (r.skipped) continue;
    const auto& T = cpu ? r.medCpu : r.medWall;
    const auto& M = cpu ? r.mraysCpu : r.mrays;
    const Gap g = gapOf(r, cpu);
    std::printf("| %s | `%s` | %.2f M | %.2f | %.2f | %.0f %% | %.3f | %.0f / %.0f / %.0f %% |\n", r.scene.c_str(),
                paramString(r.config).c_str(), double(totalRays(r.rays)) * 1e-6, M[kRenderer], M[kRaw],
                100.0 * M[kRenderer] / M[kRaw], T[kRenderer], 100.0 * g.hit, 100.0 * g.dir, 100.0 * g.rest);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obscura_bench_transfer: transfer and gi rays/s vs the same rays replayed through raw Embree"};
  Options o;
  addCommonOptions(app, o, "Smoke run: 320x180, 2 spp, 1 run unless given");
  app.add_option("--configs", o.configs,
                 "Comma list of transfer, transfer-step, transfer-d2, gi, gi-sigma (default: all)");
  app.add_option("--radius-fraction", o.radiusFraction,
                 "R as a fraction of the scene's bounding-box diagonal; sigma = 1/R (default 0.1)");
  app.add_option("--max-capture-gib", o.maxCaptureGiB,
                 "Memory cap of one configuration's captured rays and hits, GiB (default 6)");
  app.add_flag("--hook-check", o.hookCheck,
               "Also time the renderer with a pass-through recorder (the capture hook's cost)");
  CLI11_PARSE(app, argc, argv);

  try {
    if (o.quick) {
      if (app.count("--res") == 0) o.res = "320x180";
      if (app.count("--spp") == 0) o.spp = 2;
      if (app.count("--runs") == 0) o.runs = 1;
    }
    const auto [width, height] = checkCommonOptions(o);
    if (!(o.radiusFraction > 0) || !std::isfinite(o.radiusFraction))
      throw Error("--radius-fraction must be a positive number");
    if (!(o.maxCaptureGiB > 0)) throw Error("--max-capture-gib must be positive");
    const std::vector<std::string> configs = splitCommaList(o.configs);
    for (const std::string& c : configs) makeConfig(c, 1.0);  // validates the names

    const ThreadLimit limit(o.threads);
    const int threads = limit.threads();
    std::printf("obscura_bench_transfer: transfer and gi, renderer vs its captured rays replayed through raw Embree\n");
    printMachine(threads);
    std::printf("   settings   %dx%d, %d spp, seed 0, box filter, tiles 16x16, AOVs off, R = %g x bbox diagonal\n",
                width, height, o.spp, o.radiusFraction);
    std::printf("   timing     median of %d run%s, variants interleaved (order rotated each run)\n", o.runs,
                o.runs == 1 ? "" : "s");
    std::fflush(stdout);

    std::vector<Result> results;
    for (const std::string& sc : o.scenes)
      for (Result& r : benchScene(sc, o, configs, width, height, threads)) results.push_back(std::move(r));

    printTable(results, o.hookCheck, threads);
    printMarkdown(results, width, height, o.spp, threads, o.runs, false);
    if (std::any_of(results.begin(), results.end(), [](const Result& r) { return !r.skipped && r.busy(); })) {
      std::printf("\nWARNING: other processes took cores during some timed runs (rows marked busy): their wall-clock\n"
                  "figures measure the machine's load too. The same table from process CPU time (CPU s / %d threads):\n",
                  threads);
      printMarkdown(results, width, height, o.spp, threads, o.runs, true);
    }
    int checked = 0, skipped = 0, failed = 0;
    for (const Result& r : results) {
      if (r.skipped) {
        ++skipped;
        continue;
      }
      ++checked;
      if (r.mismatches || r.malformed || !r.filmsEqual || r.captured != totalRays(r.rays)) {
        ++failed;
        std::printf("\nCHECK FAILED: %s %s: captured %llu of %llu rays, %llu malformed, %llu replay hits differ, "
                    "films %s\n",
                    r.scene.c_str(), r.config.name.c_str(), (unsigned long long)r.captured,
                    (unsigned long long)totalRays(r.rays), (unsigned long long)r.malformed,
                    (unsigned long long)r.mismatches, r.filmsEqual ? "equal" : "differ");
      }
    }
    if (checked && !failed)
      std::printf("\nchecks (%d configurations): every captured ray count equals RenderStats.rays, every replayed hit "
                  "is bit-equal to the captured one, and the capture render's image equals the timed renders'.\n",
                  checked);
    if (skipped) std::printf("%d configurations skipped (capture over --max-capture-gib)\n", skipped);
    std::printf("peak RSS %.0f MiB\n", peakRssMiB());
    return failed || skipped ? 1 : 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_transfer: error: %s\n", e.what());
    return 1;
  }
}
