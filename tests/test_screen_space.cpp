// The screen-space seam (core/render/gbuffer.h) and the integrators `vo` and `ssat`
// against closed forms, invariants and the ray-traced `obscurance`.
//
// Tolerances: a pixel's value is a mean over its layers of an estimate whose
// per-pixel rotation is random (interleave=off), so pixels are independent
// draws and an image mean over N pixels has the standard error of the
// pixels' sample standard deviation / sqrt(N); tests allow 4 of them plus
// any deterministic bound named where it applies.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include <obscura/error.h>
#include "core/render/gbuffer.h"
#include "integrators/screen_space/sample_sets.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// A large floor z = 0 seen obliquely from above.
struct FloorView {
  Scene scene;
  Camera cam = makeLookAtCamera(Vec3(0, -6, 4), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "floor");
  FloorView() {
    addPlane(scene, 50.0f);
    scene.commit();
  }
};

// --- the seam ---------------------------------------------------------------------

// The G-buffer layers are the ray-traced loop's camera samples: coverage,
// albedo, normal and depth AOVs agree with `ao`'s for every pixel (same
// rays: coverage exactly; albedo to float summation, N and Z to the
// view-space round trip, a few ulps), and
// the camera ray count is the layer's pixels x spp.
TEST(ScreenSpaceSeam, LayersAreTheCameraSamples) {
  Scene scene;
  addPlane(scene, 1.0f);  // edges cross the image: fractional coverage
  const int m = addGreyMaterial(scene, 0.3f);
  addSphereCavity(scene, 0.4f, 1.0, 12, 24, m);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0.5f, -3, 2.5f), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.9f, "c");
  for (PixelFilter filter : {PixelFilter::Box, PixelFilter::Gaussian}) {
    RenderSettings s = passSettings(40, 30, 5, 7);
    s.aovs = true;
    s.filter = filter;
    RenderStats st;
    const Film ao = renderWith(scene, cam, "ao", {}, s);
    const Film vo = renderWith(scene, cam, "vo", {}, s, &st);
    // One camera ray per layer pixel: the frame's and the guard band's.
    const LayerGeometry lg = layerGeometry(*makeIntegrator("vo", {})->screenSpace(), scene, cam, 40, 30, {0, 0, 40, 30});
    EXPECT_GT(lg.band, 0);
    EXPECT_EQ(st.rays.camera, uint64_t(lg.width) * uint64_t(lg.height) * 5);
    int partial = 0;
    for (int y = 0; y < 30; ++y)
      for (int x = 0; x < 40; ++x) {
        ASSERT_EQ(ao.at(kA, x, y), vo.at(kA, x, y)) << x << "," << y;
        partial += ao.at(kA, x, y) > 0.0f && ao.at(kA, x, y) < 1.0f;
        // The layer loop sums in float (the ray-traced loop in double): 5
        // values differ by at most 5 x 2^-24 relative.
        for (int c : {kAlbedoR, kAlbedoG, kAlbedoB}) EXPECT_NEAR(ao.at(c, x, y), vo.at(c, x, y), 5.0f * 0x1p-24f);
        for (int c : {kNX, kNY, kNZ}) EXPECT_NEAR(ao.at(c, x, y), vo.at(c, x, y), 1e-5f);
        if (ao.at(kA, x, y) > 0.0f) EXPECT_NEAR(ao.at(kZ, x, y), vo.at(kZ, x, y), 1e-5f * ao.at(kZ, x, y));
        else EXPECT_EQ(vo.at(kZ, x, y), kBackgroundDepth);
      }
    EXPECT_GT(partial, 10);  // the comparison covered pixel edges
  }
}

// The depth-aware box filter: on a layer of one depth it is the plain 4x4
// box, which maps a field with the 4x4-periodic pattern of interleaving to
// its exact period mean wherever the window is whole (each window holds each
// of the 16 phases once); across a depth step nothing of the other side
// enters.
// A synthetic w x h layer of one depth, without a guard band (the layer is
// the image), for the filters' tests.
GBufferLayer flatLayer(int w, int h, float depth) {
  GBufferLayer g;
  g.width = w, g.height = h;
  g.shaded = g.image = {0, 0, w, h};
  g.depth.assign(size_t(w) * size_t(h), depth);
  return g;
}

TEST(ScreenSpaceSeam, FilterKeepsMeanAndEdges) {
  GBufferLayer g = flatLayer(16, 12, 5.0f);
  const size_t n = size_t(g.width) * g.height;
  for (int y = 0; y < g.height; ++y)
    for (int x = 10; x < g.width; ++x) g.depth[g.index(x, y)] = 9.0f;  // a step at x = 10
  g.depth[g.index(3, 11)] = kInfinity;  // one background pixel
  std::vector<SampleEstimate> in(n), out(n);
  for (int y = 0; y < g.height; ++y)
    for (int x = 0; x < g.width; ++x) {
      // phase value 0..15 / 15 on the near side, 7 on the far side
      const float v = g.depth[g.index(x, y)] == 9.0f ? 7.0f : float((y & 3) * 4 + (x & 3)) / 15.0f;
      in[g.index(x, y)] = {Vec3(v, v, v), Vec3(1, 1, 1)};
    }
  depthAwareBoxFilter(g, in.data(), 0.02f, 0, g.height, out.data());
  for (int y = 1; y + 2 < g.height; ++y)
    for (int x = 1; x + 2 < 10; ++x) {
      bool hasBackground = false;
      for (int yy = y - 1; yy <= y + 2; ++yy)
        for (int xx = x - 1; xx <= x + 2; ++xx) hasBackground |= !g.covered(g.index(xx, yy));
      if (hasBackground) continue;
      EXPECT_FLOAT_EQ(out[g.index(x, y)].num.x, 0.5f) << x << "," << y;  // mean of 0..15 / 15
    }
  for (int y = 0; y < g.height; ++y)
    for (int x = 10; x < g.width; ++x) EXPECT_EQ(out[g.index(x, y)].num.x, 7.0f);  // far side untouched
  for (int y = 0; y < g.height; ++y) EXPECT_LE(out[g.index(9, y)].num.x, 1.0f);   // near side never mixed
  EXPECT_EQ(out[g.index(3, 11)].num.x, in[g.index(3, 11)].num.x);  // background passes through
}

// The bilateral blur (VO §2, §5): a synthetic layer facing the camera, a
// near plane (depth 5) with a far plane (depth 9) to the right of x = 12 and
// a block of the near plane tilted 45 degrees (its normal off by more than
// kBlurNormalCos allows) at x < 4. The near plane holds 0.3 (as num over den
// 1), the far one 7, the tilted block 2: after a radius-4 blur every pixel
// of the near plane is still 0.3 - nothing of the far side (a depth step) or
// of the tilted block (a crease) is mixed in - and the far side is still 7.
// Tolerance: the weighted sums of up to 81 floats, each rounding by 2^-24
// relative, and the ratio of two of them: 2 x 81 x 2^-24 relative.
TEST(ScreenSpaceSeam, BlurKeepsConstantsAndEdges) {
  GBufferLayer g = flatLayer(24, 16, 5.0f);
  const size_t n = size_t(g.width) * g.height;
  g.position.assign(n, Vec3(0, 0, 0));
  g.normal.assign(n, Vec3(0, 0, 1));
  std::vector<SampleEstimate> in(n), out(n);
  const float pixel = 0.01f;  // the pixels' spacing on the planes
  for (int y = 0; y < g.height; ++y)
    for (int x = 0; x < g.width; ++x) {
      const size_t i = g.index(x, y);
      float v = 0.3f;
      if (x >= 12) g.depth[i] = 9.0f, v = 7.0f;
      if (x < 4) g.normal[i] = normalize(Vec3(1, 0, 1)), v = 2.0f;
      g.position[i] = Vec3(float(x) * pixel, float(y) * pixel, -g.depth[i]);
      in[i] = {Vec3(v, v, v), Vec3(1, 1, 1)};
    }
  const BlurKernel k(4, 0.02f);
  bilateralBlur(g, in.data(), k, 0, g.height, out.data());
  const float tol = 2 * 81 * 0x1p-24f;
  for (int y = 0; y < g.height; ++y)
    for (int x = 0; x < g.width; ++x) {
      const size_t i = g.index(x, y);
      const float want = x >= 12 ? 7.0f : x < 4 ? 2.0f : 0.3f;
      EXPECT_NEAR(out[i].num.x / out[i].den.x, want, tol * want) << x << "," << y;
    }
  // The Gaussian factor: 1 at the centre, exp(-2) at distance r (sigma = r / 2).
  EXPECT_EQ(k.weights[4 * 9 + 4], 1.0f);
  EXPECT_NEAR(k.weights[4 * 9 + 8], std::exp(-2.0f), 1e-7f);
}

// --- planes ----------------------------------------------------------------------

// With the normal, a plane leaves the half-ball and the tangent sphere (vo)
// and every test point (ssat, cosine lobe above the plane) empty: W = 1
// exactly, for every sample kind, kernel (vo's ratios divide the kernel's
// integral by itself; points draw their radii from it), interleaving and
// depth source.
TEST(ScreenSpacePlane, WithTheNormalIsOne) {
  const FloorView v;
  const RenderSettings s = passSettings(48, 36, 2, 3);
  const std::vector<std::vector<std::string>> vos = {
      {"samples=point"},
      {"samples=line"},
      {"samples=line", "centre=false"},
      {"samples=point", "kernel=quadratic"},
      {"samples=line", "kernel=quadratic"},
      {"samples=point", "normal=tangent-sphere"},
      {"samples=line", "normal=tangent-sphere"},
      {"samples=point", "normal=tangent-sphere", "kernel=quadratic"},
      {"samples=line", "normal=tangent-sphere", "kernel=quadratic"},
      // The blur: num and den are blurred alike, so W stays 1 exactly.
      {"samples=line", "blur=3"},
      {"samples=point", "kernel=quadratic", "blur=2"}};
  // (area samples: AreaSamplesOnAFrontalPlane - on a slope their depth model
  // spreads the plane over each footprint, by design)
  for (const auto& base : vos)
    for (const char* inter : {"interleave=off", "interleave=on"})
      for (const char* depth : {"depth=gbuffer", "depth=traced"}) {
        std::vector<std::string> p = base;
        p.insert(p.end(), {"radius=0.3", inter, depth, "radius2=0.05"});
        for (double w : coveredW(renderWith(v.scene, v.cam, "vo", p, s))) ASSERT_EQ(w, 1.0) << p[0] << inter << depth;
      }
  for (const char* inter : {"interleave=off", "interleave=on"})
    for (const char* depth : {"depth=gbuffer", "depth=traced"})
      for (const char* f : {"falloff=step", "falloff=sqrt", "falloff=exponential"})
        for (const char* a : {"albedo=false", "albedo=true"}) {
          const auto w = coveredW(renderWith(v.scene, v.cam, "ssat", {inter, depth, f, a, "distance=0.3", "steps=2"}, s));
          ASSERT_FALSE(w.empty());
          for (double x : w) ASSERT_EQ(x, 1.0) << inter << depth << f << a;
        }
}

// Without the normal VO is the fraction of the whole ball in front of the
// plane, 1/2. Points: each point's direction is uniformly random (a uniform
// rotation), so each is in front with probability 1/2 - unbiased.
// Lines and area samples: with chords parallel to the view direction v of P
// the disk's point symmetry splits every pair of opposite chords exactly in
// half, and the random 2D rotation makes both of a pair equally likely: 1/2.
// Our chords run along camera rays, tilted from v by at most delta = R / d
// (d: P's distance), which moves a chord's crossing with the plane by at
// most R delta / cos(incidence) = R^2 / (d cos), i.e. R^2 / h for a camera
// at height h (d cos = h on a floor). The chord weights a_k = w_k / (2 z_k)
// sum to ~3/4 (w_k ~ 2 z_k x cell area x 3 / (4 pi), cell areas sum to pi)
// against a normalizer of ~R, so W moves by at most 0.75 R / h. Area samples
// on this plane read a depth spread over each footprint (the slope), which
// the box model turns into a symmetric ramp about the mean: the same 1/2 in
// expectation, to the footprint's curvature of depth (zero on a plane up to
// perspective, the same bound). Tolerance: 4 SE + 0.75 R / h. Pixels within
// 2 of the image's edge are left out: R = 0.05 spans under a pixel here,
// and a ball reaching off the image reads as empty there.
// kernel=quadratic keeps the 1/2: rho is symmetric under the half-turn about
// an axis in the plane through P, which swaps the two half-balls (points:
// their radii are drawn from rho, the rotation stays uniform). For lines the
// numerator moves by at most Sum a_k R^2 / h (rho <= 1) against a normalizer
// Sum a_k Int rho = R x 2/5 (rho's mean over the ball): 0.75 R / h x 5/2.
TEST(ScreenSpacePlane, WithoutTheNormalIsHalf) {
  const FloorView v;
  const RenderSettings s = passSettings(48, 36, 4, 5);
  const double R = 0.05, h = 4.0;
  for (const char* kernel : {"kernel=constant", "kernel=quadratic"}) {
    const double perKernel = kernel[7] == 'q' ? 2.5 : 1.0;
    {
      const MeanSe m = meanSe(
          coveredW(renderWith(v.scene, v.cam, "vo", {"samples=point", "normal=false", "radius=0.05", kernel}, s), 2));
      EXPECT_NEAR(m.mean, 0.5, 4 * m.se) << kernel << " se " << m.se;
    }
    for (const char* kind : {"samples=line", "samples=area"})
      for (const char* c : {"centre=true", "centre=false"}) {
        const MeanSe m =
            meanSe(coveredW(renderWith(v.scene, v.cam, "vo", {kind, "normal=false", "radius=0.05", c, kernel}, s), 2));
        EXPECT_NEAR(m.mean, 0.5, 4 * m.se + perKernel * 0.75 * R / h) << kind << c << kernel << " se " << m.se;
      }
  }
}

// Interleaving (16 rotations in a 4x4 pattern, shifted per layer) and the
// depth-aware 4x4 box filter keep that mean: each rotation is uniformly
// distributed and the filter is an average of neighbours on the same plane.
// The 16 rotations are shared by all pixels, so the standard error comes
// from 16 independent renders; bounds as above.
TEST(ScreenSpacePlane, InterleavingAndFilterKeepTheMean) {
  const FloorView v;
  const double R = 0.05, h = 4.0;
  for (const char* kind : {"samples=point", "samples=line"}) {
    const MeanSe m = replicateMean(16, [&](uint32_t seed) {
      const Film f = renderWith(v.scene, v.cam, "vo", {kind, "normal=false", "radius=0.05", "interleave=on", "filter-depth=0.5"},
                                passSettings(48, 36, 1, seed));
      return meanSe(coveredW(f, 2)).mean;
    });
    EXPECT_NEAR(m.mean, 0.5, 4 * m.se + (kind[8] == 'l' ? 0.75 * R / h : 0.0)) << kind << " se " << m.se;
  }
}

// Area samples with the normal on a plane facing the camera head-on: the
// depth over every footprint is one value up to perspective, variance ~0,
// so the box model is the line model and W = 1 up to that spread (the ramp
// then has width ~0): every covered pixel within 1e-3 of 1.
TEST(ScreenSpacePlane, AreaSamplesOnAFrontalPlane) {
  Scene scene;
  addPlane(scene, 50.0f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 6), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.6f, "down");
  const auto w = coveredW(renderWith(scene, cam, "vo", {"samples=area", "radius=0.3"}, passSettings(40, 30, 2)));
  ASSERT_FALSE(w.empty());
  for (double x : w) ASSERT_NEAR(x, 1.0, 1e-3);
}

// Area samples on an open plane seen at a grazing angle (W = 1, no bands
// down the slope): test_screen_space_vo_area.cpp.

// --- the bilateral blur (VO §2, §5) -----------------------------------------------

// A frontal plane seen from above (every pixel alike).
struct FrontalPlane {
  Scene scene;
  Camera cam = makeLookAtCamera(Vec3(0, 0, 6), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.6f, "down");
  FrontalPlane() {
    addPlane(scene, 50.0f);
    scene.commit();
  }
};

// On an open area the blur averages independent pixels: point samples on
// the frontal plane without the normal (each pixel's rotation its own; the
// layer's radial shift is common to all pixels and leaves with the image's
// mean), so with one layer a blurred pixel's variance is Sum w^2 / (Sum w)^2
// of the unblurred one, w the Gaussian weights of the whole window (the
// range test passes everywhere on a plane): 1 / (effective sample count).
// Same seed with and without the blur: the blurred image is the blur of the
// other. Per replicate the ratio of the two images' sample variances over
// the pixels at least r from the frame's edge (whole windows); mean over 16
// replicates within 4 SE plus the sample variance's bias on a correlated
// field - E[S_B^2] = sigma_B^2 - Var(mean) ~ sigma_B^2 - sigma^2 / n, i.e.
// 1/n on the ratio - and the ratio-of-variances (Jensen) term, 2/n relative.
TEST(ScreenSpaceBlur, ReducesVarianceByTheKernelsSampleCount) {
  const FrontalPlane v;
  const int w = 64, h = 48, r = 3;
  double sw = 0, sw2 = 0;  // the weights, independently of the code's table
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      const double sigma = 0.5 * r, wt = std::exp(-(dx * dx + dy * dy) / (2 * sigma * sigma));
      sw += wt, sw2 += wt * wt;
    }
  const double expected = sw2 / (sw * sw);
  size_t n = 0;
  const MeanSe m = replicateMean(16, [&](uint32_t seed) {
    const std::vector<std::string> base = {"samples=point", "normal=false", "radius=0.3"};
    std::vector<std::string> blurred = base;
    blurred.push_back("blur=" + std::to_string(r));
    const Film a = renderWith(v.scene, v.cam, "vo", base, passSettings(w, h, 1, seed));
    const Film b = renderWith(v.scene, v.cam, "vo", blurred, passSettings(w, h, 1, seed));
    const auto variance = [&](const Film& f) {
      std::vector<double> x;
      for (int y = r; y < h - r; ++y)
        for (int xx = r; xx < w - r; ++xx) x.push_back(f.at(kR, xx, y));
      n = x.size();
      const MeanSe s = meanSe(x);
      return s.se * s.se * double(x.size());  // the sample variance
    };
    return variance(b) / variance(a);
  });
  const double bias = 1.0 / double(n) + 2.0 * expected / double(n);
  EXPECT_NEAR(m.mean, expected, 4 * m.se + bias) << "se " << m.se << " effective samples " << 1 / expected;
  RecordProperty("blur_variance_ratio", std::to_string(m.mean));
  RecordProperty("blur_variance_ratio_expected", std::to_string(expected));
  RecordProperty("blur_variance_ratio_se", std::to_string(m.se));
}

// Across a depth step nothing is mixed: a box (top at z = 0.6) on the
// frontal plane, seen from straight above (its sides face away from the
// camera). With the normal clamp the box's top is exactly 1 in every layer
// (an open plane: the half-ball above it is empty, over the edge too, where
// it lies in front of the floor), while the floor beside the box reads
// below 1 (the box's sides occlude it). Every pixel wholly on the top whose
// blur window reaches the floor must still read exactly 1: the floor's
// pixels lie 0.6 behind the top's plane, far beyond filter-depth x depth.
TEST(ScreenSpaceBlur, DoesNotMixAcrossADepthStep) {
  Scene scene;
  addPlane(scene, 50.0f);
  const float a = 0.5f, t = 0.6f;
  scene.addWorldPrimitive({{-a, -a, t}, {a, -a, t}, {a, a, t}, {-a, a, t}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);  // top
  scene.addWorldPrimitive({{-a, -a, 0}, {a, -a, 0}, {a, -a, t}, {-a, -a, t}, {a, a, 0}, {-a, a, 0}, {-a, a, t}, {a, a, t}},
                          {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7}, {}, {}, -1);  // two sides
  scene.addWorldPrimitive({{a, -a, 0}, {a, a, 0}, {a, a, t}, {a, -a, t}, {-a, a, 0}, {-a, -a, 0}, {-a, -a, t}, {-a, a, t}},
                          {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7}, {}, {}, -1);  // the other two
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 6), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.6f, "down");
  const int w = 48, h = 36, r = 3;
  const RasterCamera rc(cam, w, h);
  const auto onTop = [&](float fx, float fy) { return traceClosest(scene, rc.org, rc.direction(fx, fy)).hit.geomID == 1; };
  std::vector<std::pair<int, int>> edge;  // wholly on the top, the floor within r
  for (int y = r; y < h - r; ++y)
    for (int x = r; x < w - r; ++x) {
      bool whole = true, nearFloor = false;
      for (int k = 0; k < 4; ++k) whole &= onTop(float(x + (k & 1)), float(y + (k >> 1)));
      for (int dy = -r; dy <= r && whole; ++dy)
        for (int dx = -r; dx <= r; ++dx) nearFloor |= !onTop(float(x + dx) + 0.5f, float(y + dy) + 0.5f);
      if (whole && nearFloor) edge.emplace_back(x, y);
    }
  ASSERT_GT(edge.size(), 20u);
  const RenderSettings s = passSettings(w, h, 2, 3);
  const Film plain = renderWith(scene, cam, "vo", {"samples=line", "radius=0.3"}, s);
  const Film blurred = renderWith(scene, cam, "vo", {"samples=line", "radius=0.3", "blur=3"}, s);
  double floorMin = 1;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) floorMin = std::min<double>(floorMin, plain.at(kR, x, y));
  EXPECT_LT(floorMin, 0.9);  // what mixing would bring in
  for (auto [x, y] : edge) {
    ASSERT_EQ(plain.at(kR, x, y), 1.0f) << x << "," << y;
    ASSERT_EQ(blurred.at(kR, x, y), 1.0f) << x << "," << y;
  }
}

// --- a 90 degree crease -----------------------------------------------------------

// Point samples are unbiased for the ball integral (uniform direction and
// radius per point), so the mean over pixels of (W - V(h)) is 0 within 4
// standard errors (from 16 independent renders: the radial shift is shared
// by a layer's pixels) plus the pixel footprint (creaseCentres).
TEST(ScreenSpaceCrease, VoPointsMatchTheClosedForm) {
  const Crease c;
  const int w = 64, h = 48;
  const double R = 0.5;
  // The pixels: floor seen near the wall, with their footprint bound.
  const CreaseCentres cc = creaseCentres(c, w, h, R);
  const auto& pixels = cc.pixels;
  const auto& V = cc.V;
  const double footprint = cc.footprint;
  ASSERT_GT(pixels.size(), 100u);
  for (const char* depth : {"depth=gbuffer", "depth=traced"}) {
    const MeanSe m = replicateMean(16, [&](uint32_t seed) {
      const Film f = renderWith(c.scene, c.cam, "vo", {"samples=point", "radius=0.5", depth}, passSettings(w, h, 2, seed));
      double sum = 0.0;
      size_t n = 0;
      for (size_t k = 0; k < pixels.size(); ++k)
        if (f.at(kA, pixels[k].first, pixels[k].second) == 1.0f)
          sum += f.at(kR, pixels[k].first, pixels[k].second) - V[k], ++n;
      return sum / double(n);
    });
    EXPECT_NEAR(m.mean, 0.0, 4 * m.se + footprint) << depth << " se " << m.se << " footprint " << footprint;
    RecordProperty(std::string("vo_point_crease_bias_") + (depth[6] == 'g' ? "gbuffer" : "traced"), std::to_string(m.mean));
  }
}

// Z-buffer containment converges to `obscurance` with the same mu when the
// depth buffer holds every occluder and each segment crosses at most one
// surface (here: the wall), so over the same pixels and camera samples the
// two passes agree in the mean within 4 standard errors of the difference
// (from 16 independent renders: ssat's set shift is shared by a layer's
// pixels). The silhouette rule is off: a point behind the wall can lie
// farther than R behind it along an oblique camera ray (the rule's miss).
TEST(ScreenSpaceCrease, SsatConvergesToObscurance) {
  const Crease c;
  const int w = 48, h = 36;
  std::vector<std::pair<int, int>> pixels;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      Vec3 q;
      if (c.floorAt(w, h, x, y, q) && q.x < 1.0f && std::abs(q.y) < 1.5f) pixels.emplace_back(x, y);
    }
  ASSERT_GT(pixels.size(), 100u);
  for (const char* f : {"falloff=step", "falloff=linear", "falloff=exponential"}) {
    const std::vector<std::string> mu = {f, "distance=0.6", "sigma=3"};
    std::vector<std::string> rt = mu;
    rt.push_back("rays=16");
    for (const char* depth : {"depth=gbuffer", "depth=traced"}) {
      std::vector<std::string> ss = mu;
      ss.insert(ss.end(), {"silhouette=false", "interleave=off", depth});
      const MeanSe m = replicateMean(16, [&](uint32_t seed) {
        const RenderSettings s = passSettings(w, h, 4, seed);
        const Film a = renderWith(c.scene, c.cam, "ssat", ss, s);
        const Film b = renderWith(c.scene, c.cam, "obscurance", rt, s);
        double sum = 0.0;
        size_t n = 0;
        for (auto [x, y] : pixels)
          if (a.at(kA, x, y) == 1.0f) sum += double(a.at(kR, x, y)) - double(b.at(kR, x, y)), ++n;
        return sum / double(n);
      });
      EXPECT_NEAR(m.mean, 0.0, 4 * m.se) << f << " " << depth << " se " << m.se;
    }
  }
}

// The spherical cavity of docs/math.md §7 (Rs = 1, hole half-angle 1.2 about
// +Z) seen through its opening from the axis: the pixels near the bottom,
// whose test points within R = 0.5 all lie either inside the cavity in view
// of the camera or behind the wall - every occluder in the depth buffer, one
// crossing per segment - so ssat converges to `obscurance` with the same mu
// there, as on the crease (same statistics; the rule off for the same
// reason).
TEST(ScreenSpaceCavity, SsatConvergesToObscurance) {
  Scene scene;
  addSphereCavity(scene, 1.0f, 1.2, 24, 48);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 4), Vec3(0, 0, -1), Vec3(0, 1, 0), 0.45f, "hole");
  const int w = 40, h = 40;
  std::vector<std::pair<int, int>> pixels;
  const RasterCamera rc(cam, w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Vec3 d = rc.direction(float(x) + 0.5f, float(y) + 0.5f);
      const RayHit hit = traceClosest(scene, rc.org, d);
      if (hit.hit.geomID != RTC_INVALID_GEOMETRY_ID && (rc.org + d * hit.ray.tfar).z < -0.92f)
        pixels.emplace_back(x, y);
    }
  ASSERT_GT(pixels.size(), 100u);
  for (const char* f : {"falloff=step", "falloff=linear"}) {
    const std::vector<std::string> mu = {f, "distance=0.5"};
    std::vector<std::string> rt = mu, ss = mu;
    rt.push_back("rays=16");
    ss.insert(ss.end(), {"silhouette=false", "interleave=off"});
    const MeanSe m = replicateMean(16, [&](uint32_t seed) {
      const RenderSettings s = passSettings(w, h, 4, seed);
      const Film a = renderWith(scene, cam, "ssat", ss, s);
      const Film b = renderWith(scene, cam, "obscurance", rt, s);
      double sum = 0.0;
      for (auto [x, y] : pixels) sum += double(a.at(kR, x, y)) - double(b.at(kR, x, y));
      return sum / double(pixels.size());
    });
    EXPECT_NEAR(m.mean, 0.0, 4 * m.se) << f << " se " << m.se;
  }
}

// --- silhouettes ---------------------------------------------------------------------

// A thin slab (a square) floating 2 units in front of a far wall, R = 0.5:
// nothing is within R of the wall, so the ray-traced W there is exactly 1.
// Depth-buffer methods see the slab's pixels as "behind" for test points
// next to its silhouette: the dark halo. ssat's silhouette rule (R > z - z*)
// and vo's thickness model (occupied only `thickness` behind the buffer)
// each remove it exactly; without them the ring of wall pixels around the
// silhouette is visibly darker (for a point at the silhouette about half
// the test points project onto the slab; the ring mean stays below 0.9).
struct Slab {
  Scene scene;
  Camera cam = makeLookAtCamera(Vec3(0.3f, 0.2f, 8), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.5f, "slab");
  Slab() {
    addPlane(scene, 20.0f, 0.0f);
    addPlane(scene, 0.6f, 2.0f);
    scene.commit();
  }
};

// Wall pixels seen past the slab whose centre ray crosses the slab's plane
// (z = 2) outside the slab by less than `ring`: where the halo falls.
std::vector<std::pair<int, int>> haloRing(const Slab& sl, int w, int h, float ring) {
  std::vector<std::pair<int, int>> pixels;
  const RasterCamera rc(sl.cam, w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Vec3 d = rc.direction(float(x) + 0.5f, float(y) + 0.5f);
      const RayHit hit = traceClosest(sl.scene, rc.org, d);
      if (hit.hit.geomID != 0) continue;
      const Vec3 q = rc.org + d * ((2.0f - rc.org.z) / d.z);
      const float outside = std::max(std::abs(q.x), std::abs(q.y)) - 0.6f;
      if (outside > 0.0f && outside < ring) pixels.emplace_back(x, y);
    }
  return pixels;
}

double ringMean(const Film& f, const std::vector<std::pair<int, int>>& ring, double* minimum = nullptr) {
  double sum = 0.0, lo = 1.0;
  size_t n = 0;
  for (auto [x, y] : ring)
    if (f.at(kA, x, y) == 1.0f) sum += f.at(kR, x, y), lo = std::min<double>(lo, f.at(kR, x, y)), ++n;
  if (minimum) *minimum = lo;
  return n ? sum / double(n) : -1.0;
}

// Every wall pixel (geometry 0 at the pixel centre, fully covered).
std::vector<double> wallW(const Slab& sl, const Film& f) {
  std::vector<double> v;
  const RasterCamera rc(sl.cam, f.width(), f.height());
  for (int y = 0; y < f.height(); ++y)
    for (int x = 0; x < f.width(); ++x) {
      const RayHit hit = traceClosest(sl.scene, rc.org, rc.direction(float(x) + 0.5f, float(y) + 0.5f));
      // Pixels at the slab's edge mix slab and wall samples: skip them.
      bool mixed = false;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const RayHit n = traceClosest(sl.scene, rc.org, rc.direction(float(x + dx) + 0.5f, float(y + dy) + 0.5f));
          mixed |= n.hit.geomID != hit.hit.geomID;
        }
      if (hit.hit.geomID == 0 && !mixed && f.at(kA, x, y) == 1.0f) v.push_back(f.at(kR, x, y));
    }
  return v;
}

TEST(ScreenSpaceSilhouette, RuleRemovesTheHalo) {
  const Slab sl;
  const int w = 64, h = 64;
  const RenderSettings s = passSettings(w, h, 4, 17);
  const auto ring = haloRing(sl, w, h, 0.25f);
  ASSERT_GT(ring.size(), 40u);
  // The truth: nothing within R of the wall.
  for (double v : wallW(sl, renderWith(sl.scene, sl.cam, "obscurance", {"distance=0.5", "rays=4"}, s)))
    ASSERT_EQ(v, 1.0);
  for (const char* inter : {"interleave=off", "interleave=on"}) {
    const Film with = renderWith(sl.scene, sl.cam, "ssat", {"distance=0.5", inter}, s);
    for (double v : wallW(sl, with)) ASSERT_EQ(v, 1.0) << inter;
    const Film without = renderWith(sl.scene, sl.cam, "ssat", {"distance=0.5", "silhouette=false", inter}, s);
    double lo = 1.0;
    const double m = ringMean(without, ring, &lo);
    EXPECT_LT(m, 0.9) << inter << " min " << lo;
    RecordProperty(std::string("ssat_halo_ring_mean_") + inter, std::to_string(m));
  }
}

TEST(ScreenSpaceSilhouette, ThicknessRemovesTheHalo) {
  const Slab sl;
  const int w = 64, h = 64;
  const RenderSettings s = passSettings(w, h, 4, 19);
  const auto ring = haloRing(sl, w, h, 0.25f);
  for (const char* samples : {"samples=point", "samples=line"}) {
    const Film thick = renderWith(sl.scene, sl.cam, "vo", {samples, "radius=0.5", "thickness=0.3"}, s);
    for (double v : wallW(sl, thick)) ASSERT_EQ(v, 1.0) << samples;
    const Film solid = renderWith(sl.scene, sl.cam, "vo", {samples, "radius=0.5"}, s);
    EXPECT_LT(ringMean(solid, ring), 0.9) << samples;
  }
}

// --- extremes ----------------------------------------------------------------------

void expectFiniteInUnit(const Film& f, const std::string& what) {
  for (int y = 0; y < f.height(); ++y)
    for (int x = 0; x < f.width(); ++x) {
      const float a = f.at(kA, x, y);
      for (int c : {kR, kG, kB}) {
        const float v = f.at(c, x, y);
        ASSERT_TRUE(std::isfinite(v)) << what << " at " << x << "," << y;
        ASSERT_GE(v, 0.0f) << what;
        ASSERT_LE(v, a * (1.0f + 1e-6f)) << what;  // W <= 1, premultiplied
      }
    }
}

const std::vector<std::pair<std::string, std::vector<std::string>>>& allConfigs() {
  static const std::vector<std::pair<std::string, std::vector<std::string>>> c = {
      {"vo", {"samples=point"}},
      {"vo", {"samples=line"}},
      {"vo", {"samples=line", "normal=false", "thickness=0.1", "radius2=0.3", "combine=min"}},
      {"vo", {"samples=point", "interleave=on", "depth=traced"}},
      {"ssat", {}},
      {"ssat", {"albedo=true", "interleave=off", "steps=2"}},
      {"ssat", {"albedo=true", "occluder=radiance", "steps=2"}},
      {"ssat", {"falloff=exponential", "distance=inf", "silhouette=false", "depth=traced"}},
      {"gtao", {}},
      {"gtao", {"interleave=off", "depth=traced", "e0=bent", "steps=3", "slices=2"}},
  };
  return c;
}

// R from 1e-6 to 1e6 of the scene, a grazing view, a single pixel, a
// 4097 x 3 strip, and an image that is background but for one pixel.
TEST(ScreenSpaceExtremes, FiniteAndInUnitInterval) {
  Scene scene;
  addSphereCavity(scene, 1.0f, 1.2, 10, 20);
  addPlane(scene, 3.0f, -1.0f);
  scene.commit();
  const Camera cams[] = {makeLookAtCamera(Vec3(0, -4, 3), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "oblique"),
                         makeLookAtCamera(Vec3(-9, 0, -0.999f), Vec3(9, 0, -1.0f), Vec3(0, 0, 1), 0.3f, "grazing")};
  for (const auto& [name, base] : allConfigs())
    for (const char* r : {"1e-6", "1", "1e6"}) {
      std::vector<std::string> p = base;
      const bool vo = name == "vo" || name == "gtao";  // (their radius is `radius`)
      bool hasDistance = false;
      for (const auto& q : p) hasDistance |= q.rfind("distance=", 0) == 0;
      if (vo) p.push_back(std::string("radius=") + r);
      else if (!hasDistance) p.push_back(std::string("distance=") + r);
      for (const Camera& cam : cams) expectFiniteInUnit(renderWith(scene, cam, name, p, passSettings(24, 16, 2)), name + " R=" + r);
      expectFiniteInUnit(renderWith(scene, cams[0], name, p, passSettings(1, 1, 3)), name + " 1x1");
    }
  for (const auto& [name, p] : allConfigs())
    expectFiniteInUnit(renderWith(scene, cams[0], name, p, passSettings(4097, 3, 1)), name + " 4097x3");
  // One pixel sees geometry: a far camera with a tiny field of view onto
  // the cavity's edge.
  Scene speck;
  addPlane(speck, 0.01f);
  speck.commit();
  const Camera far = makeLookAtCamera(Vec3(0, 0, 50), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.02f, "far");
  for (const auto& [name, p] : allConfigs()) {
    const Film f = renderWith(speck, far, name, p, passSettings(9, 9, 2));
    expectFiniteInUnit(f, name + " speck");
  }
}

TEST(ScreenSpaceErrors, BadParameters) {
  Scene scene;
  addPlane(scene, 1.0f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0, -2, 2), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "c");
  try {
    renderWith(scene, cam, "ssat", {"distance=inf"}, passSettings(4, 4, 1));
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'distance' must be finite"), std::string::npos) << e.what();
  }
  EXPECT_THROW(renderWith(scene, cam, "vo", {"count=0"}, passSettings(4, 4, 1)), Error);
  EXPECT_THROW(renderWith(scene, cam, "vo", {"samples=area2"}, passSettings(4, 4, 1)), Error);
  EXPECT_EQ(IntegratorRegistry::instance().find("vo").kind, IntegratorKind::ScreenSpace);
  EXPECT_EQ(IntegratorRegistry::instance().find("ao").kind, IntegratorKind::RayTraced);
}

}  // namespace
}  // namespace obscura::test
