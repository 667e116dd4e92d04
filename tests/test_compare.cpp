// `obscura compare`: the error metrics on tiny images with known answers,
// the Pareto front, CONFIG parsing, and an end-to-end comparison in the
// spherical cavity, where the closed forms of docs/math.md §7 predict
// every config's bias and so the ranking.
#include <gtest/gtest.h>

#include <signal.h>

#include <chrono>
#include <cmath>
#include <thread>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "app/compare.h"
#include "app/report.h"
#include "core/error.h"
#include "core/metrics.h"
#include "integrators/multibounce_mapping.h"
#include "tests/gltf_builder.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// A w x h pass with W values `w` (one per pixel, grey) and coverage `a`.
PassImage grey(int w, int h, std::vector<float> W, std::vector<float> a = {}) {
  PassImage p;
  p.width = w, p.height = h;
  if (a.empty()) a.assign(W.size(), 1.0f);
  for (size_t i = 0; i < W.size(); ++i) {
    p.r.push_back(W[i] * a[i]), p.g.push_back(W[i] * a[i]), p.b.push_back(W[i] * a[i]);
    p.a.push_back(a[i]);
  }
  return p;
}

TEST(CompareMetrics, KnownAnswersOnATinyImage) {
  // Errors 0.1, -0.2, 0.3, 0 (per channel, grey) against a reference of 0.5.
  const PassImage ref = grey(2, 2, {0.5f, 0.5f, 0.5f, 0.5f});
  const PassImage test = grey(2, 2, {0.6f, 0.3f, 0.8f, 0.5f});
  const ErrorMetrics m = errorMetrics(test, ref);
  EXPECT_EQ(m.values, 12u);
  const double e[] = {0.6f - 0.5, 0.3f - 0.5, 0.8f - 0.5, 0.0};
  double se = 0, ae = 0, rel = 0;
  for (double x : e) se += x * x, ae += std::abs(x), rel += x * x / (0.25 + kRelMseEpsilon);
  EXPECT_DOUBLE_EQ(m.rmse, std::sqrt(se / 4));
  EXPECT_DOUBLE_EQ(m.mae, ae / 4);
  EXPECT_DOUBLE_EQ(m.relMse, rel / 4);
  // 12 values; nearest rank ceil(0.99 * 12) = 12: the largest |e|.
  EXPECT_DOUBLE_EQ(m.p99, std::abs(e[2]));
}

TEST(CompareMetrics, PercentileIsNearestRank) {
  // 100 pixels with |e| = 0.01 k, k = 0..99 (x 3 channels = 300 values):
  // rank ceil(0.99 * 300) = 297, the 297th smallest is k = 98.
  std::vector<float> W, R;
  for (int k = 0; k < 100; ++k) W.push_back(0.01f * float(k)), R.push_back(0.0f);
  const ErrorMetrics m = errorMetrics(grey(10, 10, W), grey(10, 10, R));
  EXPECT_FLOAT_EQ(float(m.p99), 0.98f);
}

TEST(CompareMetrics, OnlyFullyCoveredReferencePixelsCount) {
  // Pixel 1: reference coverage 1/2 (an edge): left out; pixel 2: the test
  // missed it entirely: left out. Un-premultiplied W is compared.
  const PassImage ref = grey(3, 1, {0.5f, 0.5f, 0.5f}, {1.0f, 0.5f, 1.0f});
  const PassImage test = grey(3, 1, {0.7f, 0.0f, 0.0f}, {0.5f, 1.0f, 0.0f});
  const ErrorMetrics m = errorMetrics(test, ref);
  EXPECT_EQ(m.values, 3u);
  EXPECT_NEAR(m.rmse, 0.2, 1e-6);
  EXPECT_THROW(errorMetrics(grey(1, 1, {0.5f}, {0.0f}), grey(1, 1, {0.5f})), Error);
  EXPECT_THROW(errorMetrics(grey(2, 1, {0.5f, 0.5f}), grey(1, 1, {0.5f})), Error);
}

TEST(CompareMetrics, BiasAndVarianceSplit) {
  // Two renders per pixel: ref + b +- s. Per value: mean = ref + b,
  // variance = (s^2 + s^2) / (2 - 1) = 2 s^2, bias2 = b^2 + 0 - variance / 2 + ...
  // i.e. mean (m - ref)^2 = b^2 exactly, so bias2 = b^2 - s^2.
  const float b = 0.1f, s = 0.05f;
  const PassImage ref = grey(2, 1, {0.4f, 0.6f});
  const std::vector<PassImage> renders = {grey(2, 1, {0.4f + b + s, 0.6f + b - s}), grey(2, 1, {0.4f + b - s, 0.6f + b + s})};
  const BiasVariance bv = biasVariance(renders, ref);
  EXPECT_NEAR(bv.variance, 2.0 * s * s, 1e-6);
  EXPECT_NEAR(bv.bias2, double(b) * b - double(s) * s, 1e-6);
  // Reference noise is removed too.
  EXPECT_NEAR(biasVariance(renders, ref, 0.02).bias2, double(b) * b - double(s) * s - 4e-4, 1e-6);
  // Halves differing by d: the mean's noise is |d| / 2.
  EXPECT_NEAR(referenceNoise(grey(1, 1, {0.5f}), grey(1, 1, {0.7f})), 0.1, 1e-6);
}

TEST(CompareReport, ParetoFrontAndTargets) {
  std::vector<ReportCell> cells(5);
  const double t[] = {1, 2, 3, 4, 0.5}, e[] = {0.3, 0.1, 0.2, 0.05, 0.5};
  for (size_t i = 0; i < 5; ++i) cells[i].seconds = t[i], cells[i].error.rmse = e[i];
  // By time: 0.5 s (0.5), 1 s (0.3), 2 s (0.1), 3 s (0.2: dominated), 4 s (0.05).
  EXPECT_EQ(paretoFront(cells), (std::vector<size_t>{4, 0, 1, 3}));
  EXPECT_EQ(fastestReaching(cells, 0.25), std::optional<size_t>(1));
  EXPECT_EQ(fastestReaching(cells, 0.05), std::optional<size_t>(3));
  EXPECT_EQ(fastestReaching(cells, 0.01), std::nullopt);
}

TEST(CompareConfig, ParsesAndCanonicalizes) {
  const CompareConfig a = parseCompareConfig("obscurance:falloff=sqrt,distance=0.5");
  EXPECT_EQ(a.integrator, "obscurance");
  EXPECT_EQ(a.assignments, (std::vector<std::string>{"falloff=sqrt", "distance=0.5"}));
  // Every parameter's value is in the key, so spelling out a default is the same config.
  EXPECT_EQ(parseCompareConfig("ao").canonical, parseCompareConfig("ao:distance=inf").canonical);
  EXPECT_NE(parseCompareConfig("ao").canonical, parseCompareConfig("ao:rays=2").canonical);
}

TEST(CompareConfig, BadStringsGiveAClearError) {
  for (const std::string bad : {"", ":", "nope", "nope:x=1", "ao:", "ao:distance", "ao:=1", "ao:distance=-1",
                                "ao:bogus=1", "ao:distance=1,", "transfer:depth=x", "multibounce:mapping=fancy"}) {
    try {
      parseCompareConfig(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("-c '" + bad + "'"), std::string::npos) << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
  }
  // Through the CLI: one error line, exit 1, nothing rendered.
  const std::string dir = tempDir("compare_bad");
  const CliResult r = runCli({"compare", "-o", dir + "/out", "-c", "ao", "-c", "transfer:depth=-1", "-q"}, dir + "/err.txt");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.stderrText.find("obscura: error: -c 'transfer:depth=-1'"), std::string::npos) << r.stderrText;
  EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out"));
}

// The cavity as a glTF file: albedo a everywhere, a camera at the centre
// looking at the wall opposite the hole.
std::string writeCavityGltf(const std::string& dir, double alpha, float a) {
  std::vector<Vec3> pos, nrm;
  std::vector<uint32_t> idx;
  sphereCavityMesh(1.0f, alpha, 128, 256, pos, nrm, idx);
  GltfBuilder g;
  const int material = g.push("materials", {{"pbrMetallicRoughness", {{"baseColorFactor", {a, a, a, 1.0f}}}}});
  const json prim = {{"attributes", {{"POSITION", g.positions(pos)}, {"NORMAL", g.vec3(nrm)}}},
                     {"indices", g.indices(idx)},
                     {"material", material}};
  g.push("meshes", {{"primitives", json::array({prim})}});
  g.push("cameras", {{"type", "perspective"}, {"perspective", {{"yfov", 1.2}, {"znear", 0.001}, {"aspectRatio", 1.0}}}});
  g.scene({g.node({{"mesh", 0}}), g.node({{"camera", 0}, {"name", "centre"}})});
  return g.writeGltf(dir, "cavity");
}

// In the cavity (f = 1/4, a = 0.85) every wall point has the same W: gi and
// transfer (R = inf) estimate f / (1 - a(1 - f)) without bias (transfer's
// ratio bias is O(1/n)), AO is f, and multibounce (GTAO) is
// gtao(f, a) - so the bias^2 of each config is known. The test checks
// those within tolerance and the ranking they imply, then that a second
// run with one more spp keeps the finished cells.
TEST(CompareEndToEnd, CavityRankingFollowsTheClosedForms) {
  const std::string dir = tempDir("compare_cavity");
  const double alpha = 1.0471975511965976, f = 0.25;
  const float a = 0.85f;
  const std::string scene = writeCavityGltf(dir, alpha, a);
  const std::vector<std::string> args = {"compare", scene, "-o", dir + "/out", "--res", "24x24", "--reference-spp", "256",
                                         "--seeds", "2", "--robust", "-q", "-c", "ao", "-c", "multibounce", "-c",
                                         "transfer:rays=4", "-c", "gi"};
  std::vector<std::string> first = args;
  first.insert(first.end(), {"--spp", "64"});
  const CliResult r1 = runCli(first, dir + "/err1.txt");
  ASSERT_EQ(r1.exitCode, 0) << r1.stderrText;
  for (const char* file : {"results.csv", "results.json", "error_vs_time.svg", "contact_sheet.svg", "contact_sheet.png",
                           "heatmaps/ao.png", "heatmaps/gi.png", "heatmaps/transfer_rays=4.png", "previews/reference.png"})
    EXPECT_TRUE(std::filesystem::exists(dir + "/out/" + file)) << file;

  std::ifstream in(dir + "/out/results.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  std::map<std::string, nlohmann::json> cell;
  for (const auto& c : j["cells"]) cell[c["config"].get<std::string>()] = c;
  ASSERT_EQ(cell.size(), 4u);
  const double refNoise = j["reference"]["noiseRmse"].get<double>();
  EXPECT_GT(refNoise, 0.0);
  EXPECT_LT(refNoise, 0.05);
  // Expected bias^2 against the exact W. The measured bias^2 is against the
  // (noisy) reference, which the code corrects for; what remains is the
  // estimate's own scatter: for a per-value bias b and per-value noise of
  // the seed mean and the reference (variance v), mean over N pixels of
  // (b + noise)^2 has standard error ~ (2|b| sqrt(v) + v sqrt(2)) / sqrt(N).
  // RGB are equal here, so N = pixels. Plus the tessellation (128 x 256:
  // f moves by D^2, D = 2 pi / 256) through each closed form.
  const double N = 24.0 * 24.0, D2 = std::pow(2 * M_PI / 256, 2);
  const auto check = [&](const std::string& name, double b, double dbdf) {
    const auto& c = cell.at(name);
    const double v = c["variance"].get<double>() / 2 + refNoise * refNoise;
    const double bias = std::abs(b) + std::abs(dbdf) * D2;
    const double tol = 4 * (2 * bias * std::sqrt(v) + v * std::sqrt(2.0)) / std::sqrt(N) + 2 * std::abs(b) * std::abs(dbdf) * D2 + dbdf * dbdf * D2 * D2;
    EXPECT_NEAR(c["bias2"].get<double>(), b * b, tol) << name;
  };
  // Each config's bias as a function of f, and its slope (central difference).
  const auto Wf = [&](double x) { return x / (1 - a * (1 - x)); };
  const auto slope = [](auto fn, double x) { return (fn(x + 1e-6) - fn(x - 1e-6)) / 2e-6; };
  const auto aoBias = [&](double x) { return x - Wf(x); };
  const auto mbBias = [&](double x) { return gtaoMultiBounce(x, a) - Wf(x); };
  check("ao", aoBias(f), slope(aoBias, f));
  check("multibounce", mbBias(f), slope(mbBias, f));
  check("gi", 0.0, 0.0);
  // The ranking at equal spp: gi and transfer << multibounce << ao.
  const auto rmse = [&](const std::string& n) { return cell.at(n)["rmse"].get<double>(); };
  EXPECT_LT(rmse("transfer:rays=4"), rmse("multibounce"));
  EXPECT_LT(rmse("gi"), rmse("multibounce"));
  EXPECT_LT(rmse("multibounce"), rmse("ao"));

  // Resume: one more spp; the 64-spp cells are kept, not recomputed.
  const auto passTime = std::filesystem::last_write_time(dir + "/out/passes/ao@64.exr");
  std::vector<std::string> second = args;
  second.insert(second.end(), {"--spp", "16,64"});
  second.erase(std::find(second.begin(), second.end(), "-q"));
  const CliResult r2 = runCli(second, dir + "/err2.txt");
  ASSERT_EQ(r2.exitCode, 0) << r2.stderrText;
  EXPECT_NE(r2.stderrText.find("reference: cached"), std::string::npos) << r2.stderrText;
  size_t kept = 0;
  for (size_t p = r2.stderrText.find("(kept)"); p != std::string::npos; p = r2.stderrText.find("(kept)", p + 1)) ++kept;
  EXPECT_EQ(kept, 4u) << r2.stderrText;
  EXPECT_EQ(std::filesystem::last_write_time(dir + "/out/passes/ao@64.exr"), passTime);
  std::ifstream csv(dir + "/out/results.csv");
  size_t rows = 0;
  for (std::string line; std::getline(csv, line);) ++rows;
  EXPECT_EQ(rows, 1u + 8u);

  // The cached reference given with --reference: the same numbers.
  std::string cached;
  for (const auto& e : std::filesystem::directory_iterator(dir + "/out/cache")) cached = e.path().string();
  const CliResult r3 = runCli({"compare", scene, "-o", dir + "/given", "--res", "24x24", "--reference", cached, "--seeds",
                               "2", "--robust", "-q", "-c", "ao", "--spp", "64"},
                              dir + "/err3.txt");
  ASSERT_EQ(r3.exitCode, 0) << r3.stderrText;
  std::ifstream in3(dir + "/given/results.json");
  const nlohmann::json j3 = nlohmann::json::parse(in3);
  EXPECT_EQ(j3["cells"][0]["rmse"].get<double>(), cell.at("ao")["rmse"].get<double>());
  EXPECT_EQ(j3["reference"]["noiseRmse"].get<double>(), refNoise);
  // A reference of another size is refused with one line.
  const CliResult r4 = runCli({"compare", scene, "-o", dir + "/bad", "--res", "32x32", "--reference", cached, "-c", "ao"},
                              dir + "/err4.txt");
  EXPECT_EQ(r4.exitCode, 1);
  EXPECT_NE(r4.stderrText.find("is 24x24 but --res is 32x32"), std::string::npos) << r4.stderrText;
}

// Ctrl-C: the run stops with exit code 130, says so, and results.csv holds
// the cells that finished (complete rows only); running again keeps them.
TEST(CompareEndToEnd, InterruptKeepsFinishedCellsAndResumes) {
  const std::string dir = tempDir("compare_interrupt");
  const std::vector<std::string> args = {"compare", "-o", dir + "/out", "--res", "64x36", "--reference-spp", "8",
                                         "--spp", "1,2,4,8,16,32,64,128,256", "-c", "ao", "-c", "gi", "-q"};
  CliResult r;
  const pid_t pid = startCli(args, dir + "/err1.txt", r);
  ASSERT_GT(pid, 0) << r.stderrText;
  // Wait (up to 60 s) until at least two cells are in results.csv.
  const auto rows = [&] {
    std::ifstream in(dir + "/out/results.csv");
    size_t n = 0;
    for (std::string line; std::getline(in, line);) ++n;
    return n > 0 ? n - 1 : 0;
  };
  for (int i = 0; i < 1200 && rows() < 2; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_GE(rows(), 2u);
  kill(pid, SIGINT);
  finishCli(pid, dir + "/err1.txt", r);
  const size_t kept = rows();
  if (r.exitCode == 0) GTEST_SKIP() << "the run finished before the signal arrived";
  EXPECT_EQ(r.exitCode, 130) << r.stderrText;
  EXPECT_NE(r.stderrText.find("interrupted; " + std::to_string(kept) + " finished cell"), std::string::npos)
      << r.stderrText;
  EXPECT_LT(kept, 18u);
  // Every kept row is complete (15 fields) and its pass exists.
  {
    std::ifstream in(dir + "/out/results.csv");
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) EXPECT_GE(std::count(line.begin(), line.end(), ','), 14) << line;
  }
  std::vector<std::string> again = args;
  again.erase(std::find(again.begin(), again.end(), "-q"));
  const CliResult r2 = runCli(again, dir + "/err2.txt");
  ASSERT_EQ(r2.exitCode, 0) << r2.stderrText;
  size_t reused = 0;
  for (size_t p = r2.stderrText.find("(kept)"); p != std::string::npos; p = r2.stderrText.find("(kept)", p + 1)) ++reused;
  EXPECT_EQ(reused, kept) << r2.stderrText;
  EXPECT_EQ(rows(), 18u);
  // The finished run on the default scene wrote the whole report.
  for (const char* file : {"results.json", "summary.md", "error_vs_time.svg", "contact_sheet.svg", "contact_sheet.png",
                           "heatmaps/ao.png", "heatmaps/gi.png", "previews/reference.png", "passes/gi@256.exr"})
    EXPECT_TRUE(std::filesystem::exists(dir + "/out/" + file)) << file;
  const auto summary = readBytes(dir + "/out/summary.md");
  EXPECT_NE(std::string(summary.begin(), summary.end()).find("fastest config reaching it"), std::string::npos);
}

}  // namespace
}  // namespace obscura::test
