// `obscura compare`: the error metrics on tiny images with known answers,
// the Pareto front, CONFIG parsing, and an end-to-end comparison in the
// spherical cavity, where the closed forms of docs/math.md §7 predict
// every config's bias and so the ranking.
#include <gtest/gtest.h>

#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <thread>
#include <filesystem>
#include <fstream>
#include <regex>
#include <nlohmann/json.hpp>

#include "app/bitmap_font.h"
#include "app/compare.h"
#include "app/report.h"
#include <obscura/error.h>
#include "core/image/metrics.h"
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

// flipError's inputs (core/image/metrics.h): LDR-FLIP sees the pass clamped
// to [0, 1] as its preview shows it, HDR-FLIP the linear values; only the
// compared pixels are averaged.
TEST(CompareMetrics, FlipSeesThePreviewForLdrAndTheLinearPassForHdr) {
  const PassImage white = grey(8, 8, std::vector<float>(64, 1.0f)), bright = grey(8, 8, std::vector<float>(64, 3.0f));
  const FlipError f = flipError(bright, white, kFlipDefaultPpd, true);
  EXPECT_EQ(f.ldr, 0.0);  // both previews are white
  EXPECT_GT(f.hdr, 0.1);  // 1.6 stops apart in the linear pass
  // The uniform pair's HDR value is the same at every pixel: the mean is it.
  EXPECT_NEAR(f.hdr, f.hdrMap[27], 1e-6);
  // A pixel the reference does not cover is not averaged and reads 0 in the map.
  std::vector<float> a(64, 1.0f);
  a[0] = 0.0f;
  const PassImage holed = grey(8, 8, std::vector<float>(64, 1.0f), a);
  const FlipError g = flipError(bright, holed, kFlipDefaultPpd, true);
  EXPECT_EQ(g.ldrMap[0], 0.0f);
  EXPECT_EQ(g.hdrMap[0], 0.0f);
  EXPECT_GT(g.hdrMap[63], 0.1f);
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

TEST(CompareReport, FlipTargetsReadTheFlipColumnNotRmse) {
  std::vector<ReportCell> cells(3);
  const double t[] = {1, 2, 3}, rmse[] = {0.05, 0.5, 0.5}, flip[] = {0.4, 0.1, 0.05};
  for (size_t i = 0; i < 3; ++i) cells[i].seconds = t[i], cells[i].error.rmse = rmse[i], cells[i].flip = flip[i];
  EXPECT_EQ(fastestReaching(cells, 0.1, TargetMeasure::Rmse), std::optional<size_t>(0));
  EXPECT_EQ(fastestReaching(cells, 0.1, TargetMeasure::Flip), std::optional<size_t>(1));
  EXPECT_EQ(fastestReaching(cells, 0.06, TargetMeasure::Flip), std::optional<size_t>(2));
  EXPECT_EQ(fastestReaching(cells, 0.01, TargetMeasure::Flip), std::nullopt);
}

TEST(CompareConfig, ParsesAndCanonicalizes) {
  const CompareConfig a = parseCompareConfig("obscurance:falloff=sqrt,distance=0.5");
  EXPECT_EQ(a.integrator, "obscurance");
  EXPECT_EQ(a.assignments, (std::vector<std::string>{"falloff=sqrt", "distance=0.5"}));
  // Every parameter's value is in the key, so spelling out a default is the same config.
  EXPECT_EQ(parseCompareConfig("ao").canonical, parseCompareConfig("ao:distance=inf").canonical);
  EXPECT_NE(parseCompareConfig("ao").canonical, parseCompareConfig("ao:rays=2").canonical);
  // Render settings beside the parameters: taken out, kept, and in the key
  // only when they change the render (a plain config keeps its old key).
  const CompareConfig t = parseCompareConfig("ao:distance=1,target=0.02,min-spp=8,denoise=on");
  EXPECT_EQ(t.assignments, (std::vector<std::string>{"distance=1"}));
  EXPECT_DOUBLE_EQ(t.targetError, 0.02);
  EXPECT_EQ(t.minSpp, 8);
  EXPECT_TRUE(t.denoise);
  EXPECT_EQ(parseCompareConfig("ao:denoise=off").canonical, parseCompareConfig("ao").canonical);
  EXPECT_FALSE(parseCompareConfig("ao:denoise=off").denoise);
  EXPECT_NE(parseCompareConfig("ao:denoise=on").canonical, parseCompareConfig("ao").canonical);
  EXPECT_NE(parseCompareConfig("ao:target=0.02").canonical, parseCompareConfig("ao:target=0.01").canonical);
  EXPECT_EQ(parseCompareConfig("ao:target=0.02").canonical, parseCompareConfig("ao:target=2e-2").canonical);
  EXPECT_NE(parseCompareConfig("ao:target=0.02").canonical, parseCompareConfig("ao:target=0.02,min-spp=4").canonical);
  EXPECT_TRUE(parseCompareConfig("ao:target=0.02").assignments.empty());
}

TEST(CompareConfig, BadStringsGiveAClearError) {
  for (const std::string bad : {"", ":", "nope", "nope:x=1", "ao:", "ao:distance", "ao:=1", "ao:distance=-1",
                                "ao:bogus=1", "ao:distance=1,", "transfer:depth=x", "multibounce:mapping=fancy",
                                "ao:target=-1", "ao:target=0", "ao:target=x", "ao:target=", "ao:denoise=maybe",
                                "ao:min-spp=8", "ao:target=0.1,min-spp=0", "ao:target=0.1,target=0.2",
                                "ao:target=0.1,bogus=1", "ao:target=0.1,", "nope:target=0.1"}) {
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
  for (const std::string bad : {"ao:target=-1", "ao:denoise=maybe"}) {
    const CliResult b = runCli({"compare", "-o", dir + "/out", "-c", "ao", "-c", bad, "-q"}, dir + "/err2.txt");
    EXPECT_EQ(b.exitCode, 1);
    EXPECT_NE(b.stderrText.find("obscura: error: -c '" + bad + "': " + bad.substr(3, bad.find('=') - 3)),
              std::string::npos)
        << b.stderrText;
    EXPECT_EQ(std::count(b.stderrText.begin(), b.stderrText.end(), '\n'), 1) << b.stderrText;
    EXPECT_FALSE(std::filesystem::exists(dir + "/out"));
  }
}

// The cells a compare run kept from an earlier one (its "(kept)" lines).
size_t keptCells(const std::string& stderrText) {
  size_t n = 0;
  for (size_t p = stderrText.find("(kept)"); p != std::string::npos; p = stderrText.find("(kept)", p + 1)) ++n;
  return n;
}

// `args` run again without -q, so the progress lines show what is kept.
CliResult runVerbose(std::vector<std::string> args, const std::string& stderrPath) {
  args.erase(std::find(args.begin(), args.end(), "-q"));
  return runCli(args, stderrPath);
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
  const CliResult r2 = runVerbose(second, dir + "/err2.txt");
  ASSERT_EQ(r2.exitCode, 0) << r2.stderrText;
  EXPECT_NE(r2.stderrText.find("reference: cached"), std::string::npos) << r2.stderrText;
  EXPECT_EQ(keptCells(r2.stderrText), 4u) << r2.stderrText;
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

// results.csv as rows of named fields (header line first).
std::vector<std::map<std::string, std::string>> readCsvRows(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::vector<std::map<std::string, std::string>> rows;
  const auto split = [](const std::string& l) {  // quoted fields with "" escapes
    std::vector<std::string> f(1);
    bool q = false;
    for (size_t i = 0; i < l.size(); ++i) {
      if (q && l[i] == '"' && i + 1 < l.size() && l[i + 1] == '"') f.back() += '"', ++i;
      else if (l[i] == '"') q = !q;
      else if (!q && l[i] == ',') f.emplace_back();
      else f.back() += l[i];
    }
    return f;
  };
  if (!std::getline(in, line)) return rows;
  const std::vector<std::string> names = split(line);
  while (std::getline(in, line)) {
    const std::vector<std::string> f = split(line);
    std::map<std::string, std::string> row;
    for (size_t i = 0; i < names.size() && i < f.size(); ++i) row[names[i]] = f[i];
    rows.push_back(row);
  }
  return rows;
}

// A plain config, an adaptive one (target=) and a denoised one on the
// default scene: results.csv carries the settings and what they took, the
// adaptive cell takes fewer samples than its maximum, the denoised cell's
// time includes the filter, the headers record both, and the "fastest cell
// per RMSE target" of results.json is the one an independent scan of the
// CSV rows finds.
TEST(CompareEndToEnd, TargetAndDenoiseConfigs) {
  const std::string dir = tempDir("compare_target_denoise");
  const std::vector<std::string> args = {"compare", "-o", dir + "/out", "--res", "32x18", "--reference-spp", "16",
                                         "--spp", "8,64", "-q", "-c", "ao", "-c", "ao:target=0.1", "-c",
                                         "ao:denoise=on"};
  const CliResult r1 = runCli(args, dir + "/err1.txt");
  ASSERT_EQ(r1.exitCode, 0) << r1.stderrText;
  const auto rows = readCsvRows(dir + "/out/results.csv");
  ASSERT_EQ(rows.size(), 6u);
  std::map<std::string, std::map<std::string, std::string>> cell;  // "config@spp"
  for (const auto& row : rows) {
    for (const char* col : {"target", "min_spp", "denoise", "mean_spp", "denoise_s", "time_s", "rmse"})
      EXPECT_TRUE(row.count(col)) << col;
    cell[row.at("config") + "@" + row.at("spp")] = row;
  }
  // Plain: every pixel takes spp; no target, no denoiser.
  EXPECT_EQ(std::stod(cell.at("ao@64").at("mean_spp")), 64.0);
  EXPECT_EQ(cell.at("ao@64").at("target"), "");
  EXPECT_EQ(cell.at("ao@64").at("denoise"), "off");
  // Adaptive: ao's W is a mean of 0/1 values, so a pixel's standard error
  // after n samples is at most 0.5 / sqrt(n) (less with stratification):
  // at n >= 25 every pixel is below 0.1, so the cell cannot take all 64.
  const auto& t = cell.at("ao:target=0.1@64");
  EXPECT_EQ(std::stod(t.at("target")), 0.1);
  const double meanSpp = std::stod(t.at("mean_spp"));
  EXPECT_LT(meanSpp, 64.0);
  EXPECT_GE(meanSpp, 16.0);  // the first round: min(16, spp) samples (docs/sampling.md "Adaptive sampling")
  {
    const ReadBack b = readExr(dir + "/out/" + t.at("pass"));
    ASSERT_TRUE(b.ok);
    EXPECT_FLOAT_EQ(b.spec.get_float_attribute("obscura:targetError"), 0.1f);
    EXPECT_NEAR(b.spec.get_float_attribute("obscura:meanSpp"), meanSpp, 1e-3 * meanSpp);
    EXPECT_EQ(b.spec.get_int_attribute("obscura:spp"), 64);
  }
  // Denoised: the filter ran, its time is inside the cell's time.
  const auto& d = cell.at("ao:denoise=on@64");
  EXPECT_EQ(d.at("denoise"), "on");
  const double ds = std::stod(d.at("denoise_s"));
  EXPECT_GT(ds, 0.0);
  EXPECT_GE(std::stod(d.at("time_s")), ds);
  {
    const ReadBack b = readExr(dir + "/out/" + d.at("pass"));
    ASSERT_TRUE(b.ok);
    EXPECT_EQ(b.spec.get_string_attribute("obscura:denoise"), "atrous");
    EXPECT_FLOAT_EQ(b.spec.get_float_attribute("obscura:denoiseTime"), float(ds));
  }

  // The fastest cell per target: run again (every cell kept) with targets at
  // each cell's RMSE, so each is reached, and one below them all.
  std::string targets;
  double lowest = INFINITY;
  for (const auto& row : rows) {
    targets += (targets.empty() ? "" : ",") + row.at("rmse");
    lowest = std::min(lowest, std::stod(row.at("rmse")));
  }
  targets += "," + std::to_string(lowest / 2);
  std::vector<std::string> again = args;
  again.insert(again.end(), {"--targets", targets});
  const CliResult r2 = runCli(again, dir + "/err2.txt");
  ASSERT_EQ(r2.exitCode, 0) << r2.stderrText;
  std::ifstream in(dir + "/out/results.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  ASSERT_EQ(j["targets"].size(), rows.size() + 1);
  size_t none = 0;
  for (const auto& e : j["targets"]) {
    const double target = e["rmse"].get<double>();
    // Independently: the least time among the CSV rows with RMSE <= target.
    double best = INFINITY;
    for (const auto& row : rows)
      if (std::stod(row.at("rmse")) <= target) best = std::min(best, std::stod(row.at("time_s")));
    if (!std::isfinite(best)) {
      EXPECT_TRUE(e["fastest"].is_null()) << target;
      ++none;
      continue;
    }
    ASSERT_FALSE(e["fastest"].is_null()) << target;
    const auto& row = cell.at(e["fastest"]["config"].get<std::string>() + "@" + std::to_string(e["fastest"]["spp"].get<int>()));
    EXPECT_LE(std::stod(row.at("rmse")), target);
    EXPECT_EQ(std::stod(row.at("time_s")), best) << target;
    EXPECT_DOUBLE_EQ(e["fastest"]["seconds"].get<double>(), best) << target;
  }
  EXPECT_EQ(none, 1u);
  const auto summary = readBytes(dir + "/out/summary.md");
  EXPECT_NE(std::string(summary.begin(), summary.end()).find("not reached"), std::string::npos);

  // A results.csv of the format before these columns (its first 15; the
  // five settings columns, the three FLIP columns and the six per-seed and
  // interval columns cut) is still read: the plain cells are kept (their
  // FLIP taken from their one-seed pass), the others recomputed.
  {
    std::ifstream csv(dir + "/out/results.csv");
    std::string header, line, old;
    std::getline(csv, header);
    old = header.substr(0, header.find(",target,")) + "\n";
    while (std::getline(csv, line))
      if (line.find("target=") == std::string::npos && line.find("denoise=") == std::string::npos) {
        size_t cut = line.size();
        // Every column after the first 15 (the quoted fields before them hold no ',' here).
        const size_t later = size_t(std::count(header.begin(), header.end(), ',')) - 14;
        for (size_t k = 0; k < later; ++k) cut = line.rfind(',', cut - 1);
        old += line.substr(0, cut) + "\n";
      }
    std::ofstream(dir + "/out/results.csv") << old;
  }
  const CliResult r3 = runVerbose(args, dir + "/err3.txt");
  ASSERT_EQ(r3.exitCode, 0) << r3.stderrText;
  EXPECT_EQ(keptCells(r3.stderrText), 2u) << r3.stderrText;
  EXPECT_EQ(readCsvRows(dir + "/out/results.csv").size(), 6u);
}

// FLIP in compare (docs/compare.md "FLIP"): every cell's flip and flip_hdr
// are the FLIP of its pass (passes/) against the cached reference, recomputed
// here from those files; each cell has its two heat maps; the "fastest cell
// per FLIP target" is the one a scan of the CSV finds; another --flip-ppd
// keeps the one-seed cells and recomputes their FLIP at it; a bad value is
// one error line naming the option.
TEST(CompareEndToEnd, FlipColumnsHeatMapsAndTargets) {
  const std::string dir = tempDir("compare_flip");
  const std::vector<std::string> args = {"compare", "-o", dir + "/out", "--res", "32x18", "--reference-spp", "16",
                                         "--spp", "4,32", "-q", "-c", "ao", "-c", "gi", "--targets-flip", "0.5,0.15,1e-6"};
  const CliResult r1 = runCli(args, dir + "/err1.txt");
  ASSERT_EQ(r1.exitCode, 0) << r1.stderrText;
  std::string cached;
  for (const auto& e : std::filesystem::directory_iterator(dir + "/out/cache")) cached = e.path().string();
  const PassImage ref = readPass(cached);
  const auto check = [&](double ppd) {
    const auto rows = readCsvRows(dir + "/out/results.csv");
    std::ifstream in(dir + "/out/results.json");
    const nlohmann::json j = nlohmann::json::parse(in);
    EXPECT_NEAR(j["flipPpd"].get<double>(), ppd, 1e-9);
    EXPECT_EQ(rows.size(), 4u);
    EXPECT_EQ(j["cells"].size(), rows.size());
    for (size_t k = 0; k < rows.size(); ++k) {
      const auto& row = rows[k];
      const FlipError f = flipError(readPass(dir + "/out/" + row.at("pass")), ref, ppd);
      // The CSV keeps 9 significant digits.
      EXPECT_NEAR(std::stod(row.at("flip")), f.ldr, 1e-8 * f.ldr) << row.at("config");
      EXPECT_NEAR(std::stod(row.at("flip_hdr")), f.hdr, 1e-8 * f.hdr) << row.at("config");
      EXPECT_NEAR(std::stod(row.at("flip_ppd")), ppd, 1e-7 * ppd);
      EXPECT_GT(f.ldr, 0.0);
      EXPECT_LT(f.ldr, 1.0);
      const nlohmann::json& c = j["cells"][k];
      EXPECT_DOUBLE_EQ(c["flip"].get<double>(), f.ldr);
      for (const char* map : {"flipHeatmap", "flipHdrHeatmap"})
        EXPECT_TRUE(std::filesystem::exists(dir + "/out/" + c[map].get<std::string>())) << c[map];
    }
    // More samples of the same config: less noise, lower FLIP.
    EXPECT_LT(std::stod(rows[1].at("flip")), std::stod(rows[0].at("flip")));
    EXPECT_LT(std::stod(rows[3].at("flip")), std::stod(rows[2].at("flip")));
    ASSERT_EQ(j["flipTargets"].size(), 3u);
    for (const auto& t : j["flipTargets"]) {
      double best = INFINITY;
      std::string bestConfig;
      for (const auto& row : rows)
        if (std::stod(row.at("flip")) <= t["flip"].get<double>() && std::stod(row.at("time_s")) < best)
          best = std::stod(row.at("time_s")), bestConfig = row.at("config");
      if (std::isinf(best)) {
        EXPECT_TRUE(t["fastest"].is_null()) << t;
      } else {
        ASSERT_FALSE(t["fastest"].is_null()) << t;
        EXPECT_EQ(t["fastest"]["config"].get<std::string>(), bestConfig);
        EXPECT_DOUBLE_EQ(t["fastest"]["seconds"].get<double>(), best);
      }
    }
    EXPECT_TRUE(j["flipTargets"][2]["fastest"].is_null());  // 1e-6: no noisy pass looks the same
  };
  check(kFlipDefaultPpd);
  const auto summary = readBytes(dir + "/out/summary.md");
  EXPECT_NE(std::string(summary.begin(), summary.end()).find("| FLIP target |"), std::string::npos);

  std::vector<std::string> again = args;
  again.insert(again.end(), {"--flip-ppd", "30"});
  const CliResult r2 = runVerbose(again, dir + "/err2.txt");
  ASSERT_EQ(r2.exitCode, 0) << r2.stderrText;
  EXPECT_EQ(keptCells(r2.stderrText), 4u) << r2.stderrText;
  check(30.0);

  for (const auto& [option, value] : {std::pair{"--targets-flip", "1.5"}, std::pair{"--flip-ppd", "0"}}) {
    std::vector<std::string> bad = args;
    bad.insert(bad.end(), {option, value});
    const CliResult r = runCli(bad, dir + "/err_bad.txt");
    EXPECT_NE(r.exitCode, 0);
    EXPECT_NE(r.stderrText.find(option), std::string::npos) << r.stderrText;
    EXPECT_EQ(std::count(r.stderrText.begin(), r.stderrText.end(), '\n'), 1) << r.stderrText;
  }
}

// results.csv of the earlier formats (docs/compare.md): the current file is
// resumed whole; main's 23-column file of the FLIP columns (before the
// per-seed values) keeps a one-seed cell with its FLIP and measures a
// two-seed cell again, whose intervals then come back, while a run without
// a config writes that config's old rows back as they were; V2's 20
// columns keep a one-seed cell, its FLIP taken from its pass.
TEST(CompareEndToEnd, OlderResultsCsvFormatsResume) {
  const std::string dir = tempDir("compare_old_csv");
  // The file cut to its first n columns, header too (quotes respected).
  const auto cutTo = [](const std::string& path, size_t n) {
    std::ifstream in(path);
    std::string text, line;
    while (std::getline(in, line)) {
      size_t fields = 1, i = 0;
      bool quoted = false;
      for (; i < line.size(); ++i) {
        if (line[i] == '"') quoted = !quoted;
        else if (line[i] == ',' && !quoted && ++fields > n) break;
      }
      text += line.substr(0, i) + "\n";
    }
    in.close();
    std::ofstream(path) << text;
  };
  // Rows by "config@spp".
  const auto byCell = [](const std::vector<std::map<std::string, std::string>>& rows) {
    std::map<std::string, std::map<std::string, std::string>> m;
    for (const auto& row : rows) m[row.at("config") + "@" + row.at("spp")] = row;
    return m;
  };
  for (const int seeds : {1, 2}) {
    const std::string out = dir + "/seeds" + std::to_string(seeds), csv = out + "/results.csv";
    const std::vector<std::string> args = {"compare", "-o", out, "--res", "32x18", "--reference-spp", "16", "--spp",
                                           "2,8", "--seeds", std::to_string(seeds), "-q", "-c", "ao",
                                           "-c", "ao:distance=0.5"};
    const std::vector<std::string> aoOnly(args.begin(), args.end() - 2);
    const CliResult r1 = runCli(args, dir + "/err1.txt");
    ASSERT_EQ(r1.exitCode, 0) << r1.stderrText;
    const auto before = byCell(readCsvRows(csv));
    ASSERT_EQ(before.size(), 4u);
    for (const auto& [cell, row] : before) {
      EXPECT_EQ(row.size(), 29u);
      EXPECT_EQ(size_t(std::count(row.at("seed_mse").begin(), row.at("seed_mse").end(), ';')), size_t(seeds - 1));
    }

    const CliResult r2 = runVerbose(args, dir + "/err2.txt");
    ASSERT_EQ(r2.exitCode, 0) << r2.stderrText;
    EXPECT_EQ(keptCells(r2.stderrText), 4u) << r2.stderrText;
    EXPECT_EQ(byCell(readCsvRows(csv)), before);

    cutTo(csv, 23);
    const CliResult r3 = runVerbose(aoOnly, dir + "/err3.txt");
    ASSERT_EQ(r3.exitCode, 0) << r3.stderrText;
    const auto after = byCell(readCsvRows(csv));
    ASSERT_EQ(after.size(), 4u);
    for (const auto& [cell, row] : after) {
      EXPECT_EQ(row.size(), 29u);
      const auto& old = before.at(cell);
      if (seeds == 1 || cell.rfind("ao@", 0) != 0) {  // kept, or written back, as the file had it
        EXPECT_EQ(row.at("flip"), old.at("flip")) << cell;
        EXPECT_EQ(row.at("rmse"), old.at("rmse")) << cell;
        EXPECT_EQ(row.at("seed_mse"), "") << cell;
        EXPECT_EQ(row.at("rmse_lo"), "") << cell;
      } else {  // measured again: one value per seed and the intervals
        EXPECT_EQ(std::count(row.at("seed_mse").begin(), row.at("seed_mse").end(), ';'), 1) << cell;
        EXPECT_EQ(std::count(row.at("seed_time_s").begin(), row.at("seed_time_s").end(), ';'), 1) << cell;
        ASSERT_FALSE(row.at("rmse_lo").empty()) << cell;
        EXPECT_LE(std::stod(row.at("rmse_lo")), std::stod(row.at("rmse"))) << cell;
        EXPECT_GE(std::stod(row.at("rmse_hi")), std::stod(row.at("rmse"))) << cell;
      }
    }
    EXPECT_EQ(keptCells(r3.stderrText), seeds == 1 ? 2u : 0u) << r3.stderrText;

    if (seeds != 1) continue;
    cutTo(csv, 20);
    const CliResult r4 = runVerbose(args, dir + "/err4.txt");
    ASSERT_EQ(r4.exitCode, 0) << r4.stderrText;
    EXPECT_EQ(keptCells(r4.stderrText), 4u) << r4.stderrText;
    const auto v2 = byCell(readCsvRows(csv));
    ASSERT_EQ(v2.size(), 4u);
    for (const auto& [cell, row] : v2) {
      const double flip = std::stod(before.at(cell).at("flip"));
      EXPECT_NEAR(std::stod(row.at("flip")), flip, 1e-7 * flip) << cell;
      EXPECT_NEAR(std::stod(row.at("flip_ppd")), kFlipDefaultPpd, 1e-6) << cell;
    }
  }
}

// A run with fewer configs than the last keeps the others' rows in
// results.csv (it rewrote the file with its own rows only, and a later run
// with every config had to measure them again); results.json lists them
// under keptRows and reports this run's cells alone (docs/compare.md).
TEST(CompareEndToEnd, FewerConfigsKeepTheOtherRows) {
  const std::string dir = tempDir("compare_fewer_configs");
  const std::vector<std::string> both = {"compare", "-o", dir + "/out", "--res", "16x12", "--reference-spp", "8",
                                         "--spp", "2", "-q", "-c", "ao", "-c", "ao:distance=0.5"};
  ASSERT_EQ(runCli(both, dir + "/err1.txt").exitCode, 0);
  const auto first = readCsvRows(dir + "/out/results.csv");
  ASSERT_EQ(first.size(), 2u);
  std::vector<std::string> one(both.begin(), both.end() - 2);
  const CliResult r2 = runCli(one, dir + "/err2.txt");
  ASSERT_EQ(r2.exitCode, 0) << r2.stderrText;
  const auto second = readCsvRows(dir + "/out/results.csv");
  ASSERT_EQ(second.size(), 2u);
  std::map<std::string, std::map<std::string, std::string>> byConfig;
  for (const auto& row : first) byConfig[row.at("config")] = row;
  for (const auto& row : second) EXPECT_EQ(row, byConfig.at(row.at("config")));
  std::ifstream in(dir + "/out/results.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  ASSERT_EQ(j["cells"].size(), 1u);
  EXPECT_EQ(j["cells"][0]["config"], "ao");
  ASSERT_EQ(j["keptRows"].size(), 1u);
  EXPECT_EQ(j["keptRows"][0]["config"], "ao:distance=0.5");
  EXPECT_EQ(j["keptRows"][0]["key"], byConfig.at("ao:distance=0.5").at("key"));
  // Both configs again: both cells are found done, none is measured anew.
  const CliResult r3 = runVerbose(both, dir + "/err3.txt");
  ASSERT_EQ(r3.exitCode, 0) << r3.stderrText;
  EXPECT_EQ(keptCells(r3.stderrText), 2u) << r3.stderrText;
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
  const CliResult r2 = runVerbose(args, dir + "/err2.txt");
  ASSERT_EQ(r2.exitCode, 0) << r2.stderrText;
  EXPECT_EQ(keptCells(r2.stderrText), kept) << r2.stderrText;
  EXPECT_EQ(rows(), 18u);
  // The finished run on the default scene wrote the whole report.
  for (const char* file : {"results.json", "summary.md", "error_vs_time.svg", "contact_sheet.svg", "contact_sheet.png",
                           "heatmaps/ao.png", "heatmaps/gi.png", "previews/reference.png", "passes/gi@256.exr"})
    EXPECT_TRUE(std::filesystem::exists(dir + "/out/" + file)) << file;
  const auto summary = readBytes(dir + "/out/summary.md");
  EXPECT_NE(std::string(summary.begin(), summary.end()).find("fastest config reaching it"), std::string::npos);
}

// The font the labels are drawn in: every printable character has a glyph
// of its own (so a label reads back unambiguously), inked but for the space.
TEST(ContactSheetFont, EveryGlyphIsDistinct) {
  std::map<std::vector<uint8_t>, char> seen;
  for (int c = 32; c <= 126; ++c) {
    const uint8_t* rows = glyphRows(char(c));
    const std::vector<uint8_t> bits(rows, rows + kGlyphHeight);
    for (uint8_t r : bits) EXPECT_EQ(r >> kGlyphWidth, 0) << char(c);
    EXPECT_EQ(std::count(bits.begin(), bits.end(), 0) == kGlyphHeight, c == ' ') << char(c);
    EXPECT_TRUE(seen.emplace(bits, char(c)).second) << char(c) << " looks like " << seen[bits];
  }
  EXPECT_EQ(glyphRows('\x80'), glyphRows('?'));
  EXPECT_EQ(wrapText("abcdefg", 3), (std::vector<std::string>{"abc", "def", "g"}));
  EXPECT_EQ(wrapText("", 3), std::vector<std::string>{""});
}

// Issue #37: contact_sheet.png had no labels (its SVG had them). Each tile
// carries the SVG's two lines under it: read back glyph by glyph at the
// place report.h's layout gives (derived here from the image's size), they
// are "gi reference" and "CONFIG @ SPP spp" in results.json's contactSheet
// order, in black, then the time and error in grey; the blank column and
// rows around every glyph are white, and the tile above the label is the
// pass's preview, untouched.
TEST(CompareEndToEnd, ContactSheetPngLabelsReadBackUnderEachTile) {
  const std::string dir = tempDir("compare_contact_labels");
  const int w = 64, h = 40;  // 10 glyphs a line: the longer labels wrap
  const CliResult r = runCli({"compare", sourcePath("scenes/default.gltf"), "-o", dir + "/out", "--res", "64x40",
                              "--reference-spp", "4", "--spp", "2", "-q", "-c", "ao", "-c", "obscurance:falloff=sqrt"},
                             dir + "/err.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  std::ifstream in(dir + "/out/results.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  std::vector<std::string> want = {"gi reference"};
  std::vector<std::string> previews = {"reference"};
  for (const auto& c : j["contactSheet"]) {
    if (!c.is_object()) continue;  // "reference", first
    want.push_back(c["config"].get<std::string>() + " @ " + std::to_string(c["spp"].get<int>()) + " spp");
    previews.push_back(safeFileName(c["config"].get<std::string>()));
  }
  ASSERT_EQ(want.size(), 3u);

  auto readRgb8 = [](const std::string& path, int& W, int& H) {
    auto img = OIIO::ImageInput::open(path);
    EXPECT_TRUE(img) << OIIO::geterror();
    if (!img) return std::vector<unsigned char>();
    W = img->spec().width, H = img->spec().height;
    std::vector<unsigned char> px(size_t(W) * H * 3);
    EXPECT_TRUE(img->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, px.data()));
    return px;
  };
  int W = 0, H = 0;
  const std::vector<unsigned char> sheet = readRgb8(dir + "/out/contact_sheet.png", W, H);
  const int tiles = 3, cols = 3, rows = 1;
  ASSERT_EQ(W, cols * (w + 4) + 4);
  const int labelHeight = (H - 4) / rows - h - 4;
  ASSERT_EQ((H - 4) % rows, 0);
  const int columns = (w + 1) / kGlyphAdvance, lines = (labelHeight - kContactSheetLabelGap) / kLineAdvance;
  ASSERT_EQ(labelHeight, kContactSheetLabelGap + lines * kLineAdvance);
  const std::regex timing("[0-9.e+-]+ s, RMSE [0-9.e+-]+, FLIP [0-9.e+-]+"), noise("noise RMSE [0-9.e+-]+");
  auto pixel = [&](int x, int y) { return &sheet[(size_t(y) * W + x) * 3]; };
  auto white = [&](int x, int y) { const unsigned char* p = pixel(x, y); return p[0] == 255 && p[1] == 255 && p[2] == 255; };
  for (int t = 0; t < tiles; ++t) {
    SCOPED_TRACE("tile " + std::to_string(t));
    const int x0 = (t % cols) * (w + 4) + 4, y0 = (t / cols) * (h + labelHeight + 4) + 4;
    std::string text[2];  // black, grey
    for (int l = 0; l < lines; ++l) {
      const int ly = y0 + h + kContactSheetLabelGap + l * kLineAdvance;
      std::string line;
      int part = -1;
      for (int k = 0; k < columns; ++k) {
        const int gx = x0 + k * kGlyphAdvance;
        std::vector<uint8_t> bits(kGlyphHeight, 0);
        for (int y = 0; y < kGlyphHeight; ++y)
          for (int x = 0; x < kGlyphWidth; ++x) {
            if (white(gx + x, ly + y)) continue;
            const unsigned char* p = pixel(gx + x, ly + y);
            const int colour = p[0] == 0 && p[1] == 0 && p[2] == 0 ? 0 : p[0] == 0x55 && p[1] == 0x55 && p[2] == 0x55 ? 1 : -1;
            ASSERT_GE(colour, 0) << "ink neither black nor grey at " << gx + x << "," << ly + y;
            ASSERT_TRUE(part < 0 || part == colour) << "a line mixes black and grey";
            part = colour;
            bits[size_t(y)] |= uint8_t(1 << (kGlyphWidth - 1 - x));
          }
        char c = 0;
        for (int g = 32; g <= 126 && !c; ++g)
          if (std::equal(bits.begin(), bits.end(), glyphRows(char(g)))) c = char(g);
        ASSERT_NE(c, 0) << "no glyph at " << gx << "," << ly;
        line += c;
        // The blank column after a glyph (inside the tile) is white.
        if (gx + kGlyphWidth < x0 + w)
          for (int y = 0; y < kGlyphHeight; ++y) EXPECT_TRUE(white(gx + kGlyphWidth, ly + y));
      }
      for (int x = x0; x < x0 + w; ++x)
        for (int y = ly + kGlyphHeight; y < ly + kLineAdvance; ++y) EXPECT_TRUE(white(x, y)) << x << "," << y;
      if (part >= 0) text[part] += line;
    }
    for (std::string& s : text) s.erase(s.find_last_not_of(' ') + 1);
    EXPECT_EQ(text[0], want[size_t(t)]);
    EXPECT_TRUE(std::regex_match(text[1], t == 0 ? noise : timing)) << text[1];
    // The image above the label is the pass's preview, untouched.
    int pw = 0, ph = 0;
    const std::vector<unsigned char> preview = readRgb8(dir + "/out/previews/" + previews[size_t(t)] + ".png", pw, ph);
    ASSERT_EQ(pw, w);
    ASSERT_EQ(ph, h);
    size_t differ = 0;
    for (int y = 0; y < h; ++y)
      differ += std::memcmp(pixel(x0, y0 + y), &preview[size_t(y) * w * 3], size_t(w) * 3) != 0;
    EXPECT_EQ(differ, 0u) << "rows of the tile differ from its preview";
  }
}

}  // namespace
}  // namespace obscura::test
