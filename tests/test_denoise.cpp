// The denoiser on synthetic passes (core/image/denoise.h, docs/denoise.md): a flat
// exact W stays exact, a flat noisy W keeps its mean while its variance
// drops, and step edges in depth, normal and object do not leak. The noise
// is Gaussian of a known sigma, drawn as two halves of the samples the way
// the film's W_error is made (se = |a - b| / 2), so the variance the filter
// reads is an estimate with one degree of freedom, as in a render.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "core/image/denoise.h"
#include <obscura/error.h>
#include "core/image/film.h"

namespace obscura {
namespace {

// A synthetic film: W, coverage, the variance estimate and the guides.
struct Synth {
  int w, h;
  std::vector<float> color[3], alpha, var, n[3], z, albedo[3];
  std::vector<uint32_t> obj;
  Synth(int w_, int h_) : w(w_), h(h_) {
    const size_t s = size_t(w) * size_t(h);
    for (int c = 0; c < 3; ++c) color[c].assign(s, 0.0f), n[c].assign(s, 0.0f), albedo[c].assign(s, 0.0f);
    alpha.assign(s, 1.0f), var.assign(s, 0.0f), z.assign(s, 4.0f), obj.assign(s, 0u);
    n[2].assign(s, 1.0f);
  }
  size_t at(int x, int y) const { return size_t(y) * size_t(w) + size_t(x); }
  void setW(size_t p, float v) {
    for (int c = 0; c < 3; ++c) color[c][p] = v * alpha[p];
  }
  // W = mu from two halves a, b ~ N(mu, 2 sigma^2): the pixel is (a + b) / 2
  // ~ N(mu, sigma^2) and its variance estimate (a - b)^2 / 4.
  void setNoisy(size_t p, float mu, float sigma, std::mt19937_64& rng) {
    std::normal_distribution<float> half(mu, sigma * std::sqrt(2.0f));
    const float a = half(rng), b = half(rng);
    setW(p, 0.5f * (a + b));
    var[p] = 0.25f * (a - b) * (a - b);
  }
  DenoiseInput input(bool withObject = true, bool withAlbedo = false) const {
    DenoiseInput in;
    in.width = w, in.height = h;
    for (int c = 0; c < 3; ++c) {
      in.color[c] = color[c].data();
      in.normal[c] = n[c].data();
      in.albedo[c] = withAlbedo ? albedo[c].data() : nullptr;
    }
    in.alpha = alpha.data(), in.variance = var.data(), in.depth = z.data();
    in.object = withObject ? obj.data() : nullptr;
    return in;
  }
};

struct Output {
  std::vector<float> c[3];
};
Output run(const DenoiseInput& in, const DenoiseSettings& s = {}) {
  Output o;
  for (auto& p : o.c) p.assign(size_t(in.width) * size_t(in.height), -1.0f);
  float* out[3] = {o.c[0].data(), o.c[1].data(), o.c[2].data()};
  denoise(in, s, out);
  return o;
}

// Sum of squares of the a-trous filter's equivalent kernel with no edges
// (the kernel's taps at steps 1, 2, 4, ... convolved), in 2D: the variance factor
// of the linear filter the weights reduce to in a flat region of small
// differences (an independent computation of what the filter can reach).
double linearVarianceFactor(int iterations, int taps) {
  std::vector<double> k{1.0};
  const double b3[5] = {1 / 16.0, 4 / 16.0, 6 / 16.0, 4 / 16.0, 1 / 16.0}, binomial[3] = {0.25, 0.5, 0.25};
  const double* kernel = taps == 5 ? b3 : binomial;
  for (int i = 0; i < iterations; ++i) {
    const int step = 1 << i;
    std::vector<double> next(k.size() + size_t((taps - 1) * step), 0.0);
    for (size_t j = 0; j < k.size(); ++j)
      for (int t = 0; t < taps; ++t) next[j + size_t(t * step)] += k[j] * kernel[t];
    k = next;
  }
  double s2 = 0;
  for (double v : k) s2 += v * v;
  return s2 * s2;
}

// An open plane whose W is exactly 1 with zero variance stays exactly 1 at
// every pixel, partially covered ones included (premultiplied: alpha), and
// uncovered pixels are copied through.
TEST(Denoise, ExactFlatRegionStaysExact) {
  Synth s(96, 80);
  for (int y = 0; y < s.h; ++y)
    for (int x = 0; x < s.w; ++x) {
      const size_t p = s.at(x, y);
      s.z[p] = 1.0f / (0.2f + 0.001f * float(x) + 0.0005f * float(y));  // a slanted plane: 1/Z affine
      if (x < 4) s.alpha[p] = 0.0f, s.z[p] = kBackgroundDepth, s.n[2][p] = 0.0f;
      else if (x < 6) s.alpha[p] = 0.25f * float(x - 3);
      s.setW(p, 1.0f);
    }
  const Output o = run(s.input());
  for (int y = 0; y < s.h; ++y)
    for (int x = 0; x < s.w; ++x)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(o.c[c][s.at(x, y)], s.color[c][s.at(x, y)]) << x << "," << y;
}

// A flat noisy region: the mean over the image is unchanged within its
// standard error (from the spread over independent trials), and the
// per-pixel variance drops by a factor the test measures and reports, at
// least a tenth of the linear a-trous filter's.
TEST(Denoise, FlatNoisyRegionKeepsItsMean) {
  const int w = 192, h = 192, trials = 12, border = 62;  // 2 * (1 + 2 + 4 + 8 + 16): the 5-tap footprint's radius
  const float mu = 0.6f, sigma = 0.1f;
  std::mt19937_64 rng(7);
  std::vector<double> meanIn, meanOut;
  double sqIn = 0, sqOut = 0;
  size_t nInterior = 0;
  for (int t = 0; t < trials; ++t) {
    Synth s(w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        s.z[s.at(x, y)] = 1.0f / (0.2f + 0.0005f * float(y));
        s.setNoisy(s.at(x, y), mu, sigma, rng);
      }
    const Output o = run(s.input());
    double si = 0, so = 0;
    for (size_t p = 0; p < o.c[0].size(); ++p) si += s.color[0][p], so += o.c[0][p];
    meanIn.push_back(si / double(o.c[0].size()));
    meanOut.push_back(so / double(o.c[0].size()));
    for (int y = border; y < h - border; ++y)
      for (int x = border; x < w - border; ++x) {
        const size_t p = s.at(x, y);
        sqIn += (s.color[0][p] - mu) * (s.color[0][p] - mu);
        sqOut += (o.c[0][p] - mu) * (o.c[0][p] - mu);
        ++nInterior;
      }
  }
  auto meanSe = [](const std::vector<double>& v, double& se) {
    double m = 0, s2 = 0;
    for (double x : v) m += x;
    m /= double(v.size());
    for (double x : v) s2 += (x - m) * (x - m);
    se = std::sqrt(s2 / double(v.size() - 1) / double(v.size()));
    return m;
  };
  double seIn, seOut;
  const double mIn = meanSe(meanIn, seIn), mOut = meanSe(meanOut, seOut);
  EXPECT_NEAR(mIn, mu, 4 * seIn);  // the noise itself
  EXPECT_NEAR(mOut, mu, 4 * seOut) << "denoised mean " << mOut << " se " << seOut;
  const double varIn = sqIn / double(nInterior), varOut = sqOut / double(nInterior);
  const double linear = linearVarianceFactor(DenoiseSettings{}.iterations, DenoiseSettings{}.kernel);
  EXPECT_NEAR(varIn, sigma * sigma, 4 * sigma * sigma * std::sqrt(2.0 / double(nInterior)));
  RecordProperty("flat_variance_in", std::to_string(varIn));
  RecordProperty("flat_variance_out", std::to_string(varOut));
  RecordProperty("flat_variance_factor", std::to_string(varIn / varOut));
  RecordProperty("flat_linear_factor", std::to_string(1.0 / linear));
  std::printf("flat region: variance %.3g -> %.3g (factor %.1f; the linear a-trous filter's %.1f); mean %.5f (se %.2g)\n",
              varIn, varOut, varIn / varOut, 1.0 / linear, mOut, seOut);
  EXPECT_LT(varOut, 10.0 * linear * varIn);
}

// A vertical step edge at x = w/2 between W = mu[0] and W = mu[1], each
// side noisy with sigma, the sides told apart by one guide (`kind`). Per
// column near the edge, the denoised mean over rows and trials must be
// within 4 standard errors (from the spread of the per-trial column means)
// of its side's true value: no leakage right up to the edge.
enum class Edge { Depth, Normal, Object, None };

struct EdgeResult {
  std::vector<double> mean, se;  // per column
};

EdgeResult stepEdge(Edge kind, const DenoiseSettings& settings, int trials = 16) {
  const int w = 96, h = 128;
  const float mu[2] = {0.3f, 0.7f}, sigma = 0.1f;
  std::mt19937_64 rng(11);
  std::vector<std::vector<double>> perTrial(static_cast<size_t>(w));
  for (int t = 0; t < trials; ++t) {
    Synth s(w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const size_t p = s.at(x, y);
        const int side = x >= w / 2;
        if (kind == Edge::Depth) s.z[p] = side ? 5.0f : 4.0f;
        if (kind == Edge::Normal && side) s.n[0][p] = std::sqrt(0.5f), s.n[2][p] = std::sqrt(0.5f);  // 45 degrees
        if (kind == Edge::Object) s.obj[p] = side ? 2u : 1u;
        s.setNoisy(p, mu[side], sigma, rng);
      }
    const Output o = run(s.input(), settings);
    for (int x = 0; x < w; ++x) {
      double m = 0;
      for (int y = 0; y < h; ++y) m += o.c[0][s.at(x, y)];
      perTrial[size_t(x)].push_back(m / h);
    }
  }
  EdgeResult r;
  for (int x = 0; x < w; ++x) {
    const auto& v = perTrial[size_t(x)];
    double m = 0, s2 = 0;
    for (double a : v) m += a;
    m /= double(v.size());
    for (double a : v) s2 += (a - m) * (a - m);
    r.mean.push_back(m);
    r.se.push_back(std::sqrt(s2 / double(v.size() - 1) / double(v.size())));
  }
  return r;
}

// Columns within the footprint's reach of the edge, on both sides.
void expectNoLeak(Edge kind, const char* name) {
  const EdgeResult r = stepEdge(kind, DenoiseSettings{});
  const int w = int(r.mean.size());
  double worst = 0;
  for (int x = w / 2 - 8; x < w / 2 + 8; ++x) {
    const double truth = x >= w / 2 ? 0.7 : 0.3;
    EXPECT_NEAR(r.mean[size_t(x)], truth, 4 * r.se[size_t(x)]) << name << " edge, column " << x - w / 2 << " from it";
    worst = std::max(worst, std::abs(r.mean[size_t(x)] - truth) / r.se[size_t(x)]);
  }
  std::printf("%s edge: worst column |bias| / se = %.2f (columns -8..7 from the edge; se at the edge %.2g)\n", name,
              worst, r.se[size_t(w / 2)]);
}

TEST(Denoise, DepthEdgeDoesNotLeak) { expectNoLeak(Edge::Depth, "depth"); }
TEST(Denoise, NormalEdgeDoesNotLeak) { expectNoLeak(Edge::Normal, "normal"); }
TEST(Denoise, ObjectEdgeDoesNotLeak) { expectNoLeak(Edge::Object, "object"); }

// The control: the same step with no guide telling the sides apart, and the
// luminance term off, leaks - so the tests above can see a leak.
TEST(Denoise, UnguidedEdgeLeaksVisibly) {
  DenoiseSettings s;
  s.sigmaLuminance = 0.0f;
  const EdgeResult r = stepEdge(Edge::None, s, 4);
  const size_t e = r.mean.size() / 2;
  EXPECT_GT(std::abs(r.mean[e] - 0.7), 10 * r.se[e]);
  EXPECT_GT(std::abs(r.mean[e - 1] - 0.3), 10 * r.se[e - 1]);
}

// A ramp up to an edge (docs/denoise.md "Symmetric taps"): left of an
// object edge W rises linearly towards it (ao falling towards a crease,
// seen from the other side), right of it a flat 0.9. A pixel next to the
// edge has taps only on its own side; with each tap its own weight they all
// lie away from the edge, where the ramp is lower, and pull it down. With
// mirrored taps (the default) every tap's mirror is kept or dropped with
// it, so the ramp cancels: per column, the mean over rows and trials is the
// ramp's value within 4 standard errors (from the spread over trials).
struct RampResult {
  std::vector<double> mean, se, truth;
};
RampResult rampToEdge(const DenoiseSettings& settings) {
  const int w = 96, h = 64, trials = 16;
  const float slope = 0.01f, sigma = 0.05f;
  std::mt19937_64 rng(5);
  std::vector<std::vector<double>> perTrial(static_cast<size_t>(w));
  RampResult r;
  for (int x = 0; x < w; ++x) r.truth.push_back(x >= w / 2 ? 0.9 : 0.5 + double(slope) * (x - w / 2));
  for (int t = 0; t < trials; ++t) {
    Synth s(w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const size_t p = s.at(x, y);
        s.obj[p] = x >= w / 2 ? 2u : 1u;
        s.setNoisy(p, float(r.truth[size_t(x)]), sigma, rng);
      }
    const Output o = run(s.input(), settings);
    for (int x = 0; x < w; ++x) {
      double m = 0;
      for (int y = 0; y < h; ++y) m += o.c[0][s.at(x, y)];
      perTrial[size_t(x)].push_back(m / h);
    }
  }
  for (int x = 0; x < w; ++x) {
    const auto& v = perTrial[size_t(x)];
    double m = 0, s2 = 0;
    for (double a : v) m += a;
    m /= double(v.size());
    for (double a : v) s2 += (a - m) * (a - m);
    r.mean.push_back(m);
    r.se.push_back(std::sqrt(s2 / double(v.size() - 1) / double(v.size())));
  }
  return r;
}

TEST(Denoise, RampUpToAnEdgeKeepsItsValue) {
  const RampResult sym = rampToEdge(DenoiseSettings{});
  DenoiseSettings own;
  own.symmetric = false;
  const RampResult asym = rampToEdge(own);
  const int w = int(sym.mean.size());
  for (int x = w / 2 - 8; x < w / 2; ++x)
    EXPECT_NEAR(sym.mean[size_t(x)], sym.truth[size_t(x)], 4 * sym.se[size_t(x)]) << "column " << x - w / 2;
  const size_t e = size_t(w / 2 - 1);
  std::printf("ramp to an edge, column next to it: exact %.4f, mirrored taps %.4f (se %.2g), own weights %.4f (se %.2g)\n",
              sym.truth[e], sym.mean[e], sym.se[e], asym.mean[e], asym.se[e]);
  // The control: with each tap its own weight the column at the edge is
  // pulled down the ramp, visibly (so the assertion above can see a bias).
  EXPECT_LT(asym.mean[e], asym.truth[e] - 4 * asym.se[e]);
}

// The result does not depend on the thread count.
// The gain (adaptive sampling's measure of where the filter helps): with the
// luminance term off and one flat plane, every weight is the kernel's. One
// iteration multiplies an interior pixel's uniform variance by
// (sum k^2)^2 = (3/8)^2 exactly; over 5 the propagated product (3/8)^10
// ignores that the iterations reuse pixels and falls below the linear
// filter's true factor (linearVarianceFactor, computed here independently),
// which is the floor. A pixel with variance 0 or without W has gain 1; the
// denoised pass is the one denoise() without the gain writes.
TEST(Denoise, GainIsTheVarianceTheIterationsCarry) {
  Synth f(128, 128);
  for (int y = 0; y < f.h; ++y)
    for (int x = 0; x < f.w; ++x) {
      f.setW(f.at(x, y), 0.5f + 0.001f * float((x * 7 + y * 3) % 11));
      f.var[f.at(x, y)] = 0.01f;
    }
  // Both more than the footprint's reach (31 pixels) from the interior checked below.
  f.var[f.at(3, 3)] = 0.0f;
  f.alpha[f.at(124, 124)] = 0.0f;
  const auto gainOf = [&](int iterations, Output& o) {
    DenoiseSettings s;
    s.sigmaLuminance = 0.0f;
    s.iterations = iterations;
    std::vector<float> gain(size_t(f.w) * size_t(f.h), -1.0f);
    for (auto& p : o.c) p.assign(gain.size(), -1.0f);
    float* out[3] = {o.c[0].data(), o.c[1].data(), o.c[2].data()};
    denoise(f.input(), s, out, gain.data());
    const Output plain = run(f.input(), s);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(o.c[c], plain.c[c]) << c;
    return gain;
  };
  Output o;
  const std::vector<float> one = gainOf(1, o), five = gainOf(5, o);
  const double propagated1 = std::pow(3.0 / 8.0, 2), floor5 = linearVarianceFactor(5, 3);
  ASSERT_LT(std::pow(3.0 / 8.0, 10), floor5);  // the product falls below the floor
  // Float sums of 9 taps per iteration: a few 1e-6 relative.
  for (int y = 40; y < f.h - 40; ++y)
    for (int x = 40; x < f.w - 40; ++x) {
      ASSERT_NEAR(one[f.at(x, y)], propagated1, 1e-5 * propagated1) << x << "," << y;
      ASSERT_NEAR(five[f.at(x, y)], floor5, 1e-5 * floor5) << x << "," << y;
    }
  for (const auto* g : {&one, &five}) {
    EXPECT_EQ((*g)[f.at(3, 3)], 1.0f);
    EXPECT_EQ((*g)[f.at(124, 124)], 1.0f);
    for (float v : *g) ASSERT_TRUE(v > 0.0f && v <= 1.0f) << v;
  }
  // At the border a single iteration averages fewer taps: less reduction.
  EXPECT_GT(one[f.at(0, 64)], 1.5 * propagated1);
}

// Sample counts weigh the taps (inverse variance for a shared per-sample
// variance). Equal counts change nothing, bit for bit; with the luminance
// term off and one iteration, a pixel with W = 1 and 4 samples among
// neighbours with W = 0 and 1 sample is the count-weighted mean of its 3 x 3
// binomial taps: 4 (1/4) / (4 (1/4) + 1 (3/4)) = 4/7 (1/4 without counts).
TEST(Denoise, SampleCountsWeighTheTaps) {
  Synth f(32, 32);
  std::mt19937_64 rng(7);
  for (int y = 0; y < f.h; ++y)
    for (int x = 0; x < f.w; ++x) f.setNoisy(f.at(x, y), 0.5f, 0.1f, rng);
  std::vector<float> equal(size_t(f.w) * size_t(f.h), 8.0f);
  DenoiseInput counted = f.input();
  counted.samples = equal.data();
  const Output a = run(f.input()), b = run(counted);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(a.c[c], b.c[c]) << c;

  Synth g(16, 16);
  for (int y = 0; y < g.h; ++y)
    for (int x = 0; x < g.w; ++x) g.setW(g.at(x, y), 0.0f);
  g.setW(g.at(8, 8), 1.0f);
  std::vector<float> counts(size_t(g.w) * size_t(g.h), 1.0f);
  counts[g.at(8, 8)] = 4.0f;
  DenoiseSettings s;
  s.sigmaLuminance = 0.0f;
  s.iterations = 1;
  DenoiseInput in = g.input();
  EXPECT_NEAR(run(in, s).c[0][g.at(8, 8)], 0.25f, 1e-6f);
  in.samples = counts.data();
  EXPECT_NEAR(run(in, s).c[0][g.at(8, 8)], 4.0f / 7.0f, 1e-6f);
}

TEST(Denoise, IndependentOfThreads) {
  Synth s(64, 48);
  std::mt19937_64 rng(3);
  for (int y = 0; y < s.h; ++y)
    for (int x = 0; x < s.w; ++x) s.setNoisy(s.at(x, y), x < 30 ? 0.4f : 0.9f, 0.1f, rng);
  DenoiseSettings one, two;
  one.threads = 1, two.threads = 2;
  const Output a = run(s.input(), one), b = run(s.input(), two);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(a.c[c], b.c[c]);
}

// The filter takes a row's pixels kLanes at a time and finishes it one by
// one, with the same operations per pixel: where a row splits must not
// change a bit. The same 61 live columns (noisy W, a depth step, a normal
// crease and a second object; albedo guide on and off) padded on the right
// with 0..9 columns that hold no W (never read: their taps weigh exactly 0),
// and on the left with 0, 3 or 8, move every pixel between the vector part
// and the scalar tail of some tap pass, and move where each row's span of
// pixels with W starts and ends (the taps are summed over that span only);
// the live pixels must come out bit for bit the same.
TEST(Denoise, RowSplitChangesNoBit) {
  const int live = 61, h = 23;
  for (bool albedo : {false, true}) {
    std::vector<Output> outs;
    for (int left : {0, 3, 8})
    for (int pad = 0; pad <= 9; ++pad) {
      Synth g(left + live + pad, h);
      std::mt19937_64 rng(11);
      for (int y = 0; y < h; ++y)
        for (int X = 0; X < left + live + pad; ++X) {
          const size_t p = g.at(X, y);
          const int x = X - left;
          if (x < 0 || x >= live) {
            g.alpha[p] = 0.0f, g.z[p] = kBackgroundDepth;
            continue;
          }
          g.z[p] = x < 20 ? 4.0f : 6.0f;
          if (y > 15) g.n[0][p] = 1.0f, g.n[2][p] = 0.0f;
          if (x > 45) g.obj[p] = 2u;
          for (int c = 0; c < 3; ++c) g.albedo[c][p] = x % 7 < 3 ? 0.3f : 0.8f;
          g.setNoisy(p, 0.3f + 0.01f * float(x), 0.1f, rng);
        }
      outs.push_back(run(g.input(true, albedo)));
      const Output& a = outs.front();
      const Output& b = outs.back();
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < live; ++x)
          for (int c = 0; c < 3; ++c)
            ASSERT_EQ(a.c[c][size_t(y) * size_t(live) + size_t(x)], b.c[c][g.at(left + x, y)])
                << "left " << left << " pad " << pad << " albedo " << albedo << " at " << x << "," << y;
    }
  }
}

// A workspace reused across calls (the adaptive rounds' gain pass, then the
// final filter) gives what a fresh call gives, whatever the call before it
// held: another size, albedo planes or none, a gain or none.
TEST(Denoise, AReusedWorkspaceChangesNothing) {
  const auto synth = [](int w, int h, uint64_t seed) {
    Synth g(w, h);
    std::mt19937_64 rng(seed);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const size_t p = g.at(x, y);
        g.z[p] = x < w / 2 ? 4.0f : 5.0f;
        for (int c = 0; c < 3; ++c) g.albedo[c][p] = y % 5 < 2 ? 0.2f : 0.7f;
        g.setNoisy(p, 0.5f + 0.01f * float(y), 0.1f, rng);
      }
    return g;
  };
  const Synth big = synth(40, 30, 1), small = synth(23, 17, 2);
  struct Call {
    const Synth* g;
    bool albedo, gain;
  };
  const Call calls[] = {{&big, true, true}, {&small, false, false}, {&big, false, true}, {&big, true, false}};
  DenoiseWorkspace reused;
  for (const Call& c : calls) {
    const DenoiseInput in = c.g->input(true, c.albedo);
    const size_t n = size_t(in.width) * size_t(in.height);
    std::vector<float> fresh[4], again[4];
    for (auto* v : {fresh, again})
      for (int k = 0; k < 4; ++k) v[k].assign(n, -1.0f);
    float* outF[3] = {fresh[0].data(), fresh[1].data(), fresh[2].data()};
    float* outR[3] = {again[0].data(), again[1].data(), again[2].data()};
    denoise(in, {}, outF, c.gain ? fresh[3].data() : nullptr);
    denoise(in, {}, outR, c.gain ? again[3].data() : nullptr, &reused);
    for (int k = 0; k < 4; ++k) EXPECT_EQ(fresh[k], again[k]) << in.width << "x" << in.height << " plane " << k;
    if (!c.gain) continue;
    // The gain alone (no output planes, as the adaptive rounds ask it): the same gain.
    std::vector<float> gainOnly(n, -1.0f);
    denoise(in, {}, nullptr, gainOnly.data(), &reused);
    EXPECT_EQ(gainOnly, fresh[3]) << in.width << "x" << in.height;
  }
  EXPECT_THROW(denoise(big.input(), {}, nullptr, nullptr), Error);
}

// Missing planes and bad settings are one clear error naming the field.
TEST(Denoise, BadInputIsAnError) {
  Synth s(8, 8);
  DenoiseInput in = s.input();
  in.variance = nullptr;
  try {
    run(in);
    FAIL() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("variance"), std::string::npos) << e.what();
  }
  DenoiseSettings bad;
  bad.sigmaDepth = -1.0f;
  try {
    run(s.input(), bad);
    FAIL() << "no error";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("sigmaDepth"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace obscura
