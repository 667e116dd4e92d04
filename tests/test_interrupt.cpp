// Ctrl-C on the CLI (README: exit code 130, one line, the output not
// written): the render loop polls the flag per chunk of samples, and a
// signal during loading or subdivision ends the process at once
// (app/interrupt.h). Each test spawns `obscura`, signals it after a delay and
// checks the exit code, the message, how long the process took to go after
// the signal, and that a good output file from before is untouched and no
// temporary is left beside it.
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "tests/support.h"

namespace obscura::test {
namespace {

using Clock = std::chrono::steady_clock;

// How long a process may take to end after SIGINT. What it does then is a
// relaxed load per chunk of 256 samples (microseconds) or write + _exit, so
// this is all scheduling slack: the machine running the suite may be shared
// and busy. Before per-chunk polling this render ran on for minutes.
constexpr double kMaxSecondsAfterSignal = 3.0;

struct Interrupted {
  CliResult result;
  double secondsAfterSignal = 0;
};

// Whether process `pid` catches SIGINT yet (its SigCgt mask in /proc): before
// main installs the handler a SIGINT would kill it outright, which is not
// what these tests are about. On a busy machine starting takes seconds.
bool catchesSigint(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("SigCgt:", 0) == 0) return (std::stoull(line.substr(7), nullptr, 16) >> (SIGINT - 1)) & 1;
  return false;
}

// Starts obscura with `args`, sends SIGINT `delay` after its handler is in
// place, waits for it.
Interrupted interruptAfter(const std::vector<std::string>& args, const std::string& stderrPath,
                           std::chrono::milliseconds delay) {
  Interrupted r;
  const pid_t pid = startCli(args, stderrPath, r.result);
  if (pid <= 0) ADD_FAILURE() << r.result.stderrText;
  for (int i = 0; i < 6000 && !catchesSigint(pid); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::this_thread::sleep_for(delay);
  const auto t0 = Clock::now();
  kill(pid, SIGINT);
  finishCli(pid, stderrPath, r.result);
  r.secondsAfterSignal = std::chrono::duration<double>(Clock::now() - t0).count();
  return r;
}

// `out` holds the bytes written before the run and nothing else is in its
// directory but `keep` (no temporary sibling left behind).
void expectUntouched(const std::string& out, const std::string& before, const std::vector<std::string>& keep) {
  const auto bytes = readBytes(out);
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), before);
  for (const auto& e : std::filesystem::directory_iterator(std::filesystem::path(out).parent_path())) {
    const std::string name = e.path().filename().string();
    EXPECT_TRUE(std::find(keep.begin(), keep.end(), name) != keep.end()) << "left behind: " << name;
  }
}

// The cube cage (support.h) as an OBJ file: slow to load at a high
// subdivision level, cheap to write.
void writeCubeObj(const std::string& path) {
  std::ostringstream obj;
  const SubdivisionCage cube = cubeCage();
  for (const Vec3& p : cube.positions) obj << "v " << p.x << " " << p.y << " " << p.z << "\n";
  size_t k = 0;
  for (const int n : cube.faceSizes) {
    obj << "f";
    for (int i = 0; i < n; ++i) obj << " " << cube.faceIndices[k++] + 1;
    obj << "\n";
  }
  writeText(path, obj.str());
}

// In the render loop: 16 tiles of 16x16 pixels at 10^7 samples each take
// far longer than the test, so only the per-chunk check can stop it soon.
TEST(Interrupt, RenderLoopStopsWithinAChunk) {
  const std::string dir = tempDir("interrupt_render");
  const std::string out = dir + "/pass.exr", before = "a good pass from an earlier render";
  writeText(out, before);
  const Interrupted r = interruptAfter({"render", "-o", out, "--res", "64x64", "--spp", "10000000", "-q"},
                                       dir + "/stderr.txt", std::chrono::milliseconds(2000));
  EXPECT_EQ(r.result.exitCode, 130) << "signal " << r.result.signal << ": " << r.result.stderrText;
  EXPECT_EQ(r.result.stderrText, "obscura: interrupted; " + out + " was not written\n");
  EXPECT_LT(r.secondsAfterSignal, kMaxSecondsAfterSignal);
  expectUntouched(out, before, {"pass.exr", "stderr.txt"});
}

// During loading: a cube cage refined to level 8 (393 k quads, about a
// second of OpenSubdiv and BVH work on an idle machine) rendered at 1 spp,
// so the load is nearly all of the run. A signal then cannot be polled; the process
// must still end at once with the message and exit code 130.
TEST(Interrupt, LoadingEndsAtOnce) {
  const std::string dir = tempDir("interrupt_loading");
  writeCubeObj(dir + "/cube.obj");
  const std::string out = dir + "/pass.exr", before = "a good pass from an earlier render";
  writeText(out, before);
  const std::vector<std::string> args = {"render", dir + "/cube.obj", "--subdiv", "catmull-clark", "--subdiv-level", "8",
                                         "-o", out, "--res", "8x8", "--spp", "1", "-q", "--camera", "auto"};
  const Interrupted r = interruptAfter(args, dir + "/stderr.txt", std::chrono::milliseconds(300));
  if (r.result.exitCode == 0) GTEST_SKIP() << "the render finished before the signal arrived";
  EXPECT_EQ(r.result.exitCode, 130) << "signal " << r.result.signal << ": " << r.result.stderrText;
  EXPECT_EQ(r.result.stderrText, "obscura: interrupted; " + out + " was not written\n");
  EXPECT_LT(r.secondsAfterSignal, kMaxSecondsAfterSignal);
  expectUntouched(out, before, {"pass.exr", "cube.obj", "stderr.txt"});
}

// Before any command runs (the handler is the first thing main installs):
// `compare` while it loads its scene, with results.csv from an earlier run.
TEST(Interrupt, CompareWhileLoadingKeepsEarlierResults) {
  const std::string dir = tempDir("interrupt_compare");
  std::filesystem::create_directories(dir + "/out");
  const std::string csv = dir + "/out/results.csv", before = "key,config\n";
  writeText(csv, before);
  writeCubeObj(dir + "/cube.obj");
  const Interrupted r = interruptAfter({"compare", dir + "/cube.obj", "--subdiv", "catmull-clark", "--subdiv-level", "8",
                                        "-o", dir + "/out", "-c", "ao", "--spp", "1", "--reference-spp", "2", "--res",
                                        "8x8", "-q", "--camera", "auto"},
                                       dir + "/stderr.txt", std::chrono::milliseconds(300));
  if (r.result.exitCode == 0) GTEST_SKIP() << "the comparison finished before the signal arrived";
  EXPECT_EQ(r.result.exitCode, 130) << "signal " << r.result.signal << ": " << r.result.stderrText;
  EXPECT_EQ(r.result.stderrText, "obscura: interrupted\n");
  EXPECT_LT(r.secondsAfterSignal, kMaxSecondsAfterSignal);
  expectUntouched(csv, before, {"results.csv"});
}

}  // namespace
}  // namespace obscura::test
