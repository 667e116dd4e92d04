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
// order rotated each run (the machine is shared and noisy); the table shows
// medians, Mrays/s = (camera + AO rays) / seconds, and the renderer's
// throughput as a percentage of the best raw variant. The goal is >= 85 %.
// Also printed: triangle count, BVH build time (Scene::buildSeconds), the
// process's peak RSS (getrusage; cumulative over the scenes run so far) and
// the RSS the scene itself added, and ray counts of every variant as a check
// that all of them traced the same rays.
//
// Scenes: the viking room of ../shared/scenes (3.8 k triangles, auto camera,
// as `obscura render` picks it) and a generated ~1.13 M triangle terrain
// (generated_scene.h).
//
// Run:   build/bench/obscura_bench_ao                 both scenes, 1920x1080, 16 spp, 3 runs
//        build/bench/obscura_bench_ao --quick         480x270 smoke run
//        build/bench/obscura_bench_ao --scene generated --runs 5 --threads 1
// About 2-3 minutes at the defaults on 2 cores.
#include <CLI/CLI.hpp>
#include <sys/resource.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "bench/ao_raw.h"
#include "bench/generated_scene.h"
#include "core/error.h"
#include "core/gltf_loader.h"
#include "core/image_io.h"
#include "core/integrator.h"
#include "core/render.h"

using namespace obscura;
using namespace obscura::bench;

namespace {

const std::string kVikingRoom = std::string(OBSCURA_SHARED_SCENES) + "/viking_room/viking_room.glb";

struct Options {
  std::vector<std::string> scenes;
  std::string res = "1920x1080";
  int spp = 16;
  int runs = 3;
  int threads = 0;
  std::string distance = "inf";
  int chunk = 256;
  bool quick = false;
  std::string preview;
};

struct BenchScene {
  std::string label, source;
  std::unique_ptr<Scene> scene;
  Camera camera;
  size_t triangles = 0;
  double loadSeconds = 0;   // load + build (whole construction)
  double buildSeconds = 0;  // BVH commit only
  double rssAddedMiB = 0;   // resident memory the scene added
};

double peakRssMiB() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;  // Linux: KiB
}

double currentRssMiB() {
  std::ifstream f("/proc/self/statm");
  long pages = 0, resident = 0;
  f >> pages >> resident;
  return double(resident) * double(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

std::string cpuName() {
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("model name", 0) == 0) {
      const size_t c = line.find(':');
      if (c != std::string::npos) return line.substr(c + 2);
    }
  return "unknown CPU";
}

void parseResolution(const std::string& s, int& w, int& h) {
  const size_t x = s.find('x');
  w = h = -1;
  if (x != std::string::npos) {
    w = std::atoi(s.substr(0, x).c_str());
    h = std::atoi(s.substr(x + 1).c_str());
  }
  if (w < 1 || h < 1 || w > 65536 || h > 65536) throw Error("--res: expected WIDTHxHEIGHT, got '" + s + "'");
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

BenchScene loadScene(const std::string& which, float aspect) {
  BenchScene b;
  const double rss0 = currentRssMiB();
  const auto t0 = std::chrono::steady_clock::now();
  if (which == "generated") {
    b.label = "generated";
    b.source = "generated in code (bench/generated_scene.cpp)";
    b.scene = std::make_unique<Scene>();
    buildGeneratedScene(*b.scene);
    b.scene->commit();
    b.camera = generatedSceneCamera();
  } else {
    const std::string path = which == "viking" ? kVikingRoom : which;
    b.label = std::filesystem::path(path).stem().string();
    b.source = std::filesystem::path(path).lexically_normal().string();
    b.scene = loadGltf(path);
    // As `obscura render` without --camera: the file's first camera, else auto.
    b.camera = b.scene->cameras.empty() ? makeAutoCamera(b.scene->bounds(), aspect) : b.scene->cameras[0];
  }
  b.loadSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  b.buildSeconds = b.scene->buildSeconds();
  b.triangles = b.scene->stats().renderedTriangles;
  b.rssAddedMiB = currentRssMiB() - rss0;
  return b;
}

// The renderer side: obscura::render with the registered ao integrator.
struct RendererRun {
  const BenchScene& bs;
  std::unique_ptr<Integrator> integrator;
  IntegratorNeeds needs;
  RenderSettings settings;
  Film lastFilm;

  RendererRun(const BenchScene& b, const std::string& distance, const RenderSettings& s) : bs(b), settings(s) {
    const IntegratorDescriptor& d = IntegratorRegistry::instance().find("ao");
    ParamSet p(d.params, d.name);
    p.set("distance", distance);
    p.set("rays", "1");
    integrator = d.create(p);
    needs = d.needs(p);
  }

  double run(RayTally& tally) {
    RenderStats st;
    lastFilm = render(*bs.scene, bs.camera, *integrator, needs, settings, st);
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

constexpr int kVariants = 4;  // 0..2 raw (RawApi order), 3 = renderer
constexpr int kRenderer = 3;
const char* variantName(int v) { return v == kRenderer ? "renderer (obscura ao)" : rawApiName(RawApi(v)); }

struct SceneResult {
  std::string label;
  size_t triangles = 0;
  double buildSeconds = 0, peakMiB = 0;
  int bestRaw = 0;
  double rawMrays = 0, rendererMrays = 0;
};

SceneResult benchScene(const std::string& which, const Options& o, int width, int height, int threads,
                       float aoDistance) {
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

  RenderSettings s;
  s.width = width;
  s.height = height;
  s.spp = o.spp;
  s.threads = threads;
  s.tileSize = rs.tileSize;
  s.filter = PixelFilter::Box;
  s.aovs = false;
  s.progress = false;
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
    RenderSettings wr = s;
    wr.width = ws.width;
    wr.height = ws.height;
    wr.spp = 1;
    RendererRun wrun(bs, o.distance, wr);
    wrun.run(t);
  }

  std::array<std::vector<double>, kVariants> seconds;
  std::array<RayTally, kVariants> tally{};
  for (int r = 0; r < o.runs; ++r) {
    std::printf("   run %d/%d:", r + 1, o.runs);
    for (int k = 0; k < kVariants; ++k) {
      const int v = (k + r) % kVariants;  // rotate the order every run
      RayTally t;
      const double sec = v == kRenderer ? renderer.run(t) : raw.run(RawApi(v), t);
      if (r > 0 && (t.camera != tally[v].camera || t.ao != tally[v].ao))
        std::printf(" [ray count changed between runs!]");
      tally[v] = t;
      seconds[v].push_back(sec);
      std::printf("  %s %.3f s", v == kRenderer ? "renderer" : (v == 0 ? "single" : (v == 1 ? "packet16" : "stream1M")),
                  sec);
      std::fflush(stdout);
    }
    std::printf("\n");
  }

  std::array<double, kVariants> med{}, mrays{};
  for (int v = 0; v < kVariants; ++v) {
    med[v] = median(seconds[v]);
    mrays[v] = double(tally[v].camera + tally[v].ao) / med[v] * 1e-6;
  }
  int best = 0;
  for (int v = 1; v < 3; ++v)
    if (mrays[v] > mrays[best]) best = v;

  std::printf("\n   %-31s %10s %9s %10s   %s\n", "variant", "median s", "Mrays/s", "% of best", "all runs (s)");
  for (int v = 0; v < kVariants; ++v) {
    std::printf("   %-31s %10.3f %9.2f %9.1f%%  ", variantName(v), med[v], mrays[v], 100.0 * mrays[v] / mrays[best]);
    for (double x : seconds[v]) std::printf(" %.3f", x);
    std::printf("%s\n", v == best ? "   <- best raw" : "");
  }
  std::printf("\n   %-31s %12s %12s %11s\n", "rays traced", "camera", "AO", "unoccluded");
  for (int v = 0; v < kVariants; ++v)
    std::printf("   %-31s %12llu %12llu %10.2f%%\n", variantName(v), (unsigned long long)tally[v].camera,
                (unsigned long long)tally[v].ao,
                tally[v].ao ? 100.0 * double(tally[v].unoccluded) / double(tally[v].ao) : 0.0);
  const RayTally& rt = tally[kRenderer];
  const RayTally& bt = tally[best];
  const long long dAo = (long long)rt.ao - (long long)bt.ao;
  std::printf("   check: camera rays %s; AO rays renderer - raw = %lld (%.4f%%)\n",
              rt.camera == bt.camera ? "identical" : "DIFFER", dAo,
              bt.ao ? 100.0 * double(dAo) / double(bt.ao) : 0.0);

  const double ratio = mrays[kRenderer] / mrays[best];
  std::printf("\n   renderer / best raw (%s): %.1f%%   goal >= 85%%: %s\n", rawApiName(RawApi(best)), 100.0 * ratio,
              ratio >= 0.85 ? "met" : "NOT met");
  const double peak = peakRssMiB();
  std::printf("   peak RSS of the process so far: %.1f MiB\n", peak);
  std::fflush(stdout);

  if (!o.preview.empty()) {
    const std::string path = o.preview + bs.label + ".png";
    writePreviewPng(path, renderer.lastFilm);
    std::printf("   preview    %s\n", path.c_str());
  }

  SceneResult res;
  res.label = bs.label;
  res.triangles = bs.triangles;
  res.buildSeconds = bs.buildSeconds;
  res.peakMiB = peak;
  res.bestRaw = best;
  res.rawMrays = mrays[best];
  res.rendererMrays = mrays[kRenderer];
  return res;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obscura_bench_ao: the ao integrator's rays through raw Embree vs obscura::render"};
  Options o;
  app.add_option("--scene", o.scenes,
                 "Scene: a glTF path, 'viking' (" + kVikingRoom + ") or 'generated'; repeatable "
                 "(default: viking and generated)");
  app.add_option("--res", o.res, "Resolution WIDTHxHEIGHT (default 1920x1080)");
  app.add_option("--spp", o.spp, "Camera samples per pixel (default 16)");
  app.add_option("--runs", o.runs, "Timed runs per variant; the median is reported (default 3)");
  app.add_option("--threads", o.threads, "Worker threads, 0 = all (default 0)");
  app.add_option("--distance", o.distance, "AO distance R in scene units, or inf (default inf)");
  app.add_option("--chunk", o.chunk, "Camera samples per raw packet/stream batch, multiple of 16 (default 256, "
                                     "the renderer's chunk)");
  app.add_flag("--quick", o.quick, "Smoke run: 480x270 unless --res is given");
  app.add_option("--preview", o.preview, "Write the renderer's image of each scene to PREFIX<scene>.png");
  CLI11_PARSE(app, argc, argv);

  try {
    if (o.quick && app.count("--res") == 0) o.res = "480x270";
    int width = 0, height = 0;
    parseResolution(o.res, width, height);
    if (o.spp < 1) throw Error("--spp must be at least 1");
    if (o.runs < 1) throw Error("--runs must be at least 1");
    if (o.threads < 0) throw Error("--threads must be >= 0");
    char* end = nullptr;
    const double R = std::strtod(o.distance.c_str(), &end);
    if (o.distance.empty() || *end != '\0' || !(R > 0)) throw Error("--distance: expected a positive number or inf");
    const float aoDistance = R > double(std::numeric_limits<float>::max()) ? INFINITY : float(R);
    if (o.scenes.empty()) o.scenes = {"viking", "generated"};

    std::optional<tbb::global_control> limit;
    if (o.threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(o.threads));
    const int threads = o.threads > 0 ? o.threads : tbb::this_task_arena::max_concurrency();

    std::printf("obscura_bench_ao: ao rays through raw Embree vs obscura::render (-i ao)\n");
    std::printf("   cpu        %s, %d threads used\n", cpuName().c_str(), threads);
    std::printf("   embree     %s (headers)\n", RTC_VERSION_STRING);
    std::printf("   settings   %dx%d, %d spp, AO distance %s, rays=1, seed 0, box filter, tiles 16x16\n", width,
                height, o.spp, o.distance.c_str());
    std::printf("   timing     median of %d run%s, variants interleaved (order rotated each run), raw chunk %d\n",
                o.runs, o.runs == 1 ? "" : "s", o.chunk);
    std::fflush(stdout);

    std::vector<SceneResult> results;
    for (const std::string& sc : o.scenes) results.push_back(benchScene(sc, o, width, height, threads, aoDistance));

    std::printf("\n== summary: %dx%d, %d spp, %d threads, AO distance %s\n", width, height, o.spp, threads,
                o.distance.c_str());
    std::printf("   %-20s %10s %8s %-31s %8s %9s %9s  %s\n", "scene", "triangles", "BVH s", "best raw", "Mrays/s",
                "renderer", "ratio", "goal >= 85%");
    for (const SceneResult& r : results)
      std::printf("   %-20s %10zu %8.3f %-31s %8.2f %9.2f %8.1f%%  %s\n", r.label.c_str(), r.triangles,
                  r.buildSeconds, rawApiName(RawApi(r.bestRaw)), r.rawMrays, r.rendererMrays,
                  100.0 * r.rendererMrays / r.rawMrays, r.rendererMrays >= 0.85 * r.rawMrays ? "met" : "NOT met");
    std::printf("   peak RSS %.1f MiB (whole process)\n", peakRssMiB());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_ao: error: %s\n", e.what());
    return 1;
  }
}
