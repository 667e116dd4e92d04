// The improved-AO fit (issue 36 item 6): `ao weighting=uniform` against
// closed forms, the least-squares fit of F0 and F1 against synthetic data of
// known coefficients, `multibounce mapping=fitted` against `improved`, and
// `obscura fit`'s file and errors (docs/math.md §6 "Fitting F0 and F1",
// docs/iao_fit.md).
//
// Tolerances. AO renders: every ray is a Bernoulli(p) draw, so a mean over
// N = pixels x spp x rays draws has standard error sqrt(p(1-p)/N)
// (scrambled Sobol' only lowers it); 4 of them, plus the pixel-footprint
// bound where the closed form varies across a pixel. The fit: for Gaussian
// noise of known sigma on N pairs, the least-squares coefficients scatter by
// the Gauss-Newton standard errors sigma sqrt(diag((J^T N J)^-1))
// (improvedFitStdErrors); each is asserted within 4 of them.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>

#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "integrators/iao_fit.h"
#include "integrators/multibounce_mapping.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// --- ao weighting=uniform ----------------------------------------------------

// (On an open plane alpha = 1 exactly: tests/test_multibounce.cpp
// MultiBounceIntegrator.OpenPlaneIsOne.)

// A floor point at distance h from a wall x = 0 (the crease, seen within
// R): a direction w of the upper hemisphere meets the wall within R iff
// w_x > c = min(h / R, 1) (the wall is at distance h / w_x). With w_x = u the
// cap {u > c} of the sphere has area 2 pi (1 - c), half of it above the
// floor (the cap is symmetric in w_z), so
//   alpha = 1 - pi (1 - c) / 2 pi = (1 + c) / 2,
// while the cosine-weighted AO, with Int over the cap of max(w_z, 0) dw =
// Int_c^1 2 sqrt(1 - u^2) du = pi/2 - c sqrt(1 - c^2) - asin c, is
//   v = 1/2 + (c sqrt(1 - c^2) + asin c) / pi.
// Both are 1/2 at c = 0 (R = inf: half the hemisphere, symmetric about the
// wall's plane, is behind it) and 1 at c = 1, and differ between (at c = 1/2:
// alpha = 0.75, v = 0.8045). docs/math.md §7.
double creaseUniform(double h, double R) { return (1.0 + std::min(h / R, 1.0)) / 2.0; }
double creaseCosine(double h, double R) {
  const double c = std::min(h / R, 1.0);
  return 0.5 + (c * std::sqrt(1.0 - c * c) + std::asin(c)) / M_PI;
}

TEST(UniformAo, FiniteRadiusWallMatchesTheClosedForm) {
  const Crease c;
  const int w = 96, ht = 72, spp = 64, rays = 4;
  const double R = 0.5;
  // The floor pixels whose centre is within R of the wall (where the two
  // forms differ) and which see only floor. A pixel's expected value is
  // the closed form averaged over its area (box filter, uniform camera
  // samples): taken here as the mean over a k x k grid of sub-pixel
  // centres, whose error is at most the slope times half a sub-cell -
  // creaseCentres' footprint bound (for a slope 3 / (4R)) divided by k and
  // rescaled to the forms' slopes: alpha's 1 / (2R) (x 2/3), v's
  // 2 sqrt(1 - c^2) / (pi R) <= 2 / (pi R) (x 8 / (3 pi)).
  constexpr int k = 16;
  const CreaseCentres cc = creaseCentres(c, w, ht, R);
  std::vector<std::pair<int, int>> pixels;
  std::vector<double> uniformForm, cosineForm;
  for (const auto& [x, y] : cc.pixels) {
    double u = 0, v = 0;
    bool floor = true;
    Vec3 p;
    ASSERT_TRUE(c.floorAt(w, ht, x, y, p));
    if (p.x >= R) continue;
    for (int j = 0; j < k && floor; ++j)
      for (int i = 0; i < k && floor; ++i) {
        floor = c.floorAtFilm(w, ht, float(x) + (i + 0.5f) / k, float(y) + (j + 0.5f) / k, p);
        u += creaseUniform(p.x, R), v += creaseCosine(p.x, R);
      }
    if (!floor) continue;
    pixels.emplace_back(x, y);
    uniformForm.push_back(u / (k * k));
    cosineForm.push_back(v / (k * k));
  }
  ASSERT_GT(pixels.size(), 100u);
  for (const bool uniform : {true, false}) {
    const Film film = renderWith(c.scene, c.cam, "ao",
                                 {uniform ? "weighting=uniform" : "weighting=cosine", "distance=0.5",
                                  "rays=" + std::to_string(rays)},
                                 passSettings(w, ht, spp));
    double mean = 0, expected = 0, other = 0;
    for (size_t i = 0; i < pixels.size(); ++i) {
      mean += film.at(kR, pixels[i].first, pixels[i].second);
      expected += uniform ? uniformForm[i] : cosineForm[i];
      other += uniform ? cosineForm[i] : uniformForm[i];
    }
    const double n = double(pixels.size());
    mean /= n, expected /= n, other /= n;
    const double se = bernoulliStdErr(expected, n * spp * rays);
    const double footprint = cc.footprint / k * (uniform ? 2.0 / 3.0 : 8.0 / (3.0 * M_PI));
    const double tolerance = 4.0 * se + footprint;
    EXPECT_NEAR(mean, expected, tolerance) << (uniform ? "uniform" : "cosine") << " over " << n << " pixels";
    // The test tells the two weightings apart.
    EXPECT_GT(std::abs(other - expected), 3.0 * tolerance) << (uniform ? "uniform" : "cosine");
  }
}

// R = inf beside a wall: 1/2 for both weightings. A wall and floor of half
// size L = 1e4 stand in for infinite ones: from a floor point at distance h
// from the wall, a direction w with w_x > 0 reaches the plane x = 0 at
// (h / w_x) w, past the wall's edges only if max(|w_y|, w_z) / w_x > L / h,
// so only directions with 0 < w_x < h / L escape past it: a slab of the
// sphere of area 2 pi h / L, of which at most pi h / L in the hemisphere,
// a fraction h / (2L) of it (uniform) and at most h / L of the cosine
// weight (cos <= 1 over pi).
TEST(UniformAo, InfiniteWallIsOneHalfForBothWeightings) {
  const float L = 1e4f;
  Scene scene;
  scene.addWorldPrimitive({{0, -L, 0}, {L, -L, 0}, {L, L, 0}, {0, L, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene.addWorldPrimitive({{0, -L, 0}, {0, L, 0}, {0, L, L}, {0, -L, L}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene.commit();
  // Looking down at the floor near the wall: every pixel sees the floor
  // at h < 2.
  const Camera cam = makeLookAtCamera(Vec3(1.0f, 0, 3.0f), Vec3(1.0f, 0, 0), Vec3(0, 1, 0), 0.5f, "floor");
  const int w = 32, ht = 32, spp = 64, rays = 4;
  const double hMax = 2.0;
  for (const char* weighting : {"weighting=uniform", "weighting=cosine"}) {
    const Film film = renderWith(scene, cam, "ao", {weighting, "rays=" + std::to_string(rays)}, passSettings(w, ht, spp));
    size_t n = 0;
    const double mean = meanCovered(film, kR, &n);
    ASSERT_EQ(n, size_t(w * ht)) << weighting;
    const double se = bernoulliStdErr(0.5, double(n) * spp * rays);
    EXPECT_NEAR(mean, 0.5, 4.0 * se + hMax / L) << weighting;
  }
}

// --- the fit -------------------------------------------------------------------

// N pairs (alpha uniform on [0, 1], F0 + noise, F1 + noise) from known
// coefficients: the fit recovers them within 4 standard errors of a fit of
// that noise, reports standard errors that match those (its sigma is
// estimated from the residuals), and its pixel residual is the noise.
void expectRecovers(const ImprovedFit& truth, double sigma, int n, int bins, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, sigma);
  IaoHistogram h(bins);
  for (int i = 0; i < n; ++i) {
    const double a = U(rng);
    h.add(a, improvedF0(a, truth) + noise(rng), improvedF1(a, truth) + noise(rng));
  }
  const IaoFit fit = fitImprovedAo(h);
  double se[4];
  improvedFitStdErrors(h, truth, sigma, sigma, se);
  const double got[4] = {fit.coefficients.f0Scale, fit.coefficients.f0Exponent, fit.coefficients.f1A,
                         fit.coefficients.f1B};
  const double want[4] = {truth.f0Scale, truth.f0Exponent, truth.f1A, truth.f1B};
  const double reported[4] = {fit.f0.seLinear, fit.f0.seNonlinear, fit.f1.seLinear, fit.f1.seNonlinear};
  const char* names[4] = {"F0.scale", "F0.exponent", "F1.A", "F1.B"};
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(got[k], want[k], 4.0 * se[k]) << names[k] << " (sigma " << sigma << ", n " << n << ")";
    // sigma-hat has relative error ~ 1 / sqrt(2 N): 10% is > 30 of them.
    EXPECT_NEAR(reported[k], se[k], 0.1 * se[k]) << names[k];
  }
  // The pixels scatter by sigma about the true curve (within 10%: the
  // bin-mean approximation adds O(f'^2 / (12 bins^2)), far below sigma^2).
  EXPECT_NEAR(fit.f0.rmsPixels, sigma, 0.1 * sigma);
  EXPECT_NEAR(fit.f1.rmsPixels, sigma, 0.1 * sigma);
  EXPECT_EQ(fit.filledBins, bins);
  EXPECT_EQ(fit.pixels, double(n));
}

TEST(IaoFit, RecoversThePublishedCurvesFromNoisyPairs) { expectRecovers(ImprovedFit{}, 0.02, 200000, 1000, 1); }

TEST(IaoFit, RecoversOtherCurvesFromNoisyPairs) {
  expectRecovers(ImprovedFit{.f0Scale = 0.3, .f0Exponent = 1.4, .f1A = 12.0, .f1B = 2.0}, 0.01, 100000, 1000, 2);
  expectRecovers(ImprovedFit{.f0Scale = 0.8, .f0Exponent = 0.5, .f1A = 40.0, .f1B = 4.0}, 0.05, 400000, 1000, 3);
}

// Noise-free pairs: the minimum is the truth, to the golden section's precision.
TEST(IaoFit, NoiseFreeDataGivesTheCoefficientsBack) {
  IaoHistogram h(1000);
  const ImprovedFit truth;
  for (int i = 0; i <= 100000; ++i) {
    const double a = i / 100000.0;
    h.add(a, improvedF0(a, truth), improvedF1(a, truth));
  }
  const IaoFit fit = fitImprovedAo(h);
  EXPECT_NEAR(fit.coefficients.f0Scale, truth.f0Scale, 2e-3);
  EXPECT_NEAR(fit.coefficients.f0Exponent, truth.f0Exponent, 2e-3);
  EXPECT_NEAR(fit.coefficients.f1A, truth.f1A, 2e-2 * truth.f1A);
  EXPECT_NEAR(fit.coefficients.f1B, truth.f1B, 2e-2);
  EXPECT_LT(fit.f0.rmsMeans, 1e-4);
  EXPECT_LT(fit.f1.rmsMeans, 1e-4);
}

TEST(IaoFit, TooFewFilledBinsIsAnError) {
  IaoHistogram h(10);
  h.add(0.5, 0.5, 0.1);
  h.add(0.55, 0.5, 0.1);
  try {
    fitImprovedAo(h);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("at least 3"), std::string::npos) << e.what();
  }
}

// --- the file and mapping=fitted -----------------------------------------------

std::string publishedFile(const std::string& dir) {
  IaoFit fit;  // the published coefficients
  const std::string path = dir + "/published.json";
  writeText(path, improvedFitJson(fit, {"none"}, "test"));
  return path;
}

TEST(IaoFit, FileRoundTripsTheCoefficientsExactly) {
  const std::string dir = tempDir("iao_fit_roundtrip");
  IaoFit fit;
  fit.coefficients = ImprovedFit{.f0Scale = 0.1 + 0.2, .f0Exponent = 1.0 / 3.0, .f1A = 27.0 + 1e-13, .f1B = -M_PI};
  writeText(dir + "/c.json", improvedFitJson(fit, {"a.gltf", "b \"q\".gltf"}, "res 1x1"));
  const ImprovedFit back = readImprovedFit(dir + "/c.json");
  EXPECT_EQ(back.f0Scale, fit.coefficients.f0Scale);
  EXPECT_EQ(back.f0Exponent, fit.coefficients.f0Exponent);
  EXPECT_EQ(back.f1A, fit.coefficients.f1A);
  EXPECT_EQ(back.f1B, fit.coefficients.f1B);
}

TEST(IaoFit, FittedWithThePublishedCoefficientsIsImprovedBitForBit) {
  const std::string dir = tempDir("iao_fit_published");
  const std::string file = publishedFile(dir);
  const ImprovedFit c = readImprovedFit(file);
  for (int i = 0; i <= 400; ++i)
    for (int j = 0; j <= 40; ++j) {
      const double a = i / 400.0, rho = j / 40.0;
      ASSERT_EQ(fittedMultiBounce(a, rho, c), improvedMultiBounce(a, rho)) << a << " " << rho;
    }
  const auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  RenderSettings s = passSettings(48, 27, 8, 5);
  s.aovs = true;
  const Film improved = renderWith(*scene, scene->cameras[0], "multibounce", {"mapping=improved", "rays=2"}, s);
  const Film fitted =
      renderWith(*scene, scene->cameras[0], "multibounce", {"mapping=fitted", "fit=" + file, "rays=2"}, s);
  expectSameFilm(improved, fitted, "mapping=fitted with the published coefficients vs mapping=improved");
  // Other coefficients change the image (the file is read, not ignored).
  IaoFit other;
  other.coefficients.f1A = 10.0;
  writeText(dir + "/other.json", improvedFitJson(other, {}, ""));
  const Film changed =
      renderWith(*scene, scene->cameras[0], "multibounce", {"mapping=fitted", "fit=" + dir + "/other.json", "rays=2"}, s);
  double diff = 0;
  for (int y = 0; y < 27; ++y)
    for (int x = 0; x < 48; ++x) diff += std::abs(changed.at(kR, x, y) - improved.at(kR, x, y));
  EXPECT_GT(diff, 0.0);
}

// The message of creating multibounce with `params`.
std::string createError(const std::vector<std::string>& params) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find("multibounce");
  ParamSet p(d.params, d.name);
  for (const std::string& a : params) p.setAssignment(a);
  try {
    d.create(p);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(IaoFit, BadFilesNameTheFileAndTheField) {
  const std::string dir = tempDir("iao_fit_bad");
  const auto body = [](const std::string& f0, const std::string& f1) {
    return "{\"format\": \"obscura-iao-fit\", \"version\": 1, \"F0\": " + f0 + ", \"F1\": " + f1 + "}";
  };
  const std::string good0 = "{\"scale\": 0.5, \"exponent\": 0.75}", good1 = "{\"A\": 27, \"B\": 3}";
  const struct {
    const char* name;
    std::string text, field;
  } cases[] = {
      {"json", "{\"F0\": {\"scale\": 0.5,", "not valid JSON"},
      {"array", "[1, 2]", "expected a JSON object"},
      {"noF1", "{\"F0\": " + good0 + "}", "field 'F1'"},
      {"noB", body(good0, "{\"A\": 27}"), "field 'F1.B': missing"},
      {"text", body("{\"scale\": \"half\", \"exponent\": 0.75}", good1), "field 'F0.scale': must be a number"},
      {"zeroExp", body("{\"scale\": 0.5, \"exponent\": 0}", good1), "field 'F0.exponent': must be in (0, 100]"},
      {"negA", body(good0, "{\"A\": -1, \"B\": 3}"), "field 'F1.A': must be in [0,"},
      {"smallScale", body("{\"scale\": -2, \"exponent\": 0.75}", good1), "field 'F0.scale'"},
  };
  for (const auto& c : cases) {
    const std::string path = dir + "/" + c.name + ".json";
    writeText(path, c.text);
    const std::string msg = createError({"mapping=fitted", "fit=" + path});
    EXPECT_NE(msg.find(path), std::string::npos) << c.name << ": " << msg;
    EXPECT_NE(msg.find(c.field), std::string::npos) << c.name << ": " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << c.name << ": " << msg;
  }
  const std::string missing = createError({"mapping=fitted", "fit=" + dir + "/nonesuch.json"});
  EXPECT_NE(missing.find(dir + "/nonesuch.json: cannot open"), std::string::npos) << missing;
  EXPECT_NE(createError({"mapping=fitted"}).find("parameter 'fit'"), std::string::npos);
  EXPECT_NE(createError({"mapping=improved", "fit=" + publishedFile(dir)}).find("only with mapping=fitted"),
            std::string::npos);
}

// --- obscura fit ------------------------------------------------------------------

TEST(IaoFitCli, WritesAFileThatMultibounceReads) {
  const std::string dir = tempDir("iao_fit_cli");
  const std::string scene = sourcePath("scenes/default.gltf");
  const CliResult fit = runCli({"fit", scene, scene, "-o", dir + "/c.json", "--histogram", dir + "/h.csv", "--res",
                                "64x36", "--spp", "8", "--bins", "20", "-q"},
                               dir + "/fit.txt");
  ASSERT_EQ(fit.exitCode, 0) << fit.stderrText;
  const ImprovedFit c = readImprovedFit(dir + "/c.json");
  EXPECT_TRUE(std::isfinite(c.f1A) && std::isfinite(c.f0Exponent));
  std::ifstream csv(dir + "/h.csv");
  std::string header;
  ASSERT_TRUE(std::getline(csv, header));
  EXPECT_EQ(header.rfind("alpha_lo,alpha_hi,pixels,alpha,F0_data,F1_data", 0), 0u) << header;
  const CliResult render = runCli({"render", scene, "-o", dir + "/mb.exr", "-i", "multibounce", "-p", "mapping=fitted",
                                   "-p", "fit=" + dir + "/c.json", "--res", "32x18", "--spp", "2", "-q"},
                                  dir + "/render.txt");
  EXPECT_EQ(render.exitCode, 0) << render.stderrText;
}

TEST(IaoFitCli, BadInputIsOneLineAndNonZeroExit) {
  const std::string dir = tempDir("iao_fit_cli_bad");
  writeText(dir + "/bad.json", "{\"F0\": {\"scale\": 0.5, \"exponent\": 0.75}, \"F1\": {\"A\": 27}}");
  const std::vector<std::vector<std::string>> args = {
      {"render", "-o", dir + "/x.exr", "-i", "multibounce", "-p", "mapping=fitted", "-p", "fit=" + dir + "/missing.json",
       "--res", "8x8", "-q"},
      {"render", "-o", dir + "/x.exr", "-i", "multibounce", "-p", "mapping=fitted", "-p", "fit=" + dir + "/bad.json",
       "--res", "8x8", "-q"},
      {"fit", "-o", dir + "/c.json", "--bins", "2", "-q"},
      {"fit", "-o", dir + "/c.txt", "-q"},
      {"fit", dir + "/nonesuch.gltf", "-o", dir + "/c.json", "-q"},
  };
  const char* expect[] = {"missing.json: cannot open", "bad.json: field 'F1.B': missing", "--bins", "must end in .json",
                          "nonesuch.gltf"};
  const std::vector<CliResult> r = runClis(args, dir);
  for (size_t i = 0; i < r.size(); ++i) {
    EXPECT_NE(r[i].exitCode, 0) << i;
    EXPECT_NE(r[i].stderrText.find(expect[i]), std::string::npos) << i << ": " << r[i].stderrText;
    size_t lines = 0;
    for (char ch : r[i].stderrText) lines += ch == '\n';
    EXPECT_EQ(lines, 1u) << i << ": " << r[i].stderrText;
  }
}

}  // namespace
}  // namespace obscura::test
