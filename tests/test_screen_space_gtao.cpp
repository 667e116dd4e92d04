// The screen-space integrator `gtao` (integrators/screen_space/gtao.cpp,
// docs/math.md §15) against closed forms, its traced twin, and extremes.
//
// Tolerances: as in tests/test_screen_space.cpp, 4 standard errors of a mean
// over pixels, from independent replicate renders (seeds 1..n; the
// interleave pattern shares randomness across a layer's pixels, and even
// without it a layer's step jitter does), plus the deterministic bounds
// named where they apply.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include <obscura/error.h>
#include "integrators/multibounce_mapping.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// --- an open plane -------------------------------------------------------------

// Nothing within R but the plane itself: every slice's horizons are the
// tangent plane, so the occluded part is zero in every slice and W = 1 in
// every pixel, not only in the mean (the estimator is 1 minus the occluded
// arcs; docs/math.md §15). The plane's own samples sit on the tangent plane
// to float rounding: a horizon lifted by delta costs ~delta^2 (the
// integrand vanishes at the tangent plane), and samples within 1e-4 |P| of
// P, where delta could reach 1e-3, are no candidates: 1e-5 bounds it. For a
// plane facing the camera head-on and one seen obliquely (normals far from
// the view direction, |n_p| and gamma varying over the slices), R from a
// fraction of a pixel to far beyond the image, both interleavings and depth
// sources.
TEST(GtaoPlane, OpenPlaneIsOne) {
  Scene scene;
  addPlane(scene, 50.0f);
  scene.commit();
  const Camera cams[] = {makeLookAtCamera(Vec3(0, 0, 6), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.6f, "frontal"),
                         makeLookAtCamera(Vec3(0, -6, 4), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "oblique")};
  for (const Camera& cam : cams)
    for (const char* r : {"radius=0.01", "radius=1", "radius=100"})
      for (const char* inter : {"interleave=off", "interleave=on"})
        for (const char* depth : {"depth=gbuffer", "depth=traced"}) {
          const auto w = coveredW(renderWith(scene, cam, "gtao", {r, inter, depth, "e0=bent"}, passSettings(40, 30, 2, 3)));
          ASSERT_FALSE(w.empty());
          for (double x : w) ASSERT_NEAR(x, 1.0, 1e-5) << cam.name << " " << r << " " << inter << " " << depth;
        }
}

// --- the crease ---------------------------------------------------------------------

// On the crease (floor z = 0, wall x = 0; tests/support.h) every slice's
// visible set is one interval of directions bounded by the wall's highest
// point within R, so GTAO's horizon model is exact there and the estimator
// is unbiased for creaseCosine(h, R) - the visibility `ao distance=R`
// estimates - up to the horizon search: the wall's point at distance R is
// found exactly (the crossing of R between two samples on the wall's
// plane), but a wall piece that no sample lands on is missed, which biases
// W towards open (measured here, R = 0.5: +0.028 at steps=2, +0.0043 at 8,
// +0.0011 at 32, +0.0007 at 64; SE ~0.0003). The mean over the pixels of
// W - v(h) at steps=32 is 0 within 4 standard errors (16 replicates) plus
// the pixel footprint (creaseCentres with creaseCosine's slope 2/pi: 0.09
// in this fixture, which bounds the search's bias too).
TEST(GtaoCrease, MatchesTheClosedForm) {
  const Crease c;
  const int w = 64, h = 48;
  const double R = 0.5;
  const CreaseCentres cc = creaseCentres(c, w, h, R, creaseCosine, 2.0 / 3.14159265358979323846);
  ASSERT_GT(cc.pixels.size(), 100u);
  for (const char* depth : {"depth=gbuffer", "depth=traced"})
    for (const char* inter : {"interleave=off", "interleave=on"}) {
      const MeanSe m = replicateMean(16, [&](uint32_t seed) {
        // filter-depth=0: the interleave pattern without the 4x4 filter,
        // whose average over neighbours of other h the footprint bound
        // does not cover.
        const Film f = renderWith(c.scene, c.cam, "gtao", {"radius=0.5", depth, inter, "filter-depth=0", "steps=32"},
                                  passSettings(w, h, 2, seed));
        double sum = 0.0;
        size_t n = 0;
        for (size_t k = 0; k < cc.pixels.size(); ++k)
          if (f.at(kA, cc.pixels[k].first, cc.pixels[k].second) == 1.0f)
            sum += f.at(kR, cc.pixels[k].first, cc.pixels[k].second) - cc.V[k], ++n;
        return sum / double(n);
      });
      EXPECT_NEAR(m.mean, 0.0, 4 * m.se + cc.footprint)
          << depth << " " << inter << " se " << m.se << " footprint " << cc.footprint;
      RecordProperty(std::string("gtao_crease_bias_") + depth + "_" + inter,
                     std::to_string(m.mean) + " se " + std::to_string(m.se) + " footprint " + std::to_string(cc.footprint));
    }
}

// --- the traced twin --------------------------------------------------------------

// Where the depth buffer holds every occluder (the crease: both planes seen
// by the camera within R of every floor pixel), reading z* from the buffer
// and tracing the camera ray estimate the same W: the buffer's reads
// intersect the stored planes, exact for the crease's two planes but for
// the pixels the crease line crosses, whose one stored plane stands for
// both (the discretization the traced twin removes). Independent renders
// (seeds 1..16 and 101..116): the mean difference over the pixels within
// 4 standard errors of the difference of the two replicate means. The
// paired difference (same seeds, every slice and jitter shared), the
// crease line's share alone, is recorded: |mean| ~1e-4 here.
TEST(GtaoTraced, AgreesWithTheDepthBuffer) {
  const Crease c;
  const int w = 64, h = 48;
  const CreaseCentres cc = creaseCentres(c, w, h, 0.5, creaseCosine, 2.0 / 3.14159265358979323846);
  ASSERT_GT(cc.pixels.size(), 100u);
  const auto mean = [&](const Film& f) {
    double sum = 0.0;
    for (auto [x, y] : cc.pixels) sum += f.at(kR, x, y);
    return sum / double(cc.pixels.size());
  };
  for (const char* r : {"radius=0.25", "radius=0.5", "radius=1"}) {
    const auto render = [&](uint32_t seed, const char* depth) {
      return mean(renderWith(c.scene, c.cam, "gtao", {r, "interleave=off", depth}, passSettings(w, h, 2, seed)));
    };
    const MeanSe gb = replicateMean(16, [&](uint32_t seed) { return render(seed, "depth=gbuffer"); });
    const MeanSe tr = replicateMean(16, [&](uint32_t seed) { return render(seed + 100, "depth=traced"); });
    const double se = std::sqrt(gb.se * gb.se + tr.se * tr.se);
    EXPECT_NEAR(gb.mean - tr.mean, 0.0, 4 * se) << r << " se " << se;
    const MeanSe paired = replicateMean(8, [&](uint32_t seed) { return render(seed, "depth=gbuffer") - render(seed, "depth=traced"); });
    RecordProperty(std::string("gtao_gbuffer_minus_traced_") + r, std::to_string(gb.mean - tr.mean) + " se " + std::to_string(se));
    RecordProperty(std::string("gtao_gbuffer_minus_traced_paired_") + r,
                   std::to_string(paired.mean) + " se " + std::to_string(paired.se));
  }
}

// --- multi-bounce -------------------------------------------------------------------

// multibounce=on maps each pixel's converged W with GTAO's cubic and the
// pixel's albedo (resolvePixel): on a grey crease (albedo 0.6) every pixel
// equals gtaoMultiBounce(W without it, 0.6), to float rounding of W (the
// two renders share every sample).
TEST(GtaoMultiBounce, MapsEachPixel) {
  const Crease c;  // (its camera)
  Scene scene;
  const int grey = addGreyMaterial(scene, 0.6f);
  scene.addWorldPrimitive({{0, -10, 0}, {10, -10, 0}, {10, 10, 0}, {0, 10, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, grey);
  scene.addWorldPrimitive({{0, -10, 0}, {0, 10, 0}, {0, 10, 10}, {0, -10, 10}}, {0, 1, 2, 0, 2, 3}, {}, {}, grey);
  scene.commit();
  const RenderSettings s = passSettings(32, 24, 2, 5);
  const Film off = renderWith(scene, c.cam, "gtao", {"radius=0.5"}, s);
  const Film on = renderWith(scene, c.cam, "gtao", {"radius=0.5", "multibounce=on"}, s);
  int darker = 0;
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 32; ++x) {
      if (off.at(kA, x, y) != 1.0f) continue;
      const double W = off.at(kR, x, y);
      ASSERT_NEAR(on.at(kR, x, y), gtaoMultiBounce(W, 0.6), 1e-6) << x << "," << y;
      darker += W < 0.95;
    }
  EXPECT_GT(darker, 10);  // the comparison covered occluded pixels
}

// --- extremes ------------------------------------------------------------------------

// R over the parameter's whole range on the crease, with the bent normal,
// traced and multibounce: every pixel finite and in [0, 1]; a radius below
// the separation the search ignores (1e-4 of the camera distance) leaves
// nothing to occlude: exactly 1.
TEST(GtaoExtremes, RadiusOverItsWholeRange) {
  const Crease c;
  for (const char* r : {"1e-30", "1e-10", "1e-3", "1", "1e3", "1e10", "1e19", "1e30"}) {
    for (const std::vector<std::string>& extra :
         {std::vector<std::string>{"e0=bent"}, {"depth=traced", "interleave=off"}, {"multibounce=on", "steps=1"}}) {
      std::vector<std::string> p = extra;
      p.push_back(std::string("radius=") + r);
      const Film f = renderWith(c.scene, c.cam, "gtao", p, passSettings(24, 16, 2));
      for (int y = 0; y < f.height(); ++y)
        for (int x = 0; x < f.width(); ++x) {
          const float a = f.at(kA, x, y), v = f.at(kR, x, y);
          ASSERT_TRUE(std::isfinite(v)) << r << " " << extra[0];
          ASSERT_GE(v, 0.0f) << r;
          ASSERT_LE(v, a * (1.0f + 1e-6f)) << r;
        }
      if (std::stod(r) < 1e-9) {
        EXPECT_EQ(meanCovered(f, kR), 1.0) << r << " " << extra[0];
      }
    }
  }
}

TEST(GtaoErrors, BadParameters) {
  const Crease c;
  EXPECT_THROW(renderWith(c.scene, c.cam, "gtao", {"slices=0"}, passSettings(4, 4, 1)), Error);
  EXPECT_THROW(renderWith(c.scene, c.cam, "gtao", {"steps=65"}, passSettings(4, 4, 1)), Error);
  EXPECT_THROW(renderWith(c.scene, c.cam, "gtao", {"radius=-1"}, passSettings(4, 4, 1)), Error);
  EXPECT_THROW(renderWith(c.scene, c.cam, "gtao", {"count=4"}, passSettings(4, 4, 1)), Error);
  EXPECT_EQ(IntegratorRegistry::instance().find("gtao").kind, IntegratorKind::ScreenSpace);
}

}  // namespace
}  // namespace obscura::test
