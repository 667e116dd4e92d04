// The multi-bounce AO mappings (docs/math.md §6) on the whole unit square,
// and the `multibounce` integrator as "AO, then the mapping per pixel".
#include <gtest/gtest.h>

#include <cmath>
#include <iomanip>
#include <limits>
#include <vector>

#include "core/load/gltf_loader.h"
#include "integrators/multibounce_mapping.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// A dense grid with both edges, plus the places where the published
// improved-AO fit breaks: near alpha = 0 and 1 (0/0), around alpha = 0.9493
// (F0 crosses 1), 0.76 (F1 crosses 1 - F0) and the pole near (0.99, 0.85).
std::vector<double> denseAxis(int n, std::vector<double> extra) {
  std::vector<double> v;
  for (int i = 0; i <= n; ++i) v.push_back(double(i) / n);
  for (double x : {1e-300, 1e-12, 1e-6, 0.7635, 0.76, 0.9492532351252109, 0.94925323512521, 0.9493, 0.99, 1 - 1e-6,
                   1 - 1e-12, std::nextafter(1.0, 0.0)})
    v.push_back(x);
  v.insert(v.end(), extra.begin(), extra.end());
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

// Monotone in the AO value up to the rounding of the evaluation: both
// mappings are monotone in exact arithmetic, and a dozen double operations
// err by a few units in the last place (2^-53 for values <= 1) - at points
// 1e-16 apart they can swap by that much. We allow 8 of those units; the
// pass is stored as float, 2^29 times coarser.
constexpr double kRounding = 8 * 0x1p-53;

template <class Map>
void checkMapping(Map map, const char* name) {
  const std::vector<double> ao = denseAxis(4000, {});
  const std::vector<double> rho = denseAxis(400, {0.85, 0.849, 0.851});
  size_t checked = 0;
  for (const double r : rho) {
    double prev = -1.0;
    for (const double v : ao) {
      const double w = map(v, r);
      ASSERT_TRUE(std::isfinite(w)) << name << " v " << v << " rho " << r;
      ASSERT_GE(w, 0.0) << name << " v " << v << " rho " << r;
      ASSERT_LE(w, 1.0) << name << " v " << v << " rho " << r;
      ASSERT_GE(w, prev - kRounding) << std::setprecision(17) << name << ": not monotone in the AO value at v " << v << " rho " << r << ": " << prev << " -> " << w;
      prev = w;
      ++checked;
    }
  }
  EXPECT_GT(checked, size_t(4000 * 400));
}

TEST(MultiBounceMapping, GtaoIsFiniteBoundedAndMonotone) { checkMapping(gtaoMultiBounce, "gtao"); }
TEST(MultiBounceMapping, ImprovedIsFiniteBoundedAndMonotone) { checkMapping(improvedMultiBounce, "improved"); }

// Where the published improved-AO formula is well defined (1 - F0 > 0 and
// 1 - rho tau != 0) the stable form equals it; at rho = 1 it is the white
// furnace (W = 1 for any open fraction); at rho = 0 it is F0.
TEST(MultiBounceMapping, ImprovedEqualsThePublishedFitWhereThatIsDefined) {
  constexpr double A = 27.576937094210385, B = 3.3364392003423804;
  for (int i = 1; i < 200; ++i) {
    const double alpha = 0.9 * i / 200.0;  // F0 < 1 here
    for (const double rho : {0.0, 0.2, 0.5, 0.85, 0.99}) {
      const double F0 = alpha * (1 + std::pow(1 - alpha, 0.75) / 2);
      const double F1 = A * alpha * std::pow(1 - alpha, 1.5) * std::exp(-B * std::pow(alpha, 0.25));
      const double tau = 1 - F1 / (1 - F0);
      const double published = F0 + rho / (1 - rho * tau) * F1;
      EXPECT_NEAR(improvedMultiBounce(alpha, rho), published, 1e-12 * std::max(1.0, std::abs(published)))
          << alpha << " " << rho;
    }
    EXPECT_DOUBLE_EQ(improvedMultiBounce(alpha, 1.0), 1.0);
    EXPECT_DOUBLE_EQ(improvedMultiBounce(alpha, 0.0), alpha * (1 + std::pow(1 - alpha, 0.75) / 2));
  }
  EXPECT_EQ(improvedMultiBounce(0.0, 0.5), 0.0);
  EXPECT_EQ(improvedMultiBounce(1.0, 0.0), 1.0);
  EXPECT_EQ(improvedMultiBounce(0.0, 1.0), 1.0);  // 0/0: the white-furnace limit
}

// GTAO: the published polynomial wherever it lies in [v, 1].
TEST(MultiBounceMapping, GtaoEqualsThePublishedFit) {
  for (int i = 0; i <= 100; ++i)
    for (const double rho : {0.0, 0.3, 0.7, 0.95}) {
      const double v = i / 100.0;
      const double a = 2.0404 * rho - 0.3324, b = -4.7951 * rho + 0.6417, c = 2.7552 * rho + 0.6903;
      const double published = std::max(v, ((v * a + b) * v + c) * v);
      EXPECT_DOUBLE_EQ(gtaoMultiBounce(v, rho), std::min(published, 1.0));
    }
}

// The integrator maps the pixel's converged AO value with the pixel's mean
// albedo: with the same seed, multibounce (gtao) = the mapping applied to
// the `ao` pass and the albedo AOV, per channel, on every covered pixel.
TEST(MultiBounceIntegrator, IsTheMappingOfThePixelsAoAndAlbedo) {
  const auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  RenderSettings s = passSettings(64, 36, 16, 3);
  s.aovs = true;
  const Film ao = renderWith(*scene, scene->cameras[0], "ao", {"rays=2"}, s);
  const Film mb = renderWith(*scene, scene->cameras[0], "multibounce", {"rays=2"}, s);
  size_t checked = 0;
  for (int y = 0; y < 36; ++y)
    for (int x = 0; x < 64; ++x) {
      if (ao.at(kA, x, y) != 1.0f) continue;
      ++checked;
      const int albedo[3] = {kAlbedoR, kAlbedoG, kAlbedoB};
      const int pass[3] = {kR, kG, kB};
      for (int c = 0; c < 3; ++c) {
        const float expected = float(gtaoMultiBounce(ao.at(kR, x, y), mb.at(albedo[c], x, y)));
        ASSERT_EQ(mb.at(pass[c], x, y), expected) << "pixel " << x << "," << y << " channel " << c;
      }
    }
  EXPECT_GT(checked, size_t(64 * 36 / 2));
}

// On an open plane every AO flavour is 1 - cosine or uniform, over the
// hemisphere or a narrower cone - so `ao` and every mapping give exactly 1.
TEST(MultiBounceIntegrator, OpenPlaneIsOne) {
  Scene scene;
  addPlane(scene, 100.0f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0.3f, -2, 1), Vec3(0, 0, 0), Vec3(0, 0, 1), 1.0f, "plane");
  const std::vector<std::pair<std::string, std::vector<std::string>>> passes = {
      {"multibounce", {"mapping=gtao"}},
      {"multibounce", {"mapping=improved"}},
      {"ao", {"weighting=uniform"}},
      {"ao", {"weighting=uniform", "spread=0.4"}}};
  for (const auto& [integrator, params] : passes) {
    std::vector<std::string> p = params;
    p.push_back("rays=4");
    const Film film = renderWith(scene, cam, integrator, p, passSettings(16, 16, 4));
    size_t covered = 0;
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x)
        if (film.at(kA, x, y) == 1.0f) {
          ++covered;
          ASSERT_EQ(film.at(kR, x, y), 1.0f) << integrator << " " << params.back();
        }
    EXPECT_GT(covered, 16u * 16u / 2u) << integrator;
  }
}

}  // namespace
}  // namespace obscura::test
