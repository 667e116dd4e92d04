// The `containment` integrator (integrators/containment.cpp): obscurance of
// height-map displacement detail by containment tests on the undisplaced
// surface, against the same obscurance traced on the truly displaced,
// finely tessellated surface (core/subd/subdivision.h subdivide + displace).
//
// Scenes: a flat plane cage [0,1]^2 with uv = xy, displaced by ripples
// h(u) = 0.5 + 0.5 cos(2 pi P u) with midlevel 0.5, i.e. the field
// d = A cos(2 pi u / lambda), A = scale/2, lambda = 1/P; seen straight from
// above with a narrow lens (nearly orthographic), over the middle
// [0.25, 0.75]^2 so every ray within R stays over the plane. Both renders use
// the step falloff (AO) within R = lambda/2 (lambda in test 2) and the same
// seed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <obscura/error.h>
#include "core/subd/subdivision.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr size_t kBudget = size_t(1) << 30;
constexpr int kPeriods = 8;  // lambda = 1/8
constexpr double kLambda = 1.0 / kPeriods;
constexpr double kR = kLambda / 2;

// h(u, v) = 0.5 + 0.5 cos(2 pi P u): 1024 x 4 float texels, so bilinear
// interpolation errs by at most (1/1024)^2/8 (2 pi P)^2 0.5 = 1.5e-4 of the
// height amplitude 0.5 (0.03 %).
std::string writeFineRipples(const std::string& dir) {
  return writeHeightMap(dir + "/ripples.exr", 1024, 4, [](double u, double) { return 0.5 + 0.5 * std::cos(2 * M_PI * kPeriods * u); });
}

// The plane refined to `level`, displaced by `map` at `scale` when scale != 0.
void addRefinedPlane(Scene& scene, int level, const HeightMap* map, double scale, bool uvs = true, int material = -1) {
  SubdividedMesh m = subdivide(planeCage(4), SubdivisionScheme::CatmullClark, level, kBudget, "plane");
  if (map) displace(m, *map, scale, 0.5);
  scene.addWorldPrimitive(m.positions, m.triangles, m.normals, uvs ? m.uvs : std::vector<float>{}, material);
}

// Straight down at the middle of the plane, 0.5 x 0.5 in view.
Camera topCamera() {
  return makeLookAtCamera(Vec3(0.5f, 0.5f, 10.0f), Vec3(0.5f, 0.5f, 0.0f), Vec3(0, 1, 0), 2 * std::atan(0.025f), "top");
}

constexpr int kRes = 64, kSpp = 16, kRays = 4;

// Mean W over the image and its standard error. Every pixel is covered;
// the samples are kRes^2 kSpp kRays visibility draws whose Bernoulli
// variances sum to at most n p(1-p) for their mean p (concavity), so the
// Bernoulli standard error of the mean bounds the real one (stratification
// within a pixel only lowers it).
struct Mean {
  double value, stdErr;
};
Mean imageMean(const Film& f) {
  size_t n = 0;
  const double m = meanCovered(f, obscura::kR, &n);  // the channel, not the radius kR
  EXPECT_EQ(n, size_t(kRes) * kRes);
  return {m, bernoulliStdErr(m, double(n) * kSpp * kRays)};
}


// Traced: obscurance (step, R) of the plane refined to `level` and displaced.
Mean traced(const HeightMap& map, double scale, int level, double R = kR) {
  Scene scene;
  addRefinedPlane(scene, level, &map, scale);
  scene.commit();
  return imageMean(renderWith(scene, topCamera(), "obscurance",
                              {"distance=" + formatFloat(R), "estimator=occlusion", "rays=" + std::to_string(kRays)},
                              passSettings(kRes, kRes, kSpp)));
}

// Containment on the undisplaced plane (level 1) with m = steps.
Mean contained(const std::string& map, double scale, int steps, double R = kR) {
  Scene scene;
  addRefinedPlane(scene, 1, nullptr, 0);
  scene.commit();
  return imageMean(renderWith(scene, topCamera(), "containment",
                              {"map=" + map, "scale=" + formatFloat(scale), "midlevel=0.5", "distance=" + formatFloat(R),
                               "steps=" + std::to_string(steps), "rays=" + std::to_string(kRays)},
                              passSettings(kRes, kRes, kSpp)));
}

// 1. On a gentle field (amplitude A = lambda/(4 pi), max slope
//    A 2 pi / lambda = 0.5, R = lambda/2) containment converges to the traced
//    obscurance of the displaced surface. Tolerance = 4 standard errors of
//    the difference (the two estimates taken as independent; they share
//    their Sobol' points, which only lowers the variance of the difference)
//    plus a discretization bound: each side is also rendered with its
//    resolution halved (containment m = 16 -> 8 test points; tessellation
//    level 6 -> 5, i.e. 32 -> 16 vertices per wavelength) with the same
//    samples, and that change is taken as the bound on the remaining
//    discretization error of the finer one (which holds for any scheme
//    converging at first order or better; it also carries some noise, so it
//    errs on the large side). Measured (Release, seed 0): traced 0.96690
//    (level 5: 0.96797), containment 0.96650 (m = 8: 0.96652), SE 5e-4,
//    tolerance 3.1e-3 against an occlusion 1 - O = 0.033.
TEST(Containment, ConvergesToTracedDisplacementOnAGentleField) {
  const std::string dir = tempDir("containment_gentle");
  const std::string path = writeFineRipples(dir);
  const HeightMap map(path);
  const double scale = 2 * 0.5 * kLambda / (2 * M_PI);  // A = scale/2, slope A 2 pi / lambda = 0.5
  const Mean t6 = traced(map, scale, 6), t5 = traced(map, scale, 5);
  const Mean c16 = contained(path, scale, 16), c8 = contained(path, scale, 8);
  const double se = std::hypot(t6.stdErr, c16.stdErr);
  const double disc = std::abs(t6.value - t5.value) + std::abs(c16.value - c8.value);
  const double tol = 4 * se + disc;
  std::printf("gentle: traced L6 %.5f L5 %.5f, containment m16 %.5f m8 %.5f, SE %.2g, disc %.2g, tol %.2g\n",
              t6.value, t5.value, c16.value, c8.value, se, disc, tol);
  EXPECT_NEAR(c16.value, t6.value, tol);
  // Meaningful: the detail occludes several times the tolerance.
  EXPECT_GT(1.0 - t6.value, 5 * tol);
}

// 2. The paper's containment with m = 2 test points (the default) misses
//    more as the field steepens: with R = lambda (a ray reaches the next
//    crest), |containment - traced| at max slopes 0.25, 1 and 2
//    (A/lambda = 0.04, 0.16, 0.32), traced at level 6. Each step up in
//    slope must raise the error by more than 4 standard errors of the
//    difference (each error's SE from its two renders' sample counts). Measured (Release, seed 0): 0.0015, 0.0172, 0.0386
//    (containment too bright: crests crossed between the test points at
//    lambda/2 and lambda are missed); the full table, with R = lambda/2 and
//    2 lambda and m = 16: docs/containment.md.
TEST(Containment, ErrorGrowsWithSteepness) {
  const std::string dir = tempDir("containment_steep");
  const std::string path = writeFineRipples(dir);
  const HeightMap map(path);
  std::vector<double> err, se;
  for (const double slope : {0.25, 1.0, 2.0}) {
    const double scale = 2 * slope * kLambda / (2 * M_PI);
    const Mean t = traced(map, scale, 6, kLambda), c = contained(path, scale, 2, kLambda);
    err.push_back(std::abs(c.value - t.value));
    se.push_back(std::hypot(t.stdErr, c.stdErr));
    std::printf("slope %.2f (A/lambda %.3f): traced %.5f containment(m=2) %.5f |err| %.5f SE %.2g\n", slope,
                scale / 2 / kLambda, t.value, c.value, err.back(), se.back());
  }
  EXPECT_GT(err[1] - err[0], 4 * std::hypot(se[1], se[0]));
  EXPECT_GT(err[2] - err[1], 4 * std::hypot(se[2], se[1]));
}

// 3a. A map that cannot be read, or none, is an error naming the file.
TEST(Containment, BadMapIsAnErrorNamingTheFile) {
  Scene scene;
  addPlane(scene, 1.0f);
  scene.commit();
  const std::string missing = tempDir("containment_bad") + "/no_such_height.png";
  try {
    renderWith(scene, topCamera(), "containment", {"map=" + missing, "distance=0.1"}, passSettings(4, 4, 1));
    ADD_FAILURE() << "a missing map was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  try {
    renderWith(scene, topCamera(), "containment", {"distance=0.1"}, passSettings(4, 4, 1));
    ADD_FAILURE() << "no map was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'map'"), std::string::npos) << e.what();
  }
}

// 3b. Without texture coordinates the integrator is plain obscurance (the
//     occlusion estimator) of the macro geometry, bit for bit; with a flat
//     field (scale 0) on a uv-mapped plane too, since the displaced normal
//     is then the plane's and the macro ray decides alone. A box-shaped
//     wall stands on the plane so the macro rays have something to find.
TEST(Containment, WithoutUvsOrDisplacementItIsObscurance) {
  const std::string dir = tempDir("containment_fallback");
  const std::string path = writeFineRipples(dir);
  for (const bool uvs : {false, true}) {
    Scene scene;
    addRefinedPlane(scene, 1, nullptr, 0, uvs);
    scene.addWorldPrimitive({{0.5f, 0.2f, 0}, {0.5f, 0.8f, 0}, {0.5f, 0.8f, 0.2f}, {0.5f, 0.2f, 0.2f}},
                            {0, 1, 2, 0, 2, 3}, {}, {}, -1);
    scene.commit();
    const Camera cam = makeLookAtCamera(Vec3(0.5f, 0.5f, 3), Vec3(0.5f, 0.5f, 0), Vec3(0, 1, 0), 0.2f, "top");
    for (const char* falloff : {"step", "linear", "exponential"}) {
      const std::vector<std::string> common = {std::string("falloff=") + falloff, "distance=0.15", "sigma=10",
                                               "rays=2"};
      std::vector<std::string> c = common;
      c.insert(c.end(), {"map=" + path, uvs ? "scale=0" : "scale=0.05"});
      std::vector<std::string> o = common;
      o.push_back("estimator=occlusion");
      const Film fc = renderWith(scene, cam, "containment", c, passSettings(24, 24, 4));
      const Film fo = renderWith(scene, cam, "obscurance", o, passSettings(24, 24, 4));
      double occluded = 0;
      for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 24; ++x) {
          ASSERT_EQ(fc.at(obscura::kR, x, y), fo.at(obscura::kR, x, y)) << falloff << " uvs " << uvs << " pixel " << x << "," << y;
          occluded += 1.0 - fo.at(obscura::kR, x, y);
        }
      EXPECT_GT(occluded, 1.0) << "the wall occludes";
    }
  }
}

// 5. The transfer of eq. 9 (albedo=true) against two invariants. With a
//    grey plane of albedo a and nothing else above it, only the height field
//    closes samples, each with a~ = a, so a pixel's ratio of sums is
//    S / (N - a (N - S)) = O / (1 - a (1 - O)) for the obscurance O = S / N of
//    the very same samples (albedo=false): the closed form of docs/math.md's
//    transfer with one grey occluder, to float rounding of the per-sample
//    means (1e-6). With every albedo 1 - plane and a wall standing on it -
//    every closed sample adds 1 - 1 = 0 to the denominator: W = 1 exactly
//    (the white furnace), wherever the field or the wall closes.
TEST(Containment, TransferMatchesTheClosedFormAndTheWhiteFurnace) {
  const std::string dir = tempDir("containment_transfer");
  const std::string path = writeFineRipples(dir);
  const std::vector<std::string> p = {"map=" + path, "scale=0.04", "distance=0.1", "rays=4"};
  {
    Scene scene;
    const float a = 0.6f;
    addRefinedPlane(scene, 1, nullptr, 0, true, addGreyMaterial(scene, a));
    scene.commit();
    std::vector<std::string> t = p;
    t.push_back("albedo=true");
    const Film fo = renderWith(scene, topCamera(), "containment", p, passSettings(16, 16, 8));
    const Film ft = renderWith(scene, topCamera(), "containment", t, passSettings(16, 16, 8));
    double open = 0;
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) {
        const double O = fo.at(obscura::kR, x, y);
        EXPECT_NEAR(ft.at(obscura::kR, x, y), O / (1 - a * (1 - O)), 1e-6) << x << "," << y;
        open += O;
      }
    EXPECT_LT(open, 16 * 16 * 0.999) << "the field closes some samples";
  }
  Scene white;
  const int one = addGreyMaterial(white, 1.0f);
  addRefinedPlane(white, 1, nullptr, 0, true, one);
  white.addWorldPrimitive({{0.5f, 0.2f, 0}, {0.5f, 0.8f, 0}, {0.5f, 0.8f, 0.2f}, {0.5f, 0.2f, 0.2f}}, {0, 1, 2, 0, 2, 3},
                          {}, {}, one);
  white.commit();
  std::vector<std::string> t = p;
  t.push_back("albedo=true");
  const Camera cam = makeLookAtCamera(Vec3(0.5f, 0.5f, 3), Vec3(0.5f, 0.5f, 0), Vec3(0, 1, 0), 0.2f, "top");
  const Film f = renderWith(white, cam, "containment", t, passSettings(16, 16, 8));
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 16; ++x)
      if (f.at(kA, x, y) > 0) {
        ASSERT_EQ(f.at(obscura::kR, x, y), 1.0f) << x << "," << y;
      }
}

// 4. Extreme parameters stay finite and in [0, 1]: huge and tiny scales,
//    R = 0 (nothing occludes: exactly 1 on the plane), a huge exponential
//    reach, a midlevel far outside the map's range, and a finite distance
//    that is infinite as a float is refused like inf.
TEST(Containment, ExtremeParametersStayFiniteAndInRange) {
  const std::string dir = tempDir("containment_extreme");
  const std::string path = writeFineRipples(dir);
  Scene scene;
  addRefinedPlane(scene, 1, nullptr, 0);
  scene.commit();
  const std::vector<std::vector<std::string>> configs = {
      {"scale=1e30", "distance=0.1"},
      {"scale=-1e30", "distance=0.1", "falloff=linear"},
      {"scale=1e-30", "distance=1e30", "falloff=sqrt"},
      {"scale=0.05", "falloff=exponential", "sigma=1e-30", "distance=inf"},
      {"scale=0.05", "falloff=exponential", "sigma=1e30"},
      {"scale=0.05", "midlevel=-1e30", "distance=0.1"},
      {"scale=0.05", "distance=0"},
  };
  for (const auto& c : configs) {
    std::vector<std::string> p = c;
    p.insert(p.end(), {"map=" + path, "rays=2", "steps=3"});
    const Film f = renderWith(scene, topCamera(), "containment", p, passSettings(8, 8, 2));
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) {
        const float w = f.at(obscura::kR, x, y);
        ASSERT_TRUE(w >= 0.0f && w <= 1.0f) << c[0] << " " << c[1] << ": " << w;
        if (c.back() == "distance=0") {
          ASSERT_EQ(w, 1.0f);
        }
      }
  }
  for (const char* R : {"distance=inf", "distance=1e300"})
    EXPECT_THROW(renderWith(scene, topCamera(), "containment", {"map=" + path, R}, passSettings(4, 4, 1)), Error) << R;
}


// 6. The transfer (albedo=true) against traced displacement with `transfer`
//    (estimator=occlusion, depth 0: the same ratio Sum I / (n - Sum (1 - I) a)
//    over the same kind of samples, with a the albedo of the closest
//    occluder on the segment), on ripples of max slope 2 with R = lambda/2.
//    The plane's albedo texture is (0.9, 0.5, 0.1) on the rising slopes
//    (valley to crest, in +u) and (0.1, 0.5, 0.9) on the falling ones, so a
//    receiver on one slope is mostly occluded by the facing slope across the
//    valley, of the other albedo: where each sample reads ã matters, and it
//    is read where containment is exact. With R <= lambda/2 a segment that
//    enters the field through the facing slope cannot reach the next crest,
//    so every test point after the crossing is inside and under that same
//    slope: the first inside one has the crossing's albedo, except within a
//    texel of a step or r/m of a crest.
//    Means are taken over the receivers of each slope (by the albedo AOV;
//    pixels astride a step are left out) - over the whole image the two
//    slopes' errors would cancel. Tolerance: 4 standard errors of the mean of
//    the paired per-pixel differences (pixels are independent estimates; the
//    two renders share their samples, which makes the pairs close) plus the
//    discretization bound of test 1, |traced L6 - L5| + |containment m16 - m8|.
//    Both sides are ratios of sums over the same number of samples, so their
//    O(1/n) biases (docs/math.md §4) agree to the order of the difference
//    the test bounds. It must see where ã is read: with the texture shifted
//    by half a period (each slope taking the other's albedo) containment must
//    miss by more than 5 tolerances. (Measured: reading ã at the receiver's
//    own uv instead of the inside point's misses by about 10 tolerances.)
std::string writeAlbedoTexture(const std::string& path, double shift) {
  return writeRgbTexture(path, 1024, 4, [&](double u, double) {
    const bool rising = std::fmod(u * kPeriods + shift, 1.0) > 0.5;
    return rising ? Vec3(0.9f, 0.5f, 0.1f) : Vec3(0.1f, 0.5f, 0.9f);
  });
}

TEST(Containment, TransferConvergesToTracedTransfer) {
  const std::string dir = tempDir("containment_traced_transfer");
  const std::string path = writeFineRipples(dir);
  const std::string albedo = writeAlbedoTexture(dir + "/albedo.png", 0.0);
  const std::string shifted = writeAlbedoTexture(dir + "/shifted.png", 0.5);
  const HeightMap map(path);
  const double scale = 2 * 2.0 * kLambda / (2 * M_PI);  // max slope 2
  const std::string R = "distance=" + formatFloat(kR), rays = "rays=" + std::to_string(kRays);
  RenderSettings settings = passSettings(kRes, kRes, kSpp);
  settings.aovs = true;
  const auto tracedFilm = [&](int level) {
    Scene scene;
    addRefinedPlane(scene, level, &map, scale, true, addTexturedMaterial(scene, albedo));
    scene.commit();
    return renderWith(scene, topCamera(), "transfer", {R, rays, "estimator=occlusion"}, settings);
  };
  const auto containedFilm = [&](int steps, const std::string& texture) {
    Scene scene;
    addRefinedPlane(scene, 1, nullptr, 0, true, addTexturedMaterial(scene, texture));
    scene.commit();
    return renderWith(scene, topCamera(), "containment",
                      {"map=" + path, "scale=" + formatFloat(scale), "midlevel=0.5", R, rays, "albedo=true",
                       "steps=" + std::to_string(steps)},
                      settings);
  };
  const Film t6 = tracedFilm(6), t5 = tracedFilm(5);
  const Film c16 = containedFilm(16, albedo), c8 = containedFilm(8, albedo), wrong = containedFilm(16, shifted);
  // The receivers on each side, by the albedo AOV (pixels astride a step,
  // with a mixed albedo, are left out).
  double worstWrong = 0;
  for (const bool rising : {false, true}) {
    const auto inRegion = [&](int x, int y) {
      const float a = c16.at(kAlbedoR, x, y);
      return rising ? a > 0.85f : a < 0.15f;
    };
    for (int c = 0; c < 3; ++c) {
      const int ch = obscura::kR + c;
      double n = 0, mt6 = 0, mt5 = 0, mc16 = 0, mc8 = 0, mw = 0, d = 0, dd = 0;
      for (int y = 0; y < kRes; ++y)
        for (int x = 0; x < kRes; ++x) {
          if (!inRegion(x, y)) continue;
          const double diff = c16.at(ch, x, y) - t6.at(ch, x, y);
          n += 1, mt6 += t6.at(ch, x, y), mt5 += t5.at(ch, x, y), mc16 += c16.at(ch, x, y), mc8 += c8.at(ch, x, y);
          mw += wrong.at(ch, x, y), d += diff, dd += diff * diff;
        }
      ASSERT_GT(n, kRes * kRes / 4) << "receivers on the " << (rising ? "rising" : "falling") << " slopes";
      mt6 /= n, mt5 /= n, mc16 /= n, mc8 /= n, mw /= n, d /= n;
      const double se = std::sqrt((dd / n - d * d) / (n - 1));  // paired differences of independent pixels
      const double disc = std::abs(mt6 - mt5) + std::abs(mc16 - mc8);
      const double tol = 4 * se + disc;
      std::printf("transfer, %s slopes, channel %d: traced L6 %.5f L5 %.5f, containment m16 %.5f m8 %.5f (texture "
                  "shifted %.5f), SE %.2g, disc %.2g, tol %.2g\n",
                  rising ? "rising" : "falling", c, mt6, mt5, mc16, mc8, mw, se, disc, tol);
      EXPECT_NEAR(mc16, mt6, tol) << (rising ? "rising" : "falling") << " channel " << c;
      worstWrong = std::max(worstWrong, std::abs(mw - mt6) / tol);
    }
  }
  EXPECT_GT(worstWrong, 5.0) << "the test does not see where the occluder's albedo is read";
}

}  // namespace
}  // namespace obscura::test
