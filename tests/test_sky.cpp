// The analytic environments of `obscura sky` (app/sky.h, docs/math.md
// §14.7): their closed forms summed over the generated texels with each
// texel's exact solid angle, the sun disc's solid angle and direction, the
// Preetham sky's normalisation and symmetry, the parameter checks, and the
// CLI writing a readable EXR.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <obscura/environment.h>
#include <obscura/error.h>
#include "app/sky.h"
#include "core/scene/environment.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

constexpr double kPiD = 3.14159265358979323846;
constexpr double kDeg = kPiD / 180.0;

// Sum over texels of L_c max(0, +-w_up) Omega_j: the irradiance on a plane
// facing up (sign +1) or down (-1), by the texels' centres.
double irradiance(const SkyImage& s, int c, double sign) {
  double e = 0.0;
  for (uint32_t j = 0; j < s.height; ++j) {
    const double o = skyRowSolidAngle(s.width, s.height, j);
    for (uint32_t i = 0; i < s.width; ++i) {
      const double cosine = std::max(0.0, sign * double(skyTexelDirection(s.width, s.height, i, j).y));
      e += double(s.rgb[3 * (size_t(j) * s.width + i) + size_t(c)]) * cosine * o;
    }
  }
  return e;
}

// The error of the texel sum against the integral, for a radiance that
// depends on mu = cos theta alone (docs/math.md §14.7): with f(mu) = 2 pi
// L(mu) mu, E = Int_0^1 f dmu and the sum is Sum_j f(cos theta_c) dmu_j.
// The texel centre's mu differs from the cell's mid-mu by cos theta_c (1 -
// cos(dtheta/2)) <= dtheta^2/8, and the midpoint rule errs by f'' dmu^3 /
// 24 with dmu <= dtheta: |error| <= dtheta^2 (max|f'|/8 + max|f''|/24),
// dtheta = pi / H. Texels are floats: 1e-6 relative on top.
double quadratureBound(uint32_t H, double maxF1, double maxF2, double E) {
  const double dt = kPiD / H;
  return dt * dt * (maxF1 / 8.0 + maxF2 / 24.0) + 1e-6 * std::abs(E);
}

double texelLuminance(const SkyImage& s, uint32_t i, uint32_t j) {
  const float* t = s.rgb.data() + 3 * (size_t(j) * s.width + i);
  return luminance(Vec3(t[0], t[1], t[2]));
}

TEST(Sky, TexelSolidAnglesTileTheSphereAndCentresLieInTheirTexels) {
  const uint32_t W = 64, H = 32;
  double total = 0.0;
  for (uint32_t j = 0; j < H; ++j) total += W * skyRowSolidAngle(W, H, j);
  EXPECT_NEAR(total, 4.0 * kPiD, 1e-12);
  // The centre direction maps back into its texel (the one mapping).
  for (uint32_t j = 0; j < H; ++j)
    for (uint32_t i = 0; i < W; ++i) {
      float u, v;
      directionToLatLong(skyTexelDirection(W, H, i, j), u, v);
      EXPECT_EQ(uint32_t(u * W), i);
      EXPECT_EQ(uint32_t(v * H), j);
    }
  // Elevation and azimuth: +X at azimuth 0, +Z at 90, +Y at elevation 90.
  const Vec3 x = skyDirection(0, 0), z = skyDirection(0, 90), y = skyDirection(90, 0);
  EXPECT_NEAR(x.x, 1.0, 1e-7);
  EXPECT_NEAR(z.z, 1.0, 1e-7);
  EXPECT_NEAR(y.y, 1.0, 1e-7);
}

TEST(Sky, OvercastUpwardIrradianceIsSevenPiLzOverNine) {
  for (const uint32_t H : {32u, 256u}) {
    const double Lz = 1.7, ground = 0.25;
    const SkyImage s = overcastSky(2 * H, H, {Lz, ground});
    // f = 2 pi Lz (mu + 2 mu^2) / 3: f' <= 10 pi Lz / 3, f'' = 8 pi Lz / 3.
    const double up = 7.0 * kPiD * Lz / 9.0;
    const double tol = quadratureBound(H, 10.0 * kPiD * Lz / 3.0, 8.0 * kPiD * Lz / 3.0, up);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(irradiance(s, c, +1.0), up, tol) << "H " << H;
      // Facing down: the constant ground, pi g (f = 2 pi g mu).
      EXPECT_NEAR(irradiance(s, c, -1.0), kPiD * ground, quadratureBound(H, 2 * kPiD * ground, 0, kPiD * ground));
    }
    // The zenith row, the horizon row: L at their centres' cos theta.
    const double c0 = skyTexelDirection(2 * H, H, 0, 0).y, cH = skyTexelDirection(2 * H, H, 0, H / 2 - 1).y;
    EXPECT_NEAR(s.rgb[0], Lz * (1 + 2 * c0) / 3, 1e-6);
    EXPECT_NEAR(s.rgb[3 * size_t(H / 2 - 1) * 2 * H], Lz * (1 + 2 * cH) / 3, 1e-6);
    if (H == 256) {
      std::printf("[ overcast ] H %u: E_up %.9f, 7 pi Lz / 9 %.9f, bound %.2e\n", H, irradiance(s, 1, 1), up, tol);
    }
  }
}

TEST(Sky, GradientIrradianceIsPiTimesAPlusTwoThirdsB) {
  const uint32_t H = 128;
  for (const auto& [a, b] : std::vector<std::pair<double, double>>{{1.0, 0.5}, {2.0, -1.5}, {0.75, 0.75}}) {
    const SkyImage s = gradientSky(2 * H, H, {a, b});
    // f = 2 pi (a + b mu) mu: |f'| <= 2 pi (|a| + 2|b|), |f''| = 4 pi |b|;
    // a >= |b|: nothing clamps, and facing down mu -> -mu.
    const double f1 = 2 * kPiD * (std::abs(a) + 2 * std::abs(b)), f2 = 4 * kPiD * std::abs(b);
    const double up = kPiD * (a + 2 * b / 3), down = kPiD * (a - 2 * b / 3);
    EXPECT_NEAR(irradiance(s, 0, +1), up, quadratureBound(H, f1, f2, up)) << a << " " << b;
    EXPECT_NEAR(irradiance(s, 2, -1), down, quadratureBound(H, f1, f2, down)) << a << " " << b;
  }
  // a = 0, b = 1: L = max(0, w_up), every texel below the horizon exactly 0;
  // facing up it still is pi (a + 2b/3) (nothing clamps above the horizon).
  const SkyImage s = gradientSky(2 * H, H, {0.0, 1.0});
  EXPECT_EQ(irradiance(s, 1, -1), 0.0);
  EXPECT_NEAR(irradiance(s, 1, +1), 2 * kPiD / 3, quadratureBound(H, 4 * kPiD, 4 * kPiD, 2 * kPiD / 3));
}

TEST(Sky, HalfIrradianceIsPiLUpAndZeroDown) {
  for (const uint32_t H : {16u, 256u}) {
    const double L = 3.0;
    const SkyImage s = halfSky(2 * H, H, L);
    EXPECT_NEAR(irradiance(s, 0, +1), kPiD * L, quadratureBound(H, 2 * kPiD * L, 0, kPiD * L));
    EXPECT_EQ(irradiance(s, 0, -1), 0.0);
    // The horizon is the boundary between rows H/2 - 1 and H/2.
    EXPECT_EQ(s.rgb[3 * size_t(H / 2 - 1) * 2 * H], float(L));
    EXPECT_EQ(s.rgb[3 * size_t(H / 2) * 2 * H], 0.0f);
  }
}

TEST(Sky, TexelHoldsItsRadianceOverItsSolidAngle) {
  const uint32_t W = 64, H = 32;
  const double L = 5.0;
  const SkyImage s = texelSky(W, H, 10, 7, L);
  double power = 0.0;
  size_t nonzero = 0;
  for (uint32_t j = 0; j < H; ++j)
    for (uint32_t i = 0; i < W; ++i) {
      const float v = s.rgb[3 * (size_t(j) * W + i)];
      power += v * skyRowSolidAngle(W, H, j);
      nonzero += v != 0.0f;
    }
  EXPECT_EQ(nonzero, 1u);
  EXPECT_EQ(s.rgb[3 * (size_t(7) * W + 10) + 1], float(L));
  EXPECT_DOUBLE_EQ(power, L * skyRowSolidAngle(W, H, 7));
  // By direction: the texel the renderer looks up for that direction.
  const SkyImage d = texelSkyAt(W, H, 30.0, 100.0, L);
  const auto env = Environment::fromTexels(d.rgb, W, H, {}, "texel sky");
  EXPECT_EQ(env->view().radiance(skyDirection(30.0, 100.0)).x, float(L));
  uint32_t i, j;
  skyTexelOf(W, H, 30.0, 100.0, i, j);
  EXPECT_EQ(d.rgb[3 * (size_t(j) * W + i)], float(L));
}

TEST(Sky, SunSkyZenithLuminanceIsTheParameter) {
  for (const double T : {2.0, 3.0, 6.0, 10.0})
    for (const double elevation : {5.0, 30.0, 60.0, 89.0}) {
      SunSkyParams p;
      p.turbidity = T, p.elevation = elevation, p.Lz = 2.5;
      double x, y, Y;
      sunSkyXyY(p, Vec3(0, 1, 0), x, y, Y);
      EXPECT_NEAR(Y, p.Lz, 1e-6 * p.Lz) << T << " " << elevation;
      double xz, yz;
      preethamZenithChromaticity(T, (90.0 - elevation) * kDeg, xz, yz);
      EXPECT_NEAR(x, xz, 1e-7);
      EXPECT_NEAR(y, yz, 1e-7);
      // A daylight white-blue at the zenith ([PSS] fig. 5: x, y about 0.2 - 0.35).
      EXPECT_GT(xz, 0.2);
      EXPECT_LT(xz, 0.36);
      EXPECT_GT(yz, 0.2);
      EXPECT_LT(yz, 0.37);
      // Rec.709 luminance of the RGB: Y (the weights are the XYZ matrix's
      // Y row to 4 digits, so to 1e-4).
      EXPECT_NEAR(luminance(sunSkyRadiance(p, Vec3(0, 1, 0))), p.Lz, 2e-4 * p.Lz);
    }
  // D65 white (x, y) = (0.3127, 0.3290) is grey in Rec.709.
  const Vec3 w = xyYToRec709(0.3127, 0.3290, 1.0);
  EXPECT_NEAR(w.x, 1.0, 1e-3);
  EXPECT_NEAR(w.y, 1.0, 1e-3);
  EXPECT_NEAR(w.z, 1.0, 1e-3);
}

TEST(Sky, PerezFunctionLimits) {
  PerezCoefficients Y, x, y;
  preethamCoefficients(3.0, Y, x, y);
  // At the horizon e^(B / cos theta) -> 0: F = 1 + C e^(D gamma) + E cos^2 gamma.
  for (const double g : {0.1, 1.0, 2.5})
    EXPECT_NEAR(perez(Y, 0.0, g), 1.0 + Y.C * std::exp(Y.D * g) + Y.E * std::cos(g) * std::cos(g), 1e-12);
  // All-zero coefficients: F = 1 everywhere.
  EXPECT_EQ(perez(PerezCoefficients{}, 0.3, 0.7), 1.0);
  // Positive over the fitted turbidities (2..10), every theta and gamma.
  for (double T = 2.0; T <= 10.0; T += 0.5) {
    preethamCoefficients(T, Y, x, y);
    for (double ct = 0.0; ct <= 1.0; ct += 0.05)
      for (double g = 0.0; g <= kPiD; g += 0.05) {
        EXPECT_GT(perez(Y, ct, g), 0.0) << T;
        EXPECT_GT(perez(x, ct, g), 0.0) << T;
        EXPECT_GT(perez(y, ct, g), 0.0) << T;
      }
  }
}

TEST(Sky, SunSkyIsSymmetricAboutTheSunsVerticalPlaneAndBrightestNearTheSun) {
  const uint32_t W = 256, H = 128;
  SunSkyParams p;
  p.elevation = 30.0, p.azimuth = 0.0, p.sunDiameter = 2.0;
  const SkyImage s = sunSky(W, H, p);
  // Azimuth 0 is the middle column's edge u = 1/2: column i mirrors W - 1 - i.
  for (uint32_t j = 0; j < H; ++j)
    for (uint32_t i = 0; i < W / 2; ++i)
      for (int c = 0; c < 3; ++c) {
        const float a = s.rgb[3 * (size_t(j) * W + i) + c], b = s.rgb[3 * (size_t(j) * W + W - 1 - i) + c];
        ASSERT_NEAR(a, b, 1e-4 * std::max(a, b)) << i << "," << j << " channel " << c;
      }
  // Circumsolar brightening: 5 degrees from the sun brighter than 90 degrees
  // away at the same elevation, and the sky bluer away from the sun.
  const Vec3 near = sunSkyRadiance(p, skyDirection(30.0, 6.0)), far = sunSkyRadiance(p, skyDirection(30.0, 110.0));
  EXPECT_GT(luminance(near), 2.0 * luminance(far));
  EXPECT_GT(far.z / far.x, near.z / near.x);
}

// The sun's texels: their coverage c (recovered from the map: L = (1 - c)
// sky + c sun) times their solid angle sums to the disc's 2 pi (1 - cos r)
// within the sub-cells' discretisation - a sub-cell is in or out by its
// centre, and no point of a sub-cell is farther than delta = pi/(2 H N) +
// pi/(W N) from it, so the sum lies between the discs of radius r - delta
// and r + delta - and the coverage-weighted mean direction is the sun's
// to within half a texel.
TEST(Sky, SunDiscHasItsSolidAngleAndDirection) {
  const uint32_t W = 2048, H = 1024;
  for (const auto& [elevation, azimuth] : std::vector<std::pair<double, double>>{{15.0, 0.0}, {45.0, 200.0}, {70.0, -35.0}}) {
    SunSkyParams p;
    p.elevation = elevation, p.azimuth = azimuth;
    SunSkyInfo info;
    const SkyImage s = sunSky(W, H, p, &info);
    EXPECT_DOUBLE_EQ(info.sunRadiance, 1e5 * p.Lz);
    double omega = 0.0, dir[3] = {0, 0, 0};
    size_t texels = 0;
    double maxLum = 0.0;
    for (uint32_t j = 0; j < H / 2; ++j)
      for (uint32_t i = 0; i < W; ++i) {
        const Vec3 d = skyTexelDirection(W, H, i, j);
        const double sky = sunSkyRadiance(p, d).y, L = s.rgb[3 * (size_t(j) * W + i) + 1];
        const double c = (L - sky) / (info.sunRadiance - sky);
        if (c < 1e-6) continue;  // float rounding of a sky texel
        ++texels;
        const double o = c * skyRowSolidAngle(W, H, j);
        omega += o;
        dir[0] += o * d.x, dir[1] += o * d.y, dir[2] += o * d.z;
        maxLum = std::max(maxLum, texelLuminance(s, i, j));
      }
    const double r = 0.5 * p.sunDiameter * kDeg, delta = kPiD / (2.0 * H * 16) + kPiD / (W * 16.0);
    const double disc = 2 * kPiD * (1 - std::cos(r));
    EXPECT_GE(omega, 2 * kPiD * (1 - std::cos(r - delta))) << elevation;
    EXPECT_LE(omega, 2 * kPiD * (1 - std::cos(r + delta))) << elevation;
    EXPECT_NEAR(omega, info.sunSolidAngle, 1e-6 * disc);
    const double len = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    const double e = std::asin(dir[1] / len) / kDeg, a = std::atan2(dir[2], dir[0]) / kDeg;
    const double da = std::remainder(a - azimuth, 360.0);
    EXPECT_LE(std::abs(e - elevation), 0.5 * 180.0 / H) << elevation;
    EXPECT_LE(std::abs(da), 0.5 * 360.0 / W) << elevation;
    // The texel at the disc's centre is covered whole: the sun's radiance.
    EXPECT_NEAR(maxLum, info.sunRadiance, 1e-5 * info.sunRadiance);
    std::printf("[ sun ] elevation %g azimuth %g: %zu texels, solid angle %.6e (disc %.6e, %+.3f %%), "
                "direction off by %.4f, %.4f degrees\n",
                elevation, azimuth, texels, omega, disc, 100 * (omega / disc - 1), e - elevation, da);
  }
}

TEST(Sky, SunSkyGroundIsATenthOfTheMeanSkyOrTheParameter) {
  const uint32_t W = 128, H = 64;
  SunSkyParams p;
  p.elevation = 20.0, p.sunDiameter = 0.0;  // no sun: the upper half is the sky alone
  SunSkyInfo info;
  SkyImage s = sunSky(W, H, p, &info);
  for (int c = 0; c < 3; ++c) {
    double sum = 0.0, omega = 0.0;
    for (uint32_t j = 0; j < H / 2; ++j)
      for (uint32_t i = 0; i < W; ++i) {
        sum += s.rgb[3 * (size_t(j) * W + i) + c] * skyRowSolidAngle(W, H, j);
        omega += skyRowSolidAngle(W, H, j);
      }
    for (uint32_t j = H / 2; j < H; ++j)
      ASSERT_NEAR(s.rgb[3 * (size_t(j) * W + 5) + c], 0.1 * sum / omega, 1e-6 * sum / omega);
  }
  p.ground = 0.3;
  s = sunSky(W, H, p);
  EXPECT_EQ(s.rgb[3 * (size_t(H - 1) * W) + 2], 0.3f);
  EXPECT_EQ(s.rgb[3 * (size_t(H / 2) * W + 17)], 0.3f);
}

// A bad parameter is an obscura::Error naming it.
void expectError(const std::function<void()>& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one naming " << needle;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(Sky, BadParametersAreNamed) {
  SunSkyParams p;
  p.turbidity = 1.0;
  expectError([&] { sunSky(64, 32, p); }, "turbidity");
  p = {}, p.elevation = -5;
  expectError([&] { sunSky(64, 32, p); }, "elevation");
  p = {}, p.Lz = std::nan("");
  expectError([&] { sunSky(64, 32, p); }, "Lz");
  p = {}, p.sunRadiance = -1;
  expectError([&] { sunSky(64, 32, p); }, "sun_radiance");
  expectError([&] { sunSky(64, 33, SunSkyParams{}); }, "even");
  expectError([&] { overcastSky(64, 32, {-1.0, 0.0}); }, "Lz");
  expectError([&] { overcastSky(64, 32, {1.0, INFINITY}); }, "ground");
  expectError([&] { gradientSky(64, 32, {NAN, 0.0}); }, "gradient: a");
  expectError([&] { halfSky(64, 31, 1.0); }, "even");
  expectError([&] { texelSky(64, 32, 64, 0, 1.0); }, "column");
  expectError([&] { texelSky(64, 32, 0, 32, 1.0); }, "row");
  std::string desc;
  expectError([&] { makeSky("overcast", 64, 32, {"Lzz=1"}, desc); }, "'Lzz'");
  expectError([&] { makeSky("overcast", 64, 32, {"Lz=abc"}, desc); }, "Lz");
  expectError([&] { makeSky("overcast", 64, 32, {"Lz=1", "Lz=2"}, desc); }, "twice");
  expectError([&] { makeSky("texel", 64, 32, {"row=1.5"}, desc); }, "row");
  expectError([&] { makeSky("texel", 64, 32, {"row=1", "elevation=3"}, desc); }, "not both");
  expectError([&] { makeSky("cloudy", 64, 32, {}, desc); }, "'cloudy'");
  // What a parameter list describes.
  makeSky("overcast", 64, 32, {"ground=0.5"}, desc);
  EXPECT_EQ(desc, "overcast Lz=1 ground=0.5");
  makeSky("texel", 64, 32, {}, desc);
  EXPECT_EQ(desc, "texel column=32 row=8 L=1");
}

TEST(SkyCli, WritesAReadableFloatRgbExr) {
  const std::string dir = tempDir("sky_cli");
  const std::string out = dir + "/x.exr";
  const CliResult r = runCli({"sky", "overcast", "--res", "64x32", "-o", out}, dir + "/err.txt");
  ASSERT_EQ(r.exitCode, 0) << r.stderrText;
  const ReadBack b = readExr(out);
  ASSERT_TRUE(b.ok);
  EXPECT_EQ(b.spec.width, 64);
  EXPECT_EQ(b.spec.height, 32);
  EXPECT_EQ(b.spec.nchannels, 3);
  EXPECT_EQ(b.spec.format, OIIO::TypeDesc::FLOAT);
  EXPECT_EQ(b.spec.get_string_attribute("obscura:sky"), "overcast Lz=1 ground=0");
  EXPECT_EQ(b.spec.get_string_attribute("obscura:sky:model"), "overcast");
  const SkyImage s = overcastSky(64, 32, {});
  for (const auto& [name, c] : std::vector<std::pair<std::string, int>>{{"R", 0}, {"G", 1}, {"B", 2}}) {
    ASSERT_TRUE(b.planes.count(name)) << name;
    const std::vector<float>& p = b.planes.at(name);
    for (size_t t = 0; t < p.size(); ++t) ASSERT_EQ(p[t], s.rgb[3 * t + size_t(c)]) << name << " texel " << t;
  }
  // The renderer's loader reads a map it writes as the same map, and its
  // exact convolution (docs/math.md §14.4) gives E0 up = 7 pi Lz / 9. That
  // integrates the cosine exactly over each texel and L by its centre value:
  // per row 2 pi |Int (L(mu_c) - L(mu)) mu dmu| <= 2 pi |L'| (dtheta^2/8 +
  // dmu^2/12) dmu for the overcast sky's linear L, <= 2 pi |L'| (5/24)
  // dtheta^2 in all. 16 x 8 texels: building the core's exact E0 table
  // takes ~30 s in this binary whatever the map's size.
  const std::string small = dir + "/small.exr";
  ASSERT_EQ(runCli({"sky", "overcast", "--res", "16x8", "-o", small}, dir + "/err3.txt").exitCode, 0);
  const auto env = Environment::load(EnvironmentOptions{small});
  const SkyImage o = overcastSky(16, 8, {});
  ASSERT_EQ(env->width(), 16u);
  ASSERT_EQ(env->height(), 8u);
  for (uint32_t j = 0; j < 8; ++j)
    for (uint32_t i = 0; i < 16; ++i) ASSERT_EQ(env->view().texel(i, j).z, o.rgb[3 * (j * 16 + i) + 2]) << i << "," << j;
  const double dt = kPiD / 8, tol = 2 * kPiD * (2.0 / 3) * (5.0 / 24.0) * dt * dt + 1e-6;
  EXPECT_NEAR(kPiD * env->exactIrradianceOverPi(Vec3(0, 1, 0)).y, 7.0 * kPiD / 9.0, tol);
  EXPECT_NEAR(kPiD * env->exactIrradianceOverPi(Vec3(0, -1, 0)).y, 0.0, 1e-6);

  // A bad parameter: exit 1, one line naming it, no file.
  const std::string bad = dir + "/bad.exr";
  const CliResult e = runCli({"sky", "sunsky", "--res", "64x32", "-p", "turbidity=50", "-o", bad}, dir + "/err2.txt");
  EXPECT_EQ(e.exitCode, 1);
  EXPECT_NE(e.stderrText.find("turbidity"), std::string::npos) << e.stderrText;
  EXPECT_FALSE(std::filesystem::exists(bad));
}

}  // namespace
}  // namespace obscura::test
