// The `obscurance` integrator against the closed forms of docs/math.md §7,
// against itself (its two estimators), and against `ao`.
//
// Closed forms at the wall point of the spherical cavity opposite the hole
// (radius Rs, hole half-angle alpha, c0 = cos(alpha/2)): a cosine-weighted
// direction at angle theta from the normal leaves through the hole when
// c = cos(theta) > c0 and otherwise hits the wall at chord d = 2 Rs c, and c
// has density 2c on [0,1], so
//
//   O      = 1 - 2 Int_0^c0 (1 - mu(2 Rs c)) c dc
//   E[mu^2] = 1 - 2 Int_0^c0 (1 - mu(2 Rs c)^2) c dc   (distance estimator)
//
// With rho = R / (2 Rs), m = min(c0, rho), k = 2 sigma Rs:
//   step         O = 1 - m^2                          E[mu^2] = O
//   linear       O = 1 - m^2 + 2 m^3 / (3 rho)        E[mu^2] = 1 - m^2 + m^4 / (2 rho^2)
//   sqrt         O = 1 - m^2 + 4 m^(5/2) / (5 rho^(1/2))   E[mu^2] = 1 - m^2 + 2 m^3 / (3 rho)
//   exponential  O = 1 - 2 m^2 h(k m)                 E[mu^2] = 1 - 2 m^2 (2 h(k m) - h(2 k m))
// where h(x) = (1 - e^-x (1 + x)) / x^2 (Int_0^m e^(-kc) c dc = m^2 h(km));
// for the exponential m = min(c0, rho) because of the cut-off (mu = 1 beyond
// R). Step with m = min(c0, rho) is docs/math.md's f + max(0, c0^2 - rho^2), since
// 1 - c0^2 = f. Each closed form is checked against long-double Simpson
// quadrature of the integrals, and h against quadrature for x in 1e-12..1e12.
//
// Tolerances (as in test_ao_analytic.cpp): each covered pixel averages
// spp x rays values, so the image mean over N = pixels x spp x rays values
// has standard error sqrt(Var/N) - Var = O (1 - O) for the occlusion
// estimator (Bernoulli draws) and E[mu^2] - O^2 for the distance estimator
// (scrambled Sobol' only lowers it). We allow 4 standard errors plus the
// tessellation bound of test_ao_analytic.cpp (chords move a visibility
// boundary, or an occluder distance, by at most Rs D^2 / 8). The bound also
// covers the opaque-surface rule near the antipode, a vertex of the UV
// sphere: there the geometric normal of the pole's triangles tilts by about
// half a ring step delta from the shading normal, and the fraction
// (1 - cos delta) / 2 ~ delta^2 / 4 of the lobe that points into the
// surface is blocked (it shows as a 7.6e-6 deficit at sigma = 1e12).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <string>

#include <obscura/error.h>
#include "core/load/gltf_loader.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

std::string fmt(double v) { return formatFloat(v); }

// --- closed forms -------------------------------------------------------------

// h(x) = (1 - e^-x (1 + x)) / x^2 for x >= 0, to full double precision.
// Directly, 1 - e^-x (1 + x) = -expm1(-x) - x e^-x cancels like x (both
// terms ~ x, difference ~ x^2/2), so below x = 1/2 we sum its Taylor series
//   h(x) = Sum_{n>=2} (-1)^n (n-1)/n! x^(n-2) = 1/2 - x/3 + x^2/8 - ...
// (alternating, terms falling faster than (x/2)^n: 25 terms reach 1e-17).
double expKernel(double x) {
  if (x < 0.5) {
    double sum = 0.0, power = 1.0, factorial = 2.0;  // x^(n-2), n!
    for (int n = 2; n < 40; ++n) {
      const double term = double(n - 1) / factorial * power;
      sum += (n % 2 == 0) ? term : -term;
      if (term < 1e-18 * 0.5) break;
      power *= x;
      factorial *= double(n + 1);
    }
    return sum;
  }
  if (x > 1e150) return 1.0 / x / x;  // e^-x = 0; x^2 would overflow
  return (-std::expm1(-x) - x * std::exp(-x)) / (x * x);
}

enum class Falloff { Step, Linear, Sqrt, Exponential };
const char* name(Falloff f) {
  switch (f) {
    case Falloff::Step: return "step";
    case Falloff::Linear: return "linear";
    case Falloff::Sqrt: return "sqrt";
    case Falloff::Exponential: return "exponential";
  }
  return "?";
}

// A membership at the cavity's antipode, in the normalized units of the
// header: rho = R / (2 Rs) (may be inf), k = 2 sigma Rs.
struct Antipode {
  Falloff falloff;
  double c0, rho, k;

  double m() const { return std::min(c0, rho); }
  double O() const {
    const double m = this->m();
    switch (falloff) {
      case Falloff::Step: return 1.0 - m * m;
      case Falloff::Linear: return std::isinf(rho) ? 1.0 - m * m : 1.0 - m * m + 2.0 * m * m * m / (3.0 * rho);
      case Falloff::Sqrt:
        return std::isinf(rho) ? 1.0 - m * m : 1.0 - m * m + 0.8 * m * m * std::sqrt(m) / std::sqrt(rho);
      case Falloff::Exponential: return 1.0 - 2.0 * m * m * expKernel(k * m);
    }
    return NAN;
  }
  double meanSquare() const {  // E[mu^2] over cosine directions
    const double m = this->m();
    switch (falloff) {
      case Falloff::Step: return O();
      case Falloff::Linear:
        return std::isinf(rho) ? 1.0 - m * m : 1.0 - m * m + m * m * m * m / (2.0 * rho * rho);
      case Falloff::Sqrt: return std::isinf(rho) ? 1.0 - m * m : 1.0 - m * m + 2.0 * m * m * m / (3.0 * rho);
      case Falloff::Exponential:
        return 1.0 - 2.0 * m * m * (2.0 * expKernel(k * m) - expKernel(2.0 * k * m));
    }
    return NAN;
  }
  // mu at chord 2 Rs c, written from docs/math.md §2 independently of the
  // closed forms (long double, for the quadrature).
  long double mu(long double c) const {
    switch (falloff) {
      case Falloff::Step: return c < rho ? 0.0L : 1.0L;
      case Falloff::Linear: return std::min(c / rho, 1.0L);
      case Falloff::Sqrt: return std::min(std::sqrt(c / rho), 1.0L);
      case Falloff::Exponential: return c > rho ? 1.0L : -std::expm1(-(long double)k * c);
    }
    return NAN;
  }
};

// Composite Simpson's rule in long double, n intervals (even).
template <class F>
long double simpson(F f, long double a, long double b, int n) {
  if (b <= a) return 0.0L;
  const long double h = (b - a) / n;
  long double sum = f(a) + f(b);
  for (int i = 1; i < n; ++i) sum += f(a + h * i) * (i % 2 ? 4.0L : 2.0L);
  return sum * h / 3.0L;
}

// 1 - 2 Int_0^c0 (1 - mu^p) c dc by quadrature, split at c = rho where mu
// has a kink (linear, sqrt) or a jump (step, exponential cut-off); each piece
// takes mu's one-sided limit at the split.
long double quadrature(const Antipode& a, int power) {
  const long double split = std::min<long double>(a.c0, a.rho);
  const auto piece = [&](long double lo, long double hi, long double towards) {
    const auto f = [&](long double c) {
      const long double mu = a.mu(c == split ? std::nextafter(c, towards) : c);
      return (1.0L - (power == 1 ? mu : mu * mu)) * c;
    };
    return simpson(f, lo, hi, 1 << 18);
  };
  return 1.0L - 2.0L * (piece(0.0L, split, 0.0L) + piece(split, a.c0, 2.0L));
}

constexpr double kAlpha = 1.0471975511965976;  // 60 degrees: f = 1/4, c0^2 = 3/4
const double kC0 = std::cos(kAlpha / 2);
const double kF = (1.0 - std::cos(kAlpha)) / 2.0;
constexpr double kInf = std::numeric_limits<double>::infinity();

// h against quadrature of x^-2 Int_0^x e^-t t dt over 24 decades of x (and
// on both sides of the switch to the series at 1/2). The integrand is
// truncated at t = 120 (the tail is 121 e^-120 ~ 1e-50).
TEST(ObscuranceClosedForm, ExponentialKernelIsStableOver24Decades) {
  std::vector<double> xs = {0.4999, 0.5, 0.5001};
  for (double x = 1e-12; x <= 1.001e12; x *= std::sqrt(10.0)) xs.push_back(x);
  for (const double x : xs) {
    const long double integral =
        simpson([](long double t) { return std::exp(-t) * t; }, 0.0L, std::min<long double>(x, 120.0L), 1 << 18);
    const long double expected = integral / ((long double)x * x);
    const double got = expKernel(x);
    ASSERT_TRUE(std::isfinite(got)) << x;
    EXPECT_NEAR(got / double(expected), 1.0, 1e-13) << "x " << x;
  }
  // The cavity obscurance from it: finite, in [f, 1], f at k -> 0, 1 at k -> inf.
  for (double k = 1e-12; k <= 1.001e12; k *= 10.0) {
    const double O = Antipode{Falloff::Exponential, kC0, kInf, k}.O();
    ASSERT_TRUE(std::isfinite(O));
    EXPECT_GE(O, kF - 1e-15);
    EXPECT_LE(O, 1.0);
  }
  EXPECT_NEAR(Antipode({Falloff::Exponential, kC0, kInf, 1e-12}).O(), kF, 1e-11);
  EXPECT_NEAR(Antipode({Falloff::Exponential, kC0, kInf, 1e12}).O(), 1.0, 1e-20);
  EXPECT_DOUBLE_EQ(expKernel(0.0), 0.5);
  EXPECT_EQ(expKernel(1e300), 0.0);
}

// Every closed form (O and E[mu^2]) against direct quadrature of the
// integrals with the membership functions of docs/math.md §2.
TEST(ObscuranceClosedForm, ClosedFormsMatchQuadrature) {
  for (const Falloff f : {Falloff::Step, Falloff::Linear, Falloff::Sqrt}) {
    for (const double rho : {1e-3, 0.1, 0.5, 0.8, kC0, 1.0, 2.0, 100.0}) {
      const Antipode a{f, kC0, rho, 0.0};
      EXPECT_NEAR(a.O(), double(quadrature(a, 1)), 1e-12) << name(f) << " rho " << rho;
      EXPECT_NEAR(a.meanSquare(), double(quadrature(a, 2)), 1e-12) << name(f) << " rho " << rho;
    }
  }
  for (const double k : {1e-3, 0.1, 1.0, 4.0, 30.0}) {
    for (const double rho : {0.1, 0.5, kInf}) {
      const Antipode a{Falloff::Exponential, kC0, rho, k};
      EXPECT_NEAR(a.O(), double(quadrature(a, 1)), 1e-12) << "k " << k << " rho " << rho;
      EXPECT_NEAR(a.meanSquare(), double(quadrature(a, 2)), 1e-12) << "k " << k << " rho " << rho;
    }
  }
  // docs/math.md's forms: step = f + max(0, c0^2 - rho^2); R = inf gives f for
  // step, linear and sqrt.
  for (const double rho : {0.25, 0.5, 1.0})
    EXPECT_NEAR(Antipode({Falloff::Step, kC0, rho, 0}).O(), kF + std::max(0.0, kC0 * kC0 - rho * rho), 1e-15);
  for (const Falloff f : {Falloff::Step, Falloff::Linear, Falloff::Sqrt})
    EXPECT_NEAR(Antipode({f, kC0, kInf, 0}).O(), kF, 1e-15) << name(f);
}

// --- renders of the cavity ------------------------------------------------------

constexpr int kRings = 256, kSegments = 512;
const double kStep = std::max(2.0 * M_PI / kSegments, M_PI / kRings);
const double kTessellationBound = kStep * kStep;

std::unique_ptr<Scene> cavity(float rs) {
  auto scene = std::make_unique<Scene>();
  addSphereCavity(*scene, rs, kAlpha, kRings, kSegments);
  scene->setRobust(true);
  scene->commit();
  return scene;
}

// A very narrow view from the centre: every pixel sees the antipode
// (0,0,-Rs) to within 1e-4 Rs.
Camera antipodeCamera() { return makeLookAtCamera(Vec3(0, 0, 0), Vec3(0, 0, -1), Vec3(0, 1, 0), 1e-4f, "antipode"); }

struct Case {
  Falloff falloff;
  double rOverRs;      // R / Rs (inf allowed)
  double sigmaTimesRs;  // exponential only
};

// Parameters for the integrator, in the scene units of a cavity of radius rs.
std::vector<std::string> params(const Case& c, double rs, const std::string& estimator, int rays) {
  std::vector<std::string> p = {std::string("falloff=") + name(c.falloff), "estimator=" + estimator,
                                "rays=" + std::to_string(rays)};
  p.push_back("distance=" + fmt(c.rOverRs * rs));
  if (c.falloff == Falloff::Exponential) p.push_back("sigma=" + fmt(c.sigmaTimesRs / rs));
  return p;
}

Antipode antipode(const Case& c) { return {c.falloff, kC0, c.rOverRs / 2.0, 2.0 * c.sigmaTimesRs}; }

// Every falloff, both estimators, at two scene scales, against the closed
// forms. Prints each deviation in standard errors.
TEST(ObscuranceCavity, EveryFalloffAndEstimatorMatchesTheClosedFormAtTheAntipode) {
  const Case cases[] = {
      {Falloff::Step, 1.0, 0},          {Falloff::Step, 2.5, 0},          {Falloff::Step, kInf, 0},
      {Falloff::Linear, 1.0, 0},        {Falloff::Linear, 1.5, 0},        {Falloff::Linear, 4.0, 0},
      {Falloff::Linear, kInf, 0},   {Falloff::Sqrt, 1.0, 0},          {Falloff::Sqrt, 1.5, 0},
      {Falloff::Sqrt, 4.0, 0},          {Falloff::Sqrt, kInf, 0},     {Falloff::Exponential, kInf, 0.25},
      {Falloff::Exponential, kInf, 1.0}, {Falloff::Exponential, kInf, 4.0},
      {Falloff::Exponential, 1.0, 1.0},      // cut-off R inside the cavity
  };
  const int w = 16, h = 16, spp = 256, rays = 4;
  double worst = 0;
  for (const float rs : {1.0f, 250.0f}) {
    const auto scene = cavity(rs);
    for (const Case& c : cases) {
      const Antipode a = antipode(c);
      const double expected = a.O();
      for (const std::string estimator : {"distance", "occlusion"}) {
        const Film film = renderWith(*scene, antipodeCamera(), "obscurance", params(c, rs, estimator, rays),
                                     passSettings(w, h, spp));
        size_t n = 0;
        const double mean = meanCovered(film, kR, &n);
        ASSERT_EQ(n, size_t(w * h));
        const double var = estimator == "distance" ? a.meanSquare() - expected * expected
                                                   : expected * (1.0 - expected);
        const double se = std::sqrt(std::max(var, 1e-12) / (double(n) * spp * rays));
        const double dev = (mean - expected) / se;
        worst = std::max(worst, std::abs(dev));
        std::printf("[ obscurance ] Rs %-5g %-11s R/Rs %-4g sigma*Rs %-4g %-9s  O %.5f  mean %.5f  se %.2e  dev %+.2f se\n",
                    double(rs), name(c.falloff), c.rOverRs, c.sigmaTimesRs, estimator.c_str(), expected, mean, se, dev);
        EXPECT_NEAR(mean, expected, 4.0 * se + kTessellationBound)
            << "Rs " << rs << " " << name(c.falloff) << " R/Rs " << c.rOverRs << " sigma*Rs " << c.sigmaTimesRs
            << " " << estimator;
      }
    }
  }
  std::printf("[ obscurance ] largest deviation %.2f standard errors\n", worst);
}

// sigma -> 0: mu -> 0 for every hit, so occluders occlude fully and O -> f;
// sigma -> inf: mu -> 1, O -> 1 (docs/math.md §7).
TEST(ObscuranceCavity, ExtremeSigmaGivesEscapeFractionAndOne) {
  const auto scene = cavity(1.0f);
  const int w = 16, h = 16, spp = 128, rays = 4;
  for (const double sigma : {1e-12, 1e12}) {
    const Antipode a{Falloff::Exponential, kC0, kInf, 2.0 * sigma};
    const double expected = a.O();
    EXPECT_NEAR(expected, sigma < 1 ? kF : 1.0, 1e-11);
    for (const std::string estimator : {"distance", "occlusion"}) {
      const Film film = renderWith(*scene, antipodeCamera(), "obscurance",
                                   {"falloff=exponential", "sigma=" + fmt(sigma), "estimator=" + estimator,
                                    "rays=" + std::to_string(rays)},
                                   passSettings(w, h, spp));
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          ASSERT_TRUE(std::isfinite(film.at(kR, x, y)));
          ASSERT_GE(film.at(kR, x, y), 0.0f);
          ASSERT_LE(film.at(kR, x, y), 1.0f);
        }
      size_t n = 0;
      const double mean = meanCovered(film, kR, &n);
      ASSERT_EQ(n, size_t(w * h));
      const double var = estimator == "distance" ? a.meanSquare() - expected * expected
                                                 : expected * (1.0 - expected);
      const double se = std::sqrt(std::max(var, 1e-12) / (double(n) * spp * rays));
      std::printf("[ obscurance ] sigma %g %-9s  O %.6f  mean %.6f  diff %+.1e  se %.1e  tessellation bound %.1e\n",
                  sigma, estimator.c_str(), expected, mean, mean - expected, se, kTessellationBound);
      EXPECT_NEAR(mean, expected, 4.0 * se + kTessellationBound) << "sigma " << sigma << " " << estimator;
    }
  }
}

// The extremes of the parameters and of scene scale: every pixel finite and
// in [0,1], and still the closed form (which depends on R/Rs and sigma Rs
// only). R = 1e-9 at Rs = 1e5 is far below the float resolution of the
// scene (O = 1 - O(rho^2) ~ 1 then, and that is what comes out).
TEST(ObscuranceCavity, ExtremeParametersAndScalesStayFiniteAndCorrect) {
  const int w = 8, h = 8, spp = 64, rays = 4;
  double worst = 0;
  for (const float rs : {1e-4f, 1.0f, 1e5f}) {
    const auto scene = cavity(rs);
    for (const Falloff f : {Falloff::Step, Falloff::Linear, Falloff::Sqrt, Falloff::Exponential}) {
      for (const double R : {1e-9, 1e12, kInf}) {
        for (const double sigma : {1e-12, 1e-30, 1e12, 1e30}) {
          if (f != Falloff::Exponential && sigma != 1e-12) continue;
          const Antipode a{f, kC0, R / (2.0 * rs), 2.0 * sigma * rs};
          const double expected = a.O();
          ASSERT_TRUE(std::isfinite(expected));
          for (const std::string estimator : {"distance", "occlusion"}) {
            std::vector<std::string> p = {std::string("falloff=") + name(f), "distance=" + fmt(R),
                                          "estimator=" + estimator, "rays=" + std::to_string(rays)};
            if (f == Falloff::Exponential) p.push_back("sigma=" + fmt(sigma));
            const Film film = renderWith(*scene, antipodeCamera(), "obscurance", p, passSettings(w, h, spp));
            const std::string what = "Rs " + fmt(rs) + " " + name(f) + " R " + fmt(R) + " sigma " + fmt(sigma) +
                                     " " + estimator;
            for (int y = 0; y < h; ++y)
              for (int x = 0; x < w; ++x) {
                const float v = film.at(kR, x, y);
                ASSERT_TRUE(std::isfinite(v) && v >= 0.0f && v <= 1.0f) << what << " pixel " << v;
              }
            size_t n = 0;
            const double mean = meanCovered(film, kR, &n);
            ASSERT_EQ(n, size_t(w * h)) << what;
            const double var = estimator == "distance" ? a.meanSquare() - expected * expected
                                                       : expected * (1.0 - expected);
            const double se = std::sqrt(std::max(var, 1e-12) / (double(n) * spp * rays));
            worst = std::max(worst, std::abs(mean - expected) / se);
            EXPECT_NEAR(mean, expected, 4.0 * se + kTessellationBound) << what;
          }
        }
      }
    }
  }
  std::printf("[ obscurance ] extremes: largest deviation %.2f standard errors\n", worst);
}

// --- the default scene ------------------------------------------------------------

// The two estimators have the same expectation: their image means agree
// within the combined standard error. The film keeps no per-pixel sample
// variance, so each estimator is rendered with 8 seeds and the standard
// error of its mean is taken from the spread of the 8 image means
// (sample standard deviation / sqrt(8)). The image mean is over every pixel
// of the coverage-premultiplied R channel, whose expectation does not
// depend on the estimator. Both estimators share the camera samples of a
// seed, which correlates them positively: the variance of the difference is
// at most the sum of the variances, so the test is conservative.
TEST(ObscuranceAgreement, EstimatorsAgreeOnTheDefaultScene) {
  const auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  ASSERT_FALSE(scene->cameras.empty());
  const std::vector<std::vector<std::string>> configs = {
      {"falloff=step", "distance=0.5"},
      {"falloff=linear", "distance=1"},
      {"falloff=sqrt", "distance=1"},
      {"falloff=exponential", "sigma=2"},
      {"falloff=exponential", "sigma=1", "distance=0.5"},
  };
  constexpr int kSeeds = 8;
  for (const auto& config : configs) {
    double mean[2], se[2];
    std::string what;
    for (const auto& p : config) what += p + " ";
    for (int e = 0; e < 2; ++e) {
      std::vector<std::string> p = config;
      p.push_back(e == 0 ? "estimator=distance" : "estimator=occlusion");
      double sum = 0, sum2 = 0;
      for (int seed = 0; seed < kSeeds; ++seed) {
        const Film film = renderWith(*scene, scene->cameras[0], "obscurance", p, passSettings(64, 36, 64, 1000 + seed));
        double m = 0;
        for (int y = 0; y < film.height(); ++y)
          for (int x = 0; x < film.width(); ++x) m += film.at(kR, x, y);
        m /= double(film.width()) * film.height();
        sum += m;
        sum2 += m * m;
      }
      mean[e] = sum / kSeeds;
      const double var = std::max(0.0, (sum2 - sum * sum / kSeeds) / (kSeeds - 1));
      se[e] = std::sqrt(var / kSeeds);
    }
    const double combined = std::hypot(se[0], se[1]);
    std::printf("[ obscurance ] default scene %-40s distance %.5f  occlusion %.5f  dev %+.2f se\n", what.c_str(),
                mean[0], mean[1], (mean[0] - mean[1]) / combined);
    EXPECT_GT(combined, 0.0) << what;
    EXPECT_NEAR(mean[0], mean[1], 4.0 * combined) << what;
  }
}

bool identicalR(const Film& a, const Film& b, std::string* where) {
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x)
      if (const float va = a.at(kR, x, y), vb = b.at(kR, x, y); std::memcmp(&va, &vb, sizeof(float)) != 0) {
        *where = "pixel " + std::to_string(x) + "," + std::to_string(y) + ": " + fmt(va) + " vs " + fmt(vb);
        return false;
      }
  return true;
}

// falloff=step is ao: with the occlusion estimator r = R always, so the rays
// are ao's (same directions from the same sampler dimension, same origins,
// same tfar, the same rule for directions into the surface); with the
// distance estimator a closest hit within tfar = R exists exactly when an
// any-hit does (Embree's triangle test is the same for both queries and
// accepts t == tfar in both), and it gives mu = 0. So the images are
// bit-identical, not merely statistically equal. R = 0 is included: ao's
// zero-length rays find nothing, obscurance traces none.
TEST(ObscuranceVsAo, StepFalloffIsAoBitForBit) {
  const auto scene = loadGltf(sourcePath("scenes/default.gltf"));
  const auto cav = cavity(1.0f);
  struct View {
    const Scene* scene;
    Camera camera;
    std::vector<std::string> distances;
  };
  const View views[] = {
      {scene.get(), scene->cameras[0], {"0", "0.3", "1.5", "inf", "1e300"}},
      {cav.get(), makeLookAtCamera(Vec3(0.3f, -0.2f, -0.1f), Vec3(1, 0.2f, -0.6f), Vec3(0, 0, 1), 1.2f, "inside"),
       {"0.5", "1.7320508", "2", "inf"}},
  };
  for (const View& v : views) {
    for (const auto& R : v.distances) {
      for (const int rays : {1, 3}) {
        const RenderSettings s = passSettings(64, 36, 16, 7);
        const std::string r = "rays=" + std::to_string(rays);
        const Film ao = renderWith(*v.scene, v.camera, "ao", {"distance=" + R, r}, s);
        for (const std::string estimator : {"distance", "occlusion"}) {
          const Film ob = renderWith(*v.scene, v.camera, "obscurance",
                                     {"falloff=step", "distance=" + R, r, "estimator=" + estimator}, s);
          std::string where;
          EXPECT_TRUE(identicalR(ao, ob, &where)) << "R " << R << " " << r << " " << estimator << ": " << where;
        }
      }
    }
  }
}

// An open plane (no shading normals): every ray escapes, so O = 1 exactly
// (every pixel's W equals its coverage) for every falloff and estimator, at
// every scale, for R = 0 (nothing but the surface itself occludes) and for
// R > 0 alike.
TEST(ObscuranceEdges, OpenPlaneIsExactlyOneAtEveryScaleAndRadius) {
  for (const float scale : {1e-3f, 1.0f, 1e5f}) {
    Scene plane;
    addPlane(plane, 1e3f * scale, 0.0f);
    plane.commit();
    const Camera cam = makeLookAtCamera(Vec3(0.3f * scale, -2.0f * scale, 1.0f * scale), Vec3(0, 0, 0), Vec3(0, 0, 1),
                                        1.0f, "test");
    for (const char* f : {"step", "linear", "sqrt", "exponential"})
      for (const char* e : {"distance", "occlusion"})
        for (const double R : {0.0, 0.5 * scale, kInf}) {
          const Film film = renderWith(plane, cam, "obscurance",
                                       {std::string("falloff=") + f, "distance=" + fmt(R), "sigma=" + fmt(1.0 / scale),
                                        std::string("estimator=") + e, "rays=2"},
                                       passSettings(16, 16, 8));
          for (int y = 0; y < 16; ++y)
            for (int x = 0; x < 16; ++x)
              ASSERT_EQ(film.at(kR, x, y), film.at(kA, x, y)) << f << " " << e << " R " << R << " scale " << scale;
        }
  }
}

// Opaque surfaces: with shading normals tilted away from the geometric one
// (the plane of test_stability.cpp's grazing case, ns = normalize(1, 0, d)),
// the directions into the plane are blocked by the plane itself, for every
// falloff, estimator and R, so O is the fraction p of the cosine lobe about
// ns above the plane. p follows from the sampled directions themselves: it
// is what R = 0 returns (only the surface occludes), and with nothing else
// in the scene every R gives the same image, bit for bit.
TEST(ObscuranceEdges, DirectionsIntoTheSurfaceAreBlocked) {
  Scene scene;
  const float h = 1e3f;
  const Vec3 ns = normalize(Vec3(1, 0, 0.3f));
  scene.addWorldPrimitive({{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}}, {0, 1, 2, 0, 2, 3}, {ns, ns, ns, ns}, {}, -1);
  scene.commit();
  const Camera cam = makeLookAtCamera(Vec3(0.3f, -2, 1.5f), Vec3(0, 0, 0), Vec3(0, 0, 1), 0.8f, "tilted");
  const RenderSettings s = passSettings(16, 16, 32);
  const Film open = renderWith(scene, cam, "obscurance", {"distance=0", "rays=2"}, s);
  // Fraction of the cosine lobe about ns above the plane: by Malley's
  // method the lobe is the uniform unit disk in ns's tangent plane, and the
  // directions below the geometric plane (w.ng < 0, angle delta between ns
  // and ng) are the part of the disk outside the ellipse x^2/cos^2(delta) +
  // y^2 = 1 on one side, area pi (1 - cos delta) / 2. So
  // p = (1 + cos delta) / 2 = (1 + ns.z) / 2.
  const double p = (1.0 + double(ns.z)) / 2.0;
  size_t n = 0;
  const double mean = meanCovered(open, kR, &n);
  EXPECT_NEAR(mean, p, 4.0 * bernoulliStdErr(p, double(n) * s.spp * 2));
  for (const char* f : {"step", "linear", "sqrt", "exponential"})
    for (const char* e : {"distance", "occlusion"})
      for (const char* R : {"0.5", "inf"}) {
        const Film film = renderWith(scene, cam, "obscurance",
                                     {std::string("falloff=") + f, std::string("distance=") + R,
                                      std::string("estimator=") + e, "rays=2"},
                                     s);
        for (int y = 0; y < 16; ++y)
          for (int x = 0; x < 16; ++x) ASSERT_EQ(film.at(kR, x, y), open.at(kR, x, y)) << f << " " << e << " R " << R;
      }
}

// The occlusion estimator turns a sampled r = 0 (an empty segment) into an
// inactive ray (tnear > tfar), relying on Embree to skip it and leave tfar
// alone, so that it reads as unoccluded even where a real ray would hit.
TEST(ObscuranceEdges, InactiveRayReadsAsUnoccluded) {
  Scene plane;
  addPlane(plane, 10.0f);
  plane.commit();
  const Tracer tracer(plane.rtcScene());
  OcclusionBatch batch;
  batch.reserve(3);
  batch.push(Vec3(0, 0, 1), Vec3(0, 0, -1), kInfinity, 0.0f);  // what the integrator pushes for r = 0
  batch.push(Vec3(0, 0, 1), Vec3(0, 0, -1), 0.0f, kInfinity);   // control: blocked
  batch.push(Vec3(0, 0, 1), Vec3(0, 0, -1), 0.0f, 1.0f);        // hit at t == tfar counts (as for ao)
  tracer.occluded(batch);
  EXPECT_FALSE(batch.occluded(0));
  EXPECT_TRUE(batch.occluded(1));
  EXPECT_TRUE(batch.occluded(2));
}

// Registration: listed, no albedo needed, parameters validated.
TEST(ObscuranceEdges, RegisteredWithValidatedParameters) {
  const IntegratorDescriptor& d = IntegratorRegistry::instance().find("obscurance");
  ParamSet p(d.params, d.name);
  EXPECT_FALSE(d.needs(p).albedo);
  EXPECT_EQ(p.getEnum("falloff"), "step");
  EXPECT_EQ(p.getEnum("estimator"), "distance");
  EXPECT_TRUE(std::isinf(p.getFloat("distance")));
  EXPECT_EQ(p.getFloat("sigma"), 1.0);
  EXPECT_EQ(p.getInt("rays"), 1);
  EXPECT_THROW(p.set("falloff", "cubic"), Error);
  EXPECT_THROW(p.set("sigma", "0"), Error);
  EXPECT_THROW(p.set("sigma", "inf"), Error);
  EXPECT_THROW(p.set("distance", "-1"), Error);
  EXPECT_THROW(p.set("rays", "0"), Error);
  EXPECT_NO_THROW(p.set("sigma", "1e-30"));
  EXPECT_NO_THROW(p.set("sigma", "1e30"));
}

}  // namespace
}  // namespace obscura::test
