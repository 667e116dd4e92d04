// obscura_bench_obscurance: the obscurance integrator's two estimators
// (docs/math.md §3), measured two ways.
//
// 1. Speed. For each falloff in {linear, sqrt, exponential} and each
//    estimator in {distance, occlusion}, obscura::render() runs in process
//    with the registered `obscurance` integrator (AOVs off, no progress bar)
//    and the same rays are replayed straight through Embree with streams
//    (rtcIntersect1M for camera rays and for the distance estimator's
//    closest-hit rays, rtcOccluded1M for the occlusion estimator's any-hit
//    rays) over the renderer's 16x16 tiles, its 256-sample chunks and the
//    same thread count. Mrays/s = (camera + secondary rays) / median wall s;
//    ratio = renderer / raw.
//
//    The raw side is the capture and replay of bench/replay.h: one render
//    of each configuration is captured through RayRecorder and its very
//    batches (camera rays, the distance estimator's closest-hit rays, the
//    occlusion estimator's any-hit rays) are replayed through raw Embree
//    with the same call, batch sizes and context flags; hits are checked
//    bit-equal and every timed render's image equal to the capture's.
//
// 2. Variance at equal time. Each configuration is also rendered with seeds
//    1..K (default K = 8) at the same spp. For every pixel covered in all K
//    renders (alpha == 1) the sample variance of the pass across the seeds
//    is taken; their mean is Var, the per-pixel variance of one render
//    (it includes the pixel-footprint variance of the camera jitter, which is
//    the same for both estimators). With T the render's median wall time
//    (over the timed runs and the K seed renders alike),
//    Var x T is the variance at equal time (lower wins: halving the time
//    doubles the variance), and the relative efficiency of the occlusion
//    estimator is (Var_d T_d) / (Var_o T_o): > 1 means occlusion wins.
//    (First order: Var x T is constant only if Var ~ 1/spp; the sampler's
//    scrambled Sobol' points can converge faster on smooth pixels. T is the
//    whole render, camera rays and surface reconstruction included - what a
//    user pays - so scenes where few camera rays hit dilute the difference.)
//    The mean pass value over those pixels is printed for both estimators;
//    they estimate the same quantity, so their difference, in units of the
//    combined standard error of the mean over seeds, should be O(1) (also
//    printed paired by seed: both estimators share camera rays and
//    directions for a given seed, so the paired test is the sharper one).
//
// R = 10 % of the scene's bounding-box diagonal for linear and sqrt; the
// exponential uses sigma = 1/R and no cut-off (distance = inf).
//
// Run:   build/bench/obscura_bench_obscurance                both scenes, 960x540, 16 spp, 3 runs, 8 seeds
//        build/bench/obscura_bench_obscurance --quick        smoke run (320x180, 1 run, 4 seeds)
//        build/bench/obscura_bench_obscurance --scene scenes/default.gltf --threads 1
#include <CLI/CLI.hpp>
#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "bench/common.h"
#include "bench/replay.h"
#include "core/scene/camera.h"
#include <obscura/error.h>
#include "core/image/film.h"
#include <obscura/integrator.h>
#include "core/render/render.h"
#include <obscura/sampler.h>
#include "core/scene/scene.h"
#include "core/scene/surface.h"
#include <obscura/warp.h>
#include "integrators/falloff.h"

using namespace obscura;
using namespace obscura::bench;

namespace {

// Falloff, Estimator and the sampling of mu' are the integrator's own
// (integrators/falloff.h); this bench runs linear, sqrt and exponential.
const char* estimatorName(Estimator e) { return e == Estimator::Distance ? "distance" : "occlusion"; }

// One benchmarked configuration of the integrator.
struct Config {
  Falloff falloff;
  Estimator estimator;
  double R;      // linear/sqrt radius; inf for the exponential (no cut-off)
  double sigma;  // exponential only
  int rays;
};

struct Options : CommonOptions {
  Options() { res = "960x540"; }
  int seeds = 8;
  int rays = 1;
  double radiusFraction = 0.1;
  double maxCaptureGiB = 6.0;
};

// The raw side: the renderer's own rays, captured and replayed (bench/replay.h).

constexpr int kTile = 16;  // the renderer's default tile size

struct RawTally {  // what the capture holds
  uint64_t camera = 0;     // camera rays
  uint64_t secondary = 0;  // obscurance rays (active or not)
  uint64_t mismatches = 0; // replayed hits not bit-equal, malformed rays, or a ray count off
};

// ---------------------------------------------------------------------------
// The renderer side.

std::string exact(double x) {
  if (std::isinf(x)) return "inf";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

struct RendererRun {
  BenchIntegrator integ;
  explicit RendererRun(const Config& c)
      : integ("obscurance", {{"falloff", falloffName(c.falloff)},
                             {"estimator", estimatorName(c.estimator)},
                             {"distance", exact(c.R)},
                             {"sigma", exact(c.sigma)},
                             {"rays", std::to_string(c.rays)}}) {}
  Film run(const BenchScene& bs, const RenderSettings& s, RenderStats& st) const {
    return integ.render(*bs.scene, bs.camera, s, st);
  }
};

std::string paramString(const Config& c) {
  char buf[160];
  if (c.falloff == Falloff::Exponential)
    std::snprintf(buf, sizeof buf, "falloff=exponential sigma=%.6g distance=inf estimator=%s rays=%d", c.sigma,
                  estimatorName(c.estimator), c.rays);
  else
    std::snprintf(buf, sizeof buf, "falloff=%s distance=%.6g estimator=%s rays=%d", falloffName(c.falloff), c.R,
                  estimatorName(c.estimator), c.rays);
  return buf;
}

struct Result {
  Config config;
  // speed (timed runs, seed 0, paired with the raw replay)
  double rendSeconds = 0, rawSeconds = 0;  // medians
  double rendMrays = 0, rawMrays = 0, ratio = 0, pairedRatio = 0;
  double rendCpuUse = 0, rawCpuUse = 0;  // median CPU s / (wall s x threads)
  RayCounters rendRays;
  RawTally raw;
  std::vector<double> rendRuns, rawRuns, rendCpu, rawCpu;
  // The same from process CPU time: CPU s / threads is the wall time the run
  // takes when no other process competes for the cores (robust to a busy
  // machine, where the wall clock measures the neighbours).
  std::vector<double> rendCpuT, rawCpuT, seedCpuT;
  double rendMraysCpu = 0, rawMraysCpu = 0, ratioCpu = 0, Tcpu = 0;
  // variance (seeds 1..K)
  double var = 0;            // mean per-pixel variance of one render
  double mean = 0, se = 0;   // mean pass over covered pixels; SE over seeds
  std::vector<double> seedMeans;
  std::vector<double> seedSeconds, seedCpu;
  size_t covered = 0;
  // T: median wall s over every render of the configuration (timed runs and
  // seeds alike: the same work up to a different jitter of the same pixels)
  double T = 0;
  double allCpuUse = 0;  // median CPU use over those renders
};

double raysPerCameraSample(const Result& r) {
  return r.rendRays.camera ? double(r.rendRays.occlusion + r.rendRays.closest) / double(r.rendRays.camera) : 0.0;
}

RenderSettings benchSettings(const Options& o, int w, int h, int threads, uint32_t seed) {
  RenderSettings s = benchRenderSettings(w, h, o.spp, threads, seed);
  s.tileSize = kTile;
  return s;
}

// Times renderer and raw replay of both estimators of one falloff: each run
// does the four (estimator x side) jobs, order rotated from run to run, so a
// change of the machine's load hits all four alike.
void timePair(const BenchScene& bs, const Options& o, int w, int h, int threads, std::array<Result*, 2> pair) {
  const std::array<RendererRun, 2> rr{RendererRun(pair[0]->config), RendererRun(pair[1]->config)};
  const RenderSettings s = benchSettings(o, w, h, threads, 0);
  std::array<Capture, 2> cap;
  for (size_t i = 0; i < 2; ++i) {
    cap[i] = captureRender(*bs.scene, s, o.spp, threads, o.maxCaptureGiB,
                           [&](const RenderSettings& cs, RenderStats& st) { return rr[i].run(bs, cs, st); });
    if (cap[i].overflowed) throw Error("capture over --max-capture-gib (lower --res or --spp)");
    Result& res = *pair[i];
    res.raw.camera = cap[i].stats.rays.camera;
    res.raw.secondary = cap[i].stats.rays.occlusion + cap[i].stats.rays.closest;
    res.raw.mismatches = cap[i].ok() ? 0 : 1 + cap[i].mismatches;
  }
  for (int r = 0; r < o.runs; ++r) {
    for (int j = 0; j < 4; ++j) {
      const int job = (j + r) % 4;  // 0: rend d, 1: raw d, 2: rend o, 3: raw o
      Result& res = *pair[size_t(job / 2)];
      const double c0 = processCpuSeconds();
      if (job % 2 == 0) {
        RenderStats st;
        const Film film = rr[size_t(job / 2)].run(bs, s, st);
        if (!sameFilm(film, cap[size_t(job / 2)].film)) ++res.raw.mismatches;
        res.rendRuns.push_back(st.seconds);
        const double cpuT = (processCpuSeconds() - c0) / threads;
        res.rendCpu.push_back(cpuT / st.seconds);
        res.rendCpuT.push_back(cpuT);
        if (r > 0 && (st.rays.camera != res.rendRays.camera || st.rays.occlusion != res.rendRays.occlusion ||
                      st.rays.closest != res.rendRays.closest))
          std::printf(" [renderer ray count changed between runs!]");
        res.rendRays = st.rays;
      } else {
        ReplayTally t;
        const double sec = cap[size_t(job / 2)].replayer->run(ReplayMode::Raw, t);
        res.rawRuns.push_back(sec);
        const double cpuT = (processCpuSeconds() - c0) / threads;
        res.rawCpu.push_back(cpuT / sec);
        res.rawCpuT.push_back(cpuT);
      }
    }
  }
  for (Result* p : pair) {
    Result& res = *p;
    const double rendRays = double(res.rendRays.camera + res.rendRays.occlusion + res.rendRays.closest);
    const double rawRays = double(res.raw.camera + res.raw.secondary);
    res.rendSeconds = median(res.rendRuns);
    res.rawSeconds = median(res.rawRuns);
    res.rendMrays = rendRays / res.rendSeconds * 1e-6;
    res.rawMrays = rawRays / res.rawSeconds * 1e-6;
    res.ratio = res.rendMrays / res.rawMrays;
    // Paired by run: rays/s of the renderer over rays/s of the raw replay.
    std::vector<double> paired;
    for (size_t i = 0; i < res.rendRuns.size(); ++i)
      paired.push_back((rendRays / res.rendRuns[i]) / (rawRays / res.rawRuns[i]));
    res.pairedRatio = median(paired);
    res.rendCpuUse = median(res.rendCpu);
    res.rawCpuUse = median(res.rawCpu);
    res.rendMraysCpu = rendRays / median(res.rendCpuT) * 1e-6;
    res.rawMraysCpu = rawRays / median(res.rawCpuT) * 1e-6;
    res.ratioCpu = res.rendMraysCpu / res.rawMraysCpu;
  }
}

// Per-pixel variance across seeds 1..K of one configuration, from the pass
// planes of its K renders, over the pixels covered in every render of both
// estimators (`covered`).
void varianceOf(Result& res, const std::vector<std::vector<float>>& pass, const std::vector<unsigned char>& covered) {
  const size_t K = pass.size(), pixels = covered.size();
  double varSum = 0;
  size_t n = 0;
  std::vector<double> seedSum(K, 0.0);
  for (size_t i = 0; i < pixels; ++i) {
    if (!covered[i]) continue;
    double m = 0;
    for (size_t k = 0; k < K; ++k) m += double(pass[k][i]);
    m /= double(K);
    double ss = 0;
    for (size_t k = 0; k < K; ++k) {
      const double x = double(pass[k][i]);
      ss += (x - m) * (x - m);
      seedSum[k] += x;
    }
    varSum += ss / double(K - 1);
    ++n;
  }
  res.covered = n;
  res.var = n ? varSum / double(n) : NAN;
  res.seedMeans.clear();
  for (size_t k = 0; k < K; ++k) res.seedMeans.push_back(n ? seedSum[k] / double(n) : NAN);
  double m = 0;
  for (double x : res.seedMeans) m += x;
  m /= double(K);
  double ss = 0;
  for (double x : res.seedMeans) ss += (x - m) * (x - m);
  res.mean = m;
  res.se = std::sqrt(ss / double(K - 1) / double(K));
}

// Renders seeds 1..K of both estimators of one falloff (alternating which
// goes first) and measures each one's per-pixel variance across the seeds.
void variancePair(const BenchScene& bs, const Options& o, int w, int h, int threads, std::array<Result*, 2> pair) {
  const std::array<RendererRun, 2> rr{RendererRun(pair[0]->config), RendererRun(pair[1]->config)};
  const size_t pixels = size_t(w) * size_t(h);
  const size_t K = size_t(o.seeds);
  std::array<std::vector<std::vector<float>>, 2> pass;
  for (auto& p : pass) p.resize(K);
  std::vector<unsigned char> covered(pixels, 1);
  for (size_t k = 0; k < K; ++k) {
    const RenderSettings s = benchSettings(o, w, h, threads, uint32_t(k + 1));
    for (size_t j = 0; j < 2; ++j) {
      const size_t e = (j + k) % 2;
      RenderStats st;
      const double c0 = processCpuSeconds();
      const Film film = rr[e].run(bs, s, st);
      pair[e]->seedSeconds.push_back(st.seconds);
      const double cpuT = (processCpuSeconds() - c0) / threads;
      pair[e]->seedCpu.push_back(cpuT / st.seconds);
      pair[e]->seedCpuT.push_back(cpuT);
      const float* R = film.plane(kR);
      const float* A = film.plane(kA);
      pass[e][k].assign(R, R + pixels);
      for (size_t i = 0; i < pixels; ++i) covered[i] = covered[i] && A[i] == 1.0f;
    }
  }
  for (size_t e = 0; e < 2; ++e) {
    Result& res = *pair[e];
    varianceOf(res, pass[e], covered);
    std::vector<double> all = res.rendRuns, cpu = res.rendCpu;
    all.insert(all.end(), res.seedSeconds.begin(), res.seedSeconds.end());
    cpu.insert(cpu.end(), res.seedCpu.begin(), res.seedCpu.end());
    res.T = median(all);
    res.allCpuUse = median(cpu);
    std::vector<double> allCpuT = res.rendCpuT;
    allCpuT.insert(allCpuT.end(), res.seedCpuT.begin(), res.seedCpuT.end());
    res.Tcpu = median(allCpuT);
  }
}

struct SceneReport {
  std::string label;
  size_t triangles = 0;
  double R = 0;
  std::vector<Result> results;  // pairs: distance, occlusion per falloff
};

std::string fmtG(double x, int prec = 3) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", prec, x);
  return buf;
}

// Did other processes take cores during any timed or seed render?
bool busy(const SceneReport& rep) {
  constexpr double kIdleUse = 0.9;
  for (const Result& r : rep.results)
    if (r.rendCpuUse < kIdleUse || r.rawCpuUse < kIdleUse || r.allCpuUse < kIdleUse) return true;
  return false;
}

// cpu: times from process CPU s / threads instead of the wall clock.
void printMarkdown(const SceneReport& rep, int w, int h, int spp, int threads, int K, bool cpu) {
  std::printf("\n**%s** (%zu triangles), %dx%d, %d spp, %d threads, R = %s (10%% of the bbox diagonal), "
              "exponential sigma = 1/R without cut-off; Var over %d seeds%s:\n\n",
              rep.label.c_str(), rep.triangles, w, h, spp, threads, fmtG(rep.R, 4).c_str(), K,
              cpu ? "; times = process CPU s / threads" : "");
  std::printf("| falloff | estimator | renderer Mrays/s | raw Mrays/s | ratio | rays / camera sample | Var per pixel | "
              "time s | Var×time | relative efficiency |\n");
  std::printf("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (size_t i = 0; i < rep.results.size(); ++i) {
    const Result& r = rep.results[i];
    std::string eff = "1 (ref.)";
    if (r.config.estimator == Estimator::Occlusion && i > 0) {
      const Result& d = rep.results[i - 1];
      eff = fmtG(cpu ? (d.var * d.Tcpu) / (r.var * r.Tcpu) : (d.var * d.T) / (r.var * r.T));
    }
    const double T = cpu ? r.Tcpu : r.T;
    std::printf("| %s | %s | %.2f | %.2f | %.0f%% | %.3f | %.3e | %.3f | %.3e | %s |\n", falloffName(r.config.falloff),
                estimatorName(r.config.estimator), cpu ? r.rendMraysCpu : r.rendMrays, cpu ? r.rawMraysCpu : r.rawMrays,
                100.0 * (cpu ? r.ratioCpu : r.ratio), raysPerCameraSample(r), r.var, T, r.var * T, eff.c_str());
  }
}

SceneReport benchScene(const std::string& which, const Options& o, int w, int h, int threads) {
  std::printf("\n== scene: %s\n", which.c_str());
  std::fflush(stdout);
  BenchScene bs = loadScene(which, float(w) / float(h));
  const Vec3 cp = bs.camera.position();
  const double R = o.radiusFraction * bs.diagonal;
  std::printf("   source     %s\n", bs.source.c_str());
  std::printf("   triangles  %zu, bbox diagonal %.4g -> R = %.4g, sigma = 1/R = %.4g\n", bs.triangles, bs.diagonal, R,
              1.0 / R);
  std::printf("   camera     '%s' at (%.4g, %.4g, %.4g), yfov %.3g rad\n", bs.camera.name.c_str(), cp.x, cp.y, cp.z,
              bs.camera.yfov);
  std::fflush(stdout);

  SceneReport rep;
  rep.label = bs.label;
  rep.triangles = bs.triangles;
  rep.R = R;
  for (Falloff f : {Falloff::Linear, Falloff::Sqrt, Falloff::Exponential})
    for (Estimator e : {Estimator::Distance, Estimator::Occlusion}) {
      Config c{f, e, f == Falloff::Exponential ? double(INFINITY) : R, 1.0 / R, o.rays};
      Result r;
      r.config = c;
      rep.results.push_back(r);
    }

  // Warm-up (untimed): worker threads, per-thread buffers, first touches.
  {
    RenderSettings ws;
    ws.width = std::min(w, 128);
    ws.height = std::min(h, 128);
    ws.spp = 1;
    ws.threads = threads;
    ws.aovs = false;
    for (const Result& r : rep.results) {
      RenderStats st;
      RendererRun(r.config).run(bs, ws, st);
    }
  }

  // Both estimators of a falloff are timed, then rendered for the variance,
  // interleaved with each other.
  std::printf("\n   %-12s %-9s | %-36s | %s\n", "falloff", "estimator", "timed runs (wall s): renderer/raw",
              "seeds 1..K (wall s)");
  for (size_t i = 0; i + 1 < rep.results.size(); i += 2) {
    const std::array<Result*, 2> pair{&rep.results[i], &rep.results[i + 1]};
    timePair(bs, o, w, h, threads, pair);
    variancePair(bs, o, w, h, threads, pair);
    for (const Result* r : pair) {
      std::string runs, seeds;
      for (size_t k = 0; k < r->rendRuns.size(); ++k) {
        if (k) runs += ' ';
        runs += fmtG(r->rendRuns[k], 3);
        runs += '/';
        runs += fmtG(r->rawRuns[k], 3);
      }
      for (size_t k = 0; k < r->seedSeconds.size(); ++k) {
        if (k) seeds += ' ';
        seeds += fmtG(r->seedSeconds[k], 3);
      }
      std::printf("   %-12s %-9s | %-36s | %s\n", falloffName(r->config.falloff), estimatorName(r->config.estimator),
                  runs.c_str(), seeds.c_str());
    }
    std::fflush(stdout);
  }

  std::printf("\n   speed (Mrays/s = (camera + secondary rays) / median wall s; ratio = renderer / raw replay)\n");
  std::printf("   %-12s %-9s %9s %9s %7s %7s %7s %8s %8s %5s %5s | %7s %7s %7s  %-s\n", "falloff", "estimator",
              "rend s", "raw s", "rend", "raw", "ratio", "paired", "rays/cs", "CPU", "CPUr", "rend/c", "raw/c",
              "ratio/c", "params");
  for (const Result& r : rep.results)
    std::printf("   %-12s %-9s %9.3f %9.3f %7.2f %7.2f %6.1f%% %7.1f%% %8.3f %4.0f%% %4.0f%% | %7.2f %7.2f %6.1f%%  %s\n",
                falloffName(r.config.falloff), estimatorName(r.config.estimator), r.rendSeconds, r.rawSeconds,
                r.rendMrays, r.rawMrays, 100.0 * r.ratio, 100.0 * r.pairedRatio, raysPerCameraSample(r),
                100.0 * r.rendCpuUse, 100.0 * r.rawCpuUse, r.rendMraysCpu, r.rawMraysCpu, 100.0 * r.ratioCpu,
                paramString(r.config).c_str());
  std::printf("   paired = median over runs of the per-run ratio; rays/cs = secondary rays per camera sample;\n"
              "   CPU / CPUr = process CPU s / (wall s x %d threads) of the renderer / raw runs (< 90%%: other\n"
              "   processes took cores); rend/c, raw/c, ratio/c = the same Mrays/s from CPU s / %d threads.\n",
              threads, threads);

  std::printf("\n   ray counts            %12s %12s %12s | %12s %12s | %s\n", "rend camera", "rend occl.",
              "rend closest", "raw camera", "raw second.", "check");
  for (const Result& r : rep.results) {
    const uint64_t rendSec = r.rendRays.occlusion + r.rendRays.closest;
    const long long diff = (long long)rendSec - (long long)r.raw.secondary;
    std::printf("   %-12s %-9s %12llu %12llu %12llu | %12llu %12llu | camera %s, secondary diff %lld (%.4f%%), replay %s\n",
                falloffName(r.config.falloff), estimatorName(r.config.estimator),
                (unsigned long long)r.rendRays.camera, (unsigned long long)r.rendRays.occlusion,
                (unsigned long long)r.rendRays.closest, (unsigned long long)r.raw.camera,
                (unsigned long long)r.raw.secondary, r.rendRays.camera == r.raw.camera ? "identical" : "DIFFER", diff,
                r.raw.secondary ? 100.0 * double(diff) / double(r.raw.secondary) : 0.0,
                r.raw.mismatches ? "DIFFERS (hits, rays or images)" : "bit-equal hits, equal images");
  }

  std::printf("\n   variance at equal time (K = %d seeds; Var over the pixels covered in every render of the falloff;\n"
              "   T = median wall s over all %d renders of the configuration (timed runs and seeds); CPU = their\n"
              "   median CPU use; efficiency = (Var_d T_d) / (Var_o T_o), > 1: occlusion wins; Tcpu, eff. (CPU): the same\n"
              "   from CPU s / threads)\n",
              o.seeds, o.seeds + o.runs);
  std::printf("   %-12s %-9s %9s %12s %9s %5s %12s %11s %10s %10s | %9s %11s\n", "falloff", "estimator", "pixels",
              "Var/pixel", "T s", "CPU", "Var x T", "efficiency", "mean", "SE(mean)", "Tcpu s", "eff. (CPU)");
  for (size_t i = 0; i < rep.results.size(); ++i) {
    const Result& r = rep.results[i];
    std::string eff = "1 (ref.)", effCpu = "1 (ref.)";
    if (r.config.estimator == Estimator::Occlusion && i > 0) {
      const Result& d = rep.results[i - 1];
      eff = fmtG((d.var * d.T) / (r.var * r.T), 4);
      effCpu = fmtG((d.var * d.Tcpu) / (r.var * r.Tcpu), 4);
    }
    std::printf("   %-12s %-9s %9zu %12.4e %9.3f %4.0f%% %12.4e %11s %10.6f %10.2e | %9.3f %11s\n",
                falloffName(r.config.falloff), estimatorName(r.config.estimator), r.covered, r.var, r.T,
                100.0 * r.allCpuUse, r.var * r.T, eff.c_str(), r.mean, r.se, r.Tcpu, effCpu.c_str());
  }
  std::printf("\n   sanity: mean(distance) - mean(occlusion) per falloff (they estimate the same O)\n");
  std::printf("   %-12s %12s %14s %16s %10s\n", "falloff", "difference", "z (indep. SE)", "z (paired seeds)",
              "Var_o/Var_d");
  for (size_t i = 0; i + 1 < rep.results.size(); i += 2) {
    const Result& d = rep.results[i];
    const Result& oc = rep.results[i + 1];
    const double diff = d.mean - oc.mean;
    const double z = diff / std::sqrt(d.se * d.se + oc.se * oc.se);
    const size_t K = d.seedMeans.size();
    double md = 0;
    for (size_t k = 0; k < K; ++k) md += d.seedMeans[k] - oc.seedMeans[k];
    md /= double(K);
    double ss = 0;
    for (size_t k = 0; k < K; ++k) {
      const double x = d.seedMeans[k] - oc.seedMeans[k] - md;
      ss += x * x;
    }
    const double zp = md / std::sqrt(ss / double(K - 1) / double(K));
    std::printf("   %-12s %12.3e %14.2f %16.2f %10.3f\n", falloffName(d.config.falloff), diff, z, zp, oc.var / d.var);
  }
  std::fflush(stdout);
  return rep;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obscura_bench_obscurance: obscurance estimators - rays/s vs raw Embree, variance at equal time"};
  Options o;
  addCommonOptions(app, o, "Smoke run: 320x180, 1 run, 4 seeds unless given");
  app.add_option("--seeds", o.seeds, "Renders (seeds 1..K) per configuration for the variance (default 8)");
  app.add_option("--rays", o.rays, "The integrator's rays per camera sample (default 1)");
  app.add_option("--radius-fraction", o.radiusFraction,
                 "R as a fraction of the scene's bounding-box diagonal (default 0.1)");
  CLI11_PARSE(app, argc, argv);

  try {
    if (o.quick) {
      if (app.count("--res") == 0) o.res = "320x180";
      if (app.count("--runs") == 0) o.runs = 1;
      if (app.count("--seeds") == 0) o.seeds = 4;
    }
    const auto [width, height] = checkCommonOptions(o);
    if (o.seeds < 2) throw Error("--seeds must be at least 2");
    if (o.rays < 1 || o.rays > 65536) throw Error("--rays must be in [1, 65536]");
    if (!(o.radiusFraction > 0) || !std::isfinite(o.radiusFraction))
      throw Error("--radius-fraction must be a positive number");

    const ThreadLimit limit(o.threads);
    const int threads = limit.threads();

    std::printf("obscura_bench_obscurance: obscurance estimators, renderer vs raw Embree streams, variance at equal "
                "time\n");
    printMachine(threads);
    std::printf("   settings   %dx%d, %d spp, rays=%d, seed 0 for timing, seeds 1..%d for variance, box filter, "
                "tiles 16x16\n",
                width, height, o.spp, o.rays, o.seeds);
    std::printf("   timing     median of %d run%s per side, renderer and raw interleaved (order alternated)\n", o.runs,
                o.runs == 1 ? "" : "s");
    std::fflush(stdout);

    std::vector<SceneReport> reports;
    for (const std::string& sc : o.scenes) reports.push_back(benchScene(sc, o, width, height, threads));

    std::printf("\n== Markdown (for the README)\n");
    for (const SceneReport& r : reports) {
      printMarkdown(r, width, height, o.spp, threads, o.seeds, false);
      if (busy(r)) {
        std::printf("\nWARNING: other processes took cores during %s (CPU use < 90%%): the wall-clock figures above\n"
                    "measure the machine's load too. The same table from process CPU time (CPU s / %d threads):\n",
                    r.label.c_str(), threads);
        printMarkdown(r, width, height, o.spp, threads, o.seeds, true);
      }
    }
    std::printf("\nMrays/s = (camera + obscurance rays) / median wall s of the timed renders (seed 0); raw = the captured rays replayed "
                "through rtcIntersect1M/rtcOccluded1M, nothing else; ratio = renderer / raw; Var = mean over covered "
                "pixels of the per-pixel variance across %d seeds; time = median wall s of all renders of the "
                "configuration; relative efficiency = (Var·T)_distance / "
                "(Var·T)_occlusion (> 1: occlusion wins at equal time).\n",
                o.seeds);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_obscurance: error: %s\n", e.what());
    return 1;
  }
}
