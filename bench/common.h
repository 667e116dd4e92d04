// What the benchmarks share: scene loading (the viking room of
// ../shared/scenes, the generated 1.1M-triangle scene or any glTF file),
// the common command-line options, timing helpers (median, process CPU
// time, RSS) and the renderer settings every bench times with.
#pragma once

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include <cstdint>
#include <cstdlib>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/render.h"
#include "core/scene.h"

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

// 64-byte aligned array of n T (uninitialized), for Embree ray streams.
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

}  // namespace obscura::bench
