// `transfer` and `gi` against the closed forms of docs/math.md §4, §5 and §7.
//
// The spherical cavity (radius Rs, cap of half-angle alpha removed, every
// wall of albedo a, f = (1 - cos alpha)/2): form factors inside a sphere are
// uniform, so every wall point sees the hole with probability f and the wall
// with 1 - f, whatever direction it came from. Hence
// - full GI: W = Sum_k f (a (1 - f))^k = f / (1 - a (1 - f));
// - the closed form of section 4 at R = inf: the same (its local
//   approximation W(y) = W(x) is exact here), and so is every depth of the
//   recursive transfer with tail=closed;
// - tail=zero after N bounces: the first N + 1 terms,
//   f (1 - (a (1 - f))^(N+1)) / (1 - a (1 - f)).
//
// Tolerances:
// - Statistical: pixels are independent estimates (each has its own
//   scramble seed) of the same value, so the standard error of their mean is
//   their sample standard deviation / sqrt(pixels). We allow 4 of them.
// - Tessellation: the chord mesh moves visibility boundaries by at most
//   D^2 in f (see test_ao_analytic.cpp); we allow the change of the closed
//   form when f moves by that much.
// - The ratio estimator's bias (transfer only, section 4): with n = spp x
//   rays samples per pixel, each a Bernoulli(f) escape, the estimate is
//   K / (n - a (n - K)) with K ~ Binomial(n, f); its expectation, computed
//   exactly below, differs from W by O(1/n). Scrambled Sobol' samples
//   stratify K, which only shrinks that difference, so we allow the
//   independent-sample bias |E - W| on top.
#include <gtest/gtest.h>

#include <cmath>

#include "core/load/gltf_loader.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr int kRings = 256, kSegments = 512;
const double kStep = std::max(2.0 * M_PI / kSegments, M_PI / kRings);
const double kTessellationBound = kStep * kStep;

double cavityF(double alpha) { return (1.0 - std::cos(alpha)) / 2.0; }
double giClosedForm(double f, double a) { return f / (1.0 - a * (1.0 - f)); }
double truncatedClosedForm(double f, double a, int depth) {
  const double r = a * (1.0 - f);
  return f * (1.0 - std::pow(r, depth + 1)) / (1.0 - r);
}
// The largest change of g(f) when f moves by the tessellation bound.
template <class G>
double tessellationTolerance(G g, double f) {
  return std::max(std::abs(g(f + kTessellationBound) - g(f)), std::abs(g(f - kTessellationBound) - g(f)));
}

// E[K / (n - a (n - K))], K ~ Binomial(n, f); 0/0 (K = 0, a = 1) is 1.
double ratioExpectation(int n, double f, double a) {
  double e = 0.0;
  for (int k = 0; k <= n; ++k) {
    const double logP = std::lgamma(n + 1.0) - std::lgamma(k + 1.0) - std::lgamma(n - k + 1.0) +
                        k * std::log(f) + (n - k) * std::log1p(-f);
    const double den = n - a * (n - k);
    e += std::exp(logP) * (den > 0 ? k / den : 1.0);
  }
  return e;
}

std::unique_ptr<Scene> greyCavity(double alpha, float a) {
  auto scene = std::make_unique<Scene>();
  addSphereCavity(*scene, 1.0f, alpha, kRings, kSegments, addGreyMaterial(*scene, a));
  scene->setRobust(true);  // see test_ao_analytic.cpp: the 512-valent pole
  scene->commit();
  return scene;
}
Camera cavityCamera() { return makeLookAtCamera(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 1, 0), 1.2f, "inside"); }

const double kAlphas[] = {0.5763, 1.0471975511965976, 1.5707963267948966};  // f = 0.0806, 1/4, 1/2
const float kAlbedos[] = {0.5f, 0.85f};

// The closed form at R = inf and its recursive versions with tail=closed all
// give f / (1 - a(1 - f)) in the cavity; every channel is the same.
TEST(TransferCavity, ClosedFormAndClosedTailsMatchFullGi) {
  const int w = 16, h = 16, spp = 64, rays = 16, n = spp * rays;
  for (const double alpha : kAlphas)
    for (const float a : kAlbedos) {
      const auto scene = greyCavity(alpha, a);
      const double f = cavityF(alpha), W = giClosedForm(f, a);
      const double bias = std::abs(ratioExpectation(n, f, a) - W);
      const double tess = tessellationTolerance([&](double g) { return giClosedForm(g, a); }, f);
      for (const char* depth : {"depth=0", "depth=2"}) {
        const Film film = renderWith(*scene, cavityCamera(), "transfer", {depth, "rays=" + std::to_string(rays)},
                                     passSettings(w, h, spp));
        const PixelStats s = pixelStats(film, kR);
        ASSERT_EQ(s.n, size_t(w * h));
        EXPECT_NEAR(s.mean, W, 4 * s.se + bias + tess) << "alpha " << alpha << " a " << a << " " << depth;
        EXPECT_EQ(pixelStats(film, kG).mean, s.mean);
        EXPECT_EQ(pixelStats(film, kB).mean, s.mean);
      }
    }
}

// tail=zero truncates the series after depth bounces: a plain mean (no ratio
// bias) of the first depth + 1 terms.
TEST(TransferCavity, ZeroTailIsTheTruncatedSeries) {
  const int w = 16, h = 16, spp = 64;
  const double alpha = 1.0471975511965976;
  const float a = 0.85f;
  const auto scene = greyCavity(alpha, a);
  const double f = cavityF(alpha);
  for (const int depth : {0, 1, 2, 5}) {
    const Film film = renderWith(*scene, cavityCamera(), "transfer",
                                 {"depth=" + std::to_string(depth), "tail=zero", "rays=4"}, passSettings(w, h, spp));
    const PixelStats s = pixelStats(film, kR);
    const double expected = truncatedClosedForm(f, a, depth);
    const double tess = tessellationTolerance([&](double g) { return truncatedClosedForm(g, a, depth); }, f);
    EXPECT_NEAR(s.mean, expected, 4 * s.se + tess) << "depth " << depth;
  }
}

// Full GI: unbiased path tracing with roulette gives f / (1 - a(1 - f)).
TEST(GiCavity, PathTracerMatchesClosedForm) {
  const int w = 16, h = 16, spp = 256, rays = 4;
  for (const double alpha : kAlphas)
    for (const float a : kAlbedos) {
      const auto scene = greyCavity(alpha, a);
      const double f = cavityF(alpha), W = giClosedForm(f, a);
      const double tess = tessellationTolerance([&](double g) { return giClosedForm(g, a); }, f);
      RenderStats stats;
      const Film film =
          renderWith(*scene, cavityCamera(), "gi", {"rays=" + std::to_string(rays)}, passSettings(w, h, spp), &stats);
      const PixelStats s = pixelStats(film, kR);
      ASSERT_EQ(s.n, size_t(w * h));
      EXPECT_NEAR(s.mean, W, 4 * s.se + tess) << "alpha " << alpha << " a " << a;
      // Paths bounce: more secondary rays than one per path.
      EXPECT_GT(stats.rays.closest, uint64_t(w * h) * spp * rays);
    }
}

// max-depth = N without a closed tail is the truncated series too (roulette
// keeps it unbiased).
TEST(GiCavity, MaxDepthTruncates) {
  const double alpha = 1.0471975511965976;
  const float a = 0.85f;
  const auto scene = greyCavity(alpha, a);
  const double f = cavityF(alpha);
  for (const int depth : {0, 4}) {
    const Film film =
        renderWith(*scene, cavityCamera(), "gi", {"max-depth=" + std::to_string(depth), "rays=4"}, passSettings(16, 16, 256));
    const PixelStats s = pixelStats(film, kR);
    const double expected = truncatedClosedForm(f, a, depth);
    EXPECT_NEAR(s.mean, expected, 4 * s.se + tessellationTolerance([&](double g) { return truncatedClosedForm(g, a, depth); }, f))
        << "max-depth " << depth;
  }
}

// The error of gi falls (at least) like 1/sqrt(spp): the spread of the
// independent pixel estimates halves for each quadrupling of spp. The
// relative standard error of a sample standard deviation over N pixels is
// sqrt((kurtosis - 1) / (4N)); the ratio of two independent ones has about
// the root-sum-square of theirs; we allow 4 of those below the factor 2.
TEST(GiCavity, ErrorFallsLikeOneOverSqrtSpp) {
  const double alpha = 1.0471975511965976;
  const float a = 0.85f;
  const auto scene = greyCavity(alpha, a);
  const double W = giClosedForm(cavityF(alpha), a);
  PixelStats prev;
  for (const int spp : {4, 16, 64, 256}) {
    const Film film = renderWith(*scene, cavityCamera(), "gi", {}, passSettings(32, 32, spp, 7));
    const PixelStats s = pixelStats(film, kR);
    EXPECT_NEAR(s.mean, W, 4 * s.se + tessellationTolerance([&](double g) { return giClosedForm(g, a); }, cavityF(alpha)))
        << "spp " << spp;
    if (prev.n) {
      const auto relSe = [](const PixelStats& p) { return std::sqrt(std::max(p.kurtosis - 1.0, 0.0) / (4.0 * p.n)); };
      const double tol = std::hypot(relSe(prev), relSe(s));
      EXPECT_GE(prev.sd / s.sd, 2.0 * (1.0 - 4.0 * tol)) << "spp " << spp / 4 << " -> " << spp << ": sd " << prev.sd
                                                        << " -> " << s.sd;
    }
    prev = s;
  }
}

// --- invariants on the default scene ---------------------------------------------

std::unique_ptr<Scene> defaultSceneWithAlbedo(float a) {
  auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  for (Material& m : scene->materials) {
    m.baseColorFactor = Vec3(a, a, a);
    m.texture = -1;
  }
  return scene;
}

const std::vector<std::vector<std::string>> kMembershipConfigs = {
    {"falloff=step"},
    {"falloff=step", "distance=0.5"},
    {"falloff=linear", "distance=1"},
    {"falloff=sqrt", "distance=1"},
    {"falloff=exponential", "sigma=2"},
    {"falloff=exponential", "sigma=1", "distance=0.5"},
};

std::string describe(const std::vector<std::string>& p) {
  std::string s;
  for (const auto& x : p) s += x + " ";
  return s;
}

// White furnace: with every albedo 1 the closed form's numerator and
// denominator are equal sample for sample, so W == 1 exactly - every
// membership, both estimators, every depth with tail=closed.
TEST(TransferInvariants, WhiteFurnaceIsExactlyOne) {
  const auto scene = defaultSceneWithAlbedo(1.0f);
  for (auto config : kMembershipConfigs)
    for (const char* estimator : {"estimator=distance", "estimator=occlusion"})
      for (const char* depth : {"depth=0", "depth=2"}) {
        std::vector<std::string> p = config;
        p.insert(p.end(), {estimator, depth, "rays=2"});
        const Film film = renderWith(*scene, scene->cameras[0], "transfer", p, passSettings(48, 27, 4));
        size_t covered = 0;
        for (int y = 0; y < film.height(); ++y)
          for (int x = 0; x < film.width(); ++x)
            for (int c : {kR, kG, kB}) {
              covered += film.at(kA, x, y) > 0 && c == kR;
              ASSERT_EQ(film.at(c, x, y), film.at(kA, x, y)) << describe(p) << " pixel " << x << "," << y;
            }
        EXPECT_GT(covered, size_t(48 * 27 / 2));
      }
}

// gi in the white furnace converges to 1 (it is a plain mean: not exact).
TEST(GiInvariants, WhiteFurnaceConvergesToOne) {
  const auto scene = defaultSceneWithAlbedo(1.0f);
  for (const char* sigma : {"sigma=0", "sigma=3"}) {
    const Film film = renderWith(*scene, scene->cameras[0], "gi", {sigma}, passSettings(48, 27, 64));
    const PixelStats s = pixelStats(film, kR);
    ASSERT_GT(s.n, size_t(48 * 27 / 2));
    EXPECT_NEAR(s.mean, 1.0, 4 * s.se + 1e-6) << sigma;
  }
  // and in the cavity, where paths bounce many times before escaping
  const auto cavity = greyCavity(1.0471975511965976, 1.0f);
  const PixelStats s = pixelStats(renderWith(*cavity, cavityCamera(), "gi", {}, passSettings(16, 16, 256)), kR);
  EXPECT_NEAR(s.mean, 1.0, 4 * s.se + 1e-6);
}

// Black occluders: the transfer is the obscurance, bit for bit, for the same
// seed (same directions, same arithmetic, num/den = O/1 exactly).
TEST(TransferInvariants, BlackOccludersGiveObscuranceExactly) {
  const auto scene = defaultSceneWithAlbedo(0.0f);
  for (auto config : kMembershipConfigs)
    for (const char* estimator : {"estimator=distance", "estimator=occlusion"}) {
      std::vector<std::string> p = config;
      p.insert(p.end(), {estimator, "rays=3"});
      const Film o = renderWith(*scene, scene->cameras[0], "obscurance", p, passSettings(48, 27, 8, 5));
      for (const char* tail : {"depth=0", "depth=2"}) {
        std::vector<std::string> q = p;
        q.push_back(tail);
        const Film t = renderWith(*scene, scene->cameras[0], "transfer", q, passSettings(48, 27, 8, 5));
        size_t differ = 0;
        for (int y = 0; y < t.height(); ++y)
          for (int x = 0; x < t.width(); ++x)
            for (int c : {kR, kG, kB, kA}) differ += t.at(c, x, y) != o.at(c, x, y);
        EXPECT_EQ(differ, 0u) << describe(q);
      }
    }
}

// Albedo <= 1 (the textured default scene): W <= 1, i.e. R,G,B <= A.
TEST(TransferInvariants, NeverAboveOne) {
  const auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  for (auto config : kMembershipConfigs)
    for (const char* extra : {"depth=0", "depth=1", "estimator=occlusion"}) {
      std::vector<std::string> p = config;
      p.push_back(extra);
      const Film film = renderWith(*scene, scene->cameras[0], "transfer", p, passSettings(48, 27, 4));
      for (int y = 0; y < film.height(); ++y)
        for (int x = 0; x < film.width(); ++x)
          for (int c : {kR, kG, kB}) {
            ASSERT_TRUE(std::isfinite(film.at(c, x, y)));
            ASSERT_GE(film.at(c, x, y), 0.0f);
            ASSERT_LE(film.at(c, x, y), film.at(kA, x, y)) << describe(p) << " pixel " << x << "," << y;
          }
    }
}

// The ratio is formed per pixel, not per sample: with one ray per camera
// sample and spp = 1 the closed form in a grey cavity would be exactly AO
// (0 or 1 per pixel); with spp > 1 pixels take intermediate values that AO
// with the same samples cannot produce.
TEST(TransferInvariants, RatioIsPerPixel) {
  const auto scene = greyCavity(1.0471975511965976, 0.5f);
  const Film one = renderWith(*scene, cavityCamera(), "transfer", {}, passSettings(16, 16, 1));
  const Film ao = renderWith(*scene, cavityCamera(), "ao", {}, passSettings(16, 16, 1));
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x) ASSERT_EQ(one.at(kR, x, y), ao.at(kR, x, y));
  // spp = 2 with one open sample: 1 / (2 - a) = 2/3, not AO's 1/2.
  const Film two = renderWith(*scene, cavityCamera(), "transfer", {}, passSettings(16, 16, 2));
  const Film ao2 = renderWith(*scene, cavityCamera(), "ao", {}, passSettings(16, 16, 2));
  size_t mixed = 0;
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x)
      if (ao2.at(kR, x, y) == 0.5f) {
        ++mixed;
        EXPECT_FLOAT_EQ(two.at(kR, x, y), 1.0f / 1.5f);
      }
  EXPECT_GT(mixed, 0u);
}

// 0/0 - no open sample and every occluder white - resolves to 1.
TEST(TransferInvariants, ZeroOverZeroIsOne) {
  Scene scene;
  addSphereCavity(scene, 1.0f, 1e-3, 64, 128);  // nearly closed, albedo 1
  scene.setRobust(true);
  scene.commit();
  const Film film = renderWith(scene, cavityCamera(), "transfer", {}, passSettings(8, 8, 1));
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) EXPECT_EQ(film.at(kR, x, y), 1.0f);
}

}  // namespace
}  // namespace obscura::test
