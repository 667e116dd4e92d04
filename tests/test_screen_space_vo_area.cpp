// `vo samples=area` (VO §4.2, docs/math.md §8 "Area samples"): the depth
// moments' Gaussian pre-blur and parallel-variance merge, and the open
// grazing plane, which the plane-relative spread makes read 1.
//
// Statistics: vo shares randomness across an image (per-layer shifts), so
// standard errors come from 16 replicate renders (replicateMean, seeds
// 1..16) at a fixed 2 spp; tolerances are 4 of those standard errors plus
// the deterministic bound named at each test.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "core/render/gbuffer.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// A layer of w x h pixels whose depths are given directly (no planes: the
// moments fall back to the stored depth, as for a plane seen edge-on).
GBufferLayer depthLayer(int w, int h, const std::function<float(int, int)>& depth) {
  GBufferLayer g;
  g.width = w, g.height = h;
  g.shaded = g.image = {0, 0, w, h};
  g.view.width = float(w), g.view.height = float(h);
  g.view.filmScaleX = g.view.filmScaleY = 1.0f;
  const size_t n = size_t(w) * size_t(h);
  g.depth.resize(n), g.depthSlack.resize(n), g.plane.assign(n, {0, 0, 0, 0});
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float z = depth(x, y);
      g.depth[g.index(x, y)] = z;
      g.depthSlack[g.index(x, y)] = {z, 0.0f};
    }
  return g;
}

// The pre-blur and the mip chain on a ramp z = 100 + 0.01 x, far from 0
// against its slope: a texel's variance is the slope^2 times the variance
// of the pixel centres it mixes, per axis - the Gaussian's
// momentBlurVariance() at level 0, plus (4^l - 1) / 12 for a block of 2^l
// pre-blurred pixels. Exact for the mixture merge in real arithmetic;
// E[z^2] - E[z]^2 in float would lose it all (z^2 ~ 1e4, ulp 1e-3, against a
// variance of ~1e-4). Tolerance: the stored depths and means are floats
// (ulp 2^-17 at 100), each off by at most half an ulp, so a deviation from
// the mean is off by at most 2^-17 - against the smallest nonzero
// deviation, half the slope (a level-1 block's two columns), 0.15 %, a
// variance 0.31 % (+ its own float rounding, 1e-6). A texel's mean: within
// 2^-17 (its rounding and the inputs'). Pixels within 2 of the edge (the
// blur is renormalised there) are left out.
TEST(VoAreaMoments, PreBlurAndMipsMergeTheRampExactly) {
  const int w = 32, h = 16;
  const float slope = 0.01f;
  GBufferLayer g = depthLayer(w, h, [&](int x, int) { return 100.0f + slope * float(x); });
  const double deviation = std::ldexp(1.0, -17), relative = 2 * deviation / (0.5 * slope) + 1e-6;
  for (bool prefilter : {false, true}) {
    buildDepthMoments(g, 3, prefilter);
    const double blur = prefilter ? momentBlurVariance() : 0.0;
    for (int l = 0; l < 3; ++l) {
      const DepthMoments& m = g.moments[size_t(l)];
      const int step = 1 << l;
      const double expected = double(slope) * slope * ((double(step) * step - 1.0) / 12.0 + blur);
      for (int by = 0; by < m.height; ++by)
        for (int bx = 0; bx < m.width; ++bx) {
          if (bx * step < 2 || (bx + 1) * step > w - 2) continue;
          const size_t j = size_t(by) * size_t(m.width) + size_t(bx);
          ASSERT_EQ(m.coverage[j], 1.0f);
          // The mean: the ramp at the block's centre (the blur is symmetric).
          EXPECT_NEAR(m.mean[j], 100.0 + slope * ((bx + 0.5) * step - 0.5), deviation) << l << " " << bx;
          if (expected == 0.0)
            EXPECT_EQ(m.variance[j], 0.0f);
          else
            EXPECT_NEAR(m.variance[j], expected, relative * expected)
                << "level " << l << " texel " << bx << "," << by << " prefilter " << prefilter;
        }
    }
  }
}

// The pre-blur keeps background out of the moments (coverage, not depth):
// next to a background column the covered pixels' mean and variance are
// those of the covered neighbours only, and coverage is the Gaussian's
// share of covered taps.
TEST(VoAreaMoments, PreBlurKeepsBackgroundAsCoverage) {
  const int w = 12, h = 8;
  GBufferLayer g = depthLayer(w, h, [](int x, int) { return x == 6 ? kInfinity : 5.0f; });
  for (size_t i = 0; i < g.depth.size(); ++i)
    if (g.depth[i] == kInfinity) g.depthSlack[i] = {kInfinity, 0.0f};
  buildDepthMoments(g, 1, true);
  const DepthMoments& m = g.moments[0];
  const float* wt = kMomentBlurWeights;
  const float sum = wt[0] + wt[1] + wt[2] + wt[3] + wt[4];
  for (int x = 3; x <= 9; ++x) {
    const size_t j = g.index(x, 4);
    const int off = 6 - x;  // the background column's tap
    const float expected = std::abs(off) <= kMomentBlurRadius ? 1.0f - wt[off + kMomentBlurRadius] / sum : 1.0f;
    EXPECT_NEAR(m.coverage[j], expected, 1e-6f) << x;
    EXPECT_EQ(m.mean[j], 5.0f) << x;
    // (Not exactly 0: the merge's mean is a double quotient of floats, off
    // by ~2^-52 relative, and the spread about it is squared: < 1e-28.)
    EXPECT_LE(m.variance[j], 1e-28f) << x;
  }
}

// The open floor seen at a grazing angle (camera 1.2 up, 8 back, looking at
// the origin: incidence 81 degrees at the image's centre, 90 at the horizon,
// row 10 of 36; R = 0.3). docs/math.md §8 "The plane-relative spread": with
// the normal clamp the chord through a disk point ends where its ray meets
// the tangent plane; on an open plane the surface is that plane, so every
// ray of a footprint is free up to its own clamp and W = 1. vo models the
// footprint's surface relative to the plane, delta = z - p: on the plane the
// texels' offsets from the plane at their centres, mu_j - p(c_j), are the
// plane's own curvature over the texel, ~ p |grad p / p|^2 V_l >= 0 (the
// depth of a plane is convex along every image line), so the model's
// surface lies behind the clamp, and the spread that remains,
// |sigma_j - sigma_p,j| and the texels' differences after that curvature is
// taken out, is of higher order in the footprint over the distance to the
// horizon (vo expands both to 4th order): the box mean +- sqrt(3) sd stays
// behind the clamp and each chord's free length is its whole length. What is left is float rounding: the clamp s1 and the box's
// lower end are floats computed from lengths <= z_max + R (z_max <= 60 on
// this floor: its far edge is 58 from the camera) in a few roundings each,
// so they may cross by up to 16 ulps, 16 x 2^-24 (z_max + R), a length lost
// from a chord; W = Sum a_k free_k / Sum a_k chord_k with Sum a_k ~ 3/4 and
// Sum a_k chord_k ~ R / 2 for the clamped half-ball (the disk set's chord
// weights, test_screen_space.cpp WithoutTheNormalIsHalf), so W loses at most
// eps = 1.5 x 16 x 2^-24 (z_max + R) / R = 2.9e-4. Rows from 16 down (the
// footprint, <= 2.2 pixels sd there, well under the distance to the
// horizon, >= 6 pixels); the test asserts |mean - 1| <= 4 SE (16
// replicates) + eps, with the pre-blur and without. Before the
// plane-relative spread the same rows read ~0.91 (box mu +- sigma, no
// pre-blur). The whole image, horizon rows included, is recorded.
struct GrazingFloor {
  Scene scene;
  Camera cam = makeLookAtCamera(Vec3(0, -8, 1.2f), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.6f, "grazing");
  static constexpr int w = 48, h = 36, first = 16, border = 2, replicates = 16;
  static constexpr double R = 0.3, zMax = 60.0;
  static constexpr double eps = 1.5 * 16 * 0x1p-24 * (zMax + R) / R;  // float rounding (above)
  GrazingFloor() {
    addPlane(scene, 50.0f);
    scene.commit();
  }
  // Per replicate, the mean W of each row from `first` down (covered pixels
  // at least `border` from the sides).
  std::vector<std::vector<double>> rowMeans(const std::vector<std::string>& params) const {
    std::vector<std::vector<double>> rows(static_cast<size_t>(h));  // [row][replicate]
    for (uint32_t seed = 1; seed <= uint32_t(replicates); ++seed) {
      const Film f = renderWith(scene, cam, "vo", params, passSettings(w, h, 2, seed));
      for (int y = first; y < h; ++y) {
        double sum = 0.0;
        int n = 0;
        for (int x = border; x < w - border; ++x)
          if (f.at(kA, x, y) == 1.0f) sum += f.at(kR, x, y), ++n;
        rows[size_t(y)].push_back(n > 0 ? sum / n : 0.0);
      }
    }
    return rows;
  }
};

TEST(VoAreaGrazing, OpenPlaneReadsOne) {
  const GrazingFloor v;
  for (const char* prefilter : {"prefilter=on", "prefilter=off"}) {
    const std::vector<std::string> p = {"samples=area", "radius=0.3", prefilter};  // R
    const MeanSe m = replicateMean(GrazingFloor::replicates, [&](uint32_t seed) {
      const Film f = renderWith(v.scene, v.cam, "vo", p, passSettings(GrazingFloor::w, GrazingFloor::h, 2, seed));
      double sum = 0.0;
      int n = 0;
      for (int y = GrazingFloor::first; y < GrazingFloor::h; ++y)
        for (int x = GrazingFloor::border; x < GrazingFloor::w - GrazingFloor::border; ++x)
          if (f.at(kA, x, y) == 1.0f) sum += f.at(kR, x, y), ++n;
      return sum / n;
    });
    EXPECT_NEAR(m.mean, 1.0, 4 * m.se + GrazingFloor::eps) << prefilter << " se " << m.se;
    RecordProperty(std::string("vo_area_grazing_mean_") + prefilter, std::to_string(m.mean));
    // The whole image, horizon rows included (recorded, not asserted: near
    // the horizon the footprint outgrows the distance to it).
    const Film f = renderWith(v.scene, v.cam, "vo", p, passSettings(GrazingFloor::w, GrazingFloor::h, 2, 1));
    const MeanSe all = meanSe(coveredW(f));
    const std::vector<double> ws = coveredW(f);
    RecordProperty(std::string("vo_area_grazing_all_mean_") + prefilter, std::to_string(all.mean));
    RecordProperty(std::string("vo_area_grazing_all_min_") + prefilter,
                   std::to_string(*std::min_element(ws.begin(), ws.end())));
  }
}

// No bands down a slope: the moments are filtered trilinearly (and
// pre-blurred), so W changes smoothly where the level or the texel changes;
// with the plane-relative spread it does not change at all on the open
// plane (OpenPlaneReadsOne's derivation: every row from `first` down reads
// 1 within eps, float rounding). Bound for the difference of neighbouring
// rows' means: 4 SE of the difference (from the replicates) plus eps, the
// deterministic bound of OpenPlaneReadsOne (both rows lie in [1 - eps, 1]). The nearest texel of the
// rounded level gave alternating 0.855 / 0.920 rows; trilinear reads with
// the box model about the absolute depth, steps <= 0.012 on a mean of 0.91.
TEST(VoAreaGrazing, NoBandsOnASlope) {
  const GrazingFloor v;
  for (const char* prefilter : {"prefilter=on", "prefilter=off"}) {
    const auto rows = v.rowMeans({"samples=area", "radius=0.3", prefilter});
    double spread = 0.0;
    for (int y = GrazingFloor::first; y + 1 < GrazingFloor::h; ++y) {
      std::vector<double> d;
      for (int r = 0; r < GrazingFloor::replicates; ++r) d.push_back(rows[size_t(y + 1)][size_t(r)] - rows[size_t(y)][size_t(r)]);
      const MeanSe m = meanSe(d);
      spread = std::max(spread, std::abs(m.mean));
      EXPECT_LE(std::abs(m.mean), 4 * m.se + GrazingFloor::eps) << prefilter << " rows " << y << ", " << y + 1 << ": "
                                            << meanSe(rows[size_t(y)]).mean << " -> " << meanSe(rows[size_t(y + 1)]).mean;
    }
    RecordProperty(std::string("vo_area_grazing_row_step_") + prefilter, std::to_string(spread));
  }
}

}  // namespace
}  // namespace obscura::test
