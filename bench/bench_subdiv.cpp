// obscura_bench_subdiv: the two subdivision backends on one displaced cage.
//
// For each level L (and each backend) the cage is loaded the way
// `obscura render CAGE --subdiv catmull-clark --subdiv-level L
// --subdiv-backend B --displace MAP` loads it (core/load/cage.h), then rendered
// with the `ao` integrator. Reported, medians over --runs:
//   load s    : the whole scene construction (OBJ parse, height map read,
//               OpenSubdiv refinement + displacement, or Embree's
//               tessellation in the BVH build)
//   build s   : the BVH commit alone (Embree tessellates while it builds)
//   Embree MiB: what Embree's memory monitor counted after the build
//               (vertex/index buffers, tessellation grids, BVH); peak MiB
//               the most it held at once (the builder's temporaries)
//   mesh MiB  : what the renderer keeps beside Embree (normals and uvs of
//               the OpenSubdiv triangles; the Embree backend keeps the cage's
//               corner uvs only)
//   render s  : obscura::render() wall time (camera rays + AO rays)
//   Mrays/s   : (camera + AO rays) / render s
// Level L means 2^L segments per cage edge on both backends (OpenSubdiv's
// uniform level; Embree's tessellation rate 2^L), so the two trace surfaces
// of the same resolution.
//
// Run:  build/bench/obscura_bench_subdiv                    Spot + lava, levels 3..7, 960x540, 16 spp, 3 runs
//       build/bench/obscura_bench_subdiv --quick            smoke run
//       build/bench/obscura_bench_subdiv --cage my.obj --map h.png --scale 0.02 --levels 2,4
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "bench/common.h"
#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include <obscura/integrator.h>
#include "core/render/render.h"

using namespace obscura;
using namespace obscura::bench;

namespace {

struct Row {
  double load = 0, build = 0, embreeMiB = 0, embreePeakMiB = 0, meshMiB = 0, render = 0, mrays = 0;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The OpenSubdiv and Embree subdivision backends: memory, build and render time"};
  CommonOptions common;
  common.res = "960x540";
  addCommonOptions(app, common, "smoke run: 320x180, 4 spp, levels 3,4, 1 run");
  std::string cage = std::string(OBSCURA_SHARED_SCENES) + "/spot_cage/spot_control_mesh.obj";
  std::string map = std::string(OBSCURA_SHARED_SCENES) + "/lava_heightmap/lava_01_height_1k.png";
  double scale = 0.03, midlevel = 0.5;
  std::string levels = "3,4,5,6,7";
  app.add_option("--cage", cage, "OBJ cage with uvs");
  app.add_option("--map", map, "Height map");
  app.add_option("--scale", scale, "Displacement scale (scene units per unit height)");
  app.add_option("--midlevel", midlevel, "Displacement midlevel");
  app.add_option("--levels", levels, "Comma-separated uniform levels");
  CLI11_PARSE(app, argc, argv);
  try {
    if (common.quick) common.res = "320x180", common.spp = 4, common.runs = 1, levels = "3,4";
    if (common.scenes.empty()) common.scenes = {"unused"};
    const BenchSize size = checkCommonOptions(common);
    const ThreadLimit threads(common.threads);
    printMachine(threads.threads());
    std::printf("cage %s\nmap  %s (scale %g, midlevel %g)\n%dx%d, %d spp, ao, %d runs (medians)\n\n", cage.c_str(),
                map.c_str(), scale, midlevel, size.width, size.height, common.spp, common.runs);
    std::printf("%-7s %5s %10s %9s %9s %11s %9s %9s %9s %9s\n", "backend", "level", "faces", "load s", "build s",
                "Embree MiB", "peak MiB", "mesh MiB", "render s", "Mrays/s");
    const IntegratorDescriptor& ao = IntegratorRegistry::instance().find("ao");
    const ParamSet params(ao.params, "ao");
    for (const std::string& ls : splitCommaList(levels)) {
      const int level = std::stoi(ls);
      for (const SubdivisionBackend backend : {SubdivisionBackend::OpenSubdiv, SubdivisionBackend::Embree}) {
        LoadOptions o;
        o.subdivision = true;
        o.backend = backend;
        o.subdivisionLevel = level;
        o.displacementMap = map;
        o.displacementScale = scale;
        o.displacementMidlevel = midlevel;
        o.maxMemoryBytes = size_t(16) << 30;
        std::vector<Row> rows;
        size_t faces = 0;
        for (int run = 0; run < common.runs; ++run) {
          Row r;
          const auto t0 = std::chrono::steady_clock::now();
          std::unique_ptr<Scene> scene = obscura::loadScene(cage, o);
          r.load = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          r.build = scene->buildSeconds();
          r.embreeMiB = double(scene->embreeBytes()) / (1 << 20);
          r.embreePeakMiB = double(scene->embreePeakBytes()) / (1 << 20);
          const SceneStats st = scene->stats();
          faces = backend == SubdivisionBackend::Embree ? st.subdivisionFaces : st.renderedTriangles;
          r.meshMiB = double(scene->attributeBytes()) / (1 << 20);
          const Camera cam = makeAutoCamera(scene->bounds(), float(size.width) / float(size.height));
          const std::unique_ptr<Integrator> integ = ao.create(params);
          RenderStats stats;
          const RenderSettings s = benchRenderSettings(size.width, size.height, common.spp, threads.threads());
          render(*scene, cam, *integ, ao.needs(params), s, stats);
          r.render = stats.seconds;
          r.mrays = double(stats.rays.camera + stats.rays.occlusion) / stats.seconds / 1e6;
          rows.push_back(r);
        }
        const auto med = [&](double Row::*f) {
          std::vector<double> v;
          for (const Row& r : rows) v.push_back(r.*f);
          return median(v);
        };
        std::printf("%-7s %5d %10zu %9.3f %9.3f %11.1f %9.1f %9.1f %9.3f %9.2f\n",
                    backend == SubdivisionBackend::Embree ? "embree" : "osd", level, faces, med(&Row::load),
                    med(&Row::build), med(&Row::embreeMiB), med(&Row::embreePeakMiB), med(&Row::meshMiB),
                    med(&Row::render), med(&Row::mrays));
        std::fflush(stdout);
      }
    }
    std::printf("\nfaces: triangles (osd) or cage faces (embree, each tessellated to 2^level segments per edge)\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "obscura_bench_subdiv: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
