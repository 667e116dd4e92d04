// Issue #37: what Blender's compositor (3.4, Debian's `blender`) makes of a
// render, driven headless by tests/blender/composite_passes.py. Skipped,
// saying so, when `blender` is not on PATH, except in CI (clientsRequired:
// setup.sh test installs it), where that fails.
// - The error and sample-count layers (W_error.Y, spp.Y) are outputs of
//   the Image node, single values, and the composited pass equals the
//   file's channel bit for bit; under their earlier names (W.error, spp)
//   Blender's multilayer reader dropped them ("unknown channel token").
// docs/exr.md "Channels".
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <unistd.h>

#include "tests/support.h"

namespace obscura::test {
namespace {

// The blender program on PATH, or "".
std::string blenderOnPath() {
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "");
  for (std::string dir; std::getline(dirs, dir, ':');) {
    const std::string exe = (dir.empty() ? "." : dir) + "/blender";
    if (::access(exe.c_str(), X_OK) == 0) return exe;
  }
  return "";
}

std::string readText(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(Blender, CompositorShowsTheErrorAndSampleCountPasses) {
  const std::string blender = blenderOnPath();
  if (blender.empty()) {
    const char* why = "blender is not on PATH (Debian's package `blender` runs this check; setup.sh test installs it)";
    if (clientsRequired()) FAIL() << why;
    GTEST_SKIP() << why;
  }
  const std::string dir = tempDir("blender_passes");
  const int w = 32, h = 24;
  // Adaptive, so spp varies over the frame and the error is not constant.
  const CliResult r = runCli({"render", sourcePath("scenes/default.gltf"), "-o", dir + "/pass.exr", "--res",
                              std::to_string(w) + "x" + std::to_string(h), "--spp", "64", "--target-error", "0.05",
                              "--min-spp", "8", "-q"},
                             dir + "/render.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;

  const std::string log = dir + "/blender.txt";
  const std::string command = "timeout 600 '" + blender + "' -b --factory-startup -P '" +
                              sourcePath("tests/blender/composite_passes.py") + "' -- '" + dir + "/pass.exr' '" + dir +
                              "' " + std::to_string(w) + "x" + std::to_string(h) + " W_error spp > '" + log + "' 2>&1";
  const int status = std::system(command.c_str());
  const std::string said = readText(log);
  ASSERT_EQ(status, 0) << said;
  EXPECT_EQ(said.find("unknown channel token"), std::string::npos) << said;
  EXPECT_EQ(said.find("bad channel name"), std::string::npos) << said;

  // The Image node's outputs: name -> socket type.
  std::map<std::string, std::string> outputs;
  std::istringstream lines(readText(dir + "/outputs.txt"));
  for (std::string name, type; lines >> name >> type;) outputs[name] = type;
  EXPECT_EQ(outputs["W_error"], "VALUE");
  EXPECT_EQ(outputs["spp"], "VALUE");
  // The rest as before: R,G,B,A are Blender's Combined (with its Alpha), Z its Depth.
  EXPECT_EQ(outputs["Combined"], "RGBA");
  EXPECT_EQ(outputs["Depth"], "VALUE");
  EXPECT_EQ(outputs["N"], "RGBA");
  EXPECT_EQ(outputs["albedo"], "RGBA");

  const ReadBack file = readExr(dir + "/pass.exr");
  ASSERT_TRUE(file.ok);
  for (const auto& [socket, channel] : {std::pair<std::string, std::string>{"W_error", kErrorPlane}, {"spp", kSppPlane}}) {
    SCOPED_TRACE(socket);
    const ReadBack composited = readExr(dir + "/" + socket + ".exr");
    ASSERT_TRUE(composited.ok) << said;
    ASSERT_EQ(composited.spec.width, w);
    ASSERT_EQ(composited.spec.height, h);
    const std::vector<float>& got = composited.planes.at("R");
    const std::vector<float>& want = file.planes.at(channel);
    ASSERT_EQ(got.size(), want.size());
    // A value socket reaches the Composite node unchanged: bit for bit.
    size_t differ = 0;
    for (size_t i = 0; i < got.size(); ++i) differ += std::memcmp(&got[i], &want[i], sizeof(float)) != 0;
    EXPECT_EQ(differ, 0u) << "of " << got.size() << " pixels";
  }
  // The pass carries information: spp varies under adaptive sampling.
  const auto& spp = file.planes.at(kSppPlane);
  EXPECT_LT(*std::min_element(spp.begin(), spp.end()), *std::max_element(spp.begin(), spp.end()));
}

}  // namespace
}  // namespace obscura::test
