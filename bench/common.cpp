#include "bench/common.h"

#include <embree3/rtcore.h>
#include <sys/resource.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <cstdarg>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>

#include "bench/generated_scene.h"
#include <obscura/error.h>
#include "core/load/gltf_loader.h"

namespace obscura::bench {

const std::string& vikingRoomPath() {
  static const std::string path = std::string(OBSCURA_SHARED_SCENES) + "/viking_room/viking_room.glb";
  return path;
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
    const std::string path = which == "viking" ? vikingRoomPath() : which;
    b.label = std::filesystem::path(path).stem().string();
    b.source = std::filesystem::path(path).lexically_normal().string();
    b.scene = loadGltf(path);
    b.camera = b.scene->cameras.empty() ? makeAutoCamera(b.scene->bounds(), aspect) : b.scene->cameras[0];
  }
  b.loadSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  b.buildSeconds = b.scene->buildSeconds();
  b.triangles = b.scene->stats().renderedTriangles;
  b.diagonal = double(length(b.scene->bounds().diagonal()));
  b.rssAddedMiB = currentRssMiB() - rss0;
  return b;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double processCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

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

void addCommonOptions(CLI::App& app, CommonOptions& o, const std::string& quickDoc) {
  app.add_option("--scene", o.scenes,
                 "Scene: a glTF path, 'viking' (" + vikingRoomPath() + ") or 'generated'; repeatable "
                 "(default: viking and generated)");
  app.add_option("--res", o.res, "Resolution WIDTHxHEIGHT (default " + o.res + ")");
  app.add_option("--spp", o.spp, "Camera samples per pixel (default " + std::to_string(o.spp) + ")");
  app.add_option("--runs", o.runs,
                 "Timed runs per variant; the median is reported (default " + std::to_string(o.runs) + ")");
  app.add_option("--threads", o.threads, "Worker threads, 0 = all (default 0)");
  app.add_flag("--quick", o.quick, quickDoc);
}

BenchSize checkCommonOptions(CommonOptions& o) {
  BenchSize s;
  const size_t x = o.res.find('x');
  int& w = s.width;
  int& h = s.height;
  w = h = -1;
  if (x != std::string::npos) {
    w = std::atoi(o.res.substr(0, x).c_str());
    h = std::atoi(o.res.substr(x + 1).c_str());
  }
  if (w < 1 || h < 1 || w > 65536 || h > 65536) throw Error("--res: expected WIDTHxHEIGHT, got '" + o.res + "'");
  if (o.spp < 1) throw Error("--spp must be at least 1");
  if (o.runs < 1) throw Error("--runs must be at least 1");
  if (o.threads < 0) throw Error("--threads must be >= 0");
  if (o.scenes.empty()) o.scenes = {"viking", "generated"};
  return s;
}

ThreadLimit::ThreadLimit(int requested) {
  if (requested > 0) limit_.emplace(tbb::global_control::max_allowed_parallelism, size_t(requested));
  threads_ = requested > 0 ? requested : tbb::this_task_arena::max_concurrency();
}

std::vector<std::string> splitCommaList(const std::string& list) {
  std::vector<std::string> out;
  size_t pos = 0;
  while (pos <= list.size()) {
    const size_t comma = std::min(list.find(',', pos), list.size());
    out.push_back(list.substr(pos, comma - pos));
    pos = comma + 1;
  }
  return out;
}

void printMachine(int threads) {
  std::printf("   cpu        %s, %d threads used\n", cpuName().c_str(), threads);
  std::printf("   embree     %s (headers)\n", RTC_VERSION_STRING);
}

RenderSettings benchRenderSettings(int width, int height, int spp, int threads, uint32_t seed) {
  return {.width = width, .height = height, .spp = spp, .seed = seed, .threads = threads, .tileSize = 16,
          .filter = PixelFilter::Box, .aovs = false, .progress = false};
}

double Timings::minUse() const {
  double m = 1;
  for (size_t i = 0; i < wall.size() && i < cpu.size(); ++i)
    if (wall[i] > 0) m = std::min(m, cpu[i] / wall[i]);
  return m;
}

std::string fmt(const char* format, ...) {
  char buf[512];
  va_list ap;
  va_start(ap, format);
  std::vsnprintf(buf, sizeof buf, format, ap);
  va_end(ap);
  return buf;
}

void MarkdownTable::print() const {
  auto line = [](const std::vector<std::string>& cells) {
    std::string s = "|";
    for (const std::string& c : cells) s += " " + c + " |";
    std::printf("%s\n", s.c_str());
  };
  line(header);
  std::string sep = "|";
  for (size_t i = 0; i < header.size(); ++i) sep += i < align.size() && align[i] == 'r' ? "---:|" : "---|";
  std::printf("%s\n", sep.c_str());
  for (const auto& r : rows) line(r);
}

BenchIntegrator::BenchIntegrator(const std::string& name,
                                 const std::vector<std::pair<std::string, std::string>>& params) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find(name);
  ParamSet p(d.params, d.name);
  for (const auto& [k, v] : params) p.set(k, v);
  integrator = d.create(p);
  needs = passNeeds(d, p);
}

Film BenchIntegrator::render(const Scene& scene, const Camera& camera, const RenderSettings& s,
                             RenderStats& stats) const {
  return obscura::render(scene, camera, *integrator, needs, s, stats);
}

}  // namespace obscura::bench
