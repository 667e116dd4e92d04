// The screen-space integrators from the command line (issue 12's "done
// when"): every option of `vo`, `ssat` and `gtao` renders the bundled scene, the
// third-party glTF scenes render with them, and `compare` runs them beside
// `ao` and `gi`. Each output is a finished EXR whose pass is finite and in
// [0, 1] wherever the pixel is covered.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "tests/support.h"

namespace obscura::test {
namespace {

const std::string kDefaultScene = sourcePath("scenes/default.gltf");

// Each option of the integrators away from its default at least once (the
// defaults themselves are the first of each list).
const std::vector<std::vector<std::string>> kConfigs = {
    {"-i", "vo"},
    {"-i", "vo", "-p", "samples=point"},
    {"-i", "vo", "-p", "samples=area", "-p", "centre=false"},
    {"-i", "vo", "-p", "radius=0.3", "-p", "radius2=1.5", "-p", "combine=min"},
    {"-i", "vo", "-p", "radius2=0.5", "-p", "combine=product", "-p", "normal=false"},
    {"-i", "vo", "-p", "thickness=0.2", "-p", "count=33", "-p", "interleave=on", "-p", "filter-depth=0.05"},
    {"-i", "vo", "-p", "samples=point", "-p", "depth=traced"},
    {"-i", "vo", "-p", "depth=traced", "-p", "count=6"},
    {"-i", "ssat"},
    {"-i", "ssat", "-p", "albedo=true", "-p", "falloff=linear"},
    {"-i", "ssat", "-p", "silhouette=false", "-p", "falloff=sqrt", "-p", "steps=2"},
    {"-i", "ssat", "-p", "falloff=exponential", "-p", "sigma=3", "-p", "distance=inf"},
    {"-i", "ssat", "-p", "interleave=off", "-p", "count=7", "-p", "filter-depth=0"},
    {"-i", "ssat", "-p", "depth=traced", "-p", "albedo=true"},
    {"-i", "gtao"},
    {"-i", "gtao", "-p", "radius=0.3", "-p", "slices=2", "-p", "steps=16", "-p", "multibounce=on"},
    {"-i", "gtao", "-p", "interleave=off", "-p", "filter-depth=0", "-p", "depth=traced", "-p", "e0=bent"},
};

std::string describe(const std::vector<std::string>& args) {
  std::string s;
  for (const std::string& a : args) s += (s.empty() ? "" : " ") + a;
  return s;
}

// The pass of a finished render: R, G, B finite and in [0, 1] where A > 0.
void expectValidPass(const std::string& path, const std::string& what) {
  const ReadBack r = readExr(path);
  ASSERT_TRUE(r.ok) << what;
  const std::vector<float>& A = r.planes.at("A");
  size_t covered = 0;
  for (const char* c : {"R", "G", "B"}) {
    const std::vector<float>& v = r.planes.at(c);
    for (size_t i = 0; i < v.size(); ++i) {
      if (!(A[i] > 0.0f)) continue;
      covered += c[0] == 'R';
      // Premultiplied by coverage: within [0, A].
      ASSERT_TRUE(std::isfinite(v[i]) && v[i] >= 0.0f && v[i] <= A[i] * (1.0f + 1e-6f))
          << what << ": " << c << "[" << i << "] = " << v[i] << ", A = " << A[i];
    }
  }
  EXPECT_GT(covered, 0u) << what << ": no pixel covered";
}

void renderAll(const std::string& scene, const std::vector<std::vector<std::string>>& configs,
               const std::string& dirName) {
  const std::string dir = tempDir(dirName);
  std::vector<std::vector<std::string>> runs;
  for (size_t k = 0; k < configs.size(); ++k) {
    std::vector<std::string> args = {"render", scene, "--res", "48x27", "--spp", "2", "-q",
                                     "-o", dir + "/out" + std::to_string(k) + ".exr"};
    args.insert(args.end(), configs[k].begin(), configs[k].end());
    runs.push_back(args);
  }
  const std::vector<CliResult> results = runClis(runs, dir);
  for (size_t k = 0; k < configs.size(); ++k) {
    const std::string what = scene + " " + describe(configs[k]);
    EXPECT_EQ(results[k].exitCode, 0) << what << ": " << results[k].stderrText;
    if (results[k].exitCode == 0) expectValidPass(dir + "/out" + std::to_string(k) + ".exr", what);
  }
}

TEST(ScreenSpaceCli, EveryOptionRendersTheBundledScene) { renderAll(kDefaultScene, kConfigs, "sscli_default"); }

TEST(ScreenSpaceCli, ThirdPartyScenesRender) {
  // Every glTF scene of ../shared/scenes, with a line, an area and a
  // transfer configuration (the scenes' scales differ: R = 0.1 is small in
  // each, so the passes have contrast).
  const std::vector<std::vector<std::string>> configs = {
      {"-i", "vo", "-p", "radius=0.1"},
      {"-i", "vo", "-p", "samples=area", "-p", "radius=0.1"},
      {"-i", "ssat", "-p", "distance=0.1", "-p", "albedo=true"},
  };
  for (const char* rel : {"cornell_box_classic/cornell-box.gltf", "cornell_box_suzanne/cornell-box.glb",
                          "damaged_helmet/DamagedHelmet.gltf", "suzanne/Suzanne.gltf", "viking_room/viking_room.glb"}) {
    const std::string path = sharedScene(rel);
    OBSCURA_NEED_SHARED_SCENE(path);
    std::string name = rel;
    name = "sscli_" + name.substr(0, name.find('/'));
    renderAll(path, configs, name);
  }
}

TEST(ScreenSpaceCli, CompareRunsThemBesideAoAndGi) {
  const std::string dir = tempDir("sscli_compare");
  const CliResult r = runCli({"compare", kDefaultScene, "-o", dir + "/out", "--res", "24x16", "--spp", "2",
                              "--reference-spp", "16", "--seeds", "1", "-q", "-c", "ao", "-c", "vo",
                              "-c", "vo:samples=area", "-c", "ssat", "-c", "ssat:albedo=true", "-c", "gi"},
                             dir + "/err.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  std::ifstream csv(dir + "/out/results.csv");
  ASSERT_TRUE(csv) << "no results.csv";
  std::string text((std::istreambuf_iterator<char>(csv)), std::istreambuf_iterator<char>());
  for (const char* config : {"ao", "vo", "vo:samples=area", "ssat", "ssat:albedo=true", "gi"})
    EXPECT_NE(text.find(",\"" + std::string(config) + "\","), std::string::npos) << config << " missing from\n" << text;
}

}  // namespace
}  // namespace obscura::test
