// obscura_bench_containment: height-map displacement detail in an
// obscurance pass, two ways, against a reference.
//
//   traced       the cage subdivided to level L and displaced (geometry:
//                core/subd/subdivision.h subdivide + displace, what `--displace`
//                builds), rendered with `obscurance` (step falloff, R,
//                estimator=occlusion);
//   containment  the UNDISPLACED cage subdivided to a coarser level L',
//                rendered with `containment` (the same R, scale, midlevel;
//                m = steps test points per sample), which tests the height
//                field instead of tracing it (integrators/containment.cpp).
//   reference    traced at a fine level with many samples per pixel: the
//                mean of two independent halves (seeds 1 and 2), whose
//                difference gives the reference's own noise (RMSE, printed).
//
// Per scene and displacement scale (a gentle and a steep one), each method
// reports the time to build its scene (subdivision, displacement, BVH) and
// to render it (medians of --runs, the two methods interleaved) and its
// error against the reference: RMSE over the pixels the reference covers
// fully and the test covers at all (core/image/metrics.h: comparedPixels,
// errorMetrics). All renders of a scene share one camera, made from the
// undisplaced surface's bounds.
//
// Scenes:
//   spot   ../shared/scenes/spot_cage/spot_control_mesh.obj (Catmull-Clark
//          cage with uvs) displaced by ../shared/scenes/lava_heightmap/
//          lava_01_height_1k.png; R = 0.05 (the cow is ~1.8 units long);
//          scales 0.01 and 0.04; levels: reference 6, traced 4, containment 3.
//   plane  the unit square (4x4 quads, uv = xy) displaced by an egg crate
//          h = 0.5 + 0.25 (cos 2 pi 8u + cos 2 pi 8v) (512^2 float texels,
//          written to a temporary file), wavelength 1/8, R = 1/16, seen
//          straight from above from afar (nearly orthographic, [0.1, 0.9]^2
//          in view), so both methods shade the same (u, v) in a pixel and
//          the error is the containment approximation's; scales for max
//          slopes 0.5 and 2 along an axis; levels: reference 7, traced 5,
//          containment 1.
//   plane-oblique  the same seen obliquely: the undisplaced surface also
//          lacks the parallax of the displaced one (a pixel shades another
//          (u, v), valleys hidden behind crests are shaded anyway), which
//          adds to the error.
//
// Run:   build/bench/obscura_bench_containment                 both scenes, 320x240, 8 spp, rays 4, 3 runs
//        build/bench/obscura_bench_containment --quick         smoke run (160x120, 1 run, reference 16 spp)
//        build/bench/obscura_bench_containment --scene plane --steps 2,8 --runs 5
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "bench/common.h"
#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include <obscura/integrator.h>
#include "core/image/metrics.h"
#include <obscura/params.h>
#include "core/render/render.h"
#include "core/subd/subdivision.h"

using namespace obscura;
using namespace obscura::bench;

namespace {

struct Options : CommonOptions {
  int rays = 4;
  int refSpp = 64;
  std::string steps = "2,8";
  bool steepness = false;
};

// One scene of the bench: how to build it at a level, displaced or not.
struct Setup {
  std::string name, map;
  double R = 0;
  std::vector<double> scales;
  int refLevel = 0, tracedLevel = 0, containmentLevel = 0;
  // Builds the scene at `level`, displaced by `scale` (0 = undisplaced).
  std::function<std::unique_ptr<Scene>(int level, double scale)> build;
  Camera camera;
};

std::string number(double x) { return formatFloat(x); }
std::string scaleText(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", x);
  return buf;
}

Film renderConfig(const Scene& scene, const Camera& camera, const std::string& integrator,
                  const std::vector<std::pair<std::string, std::string>>& params, const RenderSettings& settings,
                  RenderStats* statsOut = nullptr) {
  RenderStats stats;
  Film f = BenchIntegrator(integrator, params).render(scene, camera, settings, stats);
  if (statsOut) *statsOut = stats;
  return f;
}

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// --- scenes -------------------------------------------------------------------

Setup spotSetup(bool quick) {
  const std::string root = OBSCURA_SHARED_SCENES;
  Setup s;
  s.name = "spot";
  const std::string cage = root + "/spot_cage/spot_control_mesh.obj";
  s.map = root + "/lava_heightmap/lava_01_height_1k.png";
  if (!std::filesystem::exists(cage) || !std::filesystem::exists(s.map))
    throw Error("spot: " + cage + " or " + s.map + " is missing");
  s.R = 0.05;
  s.scales = {0.01, 0.04};
  s.refLevel = quick ? 5 : 6, s.tracedLevel = 4, s.containmentLevel = 3;
  s.build = [cage, map = s.map](int level, double scale) {
    LoadOptions o;
    o.subdivision = true;
    o.subdivisionLevel = level;
    if (scale != 0) o.displacementMap = map, o.displacementScale = scale, o.displacementMidlevel = 0.5;
    return obscura::loadScene(cage, o);
  };
  return s;
}

std::string writeEggCrate() {
  const int n = 512;
  std::vector<float> px(size_t(n) * n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x)
      px[size_t(y) * n + x] = float(0.5 + 0.25 * (std::cos(2 * M_PI * 8 * (x + 0.5) / n) +
                                                   std::cos(2 * M_PI * 8 * (y + 0.5) / n)));
  const std::string path =
      (std::filesystem::temp_directory_path() / ("obscura_bench_eggcrate_" + std::to_string(::getpid()) + ".exr"))
          .string();
  auto out = OIIO::ImageOutput::create(path);
  if (!out || !out->open(path, OIIO::ImageSpec(n, n, 1, OIIO::TypeDesc::FLOAT)) ||
      !out->write_image(OIIO::TypeDesc::FLOAT, px.data()) || !out->close())
    throw Error(path + ": cannot write the egg-crate height map");
  return path;
}

Setup planeSetup(bool quick, bool oblique) {
  Setup s;
  s.name = oblique ? "plane-oblique" : "plane";
  s.map = writeEggCrate();
  const double lambda = 1.0 / 8;
  s.R = lambda / 2;
  // Along an axis d = 0.25 scale cos(2 pi u / lambda): slope 0.25 scale 2 pi / lambda.
  for (const double slope : {0.5, 2.0}) s.scales.push_back(slope * lambda / (0.25 * 2 * M_PI));
  s.refLevel = quick ? 6 : 7, s.tracedLevel = 5, s.containmentLevel = 1;
  s.build = [map = s.map](int level, double scale) {
    SubdivisionCage c;
    const int n = 4;
    for (int i = 0; i < (n + 1) * (n + 1); ++i) {
      const float x = float(i % (n + 1)) / n, y = float(i / (n + 1)) / n;
      c.positions.emplace_back(x, y, 0.0f);
      c.uvs.insert(c.uvs.end(), {x, y});
    }
    for (int q = 0; q < n * n; ++q) {
      const int a = (q / n) * (n + 1) + q % n;
      c.faceIndices.insert(c.faceIndices.end(), {a, a + 1, a + n + 2, a + n + 1});
      c.faceSizes.push_back(4);
    }
    c.uvIndices = c.faceIndices;
    SubdividedMesh m = subdivide(c, SubdivisionScheme::CatmullClark, level, size_t(8) << 30, "plane");
    if (scale != 0) displace(m, HeightMap(map), scale, 0.5);
    auto scene = std::make_unique<Scene>();
    scene->addWorldPrimitive(m.positions, m.triangles, m.normals, m.uvs, -1);
    scene->commit();
    return scene;
  };
  return s;
}

// --- one scene ------------------------------------------------------------------

struct Row {
  std::string scene, method;
  double scale = 0;
  int level = 0, steps = 0;
  size_t triangles = 0;
  double buildS = 0, renderS = 0, rmse = 0, mae = 0, refNoise = 0, meanW = 0;
};

double meanW(const PassImage& img, const PassImage& ref) {
  const std::vector<size_t> px = comparedPixels(img, ref);
  double s = 0;
  for (const size_t i : px) s += img.W(0, i);
  return px.empty() ? 0 : s / double(px.size());
}

void benchScene(Setup& s, const Options& o, int width, int height, int threads, const std::vector<int>& steps,
                std::vector<Row>& rows) {
  {
    const std::unique_ptr<Scene> macro = s.build(s.containmentLevel, 0);
    if (s.name == "plane")
      s.camera = makeLookAtCamera(Vec3(0.5f, 0.5f, 8.0f), Vec3(0.5f, 0.5f, 0), Vec3(0, 1, 0), 2 * std::atan(0.4f / 8),
                                  "top");
    else if (s.name == "plane-oblique")
      s.camera = makeLookAtCamera(Vec3(0.5f, -0.15f, 0.75f), Vec3(0.5f, 0.45f, 0), Vec3(0, 0, 1), 0.9f, "oblique");
    else
      s.camera = makeAutoCamera(macro->bounds(), float(width) / float(height));
  }
  const std::string rays = std::to_string(o.rays);
  const std::vector<std::pair<std::string, std::string>> traceParams = {
      {"falloff", "step"}, {"distance", number(s.R)}, {"estimator", "occlusion"}, {"rays", rays}};
  for (const double scale : s.scales) {
    std::printf("%s scale %s: reference (level %d, 2 x %d spp) ...\n", s.name.c_str(), scaleText(scale).c_str(),
                s.refLevel, o.refSpp / 2);
    std::fflush(stdout);
    PassImage ref;
    double refNoise = 0;
    {
      const std::unique_ptr<Scene> fine = s.build(s.refLevel, scale);
      const PassImage a = passFromFilm(renderConfig(*fine, s.camera, "obscurance", traceParams,
                                                    benchRenderSettings(width, height, o.refSpp / 2, threads, 1)));
      const PassImage b = passFromFilm(renderConfig(*fine, s.camera, "obscurance", traceParams,
                                                    benchRenderSettings(width, height, o.refSpp / 2, threads, 2)));
      ref = averagePasses(a, b);
      refNoise = referenceNoise(a, b);
    }
    // The methods: traced at L, containment at L' for each m.
    struct Method {
      std::string name;
      int level, steps;
    };
    std::vector<Method> methods = {{"traced", s.tracedLevel, 0}};
    for (const int m : steps) methods.push_back({"containment", s.containmentLevel, m});
    std::vector<std::vector<double>> build(methods.size()), time(methods.size());
    std::vector<PassImage> images(methods.size());
    std::vector<size_t> tris(methods.size());
    for (int run = 0; run < o.runs; ++run)
      for (size_t k = 0; k < methods.size(); ++k) {
        const size_t j = (k + size_t(run)) % methods.size();  // rotate the order each run
        const Method& me = methods[j];
        const auto t0 = std::chrono::steady_clock::now();
        const std::unique_ptr<Scene> scene = s.build(me.level, me.steps ? 0.0 : scale);
        build[j].push_back(seconds(t0));
        tris[j] = scene->stats().renderedTriangles;
        RenderStats stats;
        Film f = me.steps ? renderConfig(*scene, s.camera, "containment",
                                         {{"map", s.map}, {"scale", number(scale)}, {"midlevel", "0.5"},
                                          {"falloff", "step"}, {"distance", number(s.R)}, {"rays", rays},
                                          {"steps", std::to_string(me.steps)}},
                                         benchRenderSettings(width, height, o.spp, threads), &stats)
                          : renderConfig(*scene, s.camera, "obscurance", traceParams,
                                         benchRenderSettings(width, height, o.spp, threads), &stats);
        time[j].push_back(stats.seconds);
        if (run == 0) images[j] = passFromFilm(f);
      }
    for (size_t j = 0; j < methods.size(); ++j) {
      const ErrorMetrics e = errorMetrics(images[j], ref);
      rows.push_back({s.name, methods[j].name, scale, methods[j].level, methods[j].steps, tris[j], median(build[j]),
                      median(time[j]), e.rmse, e.mae, refNoise, meanW(images[j], ref)});
    }
    rows.push_back({s.name, "reference", scale, s.refLevel, 0, 0, 0, 0, 0, 0, refNoise, meanW(ref, ref)});
  }
}

// --steepness: on the plane seen from above, the mean W of containment and of
// traced displacement (level 6, 64 vertices per wavelength) at max slopes
// 0.25..4 and R = lambda/2, lambda, 2 lambda, for m = 2 and 16; the
// difference and its standard error (Bernoulli bound over all of the
// image's samples, the two renders taken as independent).
void steepnessTable(const Options& o, int width, int height, int threads) {
  Setup s = planeSetup(false, false);
  const double lambda = 1.0 / 8;
  const Camera camera =
      makeLookAtCamera(Vec3(0.5f, 0.5f, 8.0f), Vec3(0.5f, 0.5f, 0), Vec3(0, 1, 0), 2 * std::atan(0.4f / 8), "top");
  const std::unique_ptr<Scene> macro = s.build(1, 0);
  const double n = double(width) * height * o.spp * o.rays;
  const auto mean = [&](const Film& f) {
    const PassImage img = passFromFilm(f);
    double sum = 0;
    for (size_t i = 0; i < img.pixels(); ++i) sum += img.W(0, i);
    return sum / double(img.pixels());
  };
  const auto se = [&](double p) { return std::sqrt(std::max(p * (1 - p), 1e-12) / n); };
  std::printf("\n| R/lambda | max slope | A/lambda | traced | containment m=2 | error m=2 | containment m=16 | error m=16 | SE |\n");
  std::printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const double Rl : {0.5, 1.0, 2.0})
    for (const double slope : {0.25, 0.5, 1.0, 2.0, 4.0}) {
      const double scale = slope * lambda / (0.25 * 2 * M_PI), R = Rl * lambda;
      const auto settings = benchRenderSettings(width, height, o.spp, threads);
      const std::unique_ptr<Scene> fine = s.build(6, scale);
      const double t = mean(renderConfig(*fine, camera, "obscurance",
                                         {{"falloff", "step"}, {"distance", number(R)}, {"estimator", "occlusion"},
                                          {"rays", std::to_string(o.rays)}},
                                         settings));
      double c[2];
      for (int k = 0; k < 2; ++k)
        c[k] = mean(renderConfig(*macro, camera, "containment",
                                 {{"map", s.map}, {"scale", number(scale)}, {"falloff", "step"},
                                  {"distance", number(R)}, {"rays", std::to_string(o.rays)},
                                  {"steps", k ? "16" : "2"}},
                                 settings));
      std::printf("| %.1f | %.2f | %.3f | %.4f | %.4f | %+.4f | %.4f | %+.4f | %.4f |\n", Rl, slope,
                  0.25 * scale / lambda, t, c[0], c[0] - t, c[1], c[1] - t, std::hypot(se(t), se(c[0])));
      std::fflush(stdout);
    }
  std::filesystem::remove(s.map);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"obscura_bench_containment: traced displacement vs containment on the undisplaced surface"};
  Options o;
  o.res = "320x240";
  o.spp = 8;
  addCommonOptions(app, o, "Smoke run: 160x120, 1 run, reference 16 spp at one level coarser");
  app.add_option("--rays", o.rays, "Rays (samples) per camera sample for every render (default 4)");
  app.add_option("--ref-spp", o.refSpp, "Reference samples per pixel, two halves (default 64)");
  app.add_option("--steps", o.steps, "Containment test points m, comma-separated (default 2,8)");
  app.add_flag("--steepness", o.steepness,
               "Instead: the error of containment against traced displacement as the plane's field steepens");
  CLI11_PARSE(app, argc, argv);
  try {
    if (o.quick) {
      if (app.count("--res") == 0) o.res = "160x120";
      if (app.count("--runs") == 0) o.runs = 1;
      if (app.count("--ref-spp") == 0) o.refSpp = 16;
    }
    if (o.scenes.empty()) o.scenes = {"spot", "plane"};
    const auto [width, height] = checkCommonOptions(o);
    if (o.rays < 1 || o.rays > 65536) throw Error("--rays must be in [1, 65536]");
    if (o.refSpp < 2) throw Error("--ref-spp must be at least 2");
    std::vector<int> steps;
    for (const std::string& m : splitCommaList(o.steps)) {
      const int v = std::atoi(m.c_str());
      if (v < 1 || v > 4096) throw Error("--steps: expected integers in [1, 4096], got '" + o.steps + "'");
      steps.push_back(v);
    }
    const ThreadLimit limit(o.threads);
    const int threads = limit.threads();
    std::printf("obscura_bench_containment: traced displacement vs containment, error against a reference\n");
    printMachine(threads);
    if (o.steepness)
      std::printf("   settings   %dx%d, %d spp, rays=%d, step falloff, box filter\n", width, height, o.spp, o.rays);
    else {
      std::printf("   settings   %dx%d, %d spp, rays=%d, reference 2 x %d spp, step falloff, box filter\n", width,
                  height, o.spp, o.rays, o.refSpp / 2);
      std::printf("   timing     median of %d run%s per method, methods interleaved\n", o.runs,
                  o.runs == 1 ? "" : "s");
    }
    std::fflush(stdout);

    if (o.steepness) {
      steepnessTable(o, width, height, threads);
      return 0;
    }
    std::vector<Row> rows;
    std::vector<std::string> temporaries;
    for (const std::string& sc : o.scenes) {
      Setup s;
      if (sc == "spot") s = spotSetup(o.quick);
      else if (sc == "plane" || sc == "plane-oblique")
        s = planeSetup(o.quick, sc == "plane-oblique"), temporaries.push_back(s.map);
      else throw Error("--scene: expected spot, plane or plane-oblique, got '" + sc + "'");
      benchScene(s, o, width, height, threads, steps, rows);
    }
    for (const std::string& t : temporaries) std::filesystem::remove(t);

    std::printf("\n| scene | scale | method | level | m | triangles | build s | render s | total s | mean W | RMSE | MAE |\n");
    std::printf("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const Row& r : rows) {
      if (r.method == "reference") {
        std::printf("| %s | %s | reference | %d | | | | | | %.4f | noise %.4f | |\n", r.scene.c_str(),
                    scaleText(r.scale).c_str(), r.level, r.meanW, r.refNoise);
        continue;
      }
      std::printf("| %s | %s | %s | %d | %s | %zu | %.3f | %.3f | %.3f | %.4f | %.4f | %.4f |\n", r.scene.c_str(),
                  scaleText(r.scale).c_str(), r.method.c_str(), r.level,
                  r.steps ? std::to_string(r.steps).c_str() : "", r.triangles, r.buildS, r.renderS,
                  r.buildS + r.renderS, r.meanW, r.rmse, r.mae);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_containment: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
