// What the benchmarks share: scene loading (the viking room of
// ../shared/scenes, the generated 1.1M-triangle scene or any glTF file),
// the common command-line options, timing helpers (median, process CPU
// time, RSS), the renderer settings every bench times with, an integrator
// configured by name, and the pieces of the raw-Embree replays (aligned ray
// arrays, the renderer's walk over a tile's camera samples, the camera ray,
// the geometric-normal frame secondary rays leave from).
#pragma once

#include <CLI/CLI.hpp>
#include <embree3/rtcore.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <cstdlib>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "core/scene/camera.h"
#include <obscura/integrator.h>
#include "core/render/render.h"
#include <obscura/sampler.h>
#include "core/scene/scene.h"
#include "core/scene/surface.h"
#include <obscura/warp.h>

namespace obscura::bench {

// ../shared/scenes/viking_room/viking_room.glb (path fixed at configure time).
const std::string& vikingRoomPath();

struct BenchScene {
  std::string label, source;
  std::unique_ptr<Scene> scene;
  Camera camera;
  size_t triangles = 0;
  double diagonal = 0;      // length of the bounding-box diagonal
  double loadSeconds = 0;   // load + build (whole construction)
  double buildSeconds = 0;  // BVH commit only
  double rssAddedMiB = 0;   // resident memory the scene added
};

// `which`: "viking", "generated" or a glTF path. The camera is the file's
// first one, else auto (as `obscura render` without --camera).
BenchScene loadScene(const std::string& which, float aspect);

double median(std::vector<double> v);
double processCpuSeconds();
double peakRssMiB();     // getrusage: the process's peak so far
double currentRssMiB();  // /proc/self/statm
std::string cpuName();

// 64-byte aligned array of n T (uninitialized), for Embree ray streams and
// packets.
template <class T>
struct AlignedArray {
  explicit AlignedArray(size_t n) {
    p = static_cast<T*>(std::aligned_alloc(64, ((n * sizeof(T) + 63) / 64) * 64));
    if (!p) throw std::bad_alloc();
  }
  ~AlignedArray() { std::free(p); }
  AlignedArray(const AlignedArray&) = delete;
  AlignedArray& operator=(const AlignedArray&) = delete;
  T* p;
};

// An integrator made from its name and key=value parameters, rendered with
// the renderer (obscura::render).
struct BenchIntegrator {
  BenchIntegrator(const std::string& name, const std::vector<std::pair<std::string, std::string>>& params);
  Film render(const Scene& scene, const Camera& camera, const RenderSettings& s, RenderStats& stats) const;
  std::unique_ptr<Integrator> integrator;
  IntegratorNeeds needs;
};

// --- raw Embree replays of the renderer's rays ----------------------------

// Walks a tile's camera samples in the renderer's order (core/render/render.cpp):
// pixels row-major within the tile, each pixel's samples 0..spp-1
// consecutively; sample si draws from its replicate's key at its index
// (include/obscura/sampler.h sampleStream).
struct SampleWalk {
  SampleWalk(const Sampler& s, int x0_, int y0, int tw, int spp_)
      : sampler(s), x0(x0_), x1(x0_ + tw), spp(uint32_t(spp_)), px(x0_), py(y0),
        pixelKey(s.pixelKey(uint32_t(x0_), uint32_t(y0))), key(pixelKey) {}
  void next() {
    if (++si == spp) {
      si = 0;
      if (++px == x1) px = x0, ++py;
      pixelKey = sampler.pixelKey(uint32_t(px), uint32_t(py));
    }
    const SampleStream st = sampleStream(pixelKey, si);
    key = st.key, index = st.index;
  }
  // The current sample's camera ray direction (box filter, as the benches
  // render with).
  Vec3 direction(const RasterCamera& raster) const {
    const Sample2 f = Sampler::get2D(key, index, kDimPixelFilter);
    return raster.direction(float(px) + f.u, float(py) + f.v);
  }
  const Sampler& sampler;
  int x0, x1;
  uint32_t spp;
  int px, py;
  uint32_t si = 0;
  uint32_t pixelKey;
  uint32_t key;       // the sample's replicate key
  uint32_t index = 0; // and its index in it
};

// A closest-hit ray for rtcIntersect1/1M (mask ~0, time 0, no hit yet).
inline void setRayHit(RTCRayHit& r, Vec3 org, Vec3 dir, float tnear, float tfar, unsigned id) {
  r.ray.org_x = org.x; r.ray.org_y = org.y; r.ray.org_z = org.z; r.ray.tnear = tnear;
  r.ray.dir_x = dir.x; r.ray.dir_y = dir.y; r.ray.dir_z = dir.z;
  r.ray.time = 0.0f; r.ray.tfar = tfar; r.ray.mask = 0xffffffffU; r.ray.id = id; r.ray.flags = 0;
  r.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  r.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
}
// An occlusion ray for rtcOccluded1/1M.
inline void setRay(RTCRay& q, Vec3 org, Vec3 dir, float tnear, float tfar, unsigned id) {
  q.org_x = org.x; q.org_y = org.y; q.org_z = org.z; q.tnear = tnear;
  q.dir_x = dir.x; q.dir_y = dir.y; q.dir_z = dir.z;
  q.time = 0.0f; q.tfar = tfar; q.mask = 0xffffffffU; q.id = id; q.flags = 0;
}

// Where the raw replays start secondary rays, from what Embree returned and
// nothing read back from the scene (ao_raw.h): the geometric normal,
// normalized and flipped to face the ray, as the frame; the origin o + t*d
// pushed along it by 2^-16 of the point's magnitude. Cosine directions about
// the frame leave to the origin's side.
struct RawHitFrame {
  Vec3 org;
  Frame frame;
};
inline RawHitFrame rawHitFrame(Vec3 o, Vec3 d, float t, Vec3 ngRaw) {
  const Vec3 p = o + d * t;
  const float len = length(ngRaw);
  Vec3 ng = (len > 0.0f && std::isfinite(len)) ? ngRaw * (1.0f / len) : -d;
  if (dot(ng, d) > 0.0f) ng = -ng;
  const float mag = std::max(std::abs(p.x), std::max(std::abs(p.y), std::abs(p.z)));
  const float eps = std::max(mag * kRayOffsetRelative, std::numeric_limits<float>::min());
  return {p + ng * eps, Frame::fromNormal(ng)};
}

// Options every bench takes: --scene (repeatable), --res, --spp, --runs,
// --threads, --quick (`quickDoc` says what it does).
struct CommonOptions {
  std::vector<std::string> scenes;
  std::string res;
  int spp = 16;
  int runs = 3;
  int threads = 0;
  bool quick = false;
};
void addCommonOptions(CLI::App& app, CommonOptions& o, const std::string& quickDoc);

// Validates the common options (throws obscura::Error), parses --res into
// width and height, and defaults the scenes to viking and generated.
struct BenchSize {
  int width = 0, height = 0;
};
BenchSize checkCommonOptions(CommonOptions& o);

// Caps TBB at --threads (0 = all cores) for the process's lifetime and
// resolves the thread count.
class ThreadLimit {
 public:
  explicit ThreadLimit(int requested);
  int threads() const { return threads_; }

 private:
  std::optional<tbb::global_control> limit_;
  int threads_;
};

// "a,b,,c" -> {"a", "b", "", "c"} (the items of a comma-separated option).
std::vector<std::string> splitCommaList(const std::string& list);

// The "cpu" and "embree" lines of a bench's preamble.
void printMachine(int threads);

// The settings benches render with: box filter, 16x16 tiles, no AOVs, no
// progress bar.
RenderSettings benchRenderSettings(int width, int height, int spp, int threads, uint32_t seed = 0);

// --- timing and output formatters ----------------------------------------

// The timed runs of one variant: wall s and process CPU s / threads of each.
struct Timings {
  std::vector<double> wall, cpu;
  double medWall() const { return median(wall); }
  double medCpu() const { return median(cpu); }
  double med(bool useCpu) const { return useCpu ? medCpu() : medWall(); }
  // Lowest CPU s / wall s over the runs (1 = every thread busy in every run).
  double minUse() const;
  // Other processes took cores in some run (CPU use < 90 %): the wall-clock
  // figures measure the machine's load too.
  bool busy() const { return minUse() < 0.9; }
};

// Runs f(), which returns the wall s it timed, and records them with the
// process CPU s the call took / threads.
template <class F>
double timeRun(Timings& t, int threads, F&& f) {
  const double c0 = processCpuSeconds();
  const double wall = f();
  t.wall.push_back(wall);
  t.cpu.push_back((processCpuSeconds() - c0) / threads);
  return wall;
}

// `runs` rounds of variants 0..n-1, interleaved with the order rotated each
// round (the machine is shared and noisy): f(round, variant).
template <class F>
void interleaved(int runs, int n, F&& f) {
  for (int r = 0; r < runs; ++r)
    for (int k = 0; k < n; ++k) f(r, (k + r) % n);
}

inline double mraysPerSecond(double rays, double seconds) { return seconds > 0 ? rays / seconds * 1e-6 : 0.0; }

// printf into a std::string.
std::string fmt(const char* format, ...) __attribute__((format(printf, 1, 2)));

// A Markdown table: header cells, then rows; `align` holds 'l' or 'r' per
// column (r: numbers, written `---:`).
struct MarkdownTable {
  std::vector<std::string> header;
  std::string align;
  std::vector<std::vector<std::string>> rows;
  void row(std::vector<std::string> cells) { rows.push_back(std::move(cells)); }
  void print() const;
};

}  // namespace obscura::bench
