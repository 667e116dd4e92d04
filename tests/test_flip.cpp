// FLIP (core/image/flip.h) against closed forms computed here, independently,
// from the papers' formulas: a uniform pair (the CSF filters keep constants
// and the feature detectors answer 0, so the colour difference of the two
// constants is the whole value), a step edge (the detectors' response is a
// tail sum of their normalised kernels), identical images (0 exactly), and
// the invariants symmetry, monotonicity and range.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <obscura/error.h>
#include "core/image/flip.h"

namespace obscura {
namespace {

FlipImage uniform(int w, int h, float r, float g, float b) {
  FlipImage im;
  im.width = w, im.height = h;
  im.r.assign(im.pixels(), r), im.g.assign(im.pixels(), g), im.b.assign(im.pixels(), b);
  return im;
}

FlipImage noise(int w, int h, unsigned seed, float scale) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, scale);
  FlipImage im = uniform(w, h, 0, 0, 0);
  for (size_t i = 0; i < im.pixels(); ++i) im.r[i] = u(rng), im.g[i] = u(rng), im.b[i] = u(rng);
  return im;
}

// --- The colour pipeline on constants, written out from the paper ----------
// linear sRGB -> XYZ (IEC 61966-2-1, D65) -> CIE L*a*b* relative to the XYZ of
// RGB white -> Hunt adjustment -> HyAB -> ^0.7 -> remap with c_max, p_c, p_t.
struct Lab {
  double L, a, b;
};
Lab huntLabOf(double r, double g, double b) {
  const double M[3][3] = {{0.4124564, 0.3575761, 0.1804375}, {0.2126729, 0.7151522, 0.0721750},
                          {0.0193339, 0.1191920, 0.9503041}};
  double xyz[3], white[3];
  for (int i = 0; i < 3; ++i) {
    xyz[i] = M[i][0] * r + M[i][1] * g + M[i][2] * b;
    white[i] = M[i][0] + M[i][1] + M[i][2];
  }
  const auto f = [](double t) {
    const double d = 6.0 / 29.0;
    return t > d * d * d ? std::cbrt(t) : t / (3 * d * d) + 4.0 / 29.0;
  };
  const double fx = f(xyz[0] / white[0]), fy = f(xyz[1] / white[1]), fz = f(xyz[2] / white[2]);
  const double L = 116 * fy - 16;
  return {L, 0.01 * L * 500 * (fx - fy), 0.01 * L * 200 * (fy - fz)};
}
double hyab(Lab p, Lab q) { return std::abs(p.L - q.L) + std::hypot(p.a - q.a, p.b - q.b); }
double closedFormColour(const double ref[3], const double test[3]) {
  const double cmax = std::pow(hyab(huntLabOf(0, 1, 0), huntLabOf(0, 0, 1)), 0.7);
  const double e = std::pow(hyab(huntLabOf(ref[0], ref[1], ref[2]), huntLabOf(test[0], test[1], test[2])), 0.7);
  const double pc = 0.4, pt = 0.95;
  return e < pc * cmax ? pt / (pc * cmax) * e : pt + (e - pc * cmax) / (cmax - pc * cmax) * (1 - pt);
}
double aces(double x) {  // Narkowicz's ACES fit of 0.6 x (HDR-FLIP's tone mapper)
  x *= 0.6;
  return std::clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

// Float planes filtered by kernels of 2r+1 taps that sum to 1: a constant of
// magnitude <= 100 (Y_y, C_x, C_z) comes back within ~(2r+1) * 2^-24 * 100
// ~ 1e-4 in those units (r <= 10 at 67 ppd), which moves L*a*b* and the
// remapped difference by less than 1e-4.
constexpr double kConstantTolerance = 1e-4;

// The whole LDR-FLIP written out as the paper states it, in double and with
// the 2-D kernels applied directly (no separation), edges replicated.
std::vector<double> directLdrFlip(const FlipImage& ref, const FlipImage& test, double ppd) {
  const int w = ref.width, h = ref.height;
  const double pi = 3.14159265358979323846;
  const double M[3][3] = {{0.4124564, 0.3575761, 0.1804375}, {0.2126729, 0.7151522, 0.0721750},
                          {0.0193339, 0.1191920, 0.9503041}};
  double white[3];
  for (int i = 0; i < 3; ++i) white[i] = M[i][0] + M[i][1] + M[i][2];
  const auto at = [&](const std::vector<double>& p, int x, int y) {
    return p[size_t(std::clamp(y, 0, h - 1)) * w + size_t(std::clamp(x, 0, w - 1))];
  };
  const auto correlate = [&](const std::vector<double>& p, const std::vector<double>& k, int r) {
    std::vector<double> out(p.size());
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        double s = 0;
        for (int j = -r; j <= r; ++j)
          for (int i = -r; i <= r; ++i) s += k[size_t(j + r) * (2 * r + 1) + size_t(i + r)] * at(p, x + i, y + j);
        out[size_t(y) * w + x] = s;
      }
    return out;
  };
  // Opponent space and luminance.
  struct Opp {
    std::vector<double> Y, X, Z, lum;
  };
  const auto opponent = [&](const FlipImage& im) {
    Opp o;
    for (size_t i = 0; i < im.pixels(); ++i) {
      const double rgb[3] = {std::clamp(double(im.r[i]), 0.0, 1.0), std::clamp(double(im.g[i]), 0.0, 1.0),
                             std::clamp(double(im.b[i]), 0.0, 1.0)};
      double v[3];
      for (int c = 0; c < 3; ++c) v[c] = (M[c][0] * rgb[0] + M[c][1] * rgb[1] + M[c][2] * rgb[2]) / white[c];
      o.Y.push_back(116 * v[1] - 16), o.X.push_back(500 * (v[0] - v[1])), o.Z.push_back(200 * (v[1] - v[2]));
      o.lum.push_back(v[1]);
    }
    return o;
  };
  const int rc = int(std::ceil(3 * std::sqrt(0.04 / (2 * pi * pi)) * ppd));
  const auto csf = [&](double a1, double b1, double a2, double b2) {
    std::vector<double> k;
    double sum = 0;
    for (int j = -rc; j <= rc; ++j)
      for (int i = -rc; i <= rc; ++i) {
        const double d2 = (i * i + j * j) / (ppd * ppd);
        k.push_back(a1 * std::sqrt(pi / b1) * std::exp(-pi * pi * d2 / b1) + a2 * std::sqrt(pi / b2) * std::exp(-pi * pi * d2 / b2));
        sum += k.back();
      }
    for (double& v : k) v /= sum;
    return k;
  };
  const std::vector<double> kA = csf(1, 0.0047, 0, 1e-5), kRG = csf(1, 0.0053, 0, 1e-5), kBY = csf(34.1, 0.04, 13.5, 0.025);
  const double sigma = 0.5 * 0.082 * ppd;
  const int rf = int(std::ceil(3 * sigma));
  const auto feature = [&](bool edge, bool transpose) {
    std::vector<double> k;
    double pos = 0, neg = 0;
    for (int j = -rf; j <= rf; ++j)
      for (int i = -rf; i <= rf; ++i) {
        const double x = transpose ? j : i, g = std::exp(-(i * i + j * j) / (2 * sigma * sigma));
        k.push_back(edge ? -x * g : (x * x / (sigma * sigma) - 1) * g);
        (k.back() > 0 ? pos : neg) += std::abs(k.back());
      }
    for (double& v : k) v /= v > 0 ? pos : neg;
    return k;
  };
  const std::vector<double> ex = feature(true, false), ey = feature(true, true), px = feature(false, false),
                            py = feature(false, true);
  const Opp o[2] = {opponent(ref), opponent(test)};
  std::vector<Lab> lab[2];
  std::vector<double> edges[2], points[2];
  for (int t = 0; t < 2; ++t) {
    const std::vector<double> Y = correlate(o[t].Y, kA, rc), X = correlate(o[t].X, kRG, rc), Z = correlate(o[t].Z, kBY, rc);
    const std::vector<double> Ex = correlate(o[t].lum, ex, rf), Ey = correlate(o[t].lum, ey, rf);
    const std::vector<double> Px = correlate(o[t].lum, px, rf), Py = correlate(o[t].lum, py, rf);
    for (size_t i = 0; i < Y.size(); ++i) {
      const double yy = (Y[i] + 16) / 116, xyz[3] = {(yy + X[i] / 500) * white[0], yy * white[1], (yy - Z[i] / 200) * white[2]};
      // Back to linear RGB by solving M rgb = xyz (Cramer's rule), clamped.
      const auto det = [](const double a[3][3]) {
        return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
               a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
      };
      double rgb[3];
      for (int c = 0; c < 3; ++c) {
        double Mc[3][3];
        for (int r = 0; r < 3; ++r)
          for (int k = 0; k < 3; ++k) Mc[r][k] = k == c ? xyz[r] : M[r][k];
        rgb[c] = std::clamp(det(Mc) / det(M), 0.0, 1.0);
      }
      lab[t].push_back(huntLabOf(rgb[0], rgb[1], rgb[2]));
      edges[t].push_back(std::hypot(Ex[i], Ey[i]));
      points[t].push_back(std::hypot(Px[i], Py[i]));
    }
  }
  const double cmax = std::pow(hyab(huntLabOf(0, 1, 0), huntLabOf(0, 0, 1)), 0.7);
  std::vector<double> out;
  for (size_t i = 0; i < lab[0].size(); ++i) {
    const double e = std::pow(hyab(lab[0][i], lab[1][i]), 0.7), knee = 0.4 * cmax;
    const double dEc = e < knee ? 0.95 / knee * e : 0.95 + (e - knee) / (cmax - knee) * 0.05;
    const double dEf =
        std::sqrt(std::max(std::abs(edges[0][i] - edges[1][i]), std::abs(points[0][i] - points[1][i])) / std::sqrt(2.0));
    out.push_back(std::pow(dEc, 1 - dEf));
  }
  return out;
}

TEST(Flip, DefaultPixelsPerDegreeIsThePapersMonitor) {
  // 0.7 m wide 3840 pixels seen from 0.7 m: 3840 * pi / 180.
  EXPECT_NEAR(kFlipDefaultPpd, 67.0206, 1e-4);
}

TEST(Flip, IdenticalImagesGiveZeroExactly) {
  const FlipImage a = noise(37, 23, 1, 1.0f);
  for (const float v : ldrFlip(a, a)) ASSERT_EQ(v, 0.0f);
  const FlipImage hdr = noise(37, 23, 2, 20.0f);
  for (const float v : hdrFlip(hdr, hdr, flipExposures(hdr))) ASSERT_EQ(v, 0.0f);
}

TEST(Flip, UniformPairIsTheColourDifferenceOfTheConstants) {
  const double pairs[][2][3] = {{{0.5, 0.5, 0.5}, {0.6, 0.6, 0.6}},   // grey, small step (below the knee)
                                {{0.2, 0.2, 0.2}, {0.9, 0.9, 0.9}},   // grey, large step
                                {{0.1, 0.5, 0.3}, {0.4, 0.2, 0.8}},   // colour
                                {{0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}},   // the c_max pair: 1
                                {{0.0, 0.0, 0.0}, {0.001, 0.001, 0.001}}};  // dark (linear branch of L*)
  for (const auto& p : pairs) {
    const FlipImage ref = uniform(40, 30, float(p[0][0]), float(p[0][1]), float(p[0][2]));
    const FlipImage test = uniform(40, 30, float(p[1][0]), float(p[1][1]), float(p[1][2]));
    const double expected = closedFormColour(p[0], p[1]);
    const std::vector<float> map = ldrFlip(ref, test);
    for (const float v : map) ASSERT_NEAR(v, expected, kConstantTolerance);
    const float fr[3] = {float(p[0][0]), float(p[0][1]), float(p[0][2])};
    const float ft[3] = {float(p[1][0]), float(p[1][1]), float(p[1][2])};
    EXPECT_NEAR(flipColourDifference(fr, ft), expected, 1e-6);
  }
  // Green against blue is the remap's c_max: exactly 1 up to rounding.
  const double g[3] = {0, 1, 0}, b[3] = {0, 0, 1};
  EXPECT_NEAR(closedFormColour(g, b), 1.0, 1e-12);
}

TEST(Flip, UniformImagesHaveNoFeatures) {
  const std::vector<float> y(50 * 40, 0.37f);
  const FlipFeatures f = flipFeatures(y, 50, 40, kFlipDefaultPpd);
  // Each kernel's weights sum to 0 (positive part 1, negative part -1).
  for (size_t i = 0; i < y.size(); ++i) {
    ASSERT_NEAR(f.edge[i], 0.0, 1e-6);
    ASSERT_NEAR(f.point[i], 0.0, 1e-6);
  }
}

TEST(Flip, StepEdgeAnswersTheTailSumOfTheNormalisedKernels) {
  // Luminance 0 left of column x0 and h from it on, constant down the
  // columns. Along y the Gaussian sums to 1 and the y-derivative kernels to 0,
  // so the response at column x is h times the sum of the normalised 1-D
  // x-kernel over the taps o with x + o >= x0 (correlation; replicated edges
  // continue the step, so the formula holds at the borders too).
  for (const double ppd : {kFlipDefaultPpd, 20.0, 120.0}) {
    const int w = 80, hgt = 9, x0 = 40;
    const double h = 0.6, sigma = 0.5 * 0.082 * ppd;
    ASSERT_NEAR(flipFeatureSigma(ppd), sigma, 1e-12);
    const int r = int(std::ceil(3 * sigma));
    std::vector<double> e, p;
    double ePos = 0, eNeg = 0, pPos = 0, pNeg = 0;
    for (int o = -r; o <= r; ++o) {
      const double g = std::exp(-o * o / (2 * sigma * sigma));
      e.push_back(-o * g), p.push_back((o * o / (sigma * sigma) - 1) * g);
      (e.back() > 0 ? ePos : eNeg) += std::abs(e.back());
      (p.back() > 0 ? pPos : pNeg) += std::abs(p.back());
    }
    std::vector<float> y(size_t(w) * hgt);
    for (int j = 0; j < hgt; ++j)
      for (int i = 0; i < w; ++i) y[size_t(j) * w + i] = i >= x0 ? float(h) : 0.0f;
    const FlipFeatures f = flipFeatures(y, w, hgt, ppd);
    for (int x = 0; x < w; ++x) {
      double edge = 0, point = 0;
      for (int o = -r; o <= r; ++o)
        if (x + o >= x0) {
          edge += e[size_t(o + r)] / (e[size_t(o + r)] > 0 ? ePos : eNeg);
          point += p[size_t(o + r)] / (p[size_t(o + r)] > 0 ? pPos : pNeg);
        }
      for (int j = 0; j < hgt; ++j) {
        ASSERT_NEAR(f.edge[size_t(j) * w + x], h * std::abs(edge), 1e-6) << "ppd " << ppd << " x " << x;
        ASSERT_NEAR(f.point[size_t(j) * w + x], h * std::abs(point), 1e-6) << "ppd " << ppd << " x " << x;
      }
    }
    // On either side of the step every negative (positive) weight of the
    // edge kernel sees h: the response is h exactly.
    EXPECT_NEAR(f.edge[size_t(x0 - 1)], h, 1e-6);
    EXPECT_NEAR(f.edge[size_t(x0)], h, 1e-6);
  }
}

TEST(Flip, StepEdgeAgainstAFlatImageFarFromTheStep) {
  // Reference: a grey step 0.2 -> 0.8; test: flat 0.2. Beyond the reach of
  // every kernel both sides are constant: 0 on the left, the uniform pair's
  // closed form on the right; at the step the feature difference is at least
  // sqrt(0.6 / sqrt 2) (the step test's edge answer), so FLIP there is the
  // colour term raised to at most 0.35: well above it.
  const int w = 120, hgt = 8, x0 = 60;
  FlipImage ref = uniform(w, hgt, 0.2f, 0.2f, 0.2f);
  const FlipImage test = ref;
  for (int j = 0; j < hgt; ++j)
    for (int i = x0; i < w; ++i) {
      const size_t k = size_t(j) * w + i;
      ref.r[k] = ref.g[k] = ref.b[k] = 0.8f;
    }
  const std::vector<float> m = ldrFlip(ref, test);
  const double hi[3] = {0.8, 0.8, 0.8}, lo[3] = {0.2, 0.2, 0.2};
  EXPECT_NEAR(m[size_t(w - 1)], closedFormColour(hi, lo), kConstantTolerance);
  EXPECT_EQ(m[0], 0.0f);
  EXPECT_GT(m[size_t(x0)], 0.0f);
  EXPECT_LE(m[size_t(x0)], 1.0f);
}

TEST(Flip, SeparableFiltersMatchTheDirectTwoDimensionalDefinition) {
  // Noise against noise (every pixel differs clearly, so no value sits on
  // the steep start of the 0.7 and 0.5 powers) and a smooth pair, at two
  // observers. The implementation filters in float with separated kernels;
  // this one in double with the 2-D kernels: float rounding of filtered
  // values <= 100 (~1e-4) moves a remapped difference by < 1e-4 away from 0.
  FlipImage smoothA = uniform(26, 18, 0, 0, 0), smoothB = smoothA;
  for (int y = 0; y < 18; ++y)
    for (int x = 0; x < 26; ++x) {
      const size_t i = size_t(y) * 26 + x;
      smoothA.r[i] = 0.5f + 0.4f * std::sin(0.3f * x), smoothA.g[i] = 0.4f, smoothA.b[i] = 0.2f + 0.02f * y;
      smoothB.r[i] = 0.5f + 0.4f * std::sin(0.3f * x + 0.5f), smoothB.g[i] = 0.45f, smoothB.b[i] = 0.6f;
    }
  const std::pair<FlipImage, FlipImage> pairs[] = {{noise(26, 18, 11, 1.0f), noise(26, 18, 12, 1.0f)}, {smoothA, smoothB}};
  for (const auto& [a, b] : pairs)
    for (const double ppd : {kFlipDefaultPpd, 25.0}) {
      const std::vector<float> fast = ldrFlip(a, b, ppd);
      const std::vector<double> direct = directLdrFlip(a, b, ppd);
      for (size_t i = 0; i < fast.size(); ++i) ASSERT_NEAR(fast[i], direct[i], 1e-4) << "ppd " << ppd << " pixel " << i;
    }
}

TEST(Flip, SymmetricInItsArguments) {
  const FlipImage a = noise(31, 17, 3, 1.0f), b = noise(31, 17, 4, 1.0f);
  const std::vector<float> ab = ldrFlip(a, b), ba = ldrFlip(b, a);
  for (size_t i = 0; i < ab.size(); ++i) ASSERT_EQ(ab[i], ba[i]);
}

TEST(Flip, GrowsWithTheDifferenceAndStaysInTheUnitInterval) {
  double last = -1;
  for (const float d : {0.0f, 0.01f, 0.05f, 0.1f, 0.2f, 0.4f}) {
    const std::vector<float> m = ldrFlip(uniform(16, 16, 0.5f, 0.5f, 0.5f), uniform(16, 16, 0.5f + d, 0.5f + d, 0.5f + d));
    EXPECT_GT(m[0], last) << d;
    last = m[0];
  }
  const FlipImage a = noise(33, 21, 5, 3.0f), b = noise(33, 21, 6, 3.0f);  // out of range: clamped
  for (const float v : ldrFlip(a, b)) ASSERT_TRUE(v >= 0.0f && v <= 1.0f);
  for (const float v : hdrFlip(a, b, flipExposures(a))) ASSERT_TRUE(v >= 0.0f && v <= 1.0f);
}

TEST(Flip, AcesInverseAndExposureRange) {
  for (const double t : {0.1, 0.5, 0.85, 0.99}) EXPECT_NEAR(aces(flipAcesInverse(t)), t, 1e-12);
  for (const double x : {0.0, 0.01, 0.3, 2.0, 50.0}) EXPECT_NEAR(flipAces(x), aces(x), 1e-12);
  // Luminances 1, 2, 3 and 16 (grey, Y = value): max 16, median 2.5; stop -
  // start = log2(16 / 2.5) = 2.68 -> 3 exposures.
  FlipImage im = uniform(4, 1, 0, 0, 0);
  const float v[4] = {2, 16, 1, 3};
  for (int i = 0; i < 4; ++i) im.r[i] = im.g[i] = im.b[i] = v[i];
  const FlipExposures e = flipExposures(im);
  const double x85 = flipAcesInverse(0.85);
  EXPECT_NEAR(e.start, std::log2(x85 / 16.0), 1e-6);
  EXPECT_NEAR(e.stop, std::log2(x85 / 2.5), 1e-6);
  EXPECT_EQ(e.count, 3);
  // Only the pixels asked for count: {1, 3} -> max 3, median 2.
  const std::vector<size_t> some = {2, 3};
  const FlipExposures s = flipExposures(im, &some);
  EXPECT_NEAR(s.start, std::log2(x85 / 3.0), 1e-6);
  EXPECT_NEAR(s.stop, std::log2(x85 / 2.0), 1e-6);
  EXPECT_EQ(s.count, 2);  // at least two
  EXPECT_EQ(flipExposures(uniform(3, 3, 0, 0, 0)).count, 1);  // black: the single exposure 0
}

TEST(Flip, HdrUniformPairIsTheLargerColourDifferenceOverExposures) {
  // A uniform reference of luminance 4 has start = stop: two equal
  // exposures c = log2(t^-1(0.85) / 4), where the reference tone maps to 0.85.
  const FlipImage ref = uniform(24, 24, 4, 4, 4), test = uniform(24, 24, 6, 6, 6);
  const FlipExposures e = flipExposures(ref);
  EXPECT_EQ(e.count, 2);
  EXPECT_NEAR(e.start, e.stop, 1e-9);
  const double s = std::exp2(e.start);
  EXPECT_NEAR(aces(4 * s), 0.85, 1e-6);
  const double tr[3] = {aces(4 * s), aces(4 * s), aces(4 * s)}, tt[3] = {aces(6 * s), aces(6 * s), aces(6 * s)};
  for (const float v : hdrFlip(ref, test, e)) ASSERT_NEAR(v, closedFormColour(tr, tt), kConstantTolerance);
  // Over a range, the maximum: exposures -2 and 1 by hand.
  const FlipExposures range{-2.0, 1.0, 4};
  double expected = 0;
  for (const double c : {-2.0, -1.0, 0.0, 1.0}) {
    const double k = std::exp2(c), a[3] = {aces(4 * k), aces(4 * k), aces(4 * k)}, b[3] = {aces(6 * k), aces(6 * k), aces(6 * k)};
    expected = std::max(expected, closedFormColour(a, b));
  }
  for (const float v : hdrFlip(ref, test, range)) ASSERT_NEAR(v, expected, kConstantTolerance);
}

TEST(Flip, HdrDoesNotDependOnTheImagesScale) {
  // Scaling both images by 2^k moves the reference's exposure range by -k
  // stops and leaves every exposed image as it was (docs/compare.md "FLIP":
  // why the normalised radiance under a map does not change HDR-FLIP).
  // Powers of two scale floats exactly; what is left is the rounding of
  // log2 and exp2 in the exposures (~1e-15 relative), far below 1e-5.
  const FlipImage a = noise(29, 19, 7, 8.0f), b = noise(29, 19, 8, 8.0f);
  const std::vector<float> m = hdrFlip(a, b, flipExposures(a));
  for (const float s : {0.25f, 8.0f}) {
    FlipImage as = a, bs = b;
    for (FlipImage* im : {&as, &bs})
      for (std::vector<float>* plane : {&im->r, &im->g, &im->b})
        for (float& v : *plane) v *= s;
    const FlipExposures e = flipExposures(as), e0 = flipExposures(a);
    EXPECT_NEAR(e.start, e0.start - std::log2(s), 1e-9);
    EXPECT_EQ(e.count, e0.count);
    const std::vector<float> ms = hdrFlip(as, bs, e);
    for (size_t i = 0; i < m.size(); ++i) ASSERT_NEAR(ms[i], m[i], 1e-5) << s;
  }
}

TEST(Flip, BadInputIsOneClearError) {
  const FlipImage a = uniform(4, 4, 0, 0, 0), b = uniform(5, 4, 0, 0, 0);
  EXPECT_THROW(ldrFlip(a, b), Error);
  EXPECT_THROW(ldrFlip(a, a, 0.5), Error);
  EXPECT_THROW(hdrFlip(a, a, FlipExposures{0, 0, 0}), Error);
}

}  // namespace
}  // namespace obscura
