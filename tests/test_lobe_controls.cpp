// The lobe controls of the AO family (include/obscura/lobe.h, docs/math.md §11):
// `inside`, `spread`, `near`, against closed forms and independent
// quadratures, and the invariants that tie the integrators together.
//
// The scene of most tests: an open floor z = 0 and, above it, a square slab
// |x|, |y| <= a at height z = h (two triangles; surfaces are two-sided). A
// camera low beside the slab looks under it at the floor's centre with a
// narrow field of view, so every pixel sees a floor point (x0, y0) below the
// slab. At such a point, with the cosine lobe about +z:
//   AO = 1 - F,  F = (1/pi) Int_slab cos(theta) dw,
// the form factor of the rectangle from a point below it: a signed sum of
// four corner-rectangle terms (slabFormFactor). With `near` and `spread` the
// occluding part is the slab beyond distance `near` and within the cone, an
// integral in polar coordinates about the foot point (x0, y0):
//   dF = h^2 / (pi (h^2 + rho^2)^2) rho drho dphi,
// closed in rho, by the midpoint rule in phi (polarOcclusion); with
// spread, W = 1 - F_cone / sin^2(thetaMax) (docs/math.md §11).
//
// Tolerances: each pixel is spp x rays Bernoulli draws of the open/closed
// indicator, pixels independent (own scramble seeds), so the mean over
// pixels of (render - expected) has standard error at most
// sqrt(pbar (1 - pbar) / N), N = pixels x spp x rays (the mean of p(1 - p)
// is at most pbar(1 - pbar)); we allow 4 of them, plus the pixel-footprint
// bound: the closed form is evaluated at the pixel centre's floor point, the
// box filter averages over the pixel, and the value at the pixel's corners
// bounds how far that average can be (the functions are smooth and the
// footprint is tiny, so they are monotone across it).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include <obscura/error.h>
#include <obscura/lobe.h>
#include <obscura/warp.h>
#include "tests/support.h"

namespace obscura::test {
namespace {

// F of the square |x|, |y| <= a at height h from the floor point (x0, y0).
double slabFormFactor(double x0, double y0, double a, double h) {
  return rectFormFactor(-a, a, -a, a, h, x0, y0);  // tests/support.h
}

// (1/pi) Int cos(theta) dw over the part of the slab seen from the floor
// point (x0, y0) (inside the square's shadow) at horizontal distances
// rho0 < rho < rhoCone from it: farther than near (rho0 = sqrt(near^2 - h^2))
// and inside the cone (rhoCone = h tan(thetaMax)). The inner integral is
// (h^2/2) [1/(h^2 + lo^2) - 1/(h^2 + hi^2)]; phi by the midpoint rule.
double polarOcclusion(double x0, double y0, double a, double h, double rho0, double rhoCone, int n = 20000) {
  double sum = 0;
  const double inf = std::numeric_limits<double>::infinity();
  for (int i = 0; i < n; ++i) {
    const double phi = 2 * M_PI * (i + 0.5) / n, c = std::cos(phi), s = std::sin(phi);
    const double tx = c > 0 ? (a - x0) / c : c < 0 ? (-a - x0) / c : inf;
    const double ty = s > 0 ? (a - y0) / s : s < 0 ? (-a - y0) / s : inf;
    const double hi = std::min(std::min(tx, ty), rhoCone);
    if (hi <= rho0) continue;
    sum += 0.5 * h * h * (1 / (h * h + rho0 * rho0) - 1 / (h * h + hi * hi));
  }
  return sum * (2 * M_PI / n) / M_PI;
}

// The floor, the slab and a camera looking under the slab at the floor's
// centre. `material` for both (-1: the default, albedo 1).
struct Slab {
  static constexpr int kW = 16, kH = 16;
  double a, h;
  Scene scene;
  Camera cam;
  Slab(double a_, double h_, bool black = false) : a(a_), h(h_) {
    const int m = black ? addGreyMaterial(scene, 0.0f) : -1;
    // Half-size 10: the floor's ray offset (2^-16 of its coordinates, core/
    // surface.h) lowers h by 1.5e-4 at most, far below the tolerances.
    const float L = 10.0f, fa = float(a), fh = float(h);
    scene.addWorldPrimitive({{-L, -L, 0}, {L, -L, 0}, {L, L, 0}, {-L, L, 0}}, {0, 1, 2, 0, 2, 3}, {}, {}, m);
    scene.addWorldPrimitive({{-fa, -fa, fh}, {fa, -fa, fh}, {fa, fa, fh}, {-fa, fa, fh}}, {0, 1, 2, 0, 2, 3}, {}, {}, m);
    scene.commit();
    // Low beside the slab (the line to the centre passes its edge at
    // z = 0.6 h / 8 a, well below it): the 16 x 16 pixels see floor points
    // within |x| < 0.3, |y| < 0.02 of the centre, all under the slab.
    cam = makeLookAtCamera(Vec3(8.0f, 0.0f, 0.6f * fh), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.004f, "under-slab");
  }
  // The floor point seen through film position (fx, fy).
  Vec3 floorAt(float fx, float fy) const {
    const RasterCamera rc(cam, kW, kH);
    const Vec3 d = rc.direction(fx, fy);
    return rc.org + d * (-rc.org.z / d.z);
  }
  // Per pixel, W(x0, y0) at the pixel centre's floor point; their mean, and
  // the mean over pixels of the largest deviation at the pixel's corners
  // (the footprint bound).
  struct Expected {
    double mean = 0, footprint = 0;
  };
  template <class Fn>
  Expected expected(Fn W) const {
    Expected e;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const Vec3 p = floorAt(float(x) + 0.5f, float(y) + 0.5f);
        EXPECT_LT(std::max(std::abs(p.x), std::abs(p.y)), 0.5 * a) << "pixel " << x << "," << y;
        const double w = W(double(p.x), double(p.y));
        double dev = 0;
        for (int cy = 0; cy <= 1; ++cy)
          for (int cx = 0; cx <= 1; ++cx) {
            const Vec3 q = floorAt(float(x + cx), float(y + cy));
            dev = std::max(dev, std::abs(W(double(q.x), double(q.y)) - w));
          }
        e.mean += w;
        e.footprint += dev;
      }
    e.mean /= kW * kH;
    e.footprint /= kW * kH;
    return e;
  }
};

constexpr int kSpp = 64, kRays = 4;

Film renderSlab(const Slab& s, const std::string& integrator, std::vector<std::string> params, uint32_t seed = 0) {
  params.push_back("rays=" + std::to_string(kRays));
  return renderWith(s.scene, s.cam, integrator, params, passSettings(Slab::kW, Slab::kH, kSpp, seed));
}

// The render's mean over its pixels against the expected mean, within 4
// standard errors plus the footprint bound.
void expectMatches(const Film& f, const Slab::Expected& e, const std::string& what) {
  size_t n = 0;
  const double mean = meanCovered(f, kR, &n);
  ASSERT_EQ(n, size_t(Slab::kW * Slab::kH)) << what;
  const double se = bernoulliStdErr(e.mean, double(n) * kSpp * kRays);
  std::printf("%s: render %.5f, closed form %.5f, se %.2g, footprint %.2g\n", what.c_str(), mean, e.mean, se,
              e.footprint);
  EXPECT_NEAR(mean, e.mean, 4 * se + e.footprint) << what << " (se " << se << ", footprint " << e.footprint << ")";
}

bool sameImage(const Film& a, const Film& b) {
  for (int c = 0; c < 4; ++c)
    for (int y = 0; y < a.height(); ++y)
      for (int x = 0; x < a.width(); ++x)
        if (a.at(c, x, y) != b.at(c, x, y)) return false;
  return true;
}

// The quadrature this file checks against, checked against the closed form:
// without near or cone it is the whole slab's form factor (the midpoint rule
// in phi converges as 1/n^2 between the corners' kinks).
TEST(LobeControls, PolarQuadratureIsTheFormFactor) {
  const double inf = std::numeric_limits<double>::infinity();
  for (const double x0 : {0.0, 0.2, -0.37})
    for (const double y0 : {0.0, -0.1, 0.31})
      EXPECT_NEAR(polarOcclusion(x0, y0, 1.0, 0.5, 0.0, inf), slabFormFactor(x0, y0, 1.0, 0.5), 1e-7);
  // Centre: 4 x the corner rectangle.
  EXPECT_NEAR(slabFormFactor(0, 0, 1.0, 0.5), 4 * cornerFormFactor(1.0, 1.0, 0.5), 1e-15);
}

// The cone warp at spread = 1 is the cosine hemisphere of before, bit for
// bit (reimplemented here as it was), and inside a cone of sin(thetaMax) = s
// every direction has sin(theta) <= s, with E[cos^2] = 1 - s^2/2 (sin^2 is
// uniform on [0, s^2] under cos/(pi s^2)).
TEST(LobeControls, ConeWarp) {
  const auto before = [](float u, float v) {
    float x, y;
    squareToConcentricDisk(u, v, x, y);
    const float z = std::sqrt(std::max(0.0f, 1.0f - x * x - y * y));
    return Vec3(x, y, z);
  };
  const uint32_t key = Sampler(3).pixelKey(1, 2);
  const int n = 1 << 14;
  for (int i = 0; i < n; ++i) {
    const Sample2 s = Sampler::get2D(key, uint32_t(i), kFirstIntegratorDim);
    const Vec3 a = squareToCosineCone(s.u, s.v, 1.0f), b = before(s.u, s.v);
    ASSERT_TRUE(a.x == b.x && a.y == b.y && a.z == b.z) << i;
  }
  const double sinMax = std::sin(0.3 * M_PI / 2);
  double cos2 = 0;
  for (int i = 0; i < n; ++i) {
    const Sample2 s = Sampler::get2D(key, uint32_t(i), kFirstIntegratorDim);
    const Vec3 w = squareToCosineCone(s.u, s.v, float(sinMax));
    ASSERT_LE(std::sqrt(double(w.x) * w.x + double(w.y) * w.y), sinMax * (1 + 1e-6)) << i;
    cos2 += double(w.z) * w.z;
  }
  // sin^2 uniform on [0, s^2]: Var(cos^2) = s^4/12; scrambled Sobol' only
  // lowers the error of the mean.
  EXPECT_NEAR(cos2 / n, 1 - sinMax * sinMax / 2, 4 * std::sqrt(std::pow(sinMax, 4) / 12 / n));
}

// ao under the slab = 1 - F, F the closed-form form factor at each pixel's
// floor point.
TEST(LobeControls, SlabFormFactor) {
  const Slab s(1.0, 0.5);
  expectMatches(renderSlab(s, "ao", {}),
                s.expected([&](double x, double y) { return 1 - slabFormFactor(x, y, s.a, s.h); }), "ao");
}

// near < h: every slab hit lies beyond near, so every ray's verdict is the
// same and the image is the same bit for bit. near beyond the slab's
// farthest point from every seen floor point (sqrt((a+|x0|)^2 + (a+|y0|)^2
// + h^2) < sqrt(2 (1.5a)^2 + h^2)): nothing occludes, W = 1 exactly. In
// between: the part of the slab farther than near (polar quadrature).
TEST(LobeControls, NearClip) {
  const Slab s(1.0, 0.5);
  const Film plain = renderSlab(s, "ao", {});
  EXPECT_TRUE(sameImage(renderSlab(s, "ao", {"near=0.45"}), plain));
  const double beyond = std::sqrt(2 * 1.5 * s.a * 1.5 * s.a + s.h * s.h);
  const Film clear = renderSlab(s, "ao", {"near=" + formatFloat(beyond)});
  for (int y = 0; y < Slab::kH; ++y)
    for (int x = 0; x < Slab::kW; ++x) ASSERT_EQ(clear.at(kR, x, y), 1.0f) << x << "," << y;
  const double inf = std::numeric_limits<double>::infinity();
  for (const double near : {0.8, 1.2}) {
    const double rho0 = std::sqrt(near * near - s.h * s.h);
    const auto W = [&](double x, double y) { return 1 - polarOcclusion(x, y, s.a, s.h, rho0, inf, 4000); };
    expectMatches(renderSlab(s, "ao", {"near=" + formatFloat(near)}), s.expected(W), "near " + formatFloat(near));
  }
}

// spread on an open plane: every direction of the cone escapes, W = 1
// exactly at every pixel, for ao and obscurance, inside or not.
TEST(LobeControls, SpreadOnAnOpenPlaneIsOne) {
  Scene scene;
  addPlane(scene, 100.0f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0.3f, -2, 1), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "plane");
  for (const std::string config : {"ao", "obscurance"})
    for (const char* spread : {"1e-6", "0.3", "0.77"})
      for (const char* inside : {"false", "true"}) {
        const Film f = renderWith(scene, cam, config, {std::string("spread=") + spread, std::string("inside=") + inside,
                                                       "rays=2"},
                                  passSettings(16, 16, 8));
        for (int y = 0; y < 16; ++y)
          for (int x = 0; x < 16; ++x)
            ASSERT_EQ(f.at(kR, x, y), 1.0f) << config << " spread " << spread << " inside " << inside;
        size_t n = 0;
        meanCovered(f, kR, &n);
        EXPECT_EQ(n, 256u);
      }
}

// spread under the slab: W = 1 - F_cone / sin^2(thetaMax), F_cone the slab's
// part inside the cone rho < h tan(thetaMax). Slab a = 0.5, h = 1: its edges
// are 26.6 degrees off the normal, its corners 35.3; spread 0.5 (45 degrees)
// holds the whole slab, spread 1/3 (30 degrees) cuts it between edge and
// corner.
TEST(LobeControls, SpreadUnderTheSlab) {
  const Slab s(0.5, 1.0);
  for (const double spread : {0.5, 1.0 / 3.0}) {
    const double theta = spread * M_PI / 2, sin2 = std::sin(theta) * std::sin(theta);
    const auto W = [&](double x, double y) {
      return 1 - polarOcclusion(x, y, s.a, s.h, 0.0, s.h * std::tan(theta), 4000) / sin2;
    };
    expectMatches(renderSlab(s, "ao", {"spread=" + formatFloat(spread)}), s.expected(W),
                  "spread " + formatFloat(spread));
  }
}

// The lobe controls are the same numbers in every integrator: obscurance
// (step, both estimators) is ao bit for bit, transfer with black occluders is
// obscurance bit for bit (closed form and depth 1), and containment on a mesh
// without texture coordinates is obscurance's occlusion estimator bit for
// bit - all with inside, spread and near set.
TEST(LobeControls, IntegratorsAgreeWithTheControlsSet) {
  const Slab s(1.0, 0.5, true);
  for (const char* inside : {"false", "true"}) {
    const std::vector<std::string> lobe = {std::string("inside=") + inside, "spread=0.6", "near=0.7",
                                           "distance=3"};
    const Film ao = renderSlab(s, "ao", lobe);
    auto with = [&](std::vector<std::string> extra) {
      std::vector<std::string> p = lobe;
      p.insert(p.end(), extra.begin(), extra.end());
      return p;
    };
    EXPECT_TRUE(sameImage(renderSlab(s, "obscurance", lobe), ao)) << inside;
    const Film occl = renderSlab(s, "obscurance", with({"estimator=occlusion"}));
    EXPECT_TRUE(sameImage(occl, ao)) << inside;
    EXPECT_TRUE(sameImage(renderSlab(s, "transfer", lobe), ao)) << inside;
    EXPECT_TRUE(sameImage(renderSlab(s, "transfer", with({"depth=1"})), ao)) << inside;
    if (std::string(inside) == "false") {
      const std::string dir = tempDir("lobe_containment");
      const std::string map = writeHeightMap(dir + "/flat.exr", 4, 4, [](double, double) { return 0.5; });
      WarningCapture quiet;  // no texture coordinates: the fallback, announced once
      const std::vector<std::string> c = {"map=" + map, "spread=0.6", "near=0.7", "distance=3"};
      EXPECT_TRUE(sameImage(renderSlab(s, "containment", c), occl));
    }
  }
  // The same under the slab is a real test: the slab is there (W < 1).
  EXPECT_LT(meanCovered(renderSlab(s, "ao", {"spread=0.6", "near=0.7", "distance=3"}), kR), 0.9);
}

// inside as a thickness pass: a box of thickness d (faces z = 0 and z = d,
// 6 wide, R = 1 < 3 - 0.3 so no ray reaches the sides) seen from above, ao
// with distance R and inside=true. A ray into the box is open iff the bottom
// face is farther than R: d / cos(theta) > R, and cos^2(theta) is uniform on
// [0, 1] under cos/pi, so W = (d/R)^2. With spread (sin^2 theta uniform on
// [0, s^2]) W = max(0, (d/R)^2 - (1 - s^2)) / s^2. Plain ao from inside the
// box, looking up at the top face, estimates the same W.
TEST(LobeControls, InsideIsAThicknessPass) {
  const float d = 0.5f, L = 3.0f;
  const double R = 1.0;
  Scene scene;
  addPlane(scene, L, 0.0f);
  addPlane(scene, L, d);
  scene.commit();
  const Camera above = makeLookAtCamera(Vec3(0.1f, 0.05f, 5), Vec3(0, 0, d), Vec3(0, 1, 0), 0.1f, "above");
  const Camera within = makeLookAtCamera(Vec3(0.1f, 0.05f, 0.5f * d), Vec3(0, 0, d), Vec3(0, 1, 0), 0.8f, "within");
  const int w = 16, h = 16;
  const auto run = [&](const Camera& cam, std::vector<std::string> p) {
    p.push_back("distance=" + formatFloat(R));
    p.push_back("rays=" + std::to_string(kRays));
    const Film f = renderWith(scene, cam, "ao", p, passSettings(w, h, kSpp));
    size_t n = 0;
    const double m = meanCovered(f, kR, &n);
    EXPECT_EQ(n, size_t(w * h));
    return m;
  };
  const double N = double(w) * h * kSpp * kRays;
  const double dr2 = (d / R) * (d / R);
  const double inside = run(above, {"inside=true"}), flipped = run(within, {});
  std::printf("thickness: inside %.5f, flipped box %.5f, (d/R)^2 %.5f, se %.2g\n", inside, flipped, dr2,
              bernoulliStdErr(dr2, N));
  EXPECT_NEAR(inside, dr2, 4 * bernoulliStdErr(dr2, N));
  EXPECT_NEAR(flipped, dr2, 4 * bernoulliStdErr(dr2, N));
  // The two against each other, within the standard error of their
  // difference (sqrt(2) that of one, were they independent). They are in
  // fact equal: both lobes are the frame about -z at the same pixel keys,
  // so the same directions, and each direction's verdict depends on it
  // alone (the faces are planes), which the exact check pins.
  EXPECT_NEAR(inside, flipped, 4 * std::sqrt(2.0) * bernoulliStdErr(dr2, N));
  EXPECT_EQ(inside, flipped);
  // Seen from above without inside: the open sky, exactly 1.
  EXPECT_EQ(run(above, {}), 1.0);
  const double spread = 0.8, s2 = std::pow(std::sin(spread * M_PI / 2), 2);
  const double cone = std::max(0.0, dr2 - (1 - s2)) / s2;
  const double narrowed = run(above, {"inside=true", "spread=0.8"});
  std::printf("thickness, spread 0.8: %.5f, closed form %.5f\n", narrowed, cone);
  EXPECT_NEAR(narrowed, cone, 4 * bernoulliStdErr(cone, N));
}

// near only opens: each sample's direction and segment are the same with
// and without it, and a sample open without near is open with it (the ray
// tests [near, r] instead of [0, r]; containment's test points closer than
// near are skipped, the others are the same), so every pixel's W can only
// rise - exactly, not statistically. Checked for ao under the slab and for
// containment's height field (ripples of amplitude 0.1 and wavelength 0.5,
// uvs over the unit square; step falloff, so the test points are at R/2 and
// R, and near = 2R/3 skips the first), where it also rises somewhere: a
// sample whose first point is under a crest and whose second is past it.
TEST(LobeControls, NearOnlyOpens) {
  const auto expectRises = [](const Film& plain, const Film& clipped, const std::string& what) {
    bool rose = false;
    for (int y = 0; y < plain.height(); ++y)
      for (int x = 0; x < plain.width(); ++x) {
        ASSERT_GE(clipped.at(kR, x, y), plain.at(kR, x, y)) << what << " " << x << "," << y;
        rose = rose || clipped.at(kR, x, y) > plain.at(kR, x, y);
      }
    EXPECT_TRUE(rose) << what;
  };
  const Slab s(1.0, 0.5);
  expectRises(renderSlab(s, "ao", {}), renderSlab(s, "ao", {"near=0.8"}), "ao");

  Scene scene;
  scene.addWorldPrimitive({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}, {0, 1, 2, 0, 2, 3}, {}, {0, 0, 1, 0, 1, 1, 0, 1}, -1);
  scene.commit();
  const Camera top = makeLookAtCamera(Vec3(0.5f, 0.5f, 10), Vec3(0.5f, 0.5f, 0), Vec3(0, 1, 0), 0.05f, "top");
  const std::string map = writeRipples(tempDir("lobe_near_containment"));
  const std::vector<std::string> field = {"map=" + map, "scale=0.2", "distance=0.3", "rays=4"};
  auto with = [&](const std::vector<std::string>& extra) {
    std::vector<std::string> p = field;
    p.insert(p.end(), extra.begin(), extra.end());
    return renderWith(scene, top, "containment", p, passSettings(16, 16, 16));
  };
  expectRises(with({}), with({"near=0.2"}), "containment");
  expectRises(with({"spread=0.8"}), with({"spread=0.8", "near=0.2"}), "containment, spread 0.8");
}

// Explicit defaults are the defaults: the same image bit for bit for every
// integrator that has the controls (and they are what the code before them
// did: the warp is checked in ConeWarp, the sign 1 and tnear 0 are exact).
TEST(LobeControls, DefaultsAreBitIdentical) {
  const Slab s(1.0, 0.5);
  const std::vector<std::string> defaults = {"inside=false", "spread=1", "near=0"};
  for (const std::vector<std::string>& config :
       std::vector<std::vector<std::string>>{{"ao"},
                                             {"ao", "distance=0.8"},
                                             {"obscurance", "falloff=linear", "distance=2"},
                                             {"obscurance", "falloff=sqrt", "distance=2", "estimator=occlusion"},
                                             {"transfer", "distance=2"},
                                             {"transfer", "depth=1"},
                                             {"multibounce"},
                                             {"multibounce", "mapping=improved"}}) {
    std::vector<std::string> params(config.begin() + 1, config.end());
    const Film plain = renderSlab(s, config[0], params);
    params.insert(params.end(), defaults.begin(), defaults.end());
    std::string what = config[0];
    for (size_t i = 1; i < config.size(); ++i) what += " " + config[i];
    EXPECT_TRUE(sameImage(renderSlab(s, config[0], params), plain)) << what;
  }
}

// Extremes stay finite and in [0, 1]: the thinnest cone (spread 1e-6: the
// normal itself, which meets the black slab, W = 0 exactly - transfer and
// multibounce add no light from black occluders) and near far beyond the
// scene (even beyond float range: nothing occludes, W = 1 exactly).
TEST(LobeControls, Extremes) {
  const Slab s(1.0, 0.5, true);
  for (const std::string integrator : {"ao", "obscurance", "transfer", "multibounce"}) {
    const Film thin = renderSlab(s, integrator, {"spread=1e-6"});
    const Film far = renderSlab(s, integrator, {"near=1e30"});
    const Film farther = renderSlab(s, integrator, {"near=1e300"});
    for (int y = 0; y < Slab::kH; ++y)
      for (int x = 0; x < Slab::kW; ++x) {
        ASSERT_EQ(thin.at(kR, x, y), 0.0f) << integrator;
        ASSERT_EQ(far.at(kR, x, y), 1.0f) << integrator;
        ASSERT_EQ(farther.at(kR, x, y), 1.0f) << integrator;
      }
  }
}

// Bad values: one error naming the integrator and the parameter.
TEST(LobeControls, BadValuesNameTheParameter) {
  const auto error = [](const std::string& integrator, const std::vector<std::string>& params) -> std::string {
    const IntegratorDescriptor& d = IntegratorRegistry::instance().find(integrator);
    try {
      ParamSet p(d.params, d.name);
      for (const std::string& a : params) p.setAssignment(a);
      d.create(p);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  };
  for (const std::string integrator : {"ao", "obscurance", "transfer", "multibounce"}) {
    for (const char* bad : {"spread=0", "spread=1.5", "spread=-0.2", "spread=nan", "spread=inf", "near=-1",
                            "near=nan", "inside=maybe"}) {
      const std::string name = std::string(bad).substr(0, std::string(bad).find('='));
      const std::string msg = error(integrator, {bad});
      EXPECT_NE(msg.find("integrator '" + integrator + "'"), std::string::npos) << bad << ": " << msg;
      EXPECT_NE(msg.find("parameter '" + name + "'"), std::string::npos) << bad << ": " << msg;
    }
    // near must be below a finite distance (both named); 0 is always fine.
    const std::string both = error(integrator, {"distance=2", "near=2"});
    EXPECT_NE(both.find("'near'"), std::string::npos) << both;
    EXPECT_NE(both.find("'distance'"), std::string::npos) << both;
    EXPECT_EQ(error(integrator, {"distance=2", "near=1.99"}), "");
    EXPECT_EQ(error(integrator, {"distance=0", "near=0"}), "");
  }
  // containment takes spread and near, not inside.
  EXPECT_NE(error("containment", {"inside=true"}).find("unknown parameter 'inside'"), std::string::npos);
}

}  // namespace
}  // namespace obscura::test
