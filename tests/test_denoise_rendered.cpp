// The denoiser on rendered ao passes (core/image/denoise.h, docs/denoise.md): an
// open plane whose W is exactly 1 stays exactly 1, and on a 90 degree crease
// whose ao has a closed form the denoised pass's bias^2 and variance are
// measured over seeds against the noisy pass's.
//
// The variance the denoiser reads is made here the way the film's W_error
// plane makes it (standard error from two halves of a pixel's samples): each
// pass is two independent renders of spp/2 samples (seeds 2k and 2k + 1),
// W = their mean, variance = ((W_a - W_b) / 2)^2, max over channels.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/image/denoise.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

// A pass of spp samples from two halves, with the denoiser's input planes
// (the guides from the first half: N and Z are means over hits either way).
struct HalvesPass {
  Film a, b;
  std::vector<float> c[3], alpha, var;
  DenoiseInput input() const {
    DenoiseInput in;
    in.width = a.width(), in.height = a.height();
    for (int k = 0; k < 3; ++k) in.color[k] = c[k].data(), in.normal[k] = a.plane(kNX + k);
    in.alpha = alpha.data(), in.variance = var.data(), in.depth = a.plane(kZ);
    return in;
  }
  std::vector<float> denoised(const DenoiseSettings& s = {}) const {
    std::vector<float> out[3];
    for (auto& p : out) p.assign(alpha.size(), 0.0f);
    float* o[3] = {out[0].data(), out[1].data(), out[2].data()};
    denoise(input(), s, o);
    return out[0];
  }
};

HalvesPass renderHalves(const Scene& scene, const Camera& cam, const std::vector<std::string>& params, int w, int h,
                        int spp, uint32_t seed) {
  RenderSettings s = passSettings(w, h, spp / 2, 2 * seed);
  s.aovs = true;
  HalvesPass r{renderWith(scene, cam, "ao", params, s), {}, {}, {}, {}};
  s.seed = 2 * seed + 1;
  r.b = renderWith(scene, cam, "ao", params, s);
  const size_t n = size_t(w) * size_t(h);
  for (auto& p : r.c) p.assign(n, 0.0f);
  r.alpha.assign(n, 0.0f), r.var.assign(n, 0.0f);
  for (size_t p = 0; p < n; ++p) {
    const float aa = r.a.plane(kA)[p], ab = r.b.plane(kA)[p];
    r.alpha[p] = 0.5f * (aa + ab);
    float se = 0.0f;
    for (int k = 0; k < 3; ++k) {
      const float ra = r.a.plane(kR + k)[p], rb = r.b.plane(kR + k)[p];
      r.c[k][p] = 0.5f * (ra + rb);
      if (aa > 0.0f && ab > 0.0f) se = std::max(se, 0.5f * std::abs(ra / aa - rb / ab));
    }
    r.var[p] = se * se;
  }
  return r;
}

// An open plane: ao's W is exactly 1 at every hit (docs/math.md §7), so the
// pass is its coverage and the variance 0; denoised, every pixel is exactly
// what it was.
TEST(DenoiseRendered, OpenPlaneStaysExactlyOne) {
  Scene scene;
  addPlane(scene, 50.0f);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0.5f, -3.0f, 2.0f), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.7f, "plane");
  const HalvesPass pass = renderHalves(scene, cam, {}, 64, 48, 8, 0);
  const std::vector<float> d = pass.denoised();
  size_t covered = 0;
  for (size_t p = 0; p < d.size(); ++p) {
    ASSERT_EQ(pass.var[p], 0.0f);
    ASSERT_EQ(d[p], pass.c[0][p]) << "pixel " << p;
    covered += pass.alpha[p] == 1.0f && d[p] == 1.0f;
  }
  EXPECT_GT(covered, d.size() / 2);
}

// ao with distance R at a point at distance h from an infinite plane at
// right angles to its own (the crease's floor near the wall, or the wall
// near the floor): under cosine sampling the direction's projection onto the
// tangent plane is uniform on the unit disk, and the ray meets the other
// plane within R iff that projection's component towards it exceeds
// eta = h / R. The disk segment beyond eta has area acos(eta) - eta
// sqrt(1 - eta^2), so W = 1 - (acos(eta) - eta sqrt(1 - eta^2)) / pi for
// eta < 1, else 1 (docs/denoise.md "Tests").
double creaseAo(double h, double R) {
  const double eta = h / R;
  if (eta >= 1.0) return 1.0;
  return 1.0 - (std::acos(eta) - eta * std::sqrt(1.0 - eta * eta)) / M_PI;
}

// The crease (tests/support.h Crease: floor z = 0, x >= 0 and wall x = 0,
// both 20 units wide) rendered with ao distance R = 1, several seeds, noisy
// and denoised. Each pixel's exact value is the closed form averaged over
// its area (a 12 x 12 grid of traced points: the box filter's footprint),
// over pixels whose every grid point hits one of the two planes within 9 of
// the middle (|y| <= 9: the planes' ends are beyond R). Per pixel, over S
// seeds: mean m, variance v (of one render); bias^2 = (m - exact)^2 - v / S
// (unbiased), both averaged over the pixels; MSE = mean (x - exact)^2.
TEST(DenoiseRendered, CreaseBiasAndVariance) {
  const Crease c;
  const int w = 64, h = 48, spp = 8, seeds = 8, grid = 12;
  const double R = 1.0;
  const RasterCamera rc(c.cam, w, h);
  std::vector<size_t> pixels;
  std::vector<double> exact;
  std::vector<char> straddles;  // the pixel sees both planes (its N is a blend)
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double sum = 0;
      bool ok = true;
      int planes = 0;
      for (int j = 0; j < grid && ok; ++j)
        for (int i = 0; i < grid && ok; ++i) {
          const Vec3 d = rc.direction(float(x) + (float(i) + 0.5f) / float(grid), float(y) + (float(j) + 0.5f) / float(grid));
          const RayHit hit = traceClosest(c.scene, rc.org, d);
          if (hit.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
            ok = false;
            break;
          }
          const Vec3 p = rc.org + d * hit.ray.tfar;
          ok = std::abs(p.y) <= 9.0f;
          planes |= 1 << hit.hit.geomID;
          sum += creaseAo(hit.hit.geomID == 0 ? p.x : p.z, R);
        }
      if (!ok) continue;
      pixels.push_back(size_t(y) * size_t(w) + size_t(x));
      exact.push_back(sum / double(grid * grid));
      straddles.push_back(planes == 3);
    }
  ASSERT_GT(pixels.size(), size_t(w * h / 2));

  const size_t P = pixels.size();
  std::vector<double> sumN(P, 0), sqN(P, 0), sumD(P, 0), sqD(P, 0), mseN(P, 0), mseD(P, 0);
  for (int s = 0; s < seeds; ++s) {
    const HalvesPass pass = renderHalves(c.scene, c.cam, {"distance=1"}, w, h, spp, uint32_t(s));
    const std::vector<float> d = pass.denoised();
    for (size_t k = 0; k < P; ++k) {
      const size_t p = pixels[k];
      ASSERT_EQ(pass.alpha[p], 1.0f);
      const double xn = pass.c[0][p], xd = d[p];
      sumN[k] += xn, sqN[k] += xn * xn, sumD[k] += xd, sqD[k] += xd * xd;
      mseN[k] += (xn - exact[k]) * (xn - exact[k]);
      mseD[k] += (xd - exact[k]) * (xd - exact[k]);
    }
  }
  // Per pixel: variance over seeds (unbiased) and the unbiased bias^2,
  // averaged over the pixels `use` accepts.
  struct Split {
    double bias2 = 0, var = 0, mse = 0, bias2Se = 0;
    size_t n = 0;
  };
  auto split = [&](const std::vector<double>& sum, const std::vector<double>& sq, const std::vector<double>& mse,
                   bool all) {
    Split r;
    std::vector<double> b2;
    for (size_t k = 0; k < P; ++k) {
      if (!all && straddles[k]) continue;
      const double m = sum[k] / seeds, v = std::max(0.0, (sq[k] - seeds * m * m) / (seeds - 1));
      b2.push_back((m - exact[k]) * (m - exact[k]) - v / seeds);
      r.bias2 += b2.back(), r.var += v, r.mse += mse[k];
    }
    r.n = b2.size();
    r.bias2 /= double(r.n), r.var /= double(r.n), r.mse /= double(r.n * seeds);
    double s2 = 0;
    for (double b : b2) s2 += (b - r.bias2) * (b - r.bias2);
    r.bias2Se = std::sqrt(s2 / double(r.n - 1) / double(r.n));  // pixels as independent: true of the noisy pass only
    return r;
  };
  for (int all = 1; all >= 0; --all) {
    const Split n = split(sumN, sqN, mseN, all), d = split(sumD, sqD, mseD, all);
    const std::string set = all ? "all" : "off_crease";
    std::printf("crease, %s (%zu pixels), %d seeds of %d spp: noisy bias^2 %.3g (se %.2g) variance %.4g MSE %.4g; "
                "denoised bias^2 %.3g variance %.4g MSE %.4g; MSE / %.1f\n",
                set.c_str(), n.n, seeds, spp, n.bias2, n.bias2Se, n.var, n.mse, d.bias2, d.var, d.mse, n.mse / d.mse);
    RecordProperty("crease_" + set + "_noisy_bias2", std::to_string(n.bias2));
    RecordProperty("crease_" + set + "_noisy_variance", std::to_string(n.var));
    RecordProperty("crease_" + set + "_noisy_mse", std::to_string(n.mse));
    RecordProperty("crease_" + set + "_denoised_bias2", std::to_string(d.bias2));
    RecordProperty("crease_" + set + "_denoised_variance", std::to_string(d.var));
    RecordProperty("crease_" + set + "_denoised_mse", std::to_string(d.mse));
    // The noisy pass is unbiased: its bias^2 is 0 within its standard error
    // (which checks the closed form and its pixel averaging too).
    EXPECT_NEAR(n.bias2, 0.0, 4 * n.bias2Se) << set;
    EXPECT_LT(d.mse, n.mse) << set;
    // The denoiser's bias is below what averaging the S noisy renders would
    // leave (their mean's variance, var / S): a bias the test resolves, and
    // smaller than the noise it removes.
    EXPECT_LT(d.bias2, n.var / seeds) << set;
  }
}

// A step between two planes at different depths, through the render's own
// --denoise path (RenderSettings::denoise: W_error, the object guide): the
// floor z = 0 and, for x > 0, a slab 2 high whose top is an open plane
// (ao W exactly 1) and whose side is a wall 2 high at x = 0. With R = 1 < 2
// the wall is infinite for the floor's rays, so a floor point at distance d
// from it has W = creaseAo(d, 1). Seen straight down from above x = 0, the
// left half of the image is floor and the right half slab top: the same
// normal, a depth step of 2. Denoised over S seeds: the top stays exactly 1
// (nothing of the darker floor leaks up), and the floor next to the wall
// keeps its closed form within the noise of the S-seed mean (nothing of the
// top's 1 leaks down): its bias^2 stays below the noisy variance of the
// S-seed mean, the criterion of the crease test above (what remains is the
// filter's smoothing of the floor's own gradient next to the wall).
TEST(DenoiseRendered, DepthStepDoesNotLeak) {
  Scene scene;
  addPlane(scene, 50.0f);
  const float H = 2.0f;
  scene.addWorldPrimitive({{0, -50, H}, {50, -50, H}, {50, 50, H}, {0, 50, H}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene.addWorldPrimitive({{0, -50, 0}, {0, 50, 0}, {0, 50, H}, {0, -50, H}}, {0, 1, 2, 0, 2, 3}, {}, {}, -1);
  scene.commit();
  const int w = 64, h = 8, spp = 8, seeds = 12;
  const Camera cam = makeLookAtCamera(Vec3(0, 0, 8), Vec3(0, 0, 0), Vec3(0, 1, 0), 0.1f, "down");
  const RasterCamera rc(cam, w, h);
  // Column x's footprint on the floor: d in [d1, d0] from the wall (x < 0).
  const auto floorX = [&](float fx) {
    const Vec3 d = rc.direction(fx, 0.5f * float(h));
    return double(rc.org.x) - double(rc.org.z) * double(d.x) / double(d.z);
  };
  std::vector<double> sumN(size_t(w), 0), sumD(size_t(w), 0), sqN(size_t(w), 0);
  for (int s = 0; s < seeds; ++s) {
    RenderSettings st = passSettings(w, h, spp, uint32_t(100 + s));
    st.aovs = true;
    st.denoise = true;
    const Film f = renderWith(scene, cam, "ao", {"distance=1"}, st);
    const int noisy = f.find("noisy.R");
    ASSERT_GE(noisy, 0);
    for (int x = 0; x < w; ++x)
      for (int y = 0; y < h; ++y) {
        ASSERT_EQ(f.at(kA, x, y), 1.0f);
        if (floorX(float(x + 1)) > 0.0) {
          // The slab top (or the column on the edge, whose footprint is partly top).
          if (floorX(float(x)) > 1e-3) {
            ASSERT_EQ(f.at(kR, x, y), 1.0f) << "top pixel " << x << "," << y;
          }
          continue;
        }
        sumN[size_t(x)] += f.at(noisy, x, y), sqN[size_t(x)] += double(f.at(noisy, x, y)) * f.at(noisy, x, y);
        sumD[size_t(x)] += f.at(kR, x, y);
      }
  }
  // The floor columns within R of the wall: per column, the exact value is
  // the closed form averaged over the footprint (Simpson), the noisy and
  // denoised means over seeds x rows.
  const double n = double(seeds * h);
  double bias2 = 0, var = 0, near = 0;
  int columns = 0;
  for (int x = 0; x < w; ++x) {
    const double x0 = floorX(float(x)), x1 = floorX(float(x + 1));
    if (x1 > 0.0 || -x0 > 1.0) continue;
    double exact = 0;
    const int m = 100;
    for (int i = 0; i <= m; ++i) exact += (i == 0 || i == m ? 1.0 : i % 2 ? 4.0 : 2.0) * creaseAo(-(x0 + (x1 - x0) * i / m), 1.0);
    exact /= 3.0 * m;
    const double meanN = sumN[size_t(x)] / n, varN = (sqN[size_t(x)] - n * meanN * meanN) / (n - 1);
    // The noisy pass is unbiased (checks the closed form and footprint).
    EXPECT_NEAR(meanN, exact, 4.0 * std::sqrt(varN / n) + 1e-9) << "column " << x;
    const double b = sumD[size_t(x)] / n - exact;
    bias2 += b * b, var += varN, ++columns;
    if (x1 > -0.06) near = b;  // the column at the wall
  }
  ASSERT_GE(columns, 5);
  bias2 /= columns, var /= columns;
  // A leak of the slab's 1 into the floor would raise the column at the wall
  // (W = creaseAo(0, 1) = 0.5 there) by a weight times 0.5.
  std::printf("depth step: floor within R of the wall, denoised bias^2 %.3g vs noisy variance / seeds %.3g over %d "
              "columns; at the wall %+.4f\n",
              bias2, var / seeds, columns, near);
  EXPECT_LT(bias2, var / seeds);
}

}  // namespace
}  // namespace obscura::test
