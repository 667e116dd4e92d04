// Environment lighting (docs/math.md §14) against closed forms.
//
// Maps are built here from their formulas: each texel holds the mean of
// the continuous radiance over the texel (exact for the radiances below,
// which depend on theta alone), so the only difference between the map's
// E0 and the continuous closed form is the texel's: Int_row (L - Lbar)
// (cos - cosbar) dw, O(dtheta^2) of the integrand's derivatives - with
// 512 rows (dtheta = 0.0061) under 2e-5 of E0 for these skies. The exact
// table adds at most 1e-5 (its leaf model, core/scene/environment.cpp), so
// E0 is checked to kE0Tolerance = 1e-4 of its value.
//
// Sampled passes are checked to 4 standard errors of their pixel means
// (pixelStats: pixels are independent estimates).
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <cmath>
#include <functional>

#include "core/scene/environment.h"
#include <obscura/error.h>
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr double kPiD = 3.14159265358979323846;
constexpr double kE0Tolerance = 1e-4;

// A map whose texel (i, j) holds the mean over the texel of L(theta) (the
// polar angle from +Y), RGB grey; `mean(t0, t1)` is that mean.
std::shared_ptr<const Environment> thetaMap(uint32_t W, uint32_t H,
                                            const std::function<double(double t0, double t1)>& mean,
                                            EnvironmentOptions o = {}) {
  std::vector<float> rgb(size_t(W) * H * 3);
  for (uint32_t j = 0; j < H; ++j) {
    const float v = float(mean(kPiD * j / H, kPiD * (j + 1) / H));
    for (uint32_t i = 0; i < W; ++i)
      for (int c = 0; c < 3; ++c) rgb[3 * (size_t(j) * W + i) + size_t(c)] = v;
  }
  return Environment::fromTexels(std::move(rgb), W, H, o, "test map");
}

// Mean of a + b cos(theta) over [t0, t1] by solid angle:
// Int (a + b cos) sin / Int sin = a + b (sin^2 t1 - sin^2 t0) / (2 (cos t0 - cos t1)).
double linearCosMean(double a, double b, double t0, double t1) {
  return a + b * 0.5 * (std::sin(t1) * std::sin(t1) - std::sin(t0) * std::sin(t0)) / (std::cos(t0) - std::cos(t1));
}

// The CIE overcast sky, Lz (1 + 2 cos theta) / 3 above the horizon, black below.
std::shared_ptr<const Environment> overcast(double Lz, EnvironmentOptions o = {}, uint32_t W = 1024, uint32_t H = 512) {
  return thetaMap(W, H, [&](double t0, double t1) {
    return t0 >= 0.5 * kPiD ? 0.0 : linearCosMean(Lz / 3, 2 * Lz / 3, t0, t1);
  }, o);
}
// L = a + b w_up over the whole sphere.
std::shared_ptr<const Environment> gradient(double a, double b, EnvironmentOptions o = {}) {
  return thetaMap(1024, 512, [&](double t0, double t1) { return linearCosMean(a, b, t0, t1); }, o);
}
// A black map but for texel (i, j) of radiance L.
std::shared_ptr<const Environment> singleTexel(uint32_t W, uint32_t H, uint32_t i, uint32_t j, float L,
                                               EnvironmentOptions o = {}) {
  std::vector<float> rgb(size_t(W) * H * 3, 0.0f);
  for (int c = 0; c < 3; ++c) rgb[3 * (size_t(j) * W + i) + size_t(c)] = L;
  return Environment::fromTexels(std::move(rgb), W, H, o, "texel map");
}

Vec3 up() { return Vec3(0, 1, 0); }

TEST(EnvironmentMapping, KnownDirectionsMatchBlender) {
  // docs/math.md §14.1: Blender's equirectangular mapping after the glTF
  // importer's axis change (verified in Blender 3.4: bench/cycles/verify_mapping.py).
  const struct {
    Vec3 d;
    float u, v;
  } cases[] = {{{1, 0, 0}, 0.5f, 0.5f},   {{0, 0, 1}, 0.75f, 0.5f}, {{0, 0, -1}, 0.25f, 0.5f},
               {{0, 1, 0}, -1.0f, 0.0f},  {{0, -1, 0}, -1.0f, 1.0f}};
  for (const auto& c : cases) {
    float u, v;
    directionToLatLong(c.d, u, v);
    if (c.u >= 0) {
      EXPECT_FLOAT_EQ(u, c.u) << c.d.x << "," << c.d.y << "," << c.d.z;
    }
    EXPECT_NEAR(v, c.v, 1e-7) << c.d.x << "," << c.d.y << "," << c.d.z;
  }
  float u, v;
  directionToLatLong(Vec3(-1, 0, 0), u, v);  // the seam: the left or right edge
  EXPECT_TRUE(u == 0.0f || u == 1.0f) << u;
  // Round trip away from the poles.
  for (float uu : {0.1f, 0.3f, 0.62f, 0.9f})
    for (float vv : {0.05f, 0.4f, 0.77f}) {
      directionToLatLong(latLongToDirection(uu, vv), u, v);
      EXPECT_NEAR(u, uu, 2e-6);
      EXPECT_NEAR(v, vv, 2e-6);
    }
}

TEST(EnvironmentMapping, RotationTurnsTheMapAboutUp) {
  // A texel at +X, turned 90 degrees counter-clockwise seen from above, is
  // seen along -Z (right-handed about +Y).
  const uint32_t W = 64, H = 32;
  EnvironmentOptions o;
  const auto plain = singleTexel(W, H, W / 2, H / 2, 1.0f);
  o.rotationDegrees = 90;
  const auto turned = singleTexel(W, H, W / 2, H / 2, 1.0f, o);
  const Vec3 atX = latLongToDirection((W / 2 + 0.5f) / W, (H / 2 + 0.5f) / H);
  const Vec3 rotated(atX.z, atX.y, -atX.x);  // R_y(90): x' = z, z' = -x
  EXPECT_EQ(plain->view().radiance(atX).x, 1.0f);
  EXPECT_EQ(turned->view().radiance(atX).x, 0.0f);
  EXPECT_EQ(turned->view().radiance(rotated).x, 1.0f);
  // Sampling the rotated map draws the rotated direction.
  float pdf = 0;
  Vec3 L;
  const Vec3 w = turned->view().sample(Sample2{0.5f, 0.5f}, pdf, L);
  EXPECT_EQ(L.x, 1.0f);
  EXPECT_GT(dot(w, rotated), 0.99f);
}

TEST(EnvironmentIrradiance, ExactTableMeetsTheClosedForms) {
  const double Lz = 1.7;
  const auto sky = overcast(Lz);
  // E0 / pi facing up: 7 Lz / 9; facing down: 0; horizontal: Lz (1/6 + 4 / (9 pi)) (docs/math.md §14.4).
  const EnvironmentView& v = sky->view();
  EXPECT_NEAR(v.irradianceOverPi(up()).x, 7 * Lz / 9, kE0Tolerance * 7 * Lz / 9);
  EXPECT_NEAR(v.irradianceOverPi(Vec3(0, -1, 0)).x, 0.0, kE0Tolerance * Lz);
  const double wall = Lz * (1.0 / 6 + 4.0 / (9 * kPiD));
  for (const Vec3 n : {Vec3(1, 0, 0), Vec3(0, 0, 1), Vec3(-1, 0, 0), Vec3(0, 0, -1)})
    EXPECT_NEAR(v.irradianceOverPi(n).x, wall, kE0Tolerance * wall) << n.x << "," << n.z;
  const double a = 1.0, b = 0.6;
  const auto grad = gradient(a, b);
  EXPECT_NEAR(grad->view().irradianceOverPi(up()).x, a + 2 * b / 3, kE0Tolerance * a);
  EXPECT_NEAR(grad->view().irradianceOverPi(Vec3(0, -1, 0)).x, a - 2 * b / 3, kE0Tolerance * a);
  EXPECT_NEAR(grad->view().irradianceOverPi(Vec3(0, 0, 1)).x, a, kE0Tolerance * a);
}

// Brute force: every texel split into k x k pieces, each max(0, n.w) at its
// centre times its solid angle. Its own error is the pieces' cut by the
// horizon, O(1/k) of a texel along the horizon: a bound of the horizon's
// length (2 pi) x the piece's size x its width, 2 pi (pi / (H k))^2.
double bruteE0OverPi(const Environment& e, Vec3 n, int k) {
  const EnvironmentView& v = e.view();
  double sum = 0;
  for (uint32_t j = 0; j < v.height; ++j)
    for (int b = 0; b < k; ++b) {
      const double t0 = kPiD * (j + double(b) / k) / v.height, t1 = kPiD * (j + double(b + 1) / k) / v.height;
      const double omega = 2 * kPiD / (double(v.width) * k) * (std::cos(t0) - std::cos(t1));
      for (uint32_t i = 0; i < v.width; ++i)
        for (int a = 0; a < k; ++a) {
          const Vec3 w = latLongToDirection(float((i + (a + 0.5) / k) / v.width), float(0.5 * (t0 + t1) / kPiD));
          sum += double(v.texel(i, j).x) * std::max(0.0, double(dot(n, w))) * omega;
        }
    }
  return sum / kPiD;
}

TEST(EnvironmentIrradiance, ExactAndShAgainstBruteForceOnEveryMap) {
  // Small maps, arbitrary normals: the exact convolution against brute
  // force, and SH9 against both where the map is band-limited.
  const uint32_t W = 32, H = 16;
  std::vector<std::pair<std::string, std::shared_ptr<const Environment>>> maps = {
      {"overcast", overcast(1.0, {}, W, H)},
      {"gradient", thetaMap(W, H, [](double t0, double t1) { return linearCosMean(1.0, 0.5, t0, t1); })},
      {"half", thetaMap(W, H, [](double t0, double) { return t0 < 0.5 * kPiD ? 1.0 : 0.0; })},
      {"texel", singleTexel(W, H, 5, 4, 50.0f)}};
  // A ragged map: every texel different.
  std::vector<float> rgb(size_t(W) * H * 3);
  for (size_t t = 0; t < rgb.size(); ++t) rgb[t] = float((t * 2654435761u) % 1000) / 250.0f;
  maps.push_back({"ragged", Environment::fromTexels(rgb, W, H, {}, "ragged")});
  const int k = 48;
  const double bruteBound = 2 * kPiD * std::pow(kPiD / (H * k), 2);
  for (const auto& [name, env] : maps) {
    double scale = 0;  // the largest E0 / pi, for relative tolerances
    for (int s = 0; s < 24; ++s) {
      const double z = 1.0 - 2.0 * (s + 0.5) / 24, r = std::sqrt(1 - z * z), phi = 2.399963 * s;
      const Vec3 n(float(r * std::cos(phi)), float(z), float(r * std::sin(phi)));
      const double brute = bruteE0OverPi(*env, n, k);
      scale = std::max(scale, brute);
      const double exact = env->exactIrradianceOverPi(n).x;
      // Brute force errs by bruteBound x the largest radiance / pi; the exact by kE0Tolerance.
      float Lmax = 0;
      for (uint32_t t = 0; t < W * H; ++t) Lmax = std::max(Lmax, env->view().texels[4 * t]);
      EXPECT_NEAR(exact, brute, bruteBound * Lmax / kPiD + kE0Tolerance * brute) << name << " normal " << s;
    }
    if (name == "gradient") {
      // L = a + b w_y is band-limited to l <= 1 but for the texels' steps:
      // SH9 is the exact E0 up to them (a few 1e-3 at 16 rows).
      for (const Vec3 n : {up(), Vec3(0, -1, 0), Vec3(1, 0, 0), normalize(Vec3(1, 1, 0))})
        EXPECT_NEAR(env->sh9IrradianceOverPi(n).x, env->exactIrradianceOverPi(n).x, 5e-3 * scale) << name;
    }
  }
}

TEST(EnvironmentSampling, DensityIsTheSamplersProbability) {
  // Sum over texels of pdf x Omega is 1, and draws land in texels with the
  // frequency pdf x Omega (a chi-square bound on a small map).
  const uint32_t W = 16, H = 8;
  std::vector<float> rgb(size_t(W) * H * 3);
  for (size_t t = 0; t < rgb.size(); ++t) rgb[t] = float((t * 40503u) % 97) / 10.0f;
  for (int c = 0; c < 3; ++c) rgb[3 * (3 * W + 2) + size_t(c)] = 0.0f;  // a black texel: never drawn
  const auto env = Environment::fromTexels(rgb, W, H, {}, "ragged");
  const EnvironmentView& v = env->view();
  double total = 0;
  for (uint32_t j = 0; j < H; ++j)
    for (uint32_t i = 0; i < W; ++i) total += double(v.texelPdf(i, j)) * v.rowSolidAngle[j];
  EXPECT_NEAR(total, 1.0, 1e-5);
  const int n = 1 << 18;
  std::vector<int> count(W * H, 0);
  int mismatched = 0;
  for (int s = 0; s < n; ++s) {
    float pdf;
    Vec3 L;
    const Vec3 w = v.sample(Sampler::get2D(7, uint32_t(s), 3), pdf, L);
    uint32_t i, j;
    v.texelOf(w, i, j);
    count[j * W + i] += 1;
    mismatched += v.pdf(w) != pdf ? 1 : 0;
  }
  EXPECT_EQ(count[3 * W + 2], 0);
  EXPECT_LT(mismatched, n / 1000) << "draws whose direction rounds into a neighbour texel";
  double chi2 = 0;
  int cells = 0;
  for (uint32_t j = 0; j < H; ++j)
    for (uint32_t i = 0; i < W; ++i) {
      const double expect = n * double(v.texelPdf(i, j)) * v.rowSolidAngle[j];
      if (expect <= 0) continue;
      chi2 += (count[j * W + i] - expect) * (count[j * W + i] - expect) / expect;
      ++cells;
    }
  // chi^2 with cells - 1 degrees of freedom: mean cells - 1, sd sqrt(2 (cells - 1)).
  // Stratified draws only lower it.
  EXPECT_LT(chi2, (cells - 1) + 5 * std::sqrt(2.0 * (cells - 1)));
}

TEST(EnvironmentSampling, GuidedWalkIsTheBinarySearch) {
  // The guide only chooses where the walk starts (docs/math.md §14.3,
  // "Cost"): from any start the walk ends on the binary search's step, for
  // every x - the CDF's own values and their neighbours, the guide's slot
  // bounds, zero-width steps, a CDF whose last steps round to 1, a black
  // row's all-zero CDF.
  std::vector<std::vector<float>> cdfs;
  cdfs.push_back({0.0f, 0.25f, 0.25f, 0.25f, 0.5f, 1.0f});
  cdfs.push_back({0.0f, 0.0f, 0.0f, 1.0f});
  cdfs.push_back({0.0f, 0.0f, 0.0f, 0.0f, 0.0f});
  cdfs.push_back({0.0f, 1e-9f, 0.5f, 1.0f, 1.0f, 1.0f});
  std::vector<float> ragged{0.0f};
  for (uint32_t k = 1; k < 300; ++k) ragged.push_back(ragged.back() + float((k * 40503u) % 7 == 0 ? 0 : (k * 2654435761u) % 1000));
  for (float& c : ragged) c /= ragged.back();
  ragged.back() = 1.0f;
  cdfs.push_back(ragged);
  for (const std::vector<float>& cdf : cdfs) {
    const uint32_t n = uint32_t(cdf.size() - 1);
    for (const uint32_t size : {1u, 3u, n / 4 + 1, n, 4 * n + 1}) {
      std::vector<uint32_t> guide(size);
      EnvironmentView::buildGuide(cdf.data(), n, size, guide.data());
      std::vector<float> xs{0.0f, std::nextafter(1.0f, 0.0f)};
      for (const float c : cdf)
        for (const float x : {std::nextafter(c, 0.0f), c, std::nextafter(c, 1.0f)}) xs.push_back(x);
      for (uint32_t k = 0; k <= size; ++k) {
        const float b = float(k) / float(size);
        for (const float x : {std::nextafter(b, 0.0f), b, std::nextafter(b, 1.0f)}) xs.push_back(x);
      }
      for (int k = 0; k < 4096; ++k) xs.push_back(Sampler::get2D(3, uint32_t(k), 0).u);
      for (const float x : xs) {
        if (!(x >= 0.0f && x < 1.0f)) continue;
        ASSERT_EQ(EnvironmentView::guidedStep(cdf.data(), n, guide.data(), size, x),
                  EnvironmentView::searchStep(cdf.data(), n, x))
            << "n " << n << " guide " << size << " x " << x;
      }
    }
  }
  // On a map, staged draws land on the texels the binary searches give.
  const uint32_t W = 64, H = 32;
  std::vector<float> rgb(size_t(W) * H * 3, 0.0f);
  for (size_t t = 0; t < rgb.size(); ++t) rgb[t] = (t / 3) % 5 == 0 ? 0.0f : float((t * 40503u) % 97) / 10.0f;
  for (uint32_t i = 0; i < W; ++i)
    for (int c = 0; c < 3; ++c) rgb[3 * (size_t(5) * W + i) + size_t(c)] = 0.0f;  // a black row
  for (int c = 0; c < 3; ++c) rgb[3 * (size_t(9) * W + 40) + size_t(c)] = 1e5f;  // a sun
  const auto env = Environment::fromTexels(rgb, W, H, {}, "sun");
  const EnvironmentView& v = env->view();
  for (uint32_t k = 0; k < (1u << 16); ++k) {
    const Sample2 u = Sampler::get2D(11, k, 5);
    EnvironmentView::Draw d;
    v.drawRow(u, d);
    v.drawStart(d);
    v.drawColumn(u, d);
    const uint32_t j = EnvironmentView::searchStep(v.rowCdf, H, u.v);
    ASSERT_EQ(d.j, j) << k;
    ASSERT_EQ(d.i, EnvironmentView::searchStep(v.columnCdf + size_t(j) * (W + 1), W, u.u)) << k;
    float staged = 0, whole = 0;
    Vec3 Ls, Lw;
    const Vec3 ws = v.drawDirection(u, d, staged, Ls), ww = v.sample(u, whole, Lw);
    ASSERT_TRUE(ws.x == ww.x && ws.y == ww.y && ws.z == ww.z && staged == whole && Ls.x == Lw.x) << k;
    float looked = 0;
    const Vec3 L = v.radianceAndPdfAt(v.texelIndex(ws), looked);
    float direct = 0;
    const Vec3 L2 = v.radianceAndPdf(ws, direct);
    ASSERT_TRUE(L.x == L2.x && looked == direct) << k;
  }
}

// A horizontal square y = 0 (normal +Y) and a camera looking down at it.
struct OpenPlane {
  Scene scene;
  Camera cam;
  explicit OpenPlane(float albedo) {
    const int m = addGreyMaterial(scene, albedo);
    const float h = 1e3f;
    scene.addWorldPrimitive({{-h, 0, -h}, {h, 0, -h}, {h, 0, h}, {-h, 0, h}}, {0, 1, 2, 0, 2, 3}, {}, {}, m);
    scene.commit();
    cam = makeLookAtCamera(Vec3(0.3f, 2.0f, 1.0f), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.8f, "down");
  }
};

RenderSettings litSettings(int w, int h, int spp, std::shared_ptr<const Environment> env, uint32_t seed = 0) {
  RenderSettings s = passSettings(w, h, spp, seed);
  s.aovs = true;
  s.albedoAov = true;
  s.environment = std::move(env);
  return s;
}

TEST(EnvironmentShading, OpenPlaneShadedIsAlbedoTimesE0OverPi) {
  const float albedo = 0.6f;
  OpenPlane plane(albedo);
  const double Lz = 2.0;
  const auto sky = overcast(Lz);
  const double expect = albedo * 7 * Lz / 9;
  // ao: W = 1 exactly, so shaded.* is the table at the pole (a node).
  const Film ao = renderWith(plane.scene, plane.cam, "ao", {}, litSettings(24, 24, 4, sky));
  EXPECT_NEAR(meanCovered(ao, kShadedR), expect, kE0Tolerance * expect);
  // gi and dirocc: sampled, to 4 standard errors.
  for (const char* integ : {"gi", "dirocc"}) {
    const Film f = renderWith(plane.scene, plane.cam, integ, {}, litSettings(32, 32, 16, sky));
    const PixelStats st = pixelStats(f, kShadedR);
    EXPECT_NEAR(st.mean, expect, 4 * st.se + kE0Tolerance * expect) << integ;
  }
}

TEST(EnvironmentShading, SingleTexelLightsThePlaneByItsSolidAngle) {
  // E0 = L n.M (the texel's first moment; ~ L Omega cos theta) and gi on
  // the open plane is albedo E0 / pi: light sampling finds the texel.
  const uint32_t W = 256, H = 128, i = 40, j = 30;
  const float L = 1000.0f, albedo = 0.5f;
  const auto env = singleTexel(W, H, i, j, L);
  const double t0 = kPiD * j / H, t1 = kPiD * (j + 1) / H;
  const double omega = 2 * kPiD / W * (std::cos(t0) - std::cos(t1));
  const double B = 0.5 * std::sin(t0 + t1) * std::sin(t1 - t0);  // n.M facing up, per unit phi
  const double e0 = L * B * (2 * kPiD / W);
  EXPECT_NEAR(e0, L * omega * std::cos(0.5 * (t0 + t1)), L * omega * (t1 - t0));  // the first-order form
  EXPECT_NEAR(env->view().irradianceOverPi(up()).x, e0 / kPiD, 1e-5 * e0);
  OpenPlane plane(albedo);
  const Film gi = renderWith(plane.scene, plane.cam, "gi", {}, litSettings(32, 32, 16, env));
  const PixelStats st = pixelStats(gi, kShadedR);
  EXPECT_NEAR(st.mean, albedo * e0 / kPiD, 4 * st.se + 1e-5 * e0);
}

// A wall x = 0 facing +X standing on a black floor y = 0 (x >= 0): the floor
// blocks the lower half of the wall's hemisphere, so AO is 1/2, while the
// light it blocks depends on the sky.
struct WallOnFloor {
  Scene scene;
  Camera cam;
  explicit WallOnFloor(float albedo) {
    const int wall = addGreyMaterial(scene, albedo), floor = addGreyMaterial(scene, 0.0f);
    // 1e6 wide, seen from 1.5 up: the floor's far edge lets through a band
    // of 1.5e-6 rad below the horizon (1e-6 of the hemisphere's weight).
    const float h = 1e6f;
    scene.addWorldPrimitive({{0, 0, -h}, {0, h, -h}, {0, h, h}, {0, 0, h}}, {0, 1, 2, 0, 2, 3}, {}, {}, wall);
    scene.addWorldPrimitive({{0, 0, -h}, {h, 0, -h}, {h, 0, h}, {0, 0, h}}, {0, 1, 2, 0, 2, 3}, {}, {}, floor);
    scene.commit();
    cam = makeLookAtCamera(Vec3(2.0f, 1.5f, 0.2f), Vec3(0, 1.5f, 0), Vec3(0, 1, 0), 0.5f, "wall");
  }
};

TEST(EnvironmentShading, WallOnBlackFloorUnderGradientAndOvercast) {
  const float albedo = 0.8f;
  WallOnFloor wall(albedo);
  // Gradient L = a + b w_y: the wall's open quarter sphere gives
  // Int (a + b w_y)(n.w) = pi a / 2 + 2b / 3, so the reflected radiance is
  // albedo (a/2 + 2b/(3 pi)); AO x E0(n) x albedo / pi says albedo a / 2.
  const double a = 1.0, b = 0.9;
  const auto grad = gradient(a, b);
  const double truth = albedo * (a / 2 + 2 * b / (3 * kPiD));
  const Film ao = renderWith(wall.scene, wall.cam, "ao", {"rays=4"}, litSettings(24, 24, 16, grad));
  const PixelStats w = pixelStats(ao, kR);
  EXPECT_NEAR(w.mean, 0.5, 4 * w.se);
  const PixelStats aoShaded = pixelStats(ao, kShadedR);
  EXPECT_NEAR(aoShaded.mean, albedo * a / 2, 4 * aoShaded.se + kE0Tolerance);
  for (const char* integ : {"gi", "dirocc"}) {
    const Film f = renderWith(wall.scene, wall.cam, integ, {}, litSettings(32, 32, 32, grad));
    const PixelStats st = pixelStats(f, kShadedR);
    EXPECT_NEAR(st.mean, truth, 4 * st.se + kE0Tolerance) << integ;
  }
  // Overcast (black below the horizon): the floor blocks nothing lit, so
  // the wall gets all of E0(n) = Lz (pi/6 + 4/9): gi = albedo E0 / pi.
  const double Lz = 1.0;
  const auto sky = overcast(Lz);
  const Film gi = renderWith(wall.scene, wall.cam, "gi", {}, litSettings(32, 32, 32, sky));
  const PixelStats st = pixelStats(gi, kShadedR);
  EXPECT_NEAR(st.mean, albedo * Lz * (1.0 / 6 + 4.0 / (9 * kPiD)), 4 * st.se + kE0Tolerance);
}

TEST(EnvironmentShading, ConstantMapIsTheSkyBitForBit) {
  // A constant map of the sky's radiance renders every pass exactly as --sky does.
  const Vec3 L(0.7f, 0.8f, 0.9f);
  std::vector<float> rgb;
  for (int t = 0; t < 8 * 4; ++t) rgb.insert(rgb.end(), {L.x, L.y, L.z});
  const auto env = Environment::fromTexels(rgb, 8, 4, {}, "constant");
  ASSERT_TRUE(env->isConstant());
  Crease crease;
  for (const char* integ : {"ao", "obscurance", "transfer", "multibounce", "gi", "dirocc", "reflocc", "vo", "ssat"}) {
    RenderSettings withSky = litSettings(32, 24, 4, nullptr);
    withSky.sky = L;
    const Film a = renderWith(crease.scene, crease.cam, integ, {}, withSky);
    const Film b = renderWith(crease.scene, crease.cam, integ, {}, litSettings(32, 24, 4, env));
    expectSameFilm(a, b, integ);
  }
}

TEST(EnvironmentShading, BentNormalLooksE0UpAlongTheOpenDirections) {
  // On the wall over the floor under the gradient sky, the bent normal
  // tilts up (the floor blocks the lower directions), so e0=bent reads a
  // brighter E0 than e0=normal; on the open plane both are the same.
  WallOnFloor wall(1.0f);
  const auto grad = gradient(1.0, 0.9);
  const Film n = renderWith(wall.scene, wall.cam, "ao", {"rays=8"}, litSettings(16, 16, 16, grad));
  const Film b = renderWith(wall.scene, wall.cam, "ao", {"rays=8", "e0=bent"}, litSettings(16, 16, 16, grad));
  EXPECT_EQ(meanCovered(n, kR), meanCovered(b, kR));  // W itself is unchanged
  EXPECT_GT(meanCovered(b, kShadedR), meanCovered(n, kShadedR) * 1.05);
  // The bent normal of the open quarter sphere (x > 0, y > 0) is the mean
  // cosine-weighted direction, (Int x^2, Int x y, 0) = (pi/3, 2/3, 0) over
  // it: E0 there by the table, times AO = 1/2.
  const double expect = 0.5 * grad->view().irradianceOverPi(normalize(Vec3(float(kPiD / 3), 2.0f / 3, 0))).x;
  const PixelStats st = pixelStats(b, kShadedR);
  EXPECT_NEAR(st.mean, expect, 0.02 * expect);  // the per-pixel bent normal is itself an estimate
}

// L = a + b w_x, each texel its centre's value: on the crease (floor z = 0,
// wall x = 0, tests/support.h) brighter away from the wall, so a floor
// point's bent normal, tilted away from the wall, reads more light.
std::shared_ptr<const Environment> xGradient(double a, double b) {
  const uint32_t W = 512, H = 256;
  std::vector<float> rgb(size_t(W) * H * 3);
  for (uint32_t j = 0; j < H; ++j)
    for (uint32_t i = 0; i < W; ++i) {
      const Vec3 d = latLongToDirection((float(i) + 0.5f) / float(W), (float(j) + 0.5f) / float(H));
      for (int c = 0; c < 3; ++c) rgb[3 * (size_t(j) * W + i) + size_t(c)] = float(a + b * double(d.x));
    }
  return Environment::fromTexels(std::move(rgb), W, H, {}, "x gradient");
}

// The bent normals of a floor point h from the crease's wall, in the floor's
// frame (x away from the wall, z up), by quadrature - independent of the
// integrators (docs/math.md §14.6):
// - cosine: Int_open w cos(theta) dw over the directions whose segment of
//   length R stays in front of the wall (h + R w_x >= 0): obscurance's and
//   z-buffer containment's with the step falloff (every r = R);
// - volume: the first moment about P of the empty half-ball of radius R,
//   {|x - P| < R, z > 0, x > -h}: vo's with the normal clamp, closed form -
//   x: (pi/8)(R^2 - h^2)^2 for h < R (the cut cap's moment, negated), z:
//   pi R^4 / 4 less the cap's (2/3) Int_h^R (R^2 - X^2)^(3/2) dX.
Vec3 creaseCosineBent(double h, double R) {
  // For polar angle theta the open azimuths are |phi| <= phi_m, cos(phi_m)
  // = max(-1, -h / (R sin(theta))): Int cos(phi) = 2 sin(phi_m), Int 1 =
  // 2 phi_m; w cos(theta) dw = (sin cos(phi), ., cos) cos sin dtheta dphi,
  // the theta integrals over each band in closed form.
  const int n = 1 << 14;
  double bx = 0, bz = 0;
  for (int it = 0; it < n; ++it) {
    const double t0 = 0.5 * kPiD * it / n, t1 = 0.5 * kPiD * (it + 1) / n;
    const double st = std::sin(0.5 * (t0 + t1));
    const double phiM = std::acos(std::max(-1.0, -h / (R * st)));
    bx += 2 * std::sin(phiM) * (std::pow(std::sin(t1), 3) - std::pow(std::sin(t0), 3)) / 3;
    bz += 2 * phiM * (std::pow(std::cos(t0), 3) - std::pow(std::cos(t1), 3)) / 3;
  }
  return Vec3(float(bx), 0.0f, float(bz));
}
Vec3 creaseVolumeBent(double h, double R) {
  if (h >= R) return Vec3(0, 0, 1);
  const auto F = [](double t) { return 3 * t / 8 + std::sin(2 * t) / 4 + std::sin(4 * t) / 32; };
  const double cap = (2.0 / 3) * std::pow(R, 4) * (F(0.5 * kPiD) - F(std::asin(h / R)));
  const double x = kPiD / 8 * (R * R - h * h) * (R * R - h * h), z = kPiD * std::pow(R, 4) / 4 - cap;
  return Vec3(float(x), 0.0f, float(z));
}

TEST(EnvironmentShading, ScreenSpaceAndContainmentBentNormalsOnTheCrease) {
  // Floor pixels near the crease's wall under L = a + b w_x: lighting.R of
  // e0=bent is E0/pi at the pass's bent normal, here a + (2b/3) n_x (the
  // map's E0 at the direction is read from its table). Against the
  // quadrature's bent normal at each pixel centre's h: the mean over the
  // pixels within 4 standard errors (8 replicates) plus the pixel
  // footprint (half the largest change of the expected value to a
  // neighbouring centre, averaged), which also covers the pixel's
  // averaging of bent directions over its area and the bias of normalizing
  // a noisy sum (obscurance, the plain estimator, is off by 0.004, within
  // it; 16 spp). W itself is unchanged by e0 (the same samples).
  const Crease c;
  const int w = 64, ht = 48;
  const double R = 0.5, a = 1.0, b = 0.9;
  const auto map = xGradient(a, b);
  const CreaseCentres cc = creaseCentres(c, w, ht, R);
  ASSERT_GT(cc.pixels.size(), 100u);
  std::vector<double> hOf(cc.pixels.size());
  for (size_t k = 0; k < cc.pixels.size(); ++k) {
    Vec3 p;
    ASSERT_TRUE(c.floorAt(w, ht, cc.pixels[k].first, cc.pixels[k].second, p));
    hOf[k] = p.x;
  }
  // containment without texture coordinates is obscurance (its fallback,
  // announced once): the bent normal's sum in its own loop.
  const std::string flat = writeHeightMap(tempDir("bent_crease") + "/flat.exr", 4, 4, [](double, double) { return 0.5; });
  WarningCapture quiet;
  const struct {
    std::string integ;
    std::vector<std::string> params;
    bool volume;
  } passes[] = {
      {"vo", {"samples=point", "radius=0.5"}, true},
      {"vo", {"samples=point", "radius=0.5", "depth=traced"}, true},
      {"vo", {"samples=line", "radius=0.5"}, true},
      {"ssat", {"distance=0.5", "falloff=step", "silhouette=false", "interleave=off"}, false},
      {"ssat", {"distance=0.5", "falloff=step", "silhouette=false", "interleave=off", "depth=traced"}, false},
      {"obscurance", {"distance=0.5", "falloff=step", "rays=16"}, false},
      {"containment", {"map=" + flat, "distance=0.5", "falloff=step", "rays=16"}, false},
      {"gtao", {"radius=0.5", "interleave=off"}, false},
      {"gtao", {"radius=0.5", "interleave=off", "depth=traced"}, false},
  };
  for (const auto& pass : passes) {
    const auto expected = [&](double h) {
      const Vec3 B = pass.volume ? creaseVolumeBent(h, R) : creaseCosineBent(h, R);
      return map->view().irradianceOverPi(normalize(B)).x;
    };
    std::vector<double> e(cc.pixels.size());
    double footprint = 0;
    for (size_t k = 0; k < cc.pixels.size(); ++k) e[k] = expected(hOf[k]);
    for (size_t k = 0; k < cc.pixels.size(); ++k) {
      double d = 0;
      for (const auto [dx, dy] : {std::pair{1, 0}, std::pair{0, 1}}) {
        Vec3 p;
        if (c.floorAt(w, ht, cc.pixels[k].first + dx, cc.pixels[k].second + dy, p))
          d = std::max(d, std::abs(expected(p.x) - e[k]));
      }
      footprint += 0.5 * d / double(cc.pixels.size());
    }
    std::vector<std::string> bent = pass.params, normal = pass.params;
    bent.push_back("e0=bent");
    const MeanSe m = replicateMean(8, [&](uint32_t seed) {
      const Film f = renderWith(c.scene, c.cam, pass.integ, bent, litSettings(w, ht, 16, map, seed));
      const Film g = renderWith(c.scene, c.cam, pass.integ, normal, litSettings(w, ht, 16, map, seed));
      const int light = f.find("lighting.R");
      EXPECT_GE(light, 0);
      double sum = 0.0;
      size_t n = 0;
      for (size_t k = 0; k < cc.pixels.size(); ++k) {
        const auto [x, y] = cc.pixels[k];
        if (f.at(kA, x, y) != 1.0f) continue;
        EXPECT_EQ(f.at(kR, x, y), g.at(kR, x, y)) << pass.integ;
        sum += f.at(light, x, y) - e[k], ++n;
      }
      return sum / double(n);
    });
    EXPECT_NEAR(m.mean, 0.0, 4 * m.se + footprint) << pass.integ << " " << pass.params.back() << " se " << m.se
                                                   << " footprint " << footprint;
    RecordProperty(pass.integ + "_" + pass.params.back() + "_bent_bias", std::to_string(m.mean));
  }
}

TEST(EnvironmentShading, LightSamplingCutsTheSunsVariance) {
  // A sky of radiance 1 with a sun of 1e5 over 2 x 2 texels at 45 degrees:
  // gi with MIS and with cosine directions alone agree in the mean (4 SE),
  // and MIS's variance is far lower. Measured ratio: see the failure text.
  const uint32_t W = 512, H = 256;
  std::vector<float> rgb(size_t(W) * H * 3, 1.0f);
  for (uint32_t j = H / 4; j < H / 4 + 2; ++j)
    for (uint32_t i = W / 2; i < W / 2 + 2; ++i)
      for (int c = 0; c < 3; ++c) rgb[3 * (size_t(j) * W + i) + size_t(c)] = 1e5f;
  const auto env = Environment::fromTexels(rgb, W, H, {}, "sun");
  OpenPlane plane(0.5f);
  const Film mis = renderWith(plane.scene, plane.cam, "gi", {}, litSettings(32, 32, 4, env));
  const Film cosine = renderWith(plane.scene, plane.cam, "gi", {"sampling=cosine"}, litSettings(32, 32, 4, env));
  const PixelStats a = pixelStats(mis, kShadedR), b = pixelStats(cosine, kShadedR);
  EXPECT_NEAR(a.mean, b.mean, 4 * std::sqrt(a.se * a.se + b.se * b.se));
  const double truth = 0.5 * env->view().irradianceOverPi(up()).x;
  EXPECT_NEAR(a.mean, truth, 4 * a.se + kE0Tolerance * truth);
  // Cosine sampling meets the sun with probability ~ Omega cos / pi ~ 4e-5
  // a direction: its per-pixel variance is ~ 1e4 x MIS's.
  EXPECT_GT(b.sd * b.sd, 1000 * a.sd * a.sd) << "variance ratio " << (b.sd * b.sd) / (a.sd * a.sd);
}

TEST(EnvironmentShading, DirectionalOcclusionIsGisDirectLight) {
  // In a cavity under the gradient sky: dirocc x E0 x albedo/pi (its
  // shaded.*) estimates the direct light, as gi max-depth=0 does.
  Scene scene;
  const int m = addGreyMaterial(scene, 0.7f);
  addSphereCavity(scene, 1.0f, 1.0, 64, 128, m);
  scene.setRobust(true);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0.2f, -0.1f, 0.1f), Vec3(1, 0.2f, -0.6f), Vec3(0, 0, 1), 1.2f, "inside");
  const auto grad = gradient(1.0, 0.8);
  const Film d = renderWith(scene, cam, "dirocc", {}, litSettings(32, 32, 16, grad));
  const Film g = renderWith(scene, cam, "gi", {"max-depth=0"}, litSettings(32, 32, 16, grad));
  const PixelStats a = pixelStats(d, kShadedR), b = pixelStats(g, kShadedR);
  EXPECT_NEAR(a.mean, b.mean, 4 * std::sqrt(a.se * a.se + b.se * b.se));
  EXPECT_GT(a.mean, 0.0);
}

TEST(EnvironmentExtremes, StrengthOneMapSizeAndBadTexels) {
  OpenPlane plane(1.0f);
  for (const double strength : {1e-30, 1e30}) {
    EnvironmentOptions o;
    o.strength = strength;
    const auto env = gradient(1.0, 0.5, o);
    const Film f = renderWith(plane.scene, plane.cam, "gi", {}, litSettings(8, 8, 4, env));
    const Film ao = renderWith(plane.scene, plane.cam, "ao", {}, litSettings(8, 8, 4, env));
    const double expect = strength * (1.0 + 2 * 0.5 / 3);
    EXPECT_NEAR(meanCovered(ao, kShadedR) / expect, 1.0, 1e-4) << strength;
    const PixelStats st = pixelStats(f, kShadedR);
    EXPECT_TRUE(std::isfinite(st.mean)) << strength;
    EXPECT_NEAR(st.mean / expect, 1.0, 4 * st.se / expect + 1e-4) << strength;
  }
  // A 1 x 1 map is the constant sky.
  const auto one = Environment::fromTexels({0.5f, 0.25f, 2.0f}, 1, 1, {}, "one");
  EXPECT_TRUE(one->isConstant());
  EXPECT_EQ(one->view().irradianceOverPi(Vec3(0.3f, 0.9f, 0.1f)).z, 2.0f);
  // A 2 x 1 map (not 2:1): accepted, each texel a hemisphere of longitude.
  const auto two = Environment::fromTexels({1, 1, 1, 0, 0, 0}, 2, 1, {}, "two");
  // Texel 0 (u < 1/2) is the half z < 0: facing -Z sees all of it, +X half, +Z none.
  EXPECT_NEAR(two->view().irradianceOverPi(Vec3(0, 0, -1)).x, 1.0, kE0Tolerance);
  EXPECT_NEAR(two->view().irradianceOverPi(Vec3(1, 0, 0)).x, 0.5, kE0Tolerance);
  EXPECT_NEAR(two->view().irradianceOverPi(Vec3(0, 0, 1)).x, 0.0, kE0Tolerance);
  // NaN, infinite and negative texels are refused, the texel named.
  for (const float bad : {NAN, INFINITY, -1.0f}) {
    std::vector<float> rgb(4 * 2 * 3, 1.0f);
    rgb[3 * (1 * 4 + 3) + 1] = bad;
    try {
      (void)Environment::fromTexels(rgb, 4, 2, {}, "bad.exr");
      ADD_FAILURE() << "accepted " << bad;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("bad.exr: texel (column 3, row 1) channel G"), std::string::npos) << e.what();
    }
  }
}

TEST(EnvironmentShading, RotationMovesTheSunsShadow) {
  // A pole on a plane under one bright texel at elevation ~45 degrees
  // towards +X: its shadow points to -X. Turned 90 degrees the sun is
  // towards -Z and the shadow points to +Z. Seen from above (image x = +X,
  // image y = +Z), the shadow's centroid turns by 90 degrees about the pole.
  Scene scene;
  const float h = 50.0f, r = 0.1f, H = 1.0f;
  scene.addWorldPrimitive({{-h, 0, -h}, {h, 0, -h}, {h, 0, h}, {-h, 0, h}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  // The pole: a box of half-width r and height H at the origin.
  scene.addWorldPrimitive({{-r, 0, -r}, {r, 0, -r}, {r, 0, r}, {-r, 0, r}, {-r, H, -r}, {r, H, -r}, {r, H, r}, {-r, H, r}},
                          {0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7, 4, 5, 6, 4, 6, 7}, {}, {}, -1);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0, 6, 0), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.7f, "above");
  const uint32_t W = 64, Hm = 32;
  const auto angleOfShadow = [&](double degrees) {
    EnvironmentOptions o;
    o.rotationDegrees = degrees;
    const auto env = singleTexel(W, Hm, W / 2, Hm / 4, 100.0f, o);  // u = 0.5 (+X), v = 0.25 (45 degrees up)
    const int n = 64;
    const Film f = renderWith(scene, cam, "dirocc", {"rays=4"}, litSettings(n, n, 4, env));
    // The shadow: covered pixels of the plane with D < 1/2, minus the pole's own pixels near the centre.
    double sx = 0, sy = 0, count = 0;
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const double dx = x + 0.5 - n / 2.0, dy = y + 0.5 - n / 2.0;
        if (f.at(kA, x, y) == 1.0f && f.at(kR, x, y) < 0.5f && dx * dx + dy * dy > 9.0) sx += dx, sy += dy, count += 1;
      }
    EXPECT_GT(count, 20) << degrees;
    return std::atan2(sy, sx) * 180.0 / kPiD;
  };
  const double a0 = angleOfShadow(0), a90 = angleOfShadow(90);
  double turn = std::fmod(std::fabs(a90 - a0), 360.0);
  if (turn > 180) turn = 360 - turn;
  EXPECT_NEAR(turn, 90.0, 10.0) << a0 << " -> " << a90;  // the texel is 5.6 degrees wide
}

TEST(EnvironmentShading, BlackHalfGivesZeroNotNaN) {
  // A plane seen from below under a map whose lower half is black: E0 = 0
  // there, gi's W and shaded.* are 0 and finite (W is relative to the map's
  // mean radiance, never to E0).
  const auto half = thetaMap(64, 32, [](double t0, double) { return t0 < 0.5 * kPiD ? 1.0 : 0.0; });
  OpenPlane plane(0.5f);
  const Camera below = makeLookAtCamera(Vec3(0.3f, -2.0f, 1.0f), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.8f, "below");
  for (const char* integ : {"gi", "ao", "dirocc"}) {
    const Film f = renderWith(plane.scene, below, integ, {}, litSettings(16, 16, 4, half));
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) {
        ASSERT_TRUE(std::isfinite(f.at(kR, x, y))) << integ;
        // 0 up to the rounding of cos(pi/2) at the horizon's texel edge (~1e-16).
        ASSERT_NEAR(f.at(kShadedR, x, y), 0.0f, 1e-12) << integ << " " << x << "," << y;
      }
  }
}

#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_UNDEFINED__)
TEST(EnvironmentExtremes, A16kMapBuilds) {
  // 16384 x 8192 (2 GiB of texels and densities): the pyramid starts at a coarser base
  // level; the half-black map's E0 stays exact (its horizon is a texel edge).
  const uint32_t W = 16384, H = 8192;
  std::vector<float> rgb(size_t(W) * H * 3, 0.0f);
  std::fill(rgb.begin(), rgb.begin() + size_t(W) * (H / 2) * 3, 1.0f);
  const auto env = Environment::fromTexels(std::move(rgb), W, H, {}, "16k");
  EXPECT_NEAR(env->view().irradianceOverPi(up()).x, 1.0, kE0Tolerance);
  EXPECT_NEAR(env->view().irradianceOverPi(Vec3(1, 0, 0)).x, 0.5, kE0Tolerance);
  EXPECT_NEAR(env->meanRadiance().x, 0.5, 1e-6);
}
#endif

void writeMap(const std::string& path, int w, int h, const std::vector<float>& rgb) {
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out);
  ASSERT_TRUE(out->open(path, OIIO::ImageSpec(w, h, 3, OIIO::TypeDesc::FLOAT)));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, rgb.data()));
  out->close();
}

TEST(EnvironmentCli, RecordsTheMapAndRefusesBadInput) {
  const std::string dir = tempDir("environment_cli");
  std::vector<float> rgb(64 * 32 * 3, 1.0f);
  std::fill(rgb.begin() + 64 * 16 * 3, rgb.end(), 0.0f);
  const std::string map = dir + "/half.exr";
  writeMap(map, 64, 32, rgb);
  const std::string out = dir + "/lit.exr";
  const CliResult r = runCli({"render", "-i", "ao", "--res", "32x18", "--spp", "2", "-q", "--environment", map,
                              "--environment-rotation", "30", "--environment-strength", "2", "-o", out},
                             dir + "/err.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack rb = readExr(out);
  ASSERT_TRUE(rb.ok);
  EXPECT_EQ(rb.spec.get_string_attribute("obscura:environment"), map);
  EXPECT_EQ(rb.spec.get_string_attribute("obscura:environmentRotation"), "30");
  EXPECT_EQ(rb.spec.get_string_attribute("obscura:environmentStrength"), "2");
  EXPECT_EQ(rb.spec.get_string_attribute("obscura:environmentHash").size(), 16u);
  EXPECT_TRUE(rb.planes.count("lighting.R"));
  // Bad input: one line naming the option or the file, exit 1.
  rgb[3 * 5 + 2] = -1.0f;
  writeMap(dir + "/negative.exr", 64, 32, rgb);
  const struct {
    std::vector<std::string> args;
    std::string needle;
  } bad[] = {
      {{"--environment", map, "--sky", "2,2,2"}, "--sky and --environment"},
      {{"--environment", dir + "/missing.exr"}, "missing.exr"},
      {{"--environment", dir + "/negative.exr"}, "negative.exr: texel (column 5, row 0) channel B"},
      {{"--environment", map, "--environment-strength", "-1"}, "--environment-strength"},
      {{"--environment-rotation", "10"}, "need --environment"},
      {{"--environment", map, "-p", "e0=bent", "-i", "reflocc"}, "e0=bent"},
  };
  for (const auto& b : bad) {
    std::vector<std::string> args = {"render", "--res", "8x8", "--spp", "1", "-q", "-o", dir + "/bad.exr"};
    args.insert(args.end(), b.args.begin(), b.args.end());
    const CliResult e = runCli(args, dir + "/err.txt");
    EXPECT_EQ(e.exitCode, 1) << b.needle;
    EXPECT_NE(e.stderrText.find(b.needle), std::string::npos) << e.stderrText;
  }
}

}  // namespace
}  // namespace obscura::test
